"""The typed configuration of a simulation or hardware run.

A :class:`Scenario` is the only configuration. Named scenarios live in
``diagrams/*.scenarios.yaml`` and are loaded with :func:`LoadScenario`, which
uses Drake's strict ``yaml_load_typed``: an unknown key is an error naming it.
"""

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from pydrake.common.yaml import yaml_load_typed
from pydrake.solvers import SolverOptions
from pydrake.systems.analysis import SimulatorConfig

from sm2ith_drake.resources import ResolveScenarioFile

TASK_KINDS = (
    "ee_position",
    "base_position",
    "base_pose",
    "ee_position_in_base",
    "joint_posture",
)


@dataclass
class RobotConfig:
    """Which robot, and where it starts."""

    # "ridgeback_ur10" | "stretch3".
    model: str = "ridgeback_ur10"
    # Optional URDF replacing the shipped one (same joint names as the model).
    urdf_path: str = ""
    # Initial configuration q (empty: the model's nominal configuration).
    initial_q: list[float] = field(default_factory=list)
    # Initial pseudo-velocities ν (empty: zero).
    initial_nu: list[float] = field(default_factory=list)


@dataclass
class TaskConfig:
    """One task of the hierarchy; priority is the order in Scenario.tasks.

    Errors e_k (Section IV.A): ee_position: p_WE − target (3); base_position:
    (x, y) − target (2); base_pose: (x, y, θ) − target (3, θ wrapped);
    ee_position_in_base: R(θ)ᵀ(p_WE − p_WB) − target (3, "arm extended");
    joint_posture: q_arm − target (arm DOF).
    """

    kind: str = "ee_position"
    # A display name; defaults to kind.
    name: str = ""
    target: list[float] = field(default_factory=list)
    # Diagonal of the stage weight W_k (one entry: the same for every
    # component; empty: ones).
    weight: list[float] = field(default_factory=list)
    # W_N = terminal_weight · W_k.
    terminal_weight: float = 5.0
    # Weight W_ℓ of this task in the weighted-sum baseline (Section V.A).
    weighted_sum_weight: float = 1.0


@dataclass
class ControllerConfig:
    """The hierarchical MPC (Sections IV.A, IV.C)."""

    # "htmpc" (lexicographic, eq. stmpc) | "weighted_sum" (Section V.A).
    method: str = "htmpc"
    horizon: int = 10
    # Δt of the prediction model (s).
    time_step: float = 0.2
    # How often a new command is computed (s); 0 means time_step.
    control_period: float = 0.0
    # "rti": real-time iteration, sparse QPs in a persistent PIQP workspace;
    # "snopt" | "ipopt": the full nonlinear program through
    # MathematicalProgram (validation path).
    solver: str = "rti"
    # Drake SolverOptions; the entry "PIQP" configures the rti QPs (any PIQP
    # setting, e.g. {PIQP: {max_iter: 50}}); "SNOPT" / "Ipopt" the NLPs.
    solver_options: SolverOptions = field(default_factory=SolverOptions)
    # Sequential QP iterations per stage and control step (rti only).
    rti_iterations: int = 1
    # Damping ½ρ‖z − z̄‖² toward the linearization point (the shifted previous
    # plan) in every RTI QP, as in Levenberg–Marquardt: it keeps single QP
    # steps where the linearization holds (near arm singularities, at the
    # reach limit) and vanishes at a converged plan (rti only).
    rti_proximal_weight: float = 1.0
    # Slack added to |e*| in the lexicographic constraints (eq. stmpc_lex_constr).
    lexicographic_tolerance: float = 1e-3
    # J_eff = ½ Σ w_ν‖ν_k‖² + w_u‖u_k‖².
    effort_weight_nu: float = 1e-2
    effort_weight_u: float = 1e-2
    # Self-collision margin d_sc (m), eq. htmpc_self_collision.
    self_collision_distance: float = 0.02
    # Wall-clock budget for one control step (s); 0 disables the check.
    time_budget: float = 0.0
    # After a failed solve, the previous plan is replayed (shifted) for at
    # most this many control steps before braking.
    max_fallback_steps: int = 3


@dataclass
class VisualizationConfig:
    """What Meshcat shows."""

    draw_plans: bool = True
    # Publish period of the Meshcat visualizer (s).
    publish_period: float = 0.05


@dataclass
class Scenario:
    """Everything a run needs."""

    robot: RobotConfig = field(default_factory=RobotConfig)
    tasks: list[TaskConfig] = field(default_factory=list)
    controller: ControllerConfig = field(default_factory=ControllerConfig)
    # Simulated time (s).
    simulation_duration: float = 10.0
    simulator_config: SimulatorConfig = field(
        default_factory=lambda: SimulatorConfig(target_realtime_rate=0.0)
    )
    # Integration step of the simulated robot (s).
    robot_time_step: float = 0.01
    visualization: VisualizationConfig = field(default_factory=VisualizationConfig)
    random_seed: int = 0


class ScenarioError(ValueError):
    """A scenario file or override that cannot be used (message is one line)."""


def ScenarioNames(filename: str | Path) -> list[str]:
    """The names of the scenarios in a ``*.scenarios.yaml`` file."""
    path = ResolveScenarioFile(str(filename))
    try:
        with open(path) as f:
            data = yaml.safe_load(f)
    except yaml.YAMLError as e:
        raise ScenarioError(f"malformed YAML in {path}: {_OneLine(e)}") from e
    if not isinstance(data, dict):
        raise ScenarioError(f"{path} must map scenario names to scenarios")
    return [k for k in data if not str(k).startswith(".")]


def LoadScenario(
    *, filename: str | Path, scenario_name: str, scenario_text: str = "{}"
) -> Scenario:
    """Loads one named scenario, then applies the YAML ``scenario_text`` on top.

    Raises:
        FileNotFoundError: the file does not exist.
        ScenarioError: malformed YAML, unknown scenario name, unknown key or a
            value that fails validation.
    """
    path = ResolveScenarioFile(str(filename))
    names = ScenarioNames(path)
    if scenario_name not in names:
        raise ScenarioError(
            f"unknown scenario '{scenario_name}' in {path}; valid names: "
            + ", ".join(names)
        )
    try:
        scenario = yaml_load_typed(
            schema=Scenario, filename=str(path), child_name=scenario_name
        )
        scenario = yaml_load_typed(
            schema=Scenario,
            data=scenario_text,
            defaults=scenario,
            retain_map_defaults=True,
        )
    except (RuntimeError, ValueError, TypeError, yaml.YAMLError) as e:
        raise ScenarioError(f"{path}:{scenario_name}: {_OneLine(e)}") from e
    ValidateScenario(scenario)
    return scenario


def ValidateScenario(scenario: Scenario) -> None:
    """Checks values that the schema cannot; raises ScenarioError."""
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
    names = [t.name or t.kind for t in scenario.tasks]
    if len(set(names)) != len(names):
        raise ScenarioError(f"task names must be unique (set name:): {names}")
    for task in scenario.tasks:
        if task.kind not in TASK_KINDS:
            raise ScenarioError(
                f"unknown task kind '{task.kind}'; valid: {', '.join(TASK_KINDS)}"
            )


def ControlPeriod(config: ControllerConfig) -> float:
    return config.control_period if config.control_period > 0 else config.time_step


def _OneLine(e: Exception) -> str:
    return " ".join(str(e).split())


def ReplaceScenario(scenario: Scenario, **changes) -> Scenario:
    """A copy of ``scenario`` with top-level fields replaced."""
    return dataclasses.replace(scenario, **changes)
