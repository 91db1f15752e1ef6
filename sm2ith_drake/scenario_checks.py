"""Checks of the scenario values that the typed schema cannot express.

:func:`ValidateScenario` needs only the scenario: every number finite, vector lengths
that do not depend on the robot, positive durations, periods, radii and speeds.
:func:`ValidateScenarioForRobot` adds what needs the robot: the lengths of
``initial_q``, ``initial_nu`` and joint-posture targets, the start within the joint
limits, and warnings (not errors) for people who start inside the robot or inside a
wall. Every error is a :class:`ScenarioError` whose one-line message names the field.
"""

from __future__ import annotations

import dataclasses
import math
import sys

import numpy as np

from sm2ith_drake.geometry import point_segment_distance_2d
from sm2ith_drake.robots.models import MODELS
from sm2ith_drake.scenario import (
    HUMAN_BEHAVIORS,
    PREDICTORS,
    TASK_KINDS,
    WARM_STARTS,
    HumanConfig,
    RobotConfig,
    Scenario,
    ScenarioError,
)

# Target sizes that do not depend on the robot (joint_posture's: its arm).
TASK_TARGET_SIZES = {
    "ee_position": 3,
    "base_position": 2,
    "base_pose": 3,
    "ee_position_in_base": 3,
    "face_point": 2,
}


