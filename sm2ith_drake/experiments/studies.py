"""The studies (Section V and issue 12) as data: cells (scenario, robot,
people), methods (the YAML overrides that make SM²ITH, CVMM, React or the
weighted sum), the axes (safety variant, people model), seeds, the panels
of their plots and the paper's findings they test.

Every method runs the same seeds in every cell, variant and people model
(paired seeds), so a method's row can be compared with another's of the
same seed.
"""

from __future__ import annotations

import dataclasses

from sm2ith_drake.experiments.findings import CONTACT_FREE_SUCCESS
from sm2ith_drake.experiments.people import AS_SCENARIO, DoorwayPeople


@dataclasses.dataclass(frozen=True)
class Cell:
    """One scenario of a study (a box group in the plots)."""

    scenario_file: str
    scenario: str
    # The panel family (e.g. "banner", "cup", or the robot's name).
    family: str
    robot: str
    humans: int
    # Draws the cell's people from the seed; None: the scenario's own people,
    # varied by the seed (people.ApplySeed).
    people: DoorwayPeople | None = None

    @property
    def name(self) -> str:
        """The cell's name: the scenario's, with the number of people when
        they are drawn (one scenario, several cells)."""
        return (
            self.scenario if self.people is None else f"{self.scenario}_{self.humans}h"
        )


@dataclasses.dataclass(frozen=True)
class Method:
    """A controller variant: YAML applied on top of every cell's scenario."""

    name: str
    scenario_text: str = ""


@dataclasses.dataclass(frozen=True)
class Panel:
    """One box-and-whisker panel: ``metric`` over the rows of ``family``,
    grouped by the number of humans, one box per method."""

    title: str
    metric: str
    ylabel: str
    family: str


@dataclasses.dataclass(frozen=True)
class Finding:
    """One of the paper's claims as paired comparisons: on ``family`` (and
    ``humans``, if given; else every number of people pooled), ``method``
    does better on ``metric`` than each of ``than``. Holds when every paired
    difference's 95 % CI lies on the claimed side of 0; does not hold when
    one lies on the other side; else not distinguishable."""

    key: str
    claim: str
    family: str
    metric: str
    method: str
    than: tuple
    lower_is_better: bool = True
    humans: tuple = ()


@dataclasses.dataclass(frozen=True)
class Study:
    name: str
    description: str
    cells: tuple
    methods: tuple
    panels: tuple
    # Default axes (any value of people.VARIANTS / PEOPLE_MODELS can be
    # asked for with --variant / --people) and seeds per cell.
    variants: tuple = ("paper", "safe")
    people: tuple = ("orca", "social_force", "instructed")
    seeds: int = 10
    findings: tuple = ()
    # Columns of the report's per-method summary table.
    summary: tuple = (
        "success",
        "time_to_goal",
        "freezing_time",
        "collision",
        "robot_closing_contact",
        "min_human_gap",
        "intimate_space_time_base",
        "intimate_space_time",
        "fallbacks",
        "step_time_median_ms",
    )


def _Cells(file, family, robot, names_and_humans):
    return tuple(Cell(file, name, family, robot, h) for name, h in names_and_humans)


_BC = "banner_cup.scenarios.yaml"
_PP = "pick_and_place.scenarios.yaml"
_CR = "crossing.scenarios.yaml"
_DW = "doorway.scenarios.yaml"
_CVMM = Method("CVMM", "{prediction: {predictor: cvmm}}")
_REACT = Method("React", "{prediction: {predictor: react}}")
_ROBOTS = (("ridgeback_ur10", "Ridgeback–UR10"), ("stretch3", "Stretch 3"))


def _RobotPanels(*panels):
    """The same (title, metric, unit) panels for each robot, one row each."""
    return tuple(
        Panel(f"{label}: {title}", metric, unit, robot)
        for robot, label in _ROBOTS
        for title, metric, unit in panels
    )


# The doorway's people (experiments/people.py), per robot: the geometry of
# diagrams/doorway.scenarios.yaml.
DOORWAY_PEOPLE = {
    "stretch3": DoorwayPeople(
        corridor_half_width=1.0,
        door_half_width=0.5,
        robot_start=(0.0, -1.5),
        robot_radius=0.28,
        start_y=(1.0, 4.5),
        goal_y=(3.0, 4.5),
    ),
    "ridgeback_ur10": DoorwayPeople(
        corridor_half_width=1.35,
        door_half_width=0.85,
        robot_start=(0.0, -2.0),
        robot_radius=0.62,
        start_y=(1.0, 5.0),
        goal_y=(3.5, 5.0),
    ),
}
DOORWAY_CROWDS = (1, 2, 3, 5)

