"""The people of a campaign run and the studies' axes (issue 12).

- A seed varies a scenario's own people reproducibly (:func:`ApplySeed`), or,
  for the doorway, draws them at random (:class:`DoorwayPeople`); either way
  the same seed gives every method the same people (paired seeds).
- The ``people`` axis swaps the behaviour of every person who walks to
  goals (orca, social_force, instructed) for one model; scripted and
  adversarial people stay as their scenario needs them.
- The ``variant`` axis is the safety formulation: ``paper`` (the paper's
  DT-CBF only) or ``safe`` (the shipped safety mechanism), as YAML.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import yaml

from sm2ith_drake.scenario import HumanConfig, Scenario

# safety.mode of each variant (SafetyConfig.mode).
VARIANTS = ("paper", "safe")
# People models of the ``people`` axis; "scenario" keeps the scenario's own
# behaviours (a study whose only person is scripted or adversarial).
PEOPLE_MODELS = ("orca", "social_force", "instructed")
AS_SCENARIO = "scenario"
# Behaviours the people axis replaces: people who walk to their goals and
# may react to the robot.
_GOAL_WALKERS = ("orca", "social_force", "instructed")


def VariantText(variant: str) -> str:
    """The YAML override of a variant."""
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {', '.join(VARIANTS)}: {variant!r}")
    return f"{{safety: {{mode: {variant}}}}}"


def MergeYaml(*texts: str) -> str:
    """YAML overrides merged into one (later texts win; maps merge key by
    key, anything else is replaced), as one flow-style line."""
    merged: dict = {}
    for text in texts:
        data = yaml.safe_load(text) if text and text.strip() else None
        if data is None:
            continue
        if not isinstance(data, dict):
            raise ValueError(f"a scenario override must be a YAML map: {text!r}")
        _Merge(merged, data)
    if not merged:
        return ""
    return yaml.safe_dump(merged, default_flow_style=True, width=10_000).strip()


def _Merge(into: dict, data: dict) -> None:
    for key, value in data.items():
        if isinstance(value, dict) and isinstance(into.get(key), dict):
            _Merge(into[key], value)
        else:
            into[key] = value


def ApplySeed(scenario: Scenario, seed: int) -> Scenario:
    """Varies the people reproducibly: each start moves up to 0.2 m, starts
    up to 0.5 s later and walks at 90–110 % of its speed; the sensor noise is
    seeded too. The same seed gives every method the same people."""
    rng = np.random.default_rng(seed)
    humans = []
    for h in scenario.humans:
        humans.append(
            dataclasses.replace(
                h,
                start=[
                    float(v) for v in np.asarray(h.start) + rng.uniform(-0.2, 0.2, 2)
                ],
                start_time=h.start_time + float(rng.uniform(0.0, 0.5)),
                speed=h.speed * float(rng.uniform(0.9, 1.1)),
            )
        )
    return dataclasses.replace(scenario, humans=humans, random_seed=int(seed))


def ApplyPeopleModel(scenario: Scenario, people: str) -> Scenario:
    """Every person who walks to goals (orca, social_force or instructed)
    gets the behaviour ``people``; scripted and adversarial people keep
    theirs. ``people`` = "scenario" changes nobody."""
    if people == AS_SCENARIO:
        return scenario
    if people not in PEOPLE_MODELS:
        raise ValueError(
            f"people must be one of {', '.join(PEOPLE_MODELS + (AS_SCENARIO,))}: "
            f"{people!r}"
        )
    humans = [
        dataclasses.replace(h, behavior=people) if h.behavior in _GOAL_WALKERS else h
        for h in scenario.humans
    ]
    return dataclasses.replace(scenario, humans=humans)


@dataclasses.dataclass(frozen=True)
class DoorwayPeople:
    """Random people for a corridor (walls at x = ±corridor_half_width)
    with a wall across it at y = 0 and a door |x| < door_half_width.

    Person j starts on side s_j (y s_j > 0), the sides alternating from a
    random first one, so two or more people start on both sides. Its start
    is uniform in |x| ≤ corridor_half_width − radius − 0.1 and |y| ∈
    start_y, at least robot_radius + radius + 0.5 from the robot's start
    and 2 radius + 0.2 from the earlier people's starts; its goal lies on
    the other side, |y| ∈ goal_y (beyond the robot's goal), with x chosen so
    that the straight line start → goal crosses y = 0 at a point drawn
    uniformly within door_half_width − radius − 0.05 of the door's centre:
    every path goes through the door with room for the person. Speed is
    uniform in ``speed``, the start delay in ``delay``. Draws are made
    person by person from ``numpy.random.default_rng(seed)``, so the first k
    people of a crowd of n are the crowd of k drawn with the same seed.
    """

    corridor_half_width: float
    door_half_width: float
    robot_start: tuple
    robot_radius: float
    start_y: tuple = (1.0, 4.5)
    goal_y: tuple = (3.0, 4.5)
    speed: tuple = (0.5, 1.5)
    delay: tuple = (0.0, 2.0)
    radius: float = 0.3

    def Sample(self, count: int, seed: int) -> list[HumanConfig]:
        rng = np.random.default_rng(seed)
        x_max = self.corridor_half_width - self.radius - 0.1
        x_door = self.door_half_width - self.radius - 0.05
        if x_max <= 0 or x_door <= 0:
            raise ValueError("the corridor or the door is too narrow for a person")
        robot = np.asarray(self.robot_start, dtype=float)
        first_side = 1.0 if rng.uniform() < 0.5 else -1.0
        humans: list[HumanConfig] = []
        for j in range(count):
            side = first_side * (-1.0) ** j
            start, goal = self._Draw(rng, side, x_max, x_door, robot, humans)
            humans.append(
                HumanConfig(
                    behavior="orca",
                    start=[float(v) for v in start],
                    waypoints=[[float(v) for v in goal]],
                    speed=float(rng.uniform(*self.speed)),
                    radius=self.radius,
                    start_time=float(rng.uniform(*self.delay)),
                )
            )
        return humans

    def _Draw(self, rng, side, x_max, x_door, robot, humans):
        for _ in range(10_000):
            y_s = side * rng.uniform(*self.start_y)
            x_s = rng.uniform(-x_max, x_max)
            y_g = -side * rng.uniform(*self.goal_y)
            x_c = rng.uniform(-x_door, x_door)
            # The line start → goal crosses y = 0 at x_c.
            x_g = x_s + (x_c - x_s) * (abs(y_s) + abs(y_g)) / abs(y_s)
            start = np.array([x_s, y_s])
            if abs(x_g) > x_max:
                continue
            if np.linalg.norm(start - robot) < self.robot_radius + self.radius + 0.5:
                continue
            if any(
                np.linalg.norm(start - np.asarray(h.start)) < 2 * self.radius + 0.2
                for h in humans
            ):
                continue
            return start, np.array([x_g, y_g])
        raise ValueError("no room for another person in the corridor")

    def __call__(self, scenario: Scenario, count: int, seed: int) -> Scenario:
        """The scenario with ``count`` people drawn with ``seed`` (and the
        controller's human slots raised to fit them)."""
        prediction = dataclasses.replace(
            scenario.prediction,
            max_humans=max(scenario.prediction.max_humans, count),
        )
        return dataclasses.replace(
            scenario,
            humans=self.Sample(count, seed),
            prediction=prediction,
            random_seed=int(seed),
        )
