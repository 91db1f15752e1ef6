"""The paper's studies (Section V) as data: cells (scenario, robot, people),
methods (the YAML overrides that make SM²ITH, CVMM, React or the weighted
sum), seeds, and the panels of their plots.
"""

from __future__ import annotations

import dataclasses


@dataclasses.dataclass(frozen=True)
class Cell:
    """One scenario of a study (a box group in the plots)."""

    scenario_file: str
    scenario: str
    # The panel family (e.g. "banner", "cup", or the robot's name).
    family: str
    robot: str
    humans: int


@dataclasses.dataclass(frozen=True)
class Method:
    """A controller variant: YAML applied on top of every cell's scenario."""

    name: str
    scenario_text: str = ""
    seeds: int = 5


@dataclasses.dataclass(frozen=True)
class Panel:
    """One box-and-whisker panel: ``metric`` over the rows of ``family``,
    grouped by the number of humans, one box per method."""

    title: str
    metric: str
    ylabel: str
    family: str


@dataclasses.dataclass(frozen=True)
class Study:
    name: str
    description: str
    cells: tuple
    methods: tuple
    panels: tuple
    # Columns of the report's per-method summary table.
    summary: tuple = (
        "success",
        "navigation_time",
        "collision",
        "min_human_gap",
        "intimate_space_time",
        "fallbacks",
        "step_time_median_ms",
        "step_time_p95_ms",
    )


def _Cells(file, family, robot, names_and_humans):
    return tuple(Cell(file, name, family, robot, h) for name, h in names_and_humans)


_BC = "banner_cup.scenarios.yaml"


_PP = "pick_and_place.scenarios.yaml"


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
            Method("SM2ITH", "", 5),
            Method("weighted_sum", "{controller: {method: weighted_sum}}", 5),
        ),
        panels=(
            Panel("Banner (E≥B): avg. EE error", "ee_error_mean", "m", "banner"),
            Panel("Banner (E≥B): max. EE error", "ee_error_max", "m", "banner"),
            Panel("Cup (B≥E): avg. base deviation", "base_path_deviation", "m", "cup"),
            Panel("Cup (B≥E): navigation time", "navigation_time", "s", "cup"),
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
            for robot in ("ridgeback_ur10", "stretch3")
            for c in _Cells(
                _PP,
                robot,
                robot,
                [(f"pick_and_place_{robot}_{h}h", h) for h in (1, 2)],
            )
        ),
        methods=(
            Method("SM2ITH", "", 10),
            Method("CVMM", "{prediction: {predictor: cvmm}}", 5),
            Method("React", "{prediction: {predictor: react}}", 5),
        ),
        panels=tuple(
            Panel(f"{label}: {title}", metric, unit, robot)
            for robot, label in (
                ("ridgeback_ur10", "Ridgeback–UR10"),
                ("stretch3", "Stretch 3"),
            )
            for title, metric, unit in (
                ("navigation time", "navigation_time", "s"),
                ("avg. base deviation", "base_path_deviation", "m"),
                ("time in intimate space", "intimate_space_time", "s"),
                ("avg. human distance", "mean_human_distance", "m"),
            )
        ),
    ),
    "adversarial": Study(
        name="adversarial",
        description=(
            "Section V.C: a person walks straight at Stretch 3 on its way to "
            "a goal 3 m ahead. SM²ITH vs CVMM: how far the robot retreats and "
            "how close it ends to its goal."
        ),
        cells=(
            Cell(
                "crossing.scenarios.yaml",
                "adversarial_stretch3",
                "adversarial",
                "stretch3",
                1,
            ),
        ),
        methods=(
            Method("SM2ITH", "", 5),
            Method("CVMM", "{prediction: {predictor: cvmm}}", 5),
        ),
        panels=(
            Panel("Retreat from the goal", "base_retreat", "m", "adversarial"),
            Panel("Final distance to the goal", "base_error_final", "m", "adversarial"),
            Panel("Base deviation", "base_path_deviation", "m", "adversarial"),
            Panel("Closest approach (gap)", "min_human_gap", "m", "adversarial"),
        ),
        summary=(
            "base_retreat",
            "base_error_final",
            "collision",
            "min_human_gap",
            "fallbacks",
            "step_time_median_ms",
        ),
    ),
}