STUDIES = {
    "banner_cup": Study(
        name="banner_cup",
        description=(
            "Section V.A: Stretch 3 crosses the room with its arm extended "
            "while 1–3 people meet it at the centre. banner: EE ≥ base; cup: "
            "base ≥ EE. SM²ITH (lexicographic) vs the weighted sum."
        ),
        cells=_Cells(
            _BC,
            "banner",
            "stretch3",
            [(f"banner_stretch3_{h}h", h) for h in (1, 2, 3)],
        )
        + _Cells(
            _BC, "cup", "stretch3", [(f"cup_stretch3_{h}h", h) for h in (1, 2, 3)]
        ),
        methods=(
            Method("SM2ITH"),
            Method("weighted_sum", "{controller: {method: weighted_sum}}"),
        ),
        panels=(
            Panel("Banner (E≥B): avg. EE error", "ee_error_mean", "m", "banner"),
            Panel("Banner (E≥B): max. EE error", "ee_error_max", "m", "banner"),
            Panel("Cup (B≥E): avg. base deviation", "base_path_deviation", "m", "cup"),
            Panel("Cup (B≥E): navigation time", "navigation_time", "s", "cup"),
        ),
        # 2 × 120 runs ≈ 28 min with --jobs 2; add a people model with
        # --people.
        people=("orca",),
        findings=(
            Finding(
                "(a)",
                "banner, 3 people: SM²ITH's avg. EE error below the weighted sum's",
                "banner",
                "ee_error_mean",
                "SM2ITH",
                ("weighted_sum",),
                humans=(3,),
            ),
            Finding(
                "(a)",
                "banner: SM²ITH's max. EE error below the weighted sum's",
                "banner",
                "ee_error_max",
                "SM2ITH",
                ("weighted_sum",),
            ),
            Finding(
                "(a)",
                "cup: SM²ITH's base deviation below the weighted sum's",
                "cup",
                "base_path_deviation",
                "SM2ITH",
                ("weighted_sum",),
            ),
            Finding(
                "(a)",
                "cup: SM²ITH's navigation time below the weighted sum's",
                "cup",
                "navigation_time",
                "SM2ITH",
                ("weighted_sum",),
            ),
        ),
    ),
    "pick_and_place": Study(
        name="pick_and_place",
        description=(
            "Section V.B: pick-and-place on both robots with 1–2 people "
            "crossing the room. SM²ITH (interactive ORCA-KKT prediction) vs "
            "CVMM (constant velocity) vs React (no prediction)."
        ),
        cells=tuple(
            c
            for robot, _ in _ROBOTS
            for c in _Cells(
                _PP,
                robot,
                robot,
                [(f"pick_and_place_{robot}_{h}h", h) for h in (1, 2)],
            )
        ),
        methods=(Method("SM2ITH"), _CVMM, _REACT),
        panels=_RobotPanels(
            ("navigation time", "navigation_time", "s"),
            ("avg. base deviation", "base_path_deviation", "m"),
            ("time in intimate space (base)", "intimate_space_time_base", "s"),
            ("avg. human distance", "mean_human_distance", "m"),
        ),
        # 2 × 120 runs ≈ 33 min with --jobs 2 (the budget is 60 min); add a
        # people model with --people (≈ 33 min more each).
        people=("orca",),
        findings=tuple(
            Finding(
                "(b)",
                f"{label}: CVMM's base deviation above SM²ITH's and React's",
                robot,
                "base_path_deviation",
                "CVMM",
                ("SM2ITH", "React"),
                lower_is_better=False,
            )
            for robot, label in _ROBOTS
        )
        + tuple(
            Finding(
                "(b)",
                f"{label}: CVMM's navigation time above SM²ITH's and React's",
                robot,
                "navigation_time",
                "CVMM",
                ("SM2ITH", "React"),
                lower_is_better=False,
            )
            for robot, label in _ROBOTS
        )
        + (
            Finding(
                "(c)",
                "Ridgeback–UR10: React's time in intimate space (base) above "
                "SM²ITH's and CVMM's",
                "ridgeback_ur10",
                "intimate_space_time_base",
                "React",
                ("SM2ITH", "CVMM"),
                lower_is_better=False,
            ),
        ),
    ),
    "adversarial": Study(
        name="adversarial",
        description=(
            "Section V.C as the paper sets it up: a person walks head-on "
            "along Stretch 3's path toward a point behind it and adapts "
            "(headon_stretch3). SM²ITH vs CVMM: the share of steps with the "
            "person within 2 m in which the base moves toward its goal, "
            "retreat and time to goal."
        ),
        cells=(Cell(_CR, "headon_stretch3", "headon", "stretch3", 1),),
        methods=(Method("SM2ITH"), _CVMM),
        panels=(
            Panel("Progress toward the goal", "progress_share", "share", "headon"),
            Panel("Retreat from the goal", "base_retreat", "m", "headon"),
            Panel("Time to goal", "time_to_goal", "s", "headon"),
            Panel("Closest approach (gap)", "min_human_gap", "m", "headon"),
        ),
        findings=(
            Finding(
                "(d)",
                "SM²ITH keeps moving toward its goal more than CVMM",
                "headon",
                "progress_share",
                "SM2ITH",
                ("CVMM",),
                lower_is_better=False,
            ),
            Finding(
                "(d)",
                "SM²ITH retreats less than CVMM",
                "headon",
                "base_retreat",
                "SM2ITH",
                ("CVMM",),
            ),
        ),
        summary=(
            "progress_share",
            "base_retreat",
            "time_to_goal",
            "freezing_time",
            "collision",
            "robot_closing_contact",
            "min_human_gap",
            "fallbacks",
        ),
    ),
    "pursuer": Study(
        name="pursuer",
        description=(
            "A stress test (not the paper's setup): a person re-aims at "
            "Stretch 3 at twice its speed and stops 10 cm from it, on its way "
            "to a goal 3 m ahead (adversarial_stretch3). SM²ITH vs CVMM: "
            "retreat, final distance to the goal, contacts."
        ),
        cells=(Cell(_CR, "adversarial_stretch3", "pursuer", "stretch3", 1),),
        methods=(Method("SM2ITH"), _CVMM),
        panels=(
            Panel("Retreat from the goal", "base_retreat", "m", "pursuer"),
            Panel("Final distance to the goal", "base_error_final", "m", "pursuer"),
            Panel("Base deviation", "base_path_deviation", "m", "pursuer"),
            Panel("Closest approach (gap)", "min_human_gap", "m", "pursuer"),
        ),
        # The pursuer is adversarial whatever the people axis says.
        people=(AS_SCENARIO,),
        summary=(
            "base_retreat",
            "base_error_final",
            "freezing_time",
            "collision",
            "robot_closing_contact",
            "min_human_gap",
            "fallbacks",
            "step_time_median_ms",
        ),
    ),
    "doorway": Study(
        name="doorway",
        description=(
            "Issue 12: a corridor with a door; the robot drives through the "
            "door while 1, 2, 3 or 5 people drawn per seed cross it both "
            "ways (0.5–1.5 m/s). SM²ITH vs CVMM vs React: success (goal "
            "within tolerance before the time limit), time to goal, freezing "
            "time, collisions, clearance, intimate-space time."
        ),
        cells=tuple(
            Cell(_DW, f"doorway_{robot}", robot, robot, h, DOORWAY_PEOPLE[robot])
            for robot, _ in _ROBOTS
            for h in DOORWAY_CROWDS
        ),
        methods=(Method("SM2ITH"), _CVMM, _REACT),
        panels=_RobotPanels(
            ("time to goal", "time_to_goal", "s"),
            ("freezing time", "freezing_time", "s"),
            ("time in intimate space (base)", "intimate_space_time_base", "s"),
            ("closest approach (gap)", "min_human_gap", "m"),
        ),
        # 2 × 240 runs ≈ 70 min with --jobs 2; add a people model with
        # --people.
        people=("orca",),
        # Issue 12's target: SM²ITH reaches the goal, and reaches it without
        # touching anyone, more often than CVMM and React, pooled over the
        # numbers of people (pairs within each cell); then success at each
        # number of people, where the target (at least as often) is missed
        # only by a "does not hold".
        findings=tuple(
            Finding(
                "doorway",
                f"{label}: SM²ITH {what} more often than CVMM and React",
                robot,
                metric,
                "SM2ITH",
                ("CVMM", "React"),
                lower_is_better=False,
            )
            for robot, label in _ROBOTS
            for what, metric in (
                ("reaches the goal", "success"),
                ("reaches the goal without contact", CONTACT_FREE_SUCCESS),
            )
        )
        + tuple(
            Finding(
                "doorway",
                f"{label}, {h} {'person' if h == 1 else 'people'}: SM²ITH "
                "reaches the goal more often than CVMM and React",
                robot,
                "success",
                "SM2ITH",
                ("CVMM", "React"),
                lower_is_better=False,
                humans=(h,),
            )
            for robot, label in _ROBOTS
            for h in DOORWAY_CROWDS
        ),
        summary=(
            "success",
            CONTACT_FREE_SUCCESS,
            "time_to_goal",
            "freezing_time",
            "collision",
            "robot_closing_contact",
            "min_human_gap",
            "min_obstacle_clearance",
            "wall_collision",
            "intimate_space_time_base",
            "intimate_space_time",
            "fallbacks",
        ),
    ),
}