def _Numbers(value, path: str):
    """Yields (field path, number) for every number in ``value``: dataclasses,
    Drake's config structs, lists and dicts, recursively."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return
    if isinstance(value, int | float):
        yield path, value
    elif dataclasses.is_dataclass(value):
        for f in dataclasses.fields(value):
            yield from _Numbers(getattr(value, f.name), _Join(path, f.name))
    elif hasattr(type(value), "__fields__"):  # SimulatorConfig, DrakeLcmParams
        for f in type(value).__fields__:
            yield from _Numbers(getattr(value, f.name), _Join(path, f.name))
    elif isinstance(value, list | tuple):
        for i, item in enumerate(value):
            yield from _Numbers(item, f"{path}[{i}]")
    elif isinstance(value, dict):
        for key, item in value.items():
            yield from _Numbers(item, _Join(path, str(key)))


def _Join(path: str, name: str) -> str:
    return f"{path}.{name}" if path else name


def _Positive(value, name: str) -> None:
    if not value > 0:
        raise ScenarioError(f"{name} must be > 0, got {value}")


def _NonNegative(value, name: str) -> None:
    if not value >= 0:
        raise ScenarioError(f"{name} must be ≥ 0, got {value}")


def _Within(value, interval: str, name: str) -> None:
    """``value`` in ``interval``, written "[a, b]", "(a, b)" or half-open."""
    low, high = (float(x) for x in interval[1:-1].split(","))
    above = value >= low if interval[0] == "[" else value > low
    below = value <= high if interval[-1] == "]" else value < high
    if not (above and below):
        raise ScenarioError(f"{name} must be in {interval}, got {value}")


def _OneOf(value, choices: tuple, name: str) -> None:
    if value not in choices:
        raise ScenarioError(f"{name} must be {'|'.join(choices)}: {value!r}")


def _Point(value, name: str) -> None:
    if len(value) != 2:
        raise ScenarioError(f"{name} must be an [x, y] pair, got {list(value)}")


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


def _ValidateTasks(scenario: Scenario) -> None:
    if not scenario.tasks:
        raise ScenarioError("a scenario needs at least one task")
    names = [t.name or t.kind for t in scenario.tasks]
    if len(set(names)) != len(names):
        raise ScenarioError(f"task names must be unique (set name:): {names}")
    for i, task in enumerate(scenario.tasks):
        where = f"tasks[{i}] ({task.name or task.kind})"
        if task.kind not in TASK_KINDS:
            raise ScenarioError(
                f"tasks[{i}].kind: unknown task kind '{task.kind}'; valid: "
                + ", ".join(TASK_KINDS)
            )
        size = TASK_TARGET_SIZES.get(task.kind)
        if size is not None and len(task.target) != size:
            raise ScenarioError(
                f"{where}.target: a {task.kind} target has {size} entries, "
                f"got {len(task.target)}"
            )
        if size is not None and len(task.weight) not in (0, 1, size):
            raise ScenarioError(
                f"{where}.weight: 1 or {size} entries for {task.kind}, "
                f"got {len(task.weight)}"
            )
        for k, w in enumerate(task.weight):
            _NonNegative(w, f"{where}.weight[{k}]")
        if task.offset and task.kind != "base_position":
            raise ScenarioError(
                f"{where}.offset: only a base_position task has an offset, "
                f"not {task.kind}"
            )
        _NonNegative(task.terminal_weight, f"{where}.terminal_weight")
        _NonNegative(task.weighted_sum_weight, f"{where}.weighted_sum_weight")
    kinds = {t.name or t.kind: t.kind for t in scenario.tasks}
    for i, phase in enumerate(scenario.sequence):
        unknown = (set(phase.targets) | set(phase.done_when)) - set(kinds)
        if unknown:
            raise ScenarioError(
                f"sequence[{i}] names unknown tasks {sorted(unknown)}; "
                f"tasks: {sorted(kinds)}"
            )
        for name, target in phase.targets.items():
            size = TASK_TARGET_SIZES.get(kinds[name])
            if size is not None and len(target) != size:
                raise ScenarioError(
                    f"sequence[{i}].targets.{name}: a {kinds[name]} target has "
                    f"{size} entries, got {len(target)}"
                )
        _Positive(phase.tolerance, f"sequence[{i}].tolerance")
        _NonNegative(phase.hold_time, f"sequence[{i}].hold_time")


def _ValidateController(scenario: Scenario) -> None:
    c = scenario.controller
    _OneOf(c.method, ("htmpc", "weighted_sum"), "controller.method")
    _OneOf(c.solver, ("rti", "snopt", "ipopt"), "controller.solver")
    _OneOf(c.qp_solver, ("piqp", "hpipm", "auto"), "controller.qp_solver")
    _OneOf(c.rti_warm_start, WARM_STARTS, "controller.rti_warm_start")
    for name in ("horizon", "rti_iterations"):
        if (value := getattr(c, name)) < 1:
            raise ScenarioError(f"controller.{name} must be ≥ 1, got {value}")
    _Positive(c.time_step, "controller.time_step")
    # 0 means "the MPC step" (control_period) or "no budget" (time_budget).
    for name in (
        "rti_proximal_weight",
        "rti_later_pass_damping",
        "lazy_barrier_distance",
        "lazy_line_margin",
        "qp_iteration_budget",
        "rti_prediction_tolerance",
        "rti_constraint_tolerance",
        "lexicographic_tolerance",
        "self_collision_distance",
        "control_period",
        "time_budget",
        "max_fallback_steps",
        "effort_weight_nu",
        "effort_weight_u",
    ):
        _NonNegative(getattr(c, name), f"controller.{name}")
    r = c.recovery
    for name in ("stall_time", "stall_distance", "max_time", "people_distance"):
        _Positive(getattr(r, name), f"controller.recovery.{name}")
    for name in ("goal_tolerance", "people_speed", "clearance"):
        _NonNegative(getattr(r, name), f"controller.recovery.{name}")
    _Within(r.speed_fraction, "(0, 1]", "controller.recovery.speed_fraction")


def _ValidateGates(scenario: Scenario, i: int, h: HumanConfig) -> None:
    """A person's start_phase and waypoint_phases: phases of the sequence,
    one per waypoint, and not on a looping path (a gate opens once)."""
    if h.waypoint_phases and len(h.waypoint_phases) != len(h.waypoints):
        raise ScenarioError(
            f'humans[{i}].waypoint_phases: one phase name (or "") per '
            f"waypoint, got {len(h.waypoint_phases)} for "
            f"{len(h.waypoints)} waypoints"
        )
    if h.loop and any(h.waypoint_phases):
        raise ScenarioError(
            f"humans[{i}].waypoint_phases with loop: true; a gate opens once, "
            "so a looping path cannot be gated (list the crossings instead)"
        )
    phases = [phase.name for phase in scenario.sequence]
    valid = ", ".join(repr(n) for n in phases if n) or "none (no sequence)"
    gates = [("start_phase", h.start_phase)] + [
        (f"waypoint_phases[{k}]", n) for k, n in enumerate(h.waypoint_phases)
    ]
    for name, phase in gates:
        if phase and phase not in phases:
            raise ScenarioError(
                f"humans[{i}].{name} '{phase}' is not a phase of the sequence; "
                f"valid: {valid}"
            )


def _ValidatePeople(scenario: Scenario) -> None:
    for i, h in enumerate(scenario.humans):
        if h.behavior not in HUMAN_BEHAVIORS:
            raise ScenarioError(
                f"humans[{i}].behavior '{h.behavior}'; "
                f"valid: {', '.join(HUMAN_BEHAVIORS)}"
            )
        _Point(h.start, f"humans[{i}].start")
        for k, w in enumerate(h.waypoints):
            _Point(w, f"humans[{i}].waypoints[{k}]")
        _Positive(h.speed, f"humans[{i}].speed")
        _Positive(h.radius, f"humans[{i}].radius")
        _NonNegative(h.start_time, f"humans[{i}].start_time")
        _Positive(h.reaction_distance, f"humans[{i}].reaction_distance")
        _ValidateGates(scenario, i, h)
    for i, o in enumerate(scenario.obstacles):
        if len(o.vertices) < 2:
            raise ScenarioError(
                f"obstacles[{i}].vertices: at least two [x, y] vertices, "
                f"got {len(o.vertices)}"
            )
        for k, v in enumerate(o.vertices):
            _Point(v, f"obstacles[{i}].vertices[{k}]")
        _Positive(o.height, f"obstacles[{i}].height")
    pr = scenario.prediction
    if pr.predictor not in PREDICTORS:
        raise ScenarioError(
            f"prediction.predictor '{pr.predictor}'; valid: {', '.join(PREDICTORS)}"
        )
    seen = pr.max_humans + max(pr.max_extra_humans, 0)
    if seen < len(scenario.humans) and scenario.humans:
        raise ScenarioError(
            f"prediction.max_humans + max_extra_humans ({seen}) < number of "
            f"humans ({len(scenario.humans)})"
        )
    for name in ("tau", "tau_obs", "max_speed", "max_acceleration"):
        _Positive(getattr(pr, name), f"prediction.{name}")
    for name in (
        "slack_weight_acceleration",
        "slack_weight_velocity",
        "complementarity_relaxation",
        "preferred_velocity_time_constant",
        "max_speed_factor",
        "max_speed_floor",
        "max_humans",
        "max_neighbors",
        "max_extra_humans",
        "neighbor_hysteresis",
        "kkt_steps",
    ):
        _NonNegative(getattr(pr, name), f"prediction.{name}")
    if pr.max_speed_factor > 0 and not pr.max_speed_floor <= pr.max_speed:
        raise ScenarioError(
            f"prediction.max_speed_floor ({pr.max_speed_floor}) must not exceed "
            f"prediction.max_speed ({pr.max_speed})"
        )
    _Within(pr.robot_share, "[0, 1]", "prediction.robot_share")
    _Positive(pr.reciprocity.memory, "prediction.reciprocity.memory")
    for name in ("prior_weight", "min_difference", "max_share"):
        _NonNegative(getattr(pr.reciprocity, name), f"prediction.reciprocity.{name}")
    ov = pr.overtaking
    _Within(ov.share, "[0, 1]", "prediction.overtaking.share")
    _Within(ov.angle, "(0, 90)", "prediction.overtaking.angle")
    _Within(ov.keep_angle, "[0, 90]", "prediction.overtaking.keep_angle")
    for name in ("min_robot_speed", "min_person_speed"):
        _NonNegative(getattr(ov, name), f"prediction.overtaking.{name}")
    s = scenario.safety
    _Within(s.gamma, "(0, 1]", "safety.gamma")
    _Within(s.guard_gamma, "[0, 1]", "safety.guard_gamma")
    _OneOf(s.mode, ("safe", "paper"), "safety.mode")
    _OneOf(s.inside_barrier, ("decay", "exit"), "safety.inside_barrier")
    _OneOf(s.guard_inside, ("exit", "hold"), "safety.guard_inside")
    for name in (
        "turn_speed_floor guard_steps static_guard_steps guard_deviation guard_hold "
        "guard_gap guard_approach backup_margin human_margin obstacle_margin "
        "no_closer_gap no_closer_speed still_slack_weight approach_speed"
    ).split():
        _NonNegative(getattr(s, name), f"safety.{name}")
    for name in ("human_slack_weight", "no_closer_slack_weight", "human_radius"):
        _Positive(getattr(s, name), f"safety.{name}")
    for name in ("human_slack_weight", "still_slack_weight"):
        if not s.obstacle_slack_weight > getattr(s, name):
            raise ScenarioError(
                f"safety.obstacle_slack_weight must exceed safety.{name} (a wall "
                f"outranks a person's margin), got {s.obstacle_slack_weight} "
                f"against {getattr(s, name)}"
            )
    pc = scenario.perception
    _OneOf(pc.estimator, ("kalman", "truth"), "perception.estimator")
    _NonNegative(pc.noise, "perception.noise")
    _Within(pc.dropout_probability, "[0, 1)", "perception.dropout_probability")
    _Positive(pc.period, "perception.period")
    _NonNegative(pc.acceleration_noise, "perception.acceleration_noise")
    _Positive(pc.track_timeout, "perception.track_timeout")


def _ValidateTiming(scenario: Scenario) -> None:
    _Positive(scenario.simulation_duration, "simulation_duration")
    _Positive(scenario.robot_time_step, "robot_time_step")
    _Positive(scenario.crowd_time_step, "crowd_time_step")
    _Positive(scenario.visualization.publish_period, "visualization.publish_period")
    sim = scenario.simulator_config
    _Positive(sim.max_step_size, "simulator_config.max_step_size")
    _Positive(sim.accuracy, "simulator_config.accuracy")
    _NonNegative(sim.target_realtime_rate, "simulator_config.target_realtime_rate")
    hw = scenario.hardware
    for name in (
        "state_timeout",
        "detection_timeout",
        "detection_stop_timeout",
        "stale_detection_speed_scale",
    ):
        _NonNegative(getattr(hw, name), f"hardware.{name}")
    for name in ("poll_period", "driver_state_period", "driver_command_timeout"):
        _Positive(getattr(hw, name), f"hardware.{name}")


def ValidateScenario(scenario: Scenario) -> None:
    """Checks the values that the schema cannot; raises ScenarioError."""
    for path, value in _Numbers(scenario, ""):
        if not math.isfinite(value):
            raise ScenarioError(f"{path} must be a finite number, got {value}")
    _ValidateJointLimits(scenario.robot)
    _ValidateTiming(scenario)
    _ValidateController(scenario)
    _ValidateTasks(scenario)
    _ValidatePeople(scenario)


def ValidateScenarioForRobot(scenario: Scenario, robot, *, warn=None) -> None:
    """The checks that need the robot (a MobileManipulator): vector lengths,
    the start within the joint limits; people who start inside the robot's
    capsules or a wall are reported to ``warn`` (default: a line on stderr).

    Raises:
        ScenarioError: naming the field.
    """
    n, m = robot.num_positions, robot.num_velocities
    rc = scenario.robot
    if rc.initial_q and len(rc.initial_q) != n:
        raise ScenarioError(
            f"robot.initial_q needs {n} entries for {robot.name} "
            f"({', '.join(robot.position_names)}), got {len(rc.initial_q)}"
        )
    if rc.initial_nu and len(rc.initial_nu) != m:
        raise ScenarioError(
            f"robot.initial_nu needs {m} entries for {robot.name} "
            f"({', '.join(robot.velocity_names)}), got {len(rc.initial_nu)}"
        )
    q0 = np.asarray(rc.initial_q or robot.default_q, dtype=float)
    for i in range(3, n):
        if not robot.q_lower[i] - 1e-9 <= q0[i] <= robot.q_upper[i] + 1e-9:
            raise ScenarioError(
                f"robot.initial_q[{i}] ({robot.position_names[i]}) = {q0[i]:g} is "
                f"outside the joint limits [{robot.q_lower[i]:g}, "
                f"{robot.q_upper[i]:g}]"
            )
    arm = n - 3
    kinds = {}
    for i, task in enumerate(scenario.tasks):
        kinds[task.name or task.kind] = task.kind
        if task.kind == "joint_posture":
            where = f"tasks[{i}] ({task.name or task.kind})"
            if len(task.target) != arm:
                raise ScenarioError(
                    f"{where}.target: a joint_posture target of {robot.name} has "
                    f"{arm} entries ({', '.join(robot.arm_joint_names)}), "
                    f"got {len(task.target)}"
                )
            if len(task.weight) not in (0, 1, arm):
                raise ScenarioError(
                    f"{where}.weight: 1 or {arm} entries, got {len(task.weight)}"
                )
    for i, phase in enumerate(scenario.sequence):
        for name, target in phase.targets.items():
            if kinds.get(name) == "joint_posture" and len(target) != arm:
                raise ScenarioError(
                    f"sequence[{i}].targets.{name}: a joint_posture target of "
                    f"{robot.name} has {arm} entries, got {len(target)}"
                )
    warn = warn or (lambda message: print(f"warning: {message}", file=sys.stderr))
    for message in _StartOverlaps(scenario, robot, q0):
        warn(message)


def _StartOverlaps(scenario: Scenario, robot, q0) -> list[str]:
    """People who start overlapping the robot (any capsule, in the plane) or
    a wall, with the overlap in metres."""
    out = []
    kin = robot.CalcKinematics(q0)
    ends = kin.capsule_points[0, :, :, :2]
    for i, h in enumerate(scenario.humans):
        p = np.asarray(h.start, dtype=float)
        reach = robot.capsule_radii + h.radius
        gaps = point_segment_distance_2d(ends[:, 0], ends[:, 1], p)[0] - reach
        c = int(np.argmin(gaps))
        if gaps[c] < 0:
            out.append(
                f"humans[{i}].start {list(h.start)} is inside the robot: the "
                f"person overlaps its '{robot.capsule_names[c]}' by "
                f"{-gaps[c]:.2f} m"
            )
        for k, o in enumerate(scenario.obstacles):
            vertices = np.asarray(o.vertices, dtype=float)
            closed = len(vertices) >= 3  # a polygon; else a polyline
            a, b = vertices[:-1], vertices[1:]
            if closed:
                a, b = vertices, np.roll(vertices, -1, axis=0)
            d = float(point_segment_distance_2d(a, b, p)[0].min())
            inside = closed and _InsidePolygon(p, vertices)
            if inside or d < h.radius:
                depth = d + h.radius if inside else h.radius - d
                out.append(
                    f"humans[{i}].start {list(h.start)} is inside obstacles[{k}]: "
                    f"the person overlaps it by {depth:.2f} m"
                )
    return out


def _InsidePolygon(p, vertices) -> bool:
    inside = False
    for a, b in zip(vertices, np.roll(vertices, -1, axis=0), strict=True):
        if (a[1] > p[1]) != (b[1] > p[1]):
            x = a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
            inside ^= p[0] < x
    return inside
