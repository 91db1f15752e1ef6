"""The typed configuration of a simulation or hardware run.

A :class:`Scenario` is the only configuration. Named scenarios live in
``diagrams/*.scenarios.yaml`` and are loaded with
:func:`sm2ith_drake.scenario_loader.LoadScenario`, which uses Drake's strict
``yaml_load_typed``: an unknown key is an error naming it; the values the
schema cannot check are checked by :mod:`sm2ith_drake.scenario_checks`.
"""

from dataclasses import dataclass, field

from pydrake.solvers import SolverOptions
from pydrake.systems.analysis import SimulatorConfig

from sm2ith_drake.scenario_hardware import HardwareConfig
from sm2ith_drake.scenario_options import (
    OvertakingConfig,
    ReciprocityConfig,
    RecoveryConfig,
    SafetyConfig,
)

TASK_KINDS = (
    "ee_position",
    "base_position",
    "base_pose",
    "ee_position_in_base",
    "joint_posture",
    "face_point",
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
    # Narrower position limits [lower, upper] for arm joints, by joint name
    # (e.g. a wrist held near straight while it carries a banner). Must lie
    # within the URDF's limits.
    joint_limits: dict[str, list[float]] = field(default_factory=dict)


@dataclass
class TaskConfig:
    """One task of the hierarchy; priority is the order in Scenario.tasks.

    Errors e_k (Section IV.A): ee_position: p_WE − target (3); base_position:
    (x, y) − target (2); base_pose: (x, y, θ) − target (3, θ wrapped);
    ee_position_in_base: R(θ)ᵀ(p_WE − p_WB) − target (3, "arm extended");
    joint_posture: q_arm − target (arm DOF); face_point: the base's heading
    minus the bearing of the target point (1; target [x, y]).
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
    # base_position only: the point this far ahead of the base origin along
    # its x axis (m) is taken to the target (0: the origin). A differential
    # drive's origin is on the wheel axis: at a standstill a turn in place
    # does not move it to first order, so the RTI sees no use in turning; a
    # point ahead moves with both. Measured on the doorway (Stretch 3, 0.15
    # m, every method): fewer arrivals for SM²ITH and CVMM (README, Doorway).
    offset: float = 0.0


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
    # The rti stage QPs' solver: "auto" (the default: HPIPM where its dense
    # stage blocks are small, up to about 3 people, PIQP for wider ones and
    # for every QP where HPIPM is not installed, i.e. Python < 3.12; with 3
    # people ~2x / ~1.3x faster than piqp and more exact; the studies were
    # re-run with it, README, What we measured), "piqp" (sparse, every QP;
    # the default until 2026-11-27) or "hpipm" (HPIPM's Riccati IPM on the
    # QPs' time structure for every QP; options as the entry "HPIPM").
    qp_solver: str = "auto"
    # Sequential QP iterations per stage and control step (rti only): the
    # most passes a step may take. A pass after the first runs only while
    # the last one has not converged: its plan's predicted human actions are
    # more than rti_prediction_tolerance (m/s) from what the people's model
    # does at the plan's states (the KKT embedding), or the plan violates
    # the nonlinear barrier or self-collision rows by more than
    # rti_constraint_tolerance (their QPs kept only the linearizations).
    # rti_prediction_tolerance 0, or no people to predict: every pass runs
    # (an ordinary SQP). Deterministic (no clock), so a cloned Context
    # reproduces the run.
    rti_iterations: int = 1
    rti_prediction_tolerance: float = 5e-3
    rti_constraint_tolerance: float = 1e-3
    # Optional (off by default): apply the pass rule above already after a
    # non-final pass's first stage; when that stage's plan fails it, the
    # pass's lower stages are skipped and the next pass linearizes at that
    # plan (one QP fewer in a step that needs two passes, but the lower
    # stages then get one linearization instead of two). Deterministic.
    # Measured (README, Benchmark): faster, but on the head-on study with 30
    # paired seeds SM²ITH reached the goal in 168 of 180 runs instead of 178.
    rti_early_pass_check: bool = False
    # The arm's joint limits also between the knots: q_k + (Δt/2) ν_k within
    # them (control/joint_limits.py; README, Doorway). False: at the knots
    # only, as eq. htmpc_limits is written.
    joint_limits_between_knots: bool = True
    # Where HPIPM's interior point starts a stage QP (HPIPM only; PIQP
    # starts cold). "point": from the QP's linearization point (HPIPM's
    # primal warm start; in a step's first pass the shifted previous plan,
    # which the Context holds, so a cloned Context reproduces the run).
    # "passes": a pass after the first from the previous pass's solution of
    # that QP, the first pass cold (the default from 86ca64c to this one).
    # "cold": HPIPM's cold start. Measured (bench, 3 people, 200 steps,
    # README, Benchmark): mean QP iterations per step 50.4 → 37.4
    # (Ridgeback–UR10) and 44.8 → 33.5 (Stretch 3) from "passes" to "point".
    rti_warm_start: str = "point"
    # Damping ½ρ‖z − z̄‖² toward the linearization point (the shifted previous
    # plan) in every RTI QP, as in Levenberg–Marquardt: it keeps single QP
    # steps where the linearization holds (near arm singularities, at the
    # reach limit) and vanishes at a converged plan (rti only).
    rti_proximal_weight: float = 1.0
    # The damping of a pass that runs because the people's predicted actions
    # had not converged, as a multiple of the above (other passes: 1). Such
    # a pass linearizes at the last pass's plan with the people's exact
    # responses to it; damped harder, its plan stays where those responses
    # hold. Measured (README, Benchmark): KKT faithfulness 98.88 % → 99.42 %
    # within 1e-2 m/s with 10 (1: the same damping in every pass).
    rti_later_pass_damping: float = 10.0
    # Whether the damping also holds the multipliers of the people's ORCA
    # QPs (SM²ITH): forces of ~1e2 the KKT rows settle from the plan. Off:
    # measured in the doorway, not the default (README, Doorway).
    rti_proximal_multipliers: bool = True
    # PIQP's stage QPs (rti): a predicted person's DT-CBF rows with a robot
    # body are left out of the QP where the two are more than this far apart
    # (m, h at both knots of the row, at the linearization point), and
    # checked at its solution; rows it violates are put back and the QP
    # solved again, so the plan is the whole QP's (PiqpWorkspace.Solve).
    # 0: every row in every QP. HPIPM's QPs always keep every row. Bench
    # (README, Benchmark), 10 people: median 172.0–172.9 → 89.6–90.5 ms
    # (Ridgeback–UR10), 132.5–133.3 → 97.0–97.1 ms (Stretch 3).
    lazy_barrier_distance: float = 0.5
    # PIQP's QPs too wide for HPIPM: a person's lines of the robot (base,
    # nearest body) inactive by more than this (m/s) leave their primal rows
    # out (checked at the solution) and their complementarity rows' robot
    # entries (README, How it works). 0: every row. Bench, 10 people: median
    # 99.8 → 69.7 ms (Ridgeback–UR10), 103.8 → 72.1 ms (Stretch 3).
    lazy_line_margin: float = 0.25
    # A budget of QP iterations per control step (0: none), as SICNav's
    # acados controller caps its QP iterations to stay real time. The first
    # stage of the first pass is never cut short (its plan meets every hard
    # constraint); every later QP may use what is left of the budget. A
    # lower stage that runs out leaves the plan of the stages above it
    # ("solved through": the hard constraints and the higher priorities
    # hold, the lower tasks go unoptimized for that step), a later pass that
    # runs out keeps the previous pass's plan, and no pass starts once the
    # budget is spent. Counted in iterations, not seconds, so that a run
    # reproduces from a cloned Context. Only PIQP's iterations on QPs too
    # wide for HPIPM count. 120 since the sixteenth session (at 100 the
    # Stretch 3 stood still longer in the doorway: README, Benchmark).
    qp_iteration_budget: int = 120
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
    # Diagnostics: re-solve every human's relaxed-ORCA QP at the planned
    # states after each ORCA-KKT solve and log the action errors (costs a few
    # ms per human; not counted in the step time).
    check_predictions: bool = False
    recovery: RecoveryConfig = field(default_factory=RecoveryConfig)


# The ControllerConfig fields the HierarchicalSolver takes as they are.
SOLVER_SETTINGS = (
    "rti_prediction_tolerance",
    "rti_constraint_tolerance",
    "rti_early_pass_check",
    "rti_warm_start",
    "rti_later_pass_damping",
    "qp_solver",
    "lazy_barrier_distance",
    "lazy_line_margin",
    "qp_iteration_budget",
)


HUMAN_BEHAVIORS = (
    "orca",
    "social_force",
    "scripted",
    "adversarial",
    "relaxed_orca",
    "instructed",
)
PREDICTORS = ("orca_kkt", "cvmm", "react")
# Where HPIPM starts a stage QP (ControllerConfig.rti_warm_start).
WARM_STARTS = ("point", "passes", "cold")


@dataclass
class HumanConfig:
    """One simulated person (a vertical cylinder walking in the plane)."""

    # orca: walks its waypoints with ORCA, reacting to the robot base and the
    # others; social_force: Helbing's social force model; scripted: follows
    # its waypoints at its speed and ignores everyone; adversarial: walks
    # straight at the robot base; relaxed_orca: walks its waypoints exactly
    # as the SM²ITH prediction model says; instructed: walks its waypoints
    # like scripted, ignoring everyone, until the robot comes within
    # reaction_distance, then avoids the robot alone, late, and returns to
    # its path (humans/crowd.py).
    behavior: str = "orca"
    start: list[float] = field(default_factory=lambda: [0.0, 0.0])
    # Goals in order; the human stays at the last (or loops).
    waypoints: list[list[float]] = field(default_factory=list)
    loop: bool = False
    # Preferred walking speed (m/s) and the cylinder radius (m).
    speed: float = 1.0
    radius: float = 0.3
    # The human stands still until this time (s); with start_phase, counted
    # from when the robot's task sequence enters that phase.
    start_time: float = 0.0
    # The name of a phase of the scenario's ``sequence``: the human stands at
    # its start until the robot enters that phase ("" : from the run's start).
    start_phase: str = ""
    # One phase name per waypoint, or empty (no gating): the human walks to
    # waypoint k only once the robot's sequence has entered
    # waypoint_phases[k], keeping to the waypoint before it (or its start)
    # until then; "" leaves waypoint k ungated. Not with loop.
    waypoint_phases: list[str] = field(default_factory=list)
    # instructed: the gap between the robot's nearest body and the person's
    # surface (m) under which the person starts avoiding the robot.
    reaction_distance: float = 1.0


@dataclass
class ObstacleConfig:
    """A static obstacle: a wall segment (2 vertices) or a closed polygon
    (≥ 3 vertices, counter-clockwise), extruded to ``height``."""

    vertices: list[list[float]] = field(default_factory=list)
    height: float = 1.0


@dataclass
class PredictionConfig:
    """How the controller predicts the humans (Section IV.B)."""

    # orca_kkt: SM²ITH, the relaxed-ORCA QP of every human embedded through
    # its KKT conditions; cvmm: constant velocity, fixed before each solve;
    # react: humans held at their current positions.
    predictor: str = "orca_kkt"
    # ORCA time horizons for agents and static obstacles (s).
    tau: float = 2.0
    tau_obs: float = 0.5
    # Share of the avoidance a human takes toward the robot (0.5: reciprocal).
    robot_share: float = 0.5
    # That share estimated per person from how they moved (not in the paper).
    reciprocity: ReciprocityConfig = field(default_factory=ReciprocityConfig)
    # Overtakers predicted to keep clear of the robot (not in the paper).
    overtaking: OvertakingConfig = field(default_factory=OvertakingConfig)
    # Human limits in the prediction model.
    max_speed: float = 1.5
    max_acceleration: float = 2.0
    # Each person's own top speed in the model (not in the paper): with a
    # factor > 0, a person's speed limit is factor × their measured speed
    # (the larger of the measured and preferred velocities' norms), at least
    # max_speed_floor and at most max_speed. 0: max_speed for everyone. A
    # model that lets a person walking 0.6 m/s dodge at 1.5 m/s lets the
    # plan count on an escape the person cannot make (a traced doorway
    # contact). Measured with 1.2 on 580 runs and not kept: contacts with
    # ORCA people rose in banner/cup and pick-and-place (README, People).
    max_speed_factor: float = 0.0
    max_speed_floor: float = 0.5
    # Slack penalties M of the relaxed ORCA QP (acceleration, half-planes).
    slack_weight_acceleration: float = 10.0
    slack_weight_velocity: float = 100.0
    # Complementarity relaxation λᵢ cᵢ ≥ −ε of the KKT embedding (measured:
    # ε = 1e-3 → 58 %, 1e-4 → 74 %, 1e-5 → 79 %, 1e-6 → 80 % of predicted
    # actions within 1e-2 m/s of the re-solved QP in a head-on test).
    # 1e-4 was measured on 2026-11-29 and reverted: 10 people's bench p99
    # 412 → 262 ms, but on the studies SM²ITH drove into people it had kept
    # clear of (367 mm in a one-person pick-and-place run): the plan
    # chooses the people's multipliers, and a looser relaxation lets it buy
    # a dodge (a push from a line a person does not touch) that the person
    # does not make (docs/experiments/complementarity-1e-4-df7a7ac).
    complementarity_relaxation: float = 1e-5
    # Maximum number of humans the controller tracks (the program's size).
    max_humans: int = 3
    # People beyond max_humans (more tracked than slots): the nearest
    # max_humans get the slots (a newcomer takes an incumbent's only when
    # closer to the robot by neighbor_hysteresis), and the nearest
    # max_extra_humans of the rest are kept out of by the DT-CBF over the
    # whole horizon, moving on at their measured velocity (held where they
    # are for React): barrier rows only, no prediction variables, so they
    # cost a fraction of a slot. Anyone beyond both is not seen by the
    # controller (counted as dropped).
    max_extra_humans: int = 0
    # The ORCA model's preferred velocity v_pref of each person: their
    # measured velocity low-pass filtered with this time constant (s), an
    # estimate of where they mean to go that a short swerve around the robot
    # does not erase. 0: the latest measured velocity (the paper's example).
    # With 2 s the deepest barrier intrusion of a 28-run safety campaign
    # fell from 8.5 to 3.7 cm, but in 150 study runs sub-centimetre contacts
    # rose from 2 to 7: the default stays at the paper's choice.
    preferred_velocity_time_constant: float = 0.0
    # Other humans each predicted human reacts to (RVO2's maxNeighbors): the
    # ones that come closest within the horizon; the robot always counts.
    # Keeps the program's size linear in the number of people; with
    # max_neighbors ≥ max_humans − 1 every pair interacts.
    max_neighbors: int = 4
    # A current neighbour is only replaced by someone who comes closer by
    # this much (m), so the neighbour sets, and with them the QP's sparsity
    # pattern, do not flicker.
    neighbor_hysteresis: float = 0.5
    # Whether the QP's Jacobian includes the derivatives of each human's
    # ORCA lines w.r.t. its neighbours' predicted states. False: block-Jacobi
    # — the lines are evaluated at the neighbours' current predictions at
    # every linearization (so a converged plan satisfies the coupled KKT
    # system exactly) but each human's block is differentiated only w.r.t.
    # its own and the robot's states; this keeps every human's block coupled
    # to the robot only, and the factorization cost linear in the number of
    # people (see README, People).
    neighbor_derivatives: bool = False
    # The steps of the horizon over which each person's relaxed-ORCA QP is
    # embedded (not in the paper; SICNav's ``orca_kkt_horiz``): after them a
    # person holds its last predicted action, and the QP carries no KKT
    # rows. 0: the whole horizon (the paper). Fewer steps, a smaller QP.
    kkt_steps: int = 0
    # Turn a v_pref that walks into a wall onto the nearest free line (the
    # person steers for the opening; control/prediction/intent.py).
    steer_around_walls: bool = False


@dataclass
class PerceptionConfig:
    """The simulated motion-capture of the humans."""

    # "kalman": noisy, dropping detections tracked by a Kalman filter per
    # human; "truth": the controller sees the true states (ideal perception).
    estimator: str = "kalman"
    # Standard deviation of the position noise (m).
    noise: float = 0.01
    # Probability that a detection is missing in a frame.
    dropout_probability: float = 0.0
    # Detection period (s).
    period: float = 0.05
    # Kalman filter: white acceleration noise (m/s^1.5, the spectral density's
    # square root) and the time after which an unseen track is dropped (s).
    acceleration_noise: float = 0.5
    track_timeout: float = 1.0


@dataclass
class VisualizationConfig:
    """What Meshcat shows."""

    draw_plans: bool = True
    # Publish period of the Meshcat visualizer (s).
    publish_period: float = 0.05


@dataclass
class PhaseConfig:
    """One phase of a task sequence (e.g. "reach the pick pose")."""

    name: str = ""
    # New targets by task name (tasks not listed keep their targets).
    targets: dict[str, list[float]] = field(default_factory=dict)
    # The phase is done when every listed task's error norm stays within
    # ``tolerance`` for ``hold_time`` seconds (empty: all tasks with targets
    # in this phase).
    done_when: list[str] = field(default_factory=list)
    tolerance: float = 0.05
    hold_time: float = 0.5


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
    # Integration step of the simulated robot and of the crowd (s).
    robot_time_step: float = 0.01
    crowd_time_step: float = 0.05
    visualization: VisualizationConfig = field(default_factory=VisualizationConfig)
    random_seed: int = 0
    humans: list[HumanConfig] = field(default_factory=list)
    obstacles: list[ObstacleConfig] = field(default_factory=list)
    prediction: PredictionConfig = field(default_factory=PredictionConfig)
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    perception: PerceptionConfig = field(default_factory=PerceptionConfig)
    # A task sequence (pick-and-place…): phases run in order; after the last
    # its targets stay. Empty: the tasks keep their targets.
    sequence: list[PhaseConfig] = field(default_factory=list)
    # The hardware path (LCM); unused in simulation.
    hardware: HardwareConfig = field(default_factory=HardwareConfig)


class ScenarioError(ValueError):
    """A scenario file or override that cannot be used (message is one line)."""


def ControlPeriod(config: ControllerConfig) -> float:
    """The control period: ``control_period``, or the MPC step if 0."""
    return config.control_period if config.control_period > 0 else config.time_step
