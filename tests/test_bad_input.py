"""Bad scenario values are refused before the run: through the ``sm2ith run``
entry point, exit code 2, a one-line message naming the field, no traceback.
And a NaN arriving at run time never reaches the QP solver."""

import subprocess
import sys

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource

from sm2ith_drake.cli import main
from sm2ith_drake.control.hpipm_workspace import HpipmWorkspace
from sm2ith_drake.control.piqp_workspace import PiqpWorkspace
from sm2ith_drake.control.tasks import MakeTask
from sm2ith_drake.diagrams.control_stack import AddControlStack
from sm2ith_drake.humans.messages import HumanDetections
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import LoadScenario, LoadScenarioAndRobot
from sm2ith_drake.systems.humans import MocapSensor

REACH = str(GetDiagramsDir() / "reach.scenarios.yaml")
CROSSING = str(GetDiagramsDir() / "crossing.scenarios.yaml")


# (id, scenario, override, words the message must contain)
BAD_INPUTS = [
    ("nan_target", "stretch3_reach",
     "{tasks: [{kind: ee_position, target: [.nan, 0.0, 0.8]}]}",
     ["tasks[0].target[0]", "finite"]),
    ("inf_speed", "ridgeback_ur10_reach",
     "{humans: [{behavior: orca, start: [3, 3], waypoints: [[3, -3]], speed: .inf}]}",
     ["humans[0].speed", "finite"]),
    ("nan_duration", "stretch3_reach", "{simulation_duration: .nan}",
     ["simulation_duration", "finite"]),
    ("nan_weight", "stretch3_reach",
     "{tasks: [{kind: base_position, target: [1, 0], weight: [.nan]}]}",
     ["tasks[0].weight[0]"]),
    ("inf_initial_q", "stretch3_reach",
     "{robot: {initial_q: [0, 0, 0, 0.5, .inf, 0, 0]}}",
     ["robot.initial_q[4]", "finite"]),
    ("nan_obstacle_vertex", "stretch3_reach",
     "{obstacles: [{vertices: [[0, 2], [.nan, 2]]}]}",
     ["obstacles[0].vertices[1][0]"]),
    ("nan_gamma", "stretch3_reach", "{safety: {gamma: .nan}}",
     ["safety.gamma"]),
    ("unknown_qp_solver", "stretch3_reach", "{controller: {qp_solver: osqp}}",
     ["controller.qp_solver", "piqp|hpipm|auto"]),
    ("unknown_warm_start", "stretch3_reach",
     "{controller: {rti_warm_start: previous}}",
     ["controller.rti_warm_start", "point|passes|cold"]),
    ("zero_rti_iterations", "stretch3_reach", "{controller: {rti_iterations: 0}}",
     ["controller.rti_iterations", "≥ 1"]),
    ("negative_later_pass_damping", "stretch3_reach",
     "{controller: {rti_later_pass_damping: -1.0}}",
     ["controller.rti_later_pass_damping"]),
    ("unknown_inside_barrier", "stretch3_reach", "{safety: {inside_barrier: deeper}}",
     ["safety.inside_barrier", "decay|exit"]),
    ("unknown_guard_inside", "stretch3_reach", "{safety: {guard_inside: out}}",
     ["safety.guard_inside", "exit|hold"]),
    ("negative_turn_speed_floor", "stretch3_reach",
     "{safety: {turn_speed_floor: -0.1}}", ["safety.turn_speed_floor", "≥ 0"]),
    ("negative_max_speed_factor", "stretch3_reach",
     "{prediction: {max_speed_factor: -1.0}}",
     ["prediction.max_speed_factor", "≥ 0"]),
    ("max_speed_floor_above_max_speed", "stretch3_reach",
     "{prediction: {max_speed_factor: 1.2, max_speed_floor: 2.0}}",
     ["prediction.max_speed_floor", "prediction.max_speed"]),
    ("zero_reciprocity_memory", "stretch3_reach",
     "{prediction: {reciprocity: {enabled: true, memory: 0}}}",
     ["prediction.reciprocity.memory", "> 0"]),
    ("guard_gamma_above_one", "stretch3_reach",
     "{safety: {guard_gamma: 1.5}}",
     ["safety.guard_gamma", "[0, 1]"]),
    ("overtaking_share_above_one", "stretch3_reach",
     "{prediction: {overtaking: {enabled: true, share: 1.5}}}",
     ["prediction.overtaking.share", "[0, 1]"]),
    ("overtaking_keep_angle_obtuse", "stretch3_reach",
     "{prediction: {overtaking: {keep_angle: 120}}}",
     ["prediction.overtaking.keep_angle", "[0, 90]"]),
    ("overtaking_angle_right", "stretch3_reach",
     "{prediction: {overtaking: {angle: 90}}}",
     ["prediction.overtaking.angle", "(0, 90)"]),
    ("unknown_reciprocity_key", "stretch3_reach",
     "{prediction: {reciprocity: {forget: 2}}}",
     ["forget"]),
    ("nan_max_step_size", "stretch3_reach",
     "{simulator_config: {max_step_size: .nan}}",
     ["simulator_config.max_step_size"]),
    ("ee_target_too_short", "stretch3_reach",
     "{tasks: [{kind: ee_position, target: [1.0, 0.0]}]}",
     ["tasks[0]", "target", "3 entries"]),
    ("base_target_too_long", "stretch3_reach",
     "{tasks: [{kind: base_position, target: [1.0, 0.0, 0.0]}]}",
     ["tasks[0]", "target", "2 entries"]),
    ("base_pose_target_short", "stretch3_reach",
     "{tasks: [{kind: base_pose, target: [1.0, 0.0]}]}",
     ["tasks[0]", "target", "3 entries"]),
    ("joint_posture_wrong_length", "stretch3_reach",
     "{tasks: [{kind: joint_posture, target: [0.5, 0.1, 0.0]}]}",
     ["tasks[0]", "target", "4 entries"]),
    ("offset_on_an_ee_task", "stretch3_reach",
     "{tasks: [{kind: ee_position, target: [1, 0, 1], offset: 0.1}]}",
     ["tasks[0]", "offset", "base_position"]),
    ("weight_wrong_length", "stretch3_reach",
     "{tasks: [{kind: ee_position, target: [1, 0, 1], weight: [1, 1]}]}",
     ["tasks[0]", "weight"]),
    ("initial_q_wrong_length", "ridgeback_ur10_reach",
     "{robot: {initial_q: [0, 0, 0, 1]}}",
     ["robot.initial_q", "9 entries"]),
    ("initial_nu_wrong_length", "stretch3_reach",
     "{robot: {initial_nu: [0, 0, 0, 0, 0, 0, 0]}}",
     ["robot.initial_nu", "6 entries"]),
    ("initial_q_outside_limits", "stretch3_reach",
     "{robot: {initial_q: [0, 0, 0, 0.5, 0.9, 0, 0]}}",
     ["robot.initial_q[4]", "joint_arm", "limits"]),
    ("waypoint_3d", "stretch3_reach",
     "{humans: [{behavior: orca, start: [3, 3], waypoints: [[3, -3, 0]]}]}",
     ["humans[0].waypoints[0]"]),
    ("start_1d", "stretch3_reach",
     "{humans: [{behavior: orca, start: [3], waypoints: [[3, -3]]}]}",
     ["humans[0].start"]),
    ("obstacle_vertex_3d", "stretch3_reach",
     "{obstacles: [{vertices: [[0, 2, 1], [4, 2, 1]]}]}",
     ["obstacles[0].vertices[0]"]),
    ("obstacle_one_vertex", "stretch3_reach",
     "{obstacles: [{vertices: [[0, 2]]}]}",
     ["obstacles[0].vertices"]),
    ("negative_duration", "stretch3_reach", "{simulation_duration: -1.0}",
     ["simulation_duration", "> 0"]),
    ("zero_time_step", "stretch3_reach", "{controller: {time_step: 0.0}}",
     ["controller.time_step", "> 0"]),
    ("negative_control_period", "stretch3_reach",
     "{controller: {control_period: -0.1}}",
     ["controller.control_period"]),
    ("zero_perception_period", "ridgeback_ur10_reach",
     "{perception: {period: 0.0}}",
     ["perception.period"]),
    ("zero_publish_period", "stretch3_reach",
     "{visualization: {publish_period: 0}}",
     ["visualization.publish_period"]),
    ("zero_robot_time_step", "stretch3_reach", "{robot_time_step: 0.0}",
     ["robot_time_step"]),
    ("negative_radius", "stretch3_reach",
     "{humans: [{behavior: orca, start: [3, 3], waypoints: [[3, -3]], radius: -0.3}]}",
     ["humans[0].radius"]),
    ("zero_speed", "stretch3_reach",
     "{humans: [{behavior: orca, start: [3, 3], waypoints: [[3, -3]], speed: 0.0}]}",
     ["humans[0].speed", "> 0"]),
    ("zero_human_radius_safety", "stretch3_reach", "{safety: {human_radius: 0}}",
     ["safety.human_radius"]),
    ("negative_no_closer_gap", "stretch3_reach", "{safety: {no_closer_gap: -0.05}}",
     ["safety.no_closer_gap"]),
    ("negative_no_closer_speed", "stretch3_reach", "{safety: {no_closer_speed: -0.1}}",
     ["safety.no_closer_speed"]),
    ("zero_no_closer_slack_weight", "stretch3_reach",
     "{safety: {no_closer_slack_weight: 0}}",
     ["safety.no_closer_slack_weight", "> 0"]),
    ("wall_below_person_slack", "stretch3_reach",
     "{safety: {human_slack_weight: 1e6, obstacle_slack_weight: 1e5}}",
     ["safety.obstacle_slack_weight", "outranks"]),
    ("negative_tau", "stretch3_reach", "{prediction: {tau: -2.0}}",
     ["prediction.tau"]),
    ("zero_max_speed_prediction", "stretch3_reach",
     "{prediction: {max_speed: 0.0}}",
     ["prediction.max_speed"]),
    ("negative_obstacle_height", "stretch3_reach",
     "{obstacles: [{vertices: [[0, 2], [4, 2]], height: -1}]}",
     ["obstacles[0].height"]),
    ("sequence_target_length", "stretch3_reach",
     "{sequence: [{targets: {base_position: [1, 2, 3]}, done_when: [base_position]}]}",
     ["sequence[0].targets.base_position", "2 entries"]),
    ("zero_reaction_distance", "stretch3_reach",
     "{humans: [{behavior: instructed, start: [3, 3], waypoints: [[3, -3]], "
     "reaction_distance: 0.0}]}",
     ["humans[0].reaction_distance", "> 0"]),
    ("start_phase_without_sequence", "stretch3_reach",
     "{humans: [{behavior: scripted, start: [3, 3], waypoints: [[3, -3]], "
     "start_phase: cross}]}",
     ["humans[0].start_phase", "'cross'", "none (no sequence)"]),
    ("start_phase_unknown", "stretch3_reach",
     "{sequence: [{name: go, targets: {base_position: [1, 0]}}, "
     "{name: back, targets: {base_position: [0, 0]}}], "
     "humans: [{behavior: instructed, start: [3, 3], waypoints: [[3, -3]], "
     "start_phase: cross}]}",
     ["humans[0].start_phase", "'cross'", "valid: 'go', 'back'"]),
    ("waypoint_phases_length", "stretch3_reach",
     "{sequence: [{name: go, targets: {base_position: [1, 0]}}], "
     "humans: [{behavior: orca, start: [3, 3], waypoints: [[3, -3], [3, 3]], "
     "waypoint_phases: [go]}]}",
     ["humans[0].waypoint_phases", "got 1 for 2 waypoints"]),
    ("waypoint_phases_loop", "stretch3_reach",
     "{sequence: [{name: go, targets: {base_position: [1, 0]}}], "
     "humans: [{behavior: orca, start: [3, 3], waypoints: [[3, -3], [3, 3]], "
     "waypoint_phases: [go, ''], loop: true}]}",
     ["humans[0].waypoint_phases", "loop: true"]),
    ("waypoint_phases_unknown", "stretch3_reach",
     "{sequence: [{name: go, targets: {base_position: [1, 0]}}, "
     "{name: back, targets: {base_position: [0, 0]}}], "
     "humans: [{behavior: orca, start: [3, 3], waypoints: [[3, -3], [3, 3]], "
     "waypoint_phases: ['', cross]}]}",
     ["humans[0].waypoint_phases[1]", "'cross'", "valid: 'go', 'back'"]),
    # Solver settings: PIQP took a bad one at every solve (every step
    # failed), HPIPM exited the process on a name it does not know.
    ("piqp_unknown_setting", "stretch3_reach",
     "{controller: {solver_options: {options: {PIQP: {eps_absolute: 1.0e-5}}}}}",
     ["PIQP setting 'eps_absolute'", "no such setting"]),
    ("piqp_setting_wrong_type", "stretch3_reach",
     "{controller: {solver_options: {options: {PIQP: {max_iter: many}}}}}",
     ["PIQP setting 'max_iter'", "'many'", "whole number"]),
    ("piqp_setting_nan_text", "stretch3_reach",
     "{controller: {solver_options: {options: {PIQP: {eps_abs: nan}}}}}",
     ["PIQP setting 'eps_abs'", "'nan'", "finite number"]),
    ("piqp_setting_infinite", "stretch3_reach",
     "{controller: {solver_options: {options: {PIQP: {eps_rel: inf}}}}}",
     ["PIQP setting 'eps_rel'", "finite number"]),
    ("piqp_setting_text_number", "stretch3_reach",
     "{controller: {solver_options: {options: {PIQP: {eps_abs: 1e-5, max_iter: x}}}}}",
     ["PIQP setting 'max_iter'", "whole number"]),
    ("piqp_unknown_kkt_solver", "stretch3_reach",
     "{controller: {solver_options: {options: {PIQP: {kkt_solver: fast}}}}}",
     ["PIQP kkt_solver 'fast'", "sparse_ldlt"]),
    ("hpipm_unknown_setting", "stretch3_reach",
     "{controller: {solver_options: {options: {HPIPM: {tolerance: 1.0e-6}}}}}",
     ["HPIPM setting 'tolerance'", "tol_stat"]),
    ("hpipm_iter_max_not_whole", "stretch3_reach",
     "{controller: {solver_options: {options: {HPIPM: {iter_max: 2.5}}}}}",
     ["HPIPM setting 'iter_max'", "whole number"]),
    ("hpipm_unknown_mode", "stretch3_reach",
     "{controller: {solver_options: {options: {HPIPM: {mode: fastest}}}}}",
     ["HPIPM mode 'fastest'", "speed_abs"]),
]  # fmt: skip


