"""Checks of the scenario values that the typed schema cannot express."""

from sm2ith_drake.robots.models import MODELS
from sm2ith_drake.scenario import (
    HUMAN_BEHAVIORS,
    PREDICTORS,
    TASK_KINDS,
    RobotConfig,
    Scenario,
    ScenarioError,
)


def _ValidateJointLimits(robot: RobotConfig) -> None:
    model = MODELS.get(robot.model)
    for name, pair in robot.joint_limits.items():
        if model is not None and name not in model.arm_joints:
            raise ScenarioError(
                f"robot.joint_limits: unknown joint '{name}'; arm joints: "
                + ", ".join(model.arm_joints)
            )
        if len(pair) != 2 or not pair[0] < pair[1]:
            raise ScenarioError(
                f"robot.joint_limits.{name} must be [lower, upper], lower < upper"
            )


def ValidateScenario(scenario: Scenario) -> None:
    """Checks values that the schema cannot; raises ScenarioError."""
    _ValidateJointLimits(scenario.robot)
    c = scenario.controller
    if c.method not in ("htmpc", "weighted_sum"):
        raise ScenarioError(f"controller.method must be htmpc|weighted_sum: {c.method}")
    if c.solver not in ("rti", "snopt", "ipopt"):
        raise ScenarioError(f"controller.solver must be rti|snopt|ipopt: {c.solver}")
    if c.horizon < 1 or c.time_step <= 0:
        raise ScenarioError("controller.horizon must be ≥ 1 and time_step > 0")
    if c.rti_iterations < 1 or c.rti_proximal_weight < 0:
        raise ScenarioError(
            "controller.rti_iterations must be ≥ 1 and rti_proximal_weight ≥ 0"
        )
    if c.lexicographic_tolerance < 0 or c.self_collision_distance < 0:
        raise ScenarioError(
            "controller.lexicographic_tolerance and self_collision_distance must be ≥ 0"
        )
    if c.control_period < 0 or c.time_budget < 0 or c.max_fallback_steps < 0:
        raise ScenarioError(
            "controller.control_period, time_budget and max_fallback_steps must be ≥ 0"
        )
    if not scenario.tasks:
        raise ScenarioError("a scenario needs at least one task")
    names = {t.name or t.kind for t in scenario.tasks}
    for i, phase in enumerate(scenario.sequence):
        unknown = (set(phase.targets) | set(phase.done_when)) - names
        if unknown:
            raise ScenarioError(
                f"sequence[{i}] names unknown tasks {sorted(unknown)}; "
                f"tasks: {sorted(names)}"
            )
        if phase.tolerance <= 0 or phase.hold_time < 0:
            raise ScenarioError(f"sequence[{i}]: tolerance > 0 and hold_time ≥ 0")
    for i, h in enumerate(scenario.humans):
        if h.behavior not in HUMAN_BEHAVIORS:
            raise ScenarioError(
                f"humans[{i}].behavior '{h.behavior}'; "
                f"valid: {', '.join(HUMAN_BEHAVIORS)}"
            )
        if len(h.start) != 2 or any(len(w) != 2 for w in h.waypoints):
            raise ScenarioError(f"humans[{i}]: start and waypoints are [x, y] pairs")
        if h.speed < 0 or h.radius <= 0:
            raise ScenarioError(f"humans[{i}]: speed ≥ 0 and radius > 0 needed")
    for i, o in enumerate(scenario.obstacles):
        if len(o.vertices) < 2 or any(len(v) != 2 for v in o.vertices):
            raise ScenarioError(f"obstacles[{i}]: at least two [x, y] vertices")
    pr = scenario.prediction
    if pr.predictor not in PREDICTORS:
        raise ScenarioError(
            f"prediction.predictor '{pr.predictor}'; valid: {', '.join(PREDICTORS)}"
        )
    if pr.max_humans < len(scenario.humans) and scenario.humans:
        raise ScenarioError(
            f"prediction.max_humans ({pr.max_humans}) < number of humans "
            f"({len(scenario.humans)})"
        )
    if pr.preferred_velocity_time_constant < 0:
        raise ScenarioError("prediction.preferred_velocity_time_constant must be ≥ 0")
    if pr.max_neighbors < 0 or pr.neighbor_hysteresis < 0:
        raise ScenarioError(
            "prediction.max_neighbors and prediction.neighbor_hysteresis must be ≥ 0"
        )
    if not 0 < scenario.safety.gamma <= 1:
        raise ScenarioError("safety.gamma must be in (0, 1]")
    if scenario.safety.guard_steps < 0:
        raise ScenarioError("safety.guard_steps must be ≥ 0")
    pc = scenario.perception
    if pc.estimator not in ("kalman", "truth"):
        raise ScenarioError(
            f"perception.estimator must be kalman|truth: {pc.estimator}"
        )
    if pc.noise < 0 or not 0 <= pc.dropout_probability < 1 or pc.period <= 0:
        raise ScenarioError("perception: noise ≥ 0, dropout in [0, 1), period > 0")
    names = [t.name or t.kind for t in scenario.tasks]
    if len(set(names)) != len(names):
        raise ScenarioError(f"task names must be unique (set name:): {names}")
    for task in scenario.tasks:
        if task.kind not in TASK_KINDS:
            raise ScenarioError(
                f"unknown task kind '{task.kind}'; valid: {', '.join(TASK_KINDS)}"
            )