@pytest.mark.parametrize(
    "scenario, override, words",
    [b[1:] for b in BAD_INPUTS],
    ids=[b[0] for b in BAD_INPUTS],
)
def test_bad_input_exits_2_naming_the_field(scenario, override, words, capsys):
    rc = main(["run", REACH, "--scenario", scenario, "--no-meshcat",
               "--scenario_text", override])  # fmt: skip
    out, err = capsys.readouterr()
    assert rc == 2, (out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sm2ith: error:"), err
    for word in words:
        assert word in lines[0], f"{word!r} not in: {lines[0]}"
    assert "Traceback" not in err + out


def test_table_is_big_enough():
    assert len(BAD_INPUTS) >= 20
    assert len({b[2] for b in BAD_INPUTS}) == len(BAD_INPUTS)


def test_entry_point_subprocess_prints_no_traceback():
    """The installed console command, as a user runs it."""
    proc = subprocess.run(
        [sys.executable, "-m", "sm2ith_drake.cli", "run", REACH,
         "--scenario", "stretch3_reach", "--no-meshcat",
         "--scenario_text", "{tasks: [{kind: ee_position, target: [.nan, 0, 1]}]}"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 2, proc.stderr
    assert "tasks[0].target[0]" in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize(
    "start, words",
    [([0.1, 0.0], ["humans[0].start", "inside the robot", " m"]),
     ([3.0, 1.6], ["humans[0].start", "inside obstacles[0]", " m"])],
)  # fmt: skip
def test_people_starting_inside_the_robot_or_a_wall_warn(start, words, capsys):
    """A warning on stderr with the overlap, not an error."""
    text = (
        f"{{humans: [{{behavior: orca, start: {start}, waypoints: [[3, -3]]}}], "
        "obstacles: [{vertices: [[-1.0, 1.5], [8.0, 1.5]]}]}"
    )
    LoadScenarioAndRobot(
        filename=REACH, scenario_name="stretch3_reach", scenario_text=text
    )
    err = capsys.readouterr().err
    (line,) = [w for w in err.splitlines() if w.startswith("warning:")]
    for word in words:
        assert word in line, line
    overlap = float(line.split(" by ")[1].split(" m")[0])
    assert overlap > 0


class _SolverSpy:
    """Wraps the stage QPs' solvers (PIQP's and HPIPM's workspaces): records
    every QP handed to either and whether any of its numbers was NaN (bounds
    may be ±inf, never NaN)."""

    calls = 0
    nan_calls = 0

    @staticmethod
    def Wrap(solve):
        def Solve(self, *args, **kw):
            _SolverSpy.calls += 1
            if any(np.any(np.isnan(np.asarray(a, dtype=float))) for a in args):
                _SolverSpy.nan_calls += 1
            return solve(self, *args, **kw)

        return Solve


@pytest.fixture
def solver_spy(monkeypatch):
    _SolverSpy.calls = _SolverSpy.nan_calls = 0
    for workspace in (PiqpWorkspace, HpipmWorkspace):
        monkeypatch.setattr(workspace, "Solve", _SolverSpy.Wrap(workspace.Solve))
    return _SolverSpy


def test_nan_detections_in_the_closed_loop_never_reach_the_solver(
    solver_spy, monkeypatch
):
    """The simulation with motion capture that sends NaN and infinite
    positions in some frames: the Kalman filter drops them, every QP the
    controller solves is NaN-free, and the run ends with finite metrics."""
    measure = MocapSensor._Measure
    injected = []

    def corrupted(self, context, state):
        measure(self, context, state)
        frame = state.get_mutable_abstract_state(0).get_value()
        k = int(round(context.get_time() / 0.05))
        if len(frame.ids) and k % 3 == 1:
            positions = np.array(frame.positions, dtype=float)
            positions[0, k % 2] = np.nan if k % 2 else np.inf
            injected.append(k)
            state.get_mutable_abstract_state(0).set_value(
                HumanDetections(time=frame.time, ids=frame.ids, positions=positions)
            )

    monkeypatch.setattr(MocapSensor, "_Measure", corrupted)
    scenario = LoadScenario(filename=CROSSING, scenario_name="crossing_stretch3_1h")
    assert scenario.perception.estimator == "kalman"
    result = RunSimulation(scenario, duration=1.5)
    assert len(injected) >= 5
    assert solver_spy.calls > 0
    assert solver_spy.nan_calls == 0
    for key in ("ee_position.mean_error", "min_human_gap"):
        if key in result.metrics:
            assert np.isfinite(result.metrics[key]), key


def test_nan_robot_state_never_reaches_the_solver(solver_spy):
    """The controller stack of the simulation fed a NaN robot state: no QP is
    solved with it, and the command is a finite braking command."""
    scenario, robot = LoadScenarioAndRobot(
        filename=CROSSING, scenario_name="crossing_stretch3_1h"
    )
    tasks = [MakeTask(t, robot.num_positions) for t in scenario.tasks]
    builder = DiagramBuilder()
    stack = AddControlStack(builder, scenario, robot, tasks, with_estimator=True)
    m = robot.num_velocities
    x = np.concatenate([robot.default_q, np.zeros(m)])
    x[0] = np.nan
    state = builder.AddSystem(ConstantVectorSource(x))
    for port in stack.robot_state_inputs:
        builder.Connect(state.get_output_port(), port)
    detections = builder.AddSystem(
        ConstantValueSource(
            AbstractValue.Make(
                HumanDetections(
                    time=0.0, ids=np.array([0]), positions=np.array([[3.0, 1.0]])
                )
            )
        )
    )
    builder.Connect(detections.get_output_port(), stack.detections_input)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(1.0)
    context = stack.controller.GetMyContextFromRoot(simulator.get_context())
    command = stack.command.Eval(context)
    assert command.shape == (2 * m,) and np.all(np.isfinite(command))
    assert solver_spy.nan_calls == 0
    assert solver_spy.calls == 0  # never solved from a NaN state
