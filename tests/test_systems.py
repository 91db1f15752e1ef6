"""Every LeafSystem of the package on its own (issue 11, item 6): built
alone, a default Context, every input fixed, its ports checked, one update
run and its result compared with an independent reference.

pydrake binds no ``GetPeriodicEvents`` and these systems declare no forced
update events, so a periodic unrestricted update is run by a Simulator over
the lone system at the event's instant, without advancing time
(:func:`_Update`); KinematicRobot's discrete update is evaluated directly
(``EvalUniquePeriodicDiscreteUpdate``) and the visualizers' publish events
are forced (``ForcedPublish``).
"""

import math
import time
from types import SimpleNamespace

import numpy as np
import pytest
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import PortDataType

from sm2ith_drake.control.mpc_controller import ControllerState, StepRecord
from sm2ith_drake.control.tasks import MakeTask
from sm2ith_drake.humans.messages import (
    HumanDetections,
    HumanEstimate,
    HumanIntents,
    HumanPrediction,
    MpcPlan,
)
from sm2ith_drake.lcm.codecs import (
    DecodeHumanDetections,
    DecodeRobotCommand,
    DecodeRobotState,
    MakeCommandMessage,
    MakeDetectionsMessage,
    MakeRobotStateMessage,
    RawLcmMessage,
)
from sm2ith_drake.lcm.command_follower import CommandFollower
from sm2ith_drake.lcm.command_gate import (
    MODE_CONTROL,
    MODE_SLOWED,
    MODE_STOP,
    CommandGate,
    GateState,
)
from sm2ith_drake.lcm.encoders import (
    HumanDetectionsEncoder,
    PlanEncoder,
    RobotCommandEncoder,
    RobotStateEncoder,
)
from sm2ith_drake.lcm.receivers import (
    HumanDetectionsReceiver,
    ReceiverState,
    RobotCommandReceiver,
    RobotStateReceiver,
)
from sm2ith_drake.lcm.timing import CommandMonitor
from sm2ith_drake.planning.sequence import TaskReferences
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.scenario import (
    ControllerConfig,
    HumanConfig,
    ObstacleConfig,
    PhaseConfig,
    PredictionConfig,
    TaskConfig,
)
from sm2ith_drake.systems.hierarchical_mpc import HierarchicalMpc
from sm2ith_drake.systems.humans import CrowdSimulator, HumanEstimator, MocapSensor
from sm2ith_drake.systems.logger import RunLogger
from sm2ith_drake.systems.planner import TaskPlanner
from sm2ith_drake.systems.predictor import HumanPredictor
from sm2ith_drake.systems.robot import KinematicRobot
from sm2ith_drake.systems.visualization import HumanVisualizer, PlanVisualizer

VECTOR, ABSTRACT = PortDataType.kVectorValued, PortDataType.kAbstractValued


@pytest.fixture(scope="module")
def ridgeback():
    return MobileManipulator("ridgeback_ur10")


@pytest.fixture(scope="module")
def stretch():
    return MobileManipulator("stretch3")


def _Ports(system, inputs, outputs):
    """Checks the names, kinds and sizes of every port: {name: size} with
    size None for an abstract port."""

    def kinds(ports):
        return {
            p.get_name(): (None if p.get_data_type() == ABSTRACT else p.size())
            for p in ports
        }

    assert kinds(
        system.get_input_port(i) for i in range(system.num_input_ports())
    ) == dict(inputs)
    assert kinds(
        system.get_output_port(i) for i in range(system.num_output_ports())
    ) == dict(outputs)


def _Update(system, context, at: float = 0.0) -> None:
    """Runs the system's periodic events due at time ``at`` (a multiple of
    their period) once, on ``context``."""
    context.SetTime(at)
    simulator = Simulator(system, context)
    simulator.Initialize()
    simulator.AdvancePendingEvents()


def _State(robot, q=None, nu=None):
    q = robot.default_q if q is None else q
    nu = np.zeros(robot.num_velocities) if nu is None else nu
    return np.concatenate([q, nu])


# ---------------------------------------------------------------- systems/


@pytest.mark.parametrize("name", ["ridgeback_ur10", "stretch3"])
def test_kinematic_robot_integrates_and_clips(name):
    robot = MobileManipulator(name)
    n, m, h = robot.num_positions, robot.num_velocities, 0.01
    q0 = robot.default_q.copy()
    q0[2] = 0.4
    nu0 = 0.3 * robot.nu_upper
    system = KinematicRobot(robot, initial_q=q0, initial_nu=nu0, time_step=h)
    _Ports(system, {"command": 2 * m}, {"state": n + m})
    context = system.CreateDefaultContext()
    np.testing.assert_array_equal(
        system.GetOutputPort("state").Eval(context),
        [
            *q0,
            *nu0,
        ],
    )
    # Within the limits: ν' = ν + h u, then q' = q + h G(q) ν' written out.
    u = 0.5 * robot.nudot_upper * np.linspace(-1, 1, m)
    system.get_input_port().FixValue(context, np.concatenate([u, np.zeros(m)]))
    x = system.EvalUniquePeriodicDiscreteUpdate(context).get_vector().CopyToVector()
    nu1 = nu0 + h * u
    c, s = math.cos(0.4), math.sin(0.4)
    if robot.base_kind == "holonomic":  # ν = (v_x, v_y, ω, arm) in the body
        base = [c * nu1[0] - s * nu1[1], s * nu1[0] + c * nu1[1], nu1[2]]
        arm = nu1[3:]
    else:  # ν = (v, ω, arm)
        base = [c * nu1[0], s * nu1[0], nu1[1]]
        arm = nu1[2:]
    np.testing.assert_allclose(x[n:], nu1, rtol=0, atol=1e-14)
    np.testing.assert_allclose(
        x[:n], q0 + h * np.concatenate([base, arm]), rtol=0, atol=1e-14
    )
    # A command beyond the acceleration limits is clipped to them.
    system.get_input_port().FixValue(
        context, np.concatenate([10 * robot.nudot_upper, np.zeros(m)])
    )
    x = system.EvalUniquePeriodicDiscreteUpdate(context).get_vector().CopyToVector()
    np.testing.assert_allclose(
        x[n:], np.minimum(nu0 + h * robot.nudot_upper, robot.nu_upper), atol=1e-14
    )
    # A non-finite command brakes: ν' = ν − h·min(ν/h, a_max) → 0 from 0.3ν_max.
    system.get_input_port().FixValue(context, np.full(2 * m, np.nan))
    x = system.EvalUniquePeriodicDiscreteUpdate(context).get_vector().CopyToVector()
    expected = nu0 - h * np.minimum(nu0 / h, robot.nudot_upper)
    np.testing.assert_allclose(x[n:], expected, atol=1e-14)
    # A joint at its upper limit moving up stays there and stops.
    joint = n - 1
    q_lim = q0.copy()
    q_lim[joint] = robot.q_upper[joint]
    nu_up = np.zeros(m)
    nu_up[m - 1] = 0.5 * robot.nu_upper[m - 1]
    context.SetDiscreteState(np.concatenate([q_lim, nu_up]))
    system.get_input_port().FixValue(context, np.zeros(2 * m))
    x = system.EvalUniquePeriodicDiscreteUpdate(context).get_vector().CopyToVector()
    assert x[joint] == robot.q_upper[joint] and x[n + m - 1] == 0.0


def _Tasks(robot, *configs):
    return [MakeTask(t, robot.num_positions) for t in configs]


def test_task_planner_emits_the_targets(ridgeback):
    tasks = _Tasks(
        ridgeback,
        TaskConfig(kind="base_position", target=[1.0, 2.0]),
        TaskConfig(kind="ee_position", target=[0.5, 0.0, 1.0]),
    )
    n, m = ridgeback.num_positions, ridgeback.num_velocities
    system = TaskPlanner(tasks, num_states=n + m)
    _Ports(system, {"robot_state": n + m}, {"task_references": None})
    context = system.CreateDefaultContext()
    system.get_input_port().FixValue(context, _State(ridgeback))
    refs = system.GetOutputPort("task_references").Eval(context)
    assert set(refs.targets) == {"base_position", "ee_position"}
    np.testing.assert_array_equal(refs.targets["base_position"], [1.0, 2.0])
    np.testing.assert_array_equal(refs.targets["ee_position"], [0.5, 0.0, 1.0])
    assert refs.phase_index == 0 and not refs.finished


def test_task_planner_advances_a_phase_after_its_hold_time(ridgeback):
    tasks = _Tasks(ridgeback, TaskConfig(kind="base_position", target=[0.0, 0.0]))
    n, m = ridgeback.num_positions, ridgeback.num_velocities
    sequence = [
        PhaseConfig(
            name="go",
            targets={"base_position": [1.0, 0.0]},
            tolerance=0.05,
            hold_time=0.1,
        ),
        PhaseConfig(name="back", targets={"base_position": [-1.0, 0.0]}),
    ]
    system = TaskPlanner(
        tasks, num_states=n + m, robot=ridgeback, sequence=sequence, period=0.05
    )
    context = system.CreateDefaultContext()
    q = ridgeback.default_q.copy()
    q[:2] = [1.02, 0.0]  # within the tolerance of phase "go"
    system.get_input_port().FixValue(context, _State(ridgeback, q))
    output = system.GetOutputPort("task_references")
    phases = []
    for t in (0.0, 0.05, 0.1):
        _Update(system, context, t)
        phases.append(output.Eval(context).phase_index)
    # Inside since t = 0: the hold time has passed at t = 0.1, not before.
    assert phases == [0, 0, 1]
    refs = output.Eval(context)
    assert refs.phase == "back"
    np.testing.assert_array_equal(refs.targets["base_position"], [-1.0, 0.0])
    assert system.GetSequenceState(context).completed_at == [0.1]


def test_crowd_simulator_walks_a_scripted_person(ridgeback):
    n, m = ridgeback.num_positions, ridgeback.num_velocities
    humans = [
        HumanConfig(behavior="scripted", start=[5.0, 5.0], waypoints=[[9.0, 8.0]])
    ]
    dt = 0.05
    system = CrowdSimulator(
        ridgeback, humans, obstacle_segments=np.zeros((0, 2, 2)), time_step=dt
    )
    _Ports(
        system,
        {"robot_state": n + m, "task_references": None},
        {"human_truth": None, "human_intents": None},
    )
    context = system.CreateDefaultContext()
    system.GetInputPort("robot_state").FixValue(context, _State(ridgeback))
    truth = system.GetOutputPort("human_truth").Eval(context)
    np.testing.assert_array_equal(truth.positions, [[5.0, 5.0]])
    _Update(system, context)
    truth = system.GetOutputPort("human_truth").Eval(context)
    # At 1 m/s straight toward its waypoint, along (4, 3)/5, for one step.
    np.testing.assert_array_equal(truth.ids, [0])
    np.testing.assert_allclose(truth.velocities, [[0.8, 0.6]], atol=1e-12)
    np.testing.assert_allclose(truth.positions, [[5.04, 5.03]], atol=1e-12)
    # Its intent is known only to relaxed-ORCA people.
    intents = system.GetOutputPort("human_intents").Eval(context)
    assert np.all(np.isnan(intents.preferred_velocities))


def test_crowd_simulator_starts_a_person_when_its_phase_is_entered(ridgeback):
    """task_references tells the crowd where the sequence is: a person with
    a start_phase stands until the phase index reaches it, then walks at
    once (start_time 0); when it was entered is in the Context."""
    humans = [
        HumanConfig(
            behavior="instructed",
            start=[5.0, 5.0],
            waypoints=[[5.0, 9.0]],
            start_phase="cross",
        )
    ]
    system = CrowdSimulator(
        ridgeback,
        humans,
        obstacle_segments=np.zeros((0, 2, 2)),
        time_step=0.05,
        phases=["go", "cross"],
    )
    context = system.CreateDefaultContext()
    system.GetInputPort("robot_state").FixValue(context, _State(ridgeback))
    refs = system.GetInputPort("task_references")
    refs.FixValue(context, TaskReferences(phase_index=0, phase="go"))
    _Update(system, context, 0.05)
    truth = system.GetOutputPort("human_truth")
    np.testing.assert_array_equal(truth.Eval(context).positions, [[5.0, 5.0]])
    refs.FixValue(context, TaskReferences(phase_index=1, phase="cross"))
    _Update(system, context, 0.1)
    np.testing.assert_allclose(truth.Eval(context).positions, [[5.0, 5.05]])
    state = context.get_abstract_state(0).get_value()
    np.testing.assert_array_equal(state.phase_entered, [0.1])
    # A start_phase needs the input, and must be one of the phases.
    unconnected = system.CreateDefaultContext()
    system.GetInputPort("robot_state").FixValue(unconnected, _State(ridgeback))
    with pytest.raises(RuntimeError, match="task_references"):
        _Update(system, unconnected, 0.05)
    with pytest.raises(ValueError, match="start_phase 'cross'"):
        CrowdSimulator(ridgeback, humans, obstacle_segments=np.zeros((0, 2, 2)))


def _Truth(count, seed=0):
    rng = np.random.default_rng(seed)
    return HumanEstimate(
        ids=np.arange(count) + 10,
        positions=rng.uniform(-5, 5, (count, 2)),
        velocities=np.zeros((count, 2)),
    )


def test_mocap_sensor_is_the_truth_plus_noise_of_its_scale():
    truth = _Truth(4000)
    for noise in (0.0, 0.02):
        system = MocapSensor(period=0.05, noise=noise, dropout_probability=0.0)
        _Ports(system, {"human_truth": None}, {"detections": None})
        context = system.CreateDefaultContext()
        system.get_input_port().FixValue(context, truth)
        _Update(system, context, 0.1)
        frame = system.GetOutputPort("detections").Eval(context)
        assert frame.time == 0.1
        np.testing.assert_array_equal(frame.ids, truth.ids)
        error = frame.positions - truth.positions
        if noise == 0.0:
            np.testing.assert_array_equal(error, 0.0)
        else:
            # The sample std of 8000 normal draws is within 3 % of σ
            # (its relative standard error is 1/√(2·8000) ≈ 0.8 %).
            assert abs(np.std(error) / noise - 1) < 0.03
            assert abs(np.mean(error)) < 3 * noise / math.sqrt(error.size)
    system = MocapSensor(period=0.05, noise=0.0, dropout_probability=1.0)
    context = system.CreateDefaultContext()
    system.get_input_port().FixValue(context, truth)
    _Update(system, context, 0.1)
    frame = system.GetOutputPort("detections").Eval(context)
    assert frame.ids.size == 0 and frame.positions.shape == (0, 2)


def test_human_estimator_starts_a_track_at_a_detection():
    system = HumanEstimator(
        period=0.05, measurement_noise=0.01, acceleration_noise=0.5, track_timeout=1.0
    )
    _Ports(system, {"detections": None}, {"human_estimate": None})
    context = system.CreateDefaultContext()
    frame = HumanDetections(time=0.1, ids=np.array([4]), positions=[[1.0, 2.0]])
    system.get_input_port().FixValue(context, frame)
    assert system.GetOutputPort("human_estimate").Eval(context).ids.size == 0
    _Update(system, context, 0.1)
    estimate = system.GetOutputPort("human_estimate").Eval(context)
    np.testing.assert_array_equal(estimate.ids, [4])
    np.testing.assert_allclose(estimate.positions, [[1.0, 2.0]], atol=1e-12)
    np.testing.assert_allclose(estimate.velocities, 0.0, atol=1e-12)
    # The same frame again is not fused twice.
    before = system.GetTracks(context).last_frame_time
    _Update(system, context, 0.15)
    assert system.GetTracks(context).last_frame_time == before == 0.1


def _Predictor(robot, predictor, **kwargs):
    return HumanPredictor(
        robot,
        PredictionConfig(predictor=predictor, max_humans=2),
        horizon=10,
        time_step=0.2,
        control_period=0.1,
        **kwargs,
    )


def _FixPredictorInputs(system, context, robot, estimate):
    system.GetInputPort("human_estimate").FixValue(context, estimate)
    system.GetInputPort("robot_state").FixValue(context, _State(robot))
    inputs = np.zeros((10, robot.num_velocities))  # the robot stands still
    system.GetInputPort("plan").FixValue(context, MpcPlan(warm_start_inputs=inputs))


def _Slot(prediction, person):
    return int(np.nonzero(prediction.slot_ids == person)[0][0])


def test_human_predictor_constant_velocity_and_held(ridgeback):
    n, m = ridgeback.num_positions, ridgeback.num_velocities
    p, v = np.array([2.0, 1.0]), np.array([0.5, -0.2])
    estimate = HumanEstimate(ids=[5], positions=[p], velocities=[v])
    k = np.arange(11)[:, None]
    for model, expected in (("cvmm", p + 0.2 * k * v), ("react", p + 0 * k)):
        system = _Predictor(ridgeback, model, with_intents=True)
        _Ports(
            system,
            {
                "human_estimate": None,
                "robot_state": n + m,
                "plan": None,
                "human_intents": None,
            },
            {"human_prediction": None, "last_prediction": None},
        )
        context = system.CreateDefaultContext()
        _FixPredictorInputs(system, context, ridgeback, estimate)
        intent = HumanIntents(ids=[5], preferred_velocities=[[0.3, -0.4]])
        system.GetInputPort("human_intents").FixValue(context, intent)
        prediction = system.GetOutputPort("human_prediction").Eval(context)
        assert prediction.model == model and prediction.positions.shape == (11, 2, 2)
        slot = _Slot(prediction, 5)
        assert prediction.active.tolist().count(True) == 1
        np.testing.assert_allclose(prediction.positions[:, slot], expected, atol=1e-12)
        # The intent (simulation only) is the preferred velocity, not the
        # measured one the prediction extrapolates.
        np.testing.assert_array_equal(
            prediction.preferred_velocities[slot], [0.3, -0.4]
        )


def test_human_predictor_keeps_slots_by_id_across_updates(ridgeback):
    system = _Predictor(ridgeback, "cvmm")
    assert system.num_input_ports() == 3  # no human_intents without intents
    context = system.CreateDefaultContext()
    ids, p, v = [5, 9], [[2.0, 1.0], [4.0, -1.0]], [[0.5, 0.0], [0.0, 0.5]]
    _FixPredictorInputs(
        system, context, ridgeback, HumanEstimate(ids=ids, positions=p, velocities=v)
    )
    output = system.GetOutputPort("human_prediction")
    last = system.GetOutputPort("last_prediction")
    first = output.Eval(context)
    assert last.Eval(context).slot_ids.size == 0  # state only: nothing yet
    _Update(system, context)
    np.testing.assert_array_equal(last.Eval(context).positions, first.positions)
    assert system.GetPredictorState(context).slot_ids.tolist() == list(first.slot_ids)
    # The same people listed in the other order keep their slots.
    reordered = HumanEstimate(ids=ids[::-1], positions=p[::-1], velocities=v[::-1])
    system.GetInputPort("human_estimate").FixValue(context, reordered)
    second = output.Eval(context)
    np.testing.assert_array_equal(second.slot_ids, first.slot_ids)
    for person, position in zip(ids, p, strict=True):
        np.testing.assert_array_equal(
            second.positions[0, _Slot(second, person)], position
        )
    # Without the committed state, the order decides (the test can fail).
    fresh = system.CreateDefaultContext()
    _FixPredictorInputs(system, fresh, ridgeback, reordered)
    assert not np.array_equal(output.Eval(fresh).slot_ids, first.slot_ids)


def test_human_predictor_orca_person_steps_aside_of_a_standing_robot(ridgeback):
    system = _Predictor(ridgeback, "orca_kkt")
    context = system.CreateDefaultContext()
    # Walking at the robot (at the origin) from 3 m, slightly to its left.
    estimate = HumanEstimate(ids=[0], positions=[[3.0, 0.05]], velocities=[[-1, 0]])
    _FixPredictorInputs(system, context, ridgeback, estimate)
    prediction = system.GetOutputPort("human_prediction").Eval(context)
    path = prediction.positions[:, _Slot(prediction, 0)]
    assert prediction.actions is not None and prediction.multipliers is not None
    # Constant velocity would keep y = 0.05; ORCA turns it aside, to the
    # left, and the person still walks on.
    assert path[-1, 1] - 0.05 > 0.1
    assert np.all(np.diff(path[:, 0]) < 0)
    np.testing.assert_allclose(path[1], [3.0 - 0.2, 0.05], atol=0.05)


def test_hierarchical_mpc_outputs_depend_on_state_only(ridgeback):
    n, m = ridgeback.num_positions, ridgeback.num_velocities
    config = ControllerConfig()
    tasks = [TaskConfig(kind="base_position", target=[1.0, 0.5])]
    system = HierarchicalMpc(ridgeback, tasks, config)
    _Ports(
        system,
        {"robot_state": n + m, "task_references": None},
        {"command": 2 * m, "plan": None, "controller_state": None},
    )
    with_people = HierarchicalMpc(
        ridgeback, tasks, config, prediction=PredictionConfig(max_humans=1)
    )
    assert with_people.GetInputPort("human_prediction").get_data_type() == ABSTRACT
    for i in range(system.num_output_ports()):
        assert not system.HasDirectFeedthrough(output_port=i)
    context = system.CreateDefaultContext()
    x = _State(ridgeback)
    system.GetInputPort("robot_state").FixValue(context, x)
    refs = TaskReferences(targets={"base_position": np.array([1.0, 0.5])})
    system.GetInputPort("task_references").FixValue(context, refs)
    command = system.GetOutputPort("command")
    np.testing.assert_array_equal(command.Eval(context), np.zeros(2 * m))
    # A changed input changes nothing until an update runs.
    moved = x.copy()
    moved[0] = -3.0
    system.GetInputPort("robot_state").FixValue(context, moved)
    np.testing.assert_array_equal(command.Eval(context), np.zeros(2 * m))
    system.GetInputPort("robot_state").FixValue(context, x)
    _Update(system, context)
    u, nu_cmd = np.split(command.Eval(context), 2)
    state = system.GetOutputPort("controller_state").Eval(context)
    assert state.counters.steps == 1 and state.record.mode == "solved"
    # The base (heading 0: body = world axes) accelerates toward (1, 0.5).
    assert u[0] > 0.1 and u[1] > 0.05 and u[0] > u[1]
    assert np.all(np.abs(u) <= ridgeback.nudot_upper + 1e-9)
    # ν_cmd is where u takes ν = 0 within one control period.
    np.testing.assert_allclose(nu_cmd, config.time_step * u, atol=1e-12)
    plan = system.GetOutputPort("plan").Eval(context)
    assert plan.solution is state.last_solution
    assert plan.warm_start_inputs.shape == (config.horizon, m)


def test_run_logger_appends_one_sample_per_update(ridgeback):
    n, m = ridgeback.num_positions, ridgeback.num_velocities
    tasks = _Tasks(ridgeback, TaskConfig(kind="base_position", target=[4.0, 1.0]))
    system = RunLogger(ridgeback, tasks, period=0.125, with_humans=True)
    _Ports(
        system,
        {
            "robot_state": n + m,
            "task_references": None,
            "controller_state": None,
            "human_truth": None,
        },
        {},
    )
    context = system.CreateDefaultContext()
    q = ridgeback.default_q.copy()
    q[:2] = [1.0, -2.0]
    x = _State(ridgeback, q)
    truth = _Truth(2)
    system.GetInputPort("robot_state").FixValue(context, x)
    system.GetInputPort("task_references").FixValue(context, TaskReferences())
    system.GetInputPort("controller_state").FixValue(context, ControllerState())
    system.GetInputPort("human_truth").FixValue(context, truth)
    assert system.GetLog(context).times == []
    _Update(system, context, 0.25)
    log = system.GetLog(context)
    assert log.times == [0.25] and log.phases == [0]
    np.testing.assert_array_equal(log.states[0], x)
    # The task's error at the state: (x, y) − the task's own target.
    np.testing.assert_allclose(log.task_errors["base_position"][0], [-3.0, -3.0])
    np.testing.assert_array_equal(log.human_positions[0], truth.positions)
    assert log.records == []  # no control step yet
    # After a control step, the next sample also records its StepRecord.
    stepped = ControllerState()
    stepped.counters.steps = 1
    stepped.record = StepRecord(time=0.25, mode="brake")
    system.GetInputPort("controller_state").FixValue(context, stepped)
    _Update(system, context, 0.375)
    log = system.GetLog(context)
    assert log.times == [0.25, 0.375] and len(log.states) == 2
    assert [r.mode for r in log.records] == ["brake"]
    assert log.stage_errors == [None]


class _RecordingMeshcat:
    """A Meshcat that also remembers the last transform set at each path."""

    def __init__(self):
        self.meshcat = Meshcat()
        self.transforms = {}

    def SetObject(self, path, *args):
        self.meshcat.SetObject(path, *args)

    def SetTransform(self, path, transform, *args):
        self.transforms[path] = transform.translation().copy()
        self.meshcat.SetTransform(path, transform, *args)


@pytest.fixture(scope="module")
def meshcat():
    return _RecordingMeshcat()


def test_plan_visualizer_draws_the_plan_and_targets(ridgeback, meshcat):
    tasks = _Tasks(
        ridgeback,
        TaskConfig(kind="ee_position", target=[0.5, 0.0, 1.0]),
        TaskConfig(kind="base_position", target=[2.0, 1.0]),
    )
    system = PlanVisualizer(meshcat, tasks, horizon=3, period=0.1, prefix="pv")
    assert system.num_output_ports() == 0
    assert meshcat.meshcat.HasPath("/pv/base_plan/3")
    context = system.CreateDefaultContext()
    q = np.zeros((4, ridgeback.num_positions))
    q[:, 0], q[:, 1] = [0.0, 0.1, 0.2, 0.3], [0.0, 0.0, -0.1, -0.2]
    p_WE = np.arange(12.0).reshape(4, 3)
    solution = SimpleNamespace(q=q, p_WE=p_WE)
    system.GetInputPort("plan").FixValue(context, MpcPlan(solution=solution))
    refs = TaskReferences(
        targets={"ee_position": np.array([0.5, 0.0, 1.0]), "base_position": [2, 1]}
    )
    system.GetInputPort("task_references").FixValue(context, refs)
    system.ForcedPublish(context)
    t = meshcat.transforms
    np.testing.assert_allclose(t["/pv/base_plan/3"], [0.3, -0.2, 0.03])
    np.testing.assert_allclose(t["/pv/ee_plan/2"], [6.0, 7.0, 8.0])
    np.testing.assert_allclose(t["/pv/targets/ee_position"], [0.5, 0.0, 1.0])
    np.testing.assert_allclose(t["/pv/targets/base_position"], [2.0, 1.0, 0.005])


def test_visualizer_ports_are_those_their_docstrings_list(ridgeback, meshcat):
    tasks = _Tasks(ridgeback, TaskConfig(kind="base_position", target=[2.0, 1.0]))
    plan = PlanVisualizer(meshcat, tasks, horizon=2, period=0.1, prefix="pp")
    humans = HumanVisualizer(
        meshcat, [], [], horizon=2, max_humans=1, period=0.1, prefix="hp"
    )
    _Ports(humans, {"human_truth": None, "plan": None, "human_prediction": None}, {})
    _Ports(plan, {"plan": None, "task_references": None}, {})


def test_human_visualizer_places_the_walls(meshcat):
    wall = ObstacleConfig(vertices=[[0.0, 0.0], [2.0, 2.0]], height=1.0)
    HumanVisualizer(
        meshcat, [], [wall], horizon=2, max_humans=1, period=0.1, prefix="hw"
    )
    # A box centred on the segment, half its height up.
    np.testing.assert_allclose(meshcat.transforms["/hw/obstacles/0/0"], [1, 1, 0.5])


def test_human_visualizer_draws_people_and_predictions(meshcat):
    humans = [HumanConfig(radius=0.3), HumanConfig(radius=0.25)]
    system = HumanVisualizer(
        meshcat, humans, [], horizon=2, max_humans=2, period=0.1, prefix="hv"
    )
    context = system.CreateDefaultContext()
    truth = HumanEstimate(
        ids=[0, 1], positions=[[1.0, 2.0], [3.0, 4.0]], velocities=np.zeros((2, 2))
    )
    system.GetInputPort("human_truth").FixValue(context, truth)
    refined = np.arange(12.0).reshape(3, 2, 2)
    solution = SimpleNamespace(
        human_predictions=refined, human_slot_ids=np.array([7, -1])
    )
    system.GetInputPort("plan").FixValue(context, MpcPlan(solution=solution))
    predicted = HumanPrediction(
        slot_ids=np.array([7, -1]),
        active=np.array([True, False]),
        positions=-refined,
    )
    system.GetInputPort("human_prediction").FixValue(context, predicted)
    system.ForcedPublish(context)
    t = meshcat.transforms
    np.testing.assert_allclose(t["/hv/humans/1"], [3.0, 4.0, 0.85])
    # The MPC's refined prediction (green) and the predictor's (grey).
    np.testing.assert_allclose(t["/hv/human_predictions/0/2"], [8.0, 9.0, 0.06])
    np.testing.assert_allclose(t["/hv/predictor_output/0/2"], [-8.0, -9.0, 0.03])
    # An empty slot is hidden below the floor.
    assert t["/hv/human_predictions/1/2"][2] < -1.0
    assert t["/hv/predictor_output/1/2"][2] < -1.0


def test_human_visualizer_draws_the_extras_at_constant_velocity(meshcat):
    system = HumanVisualizer(
        meshcat,
        [HumanConfig()] * 3,
        [],
        horizon=2,
        max_humans=1,
        period=0.1,
        prefix="hx",
        max_extra_humans=2,
        time_step=0.5,
    )
    context = system.CreateDefaultContext()
    system.GetInputPort("plan").FixValue(context, MpcPlan())

    def Show(model):
        predicted = HumanPrediction(
            model=model,
            slot_ids=np.array([0]),
            active=np.array([True]),
            positions=np.zeros((3, 1, 2)),
            extra_ids=np.array([2, -1]),
            extra_positions=np.array([[1.0, 2.0], [0.0, 0.0]]),
            extra_velocities=np.array([[0.4, -0.2], [0.0, 0.0]]),
        )
        system.GetInputPort("human_prediction").FixValue(context, predicted)
        system.ForcedPublish(context)
        return meshcat.transforms

    t = Show("orca_kkt")
    # Where the DT-CBF assumes person 2: p0 + k·Δt·v.
    np.testing.assert_allclose(t["/hx/extra_humans/0/0"], [1.0, 2.0, 0.04])
    np.testing.assert_allclose(t["/hx/extra_humans/0/2"], [1.4, 1.8, 0.04])
    assert t["/hx/extra_humans/1/1"][2] < -1.0  # no second extra
    # React holds everyone where measured.
    np.testing.assert_allclose(Show("react")["/hx/extra_humans/0/2"], [1.0, 2.0, 0.04])


# ---------------------------------------------------------------- lcm/


def _Raw(message, sequence):
    data = message if isinstance(message, bytes) else message.encode()
    return RawLcmMessage(data, sequence)


def test_robot_state_receiver_decodes_and_counts_garbage(stretch):
    n, m = stretch.num_positions, stretch.num_velocities
    system = RobotStateReceiver(stretch, initial_q=stretch.default_q, period=0.005)
    _Ports(system, {"lcm_message": None}, {"state": n + m, "state_status": None})
    context = system.CreateDefaultContext()
    system.get_input_port().FixValue(context, RawLcmMessage())
    state = system.GetOutputPort("state")
    np.testing.assert_array_equal(state.Eval(context), _State(stretch))
    x = np.arange(n + m, dtype=float) / 10
    message = MakeRobotStateMessage(x, num_positions=n, utime=1000)
    system.get_input_port().FixValue(context, _Raw(message, 1))
    _Update(system, context, 0.01)
    np.testing.assert_array_equal(state.Eval(context), x)
    status = system.GetOutputPort("state_status").Eval(context)
    assert status.utime == 1000 and status.receive_time == 0.01
    # Garbage is rejected and counted; the last good state stays.
    system.get_input_port().FixValue(context, _Raw(b"\x01garbage", 2))
    _Update(system, context, 0.015)
    np.testing.assert_array_equal(state.Eval(context), x)
    counters = system.GetOutputPort("state_status").Eval(context).counters
    assert (counters.received, counters.accepted) == (2, 1)
    assert counters.rejected == {"undecodable": 1}
    # A message of the wrong robot too.
    wrong = MakeRobotStateMessage(np.zeros(n + m + 1), num_positions=n, utime=2000)
    system.get_input_port().FixValue(context, _Raw(wrong, 3))
    _Update(system, context, 0.02)
    counters = system.GetOutputPort("state_status").Eval(context).counters
    assert counters.rejected == {"undecodable": 1, "wrong_size": 1}


def test_detections_receiver_stamps_frames_and_drops_unknown_ids():
    system = HumanDetectionsReceiver(period=0.005, timeout=0.2, known_ids=[1, 2])
    _Ports(
        system, {"lcm_message": None}, {"detections": None, "detections_status": None}
    )
    context = system.CreateDefaultContext()
    frame = HumanDetections(ids=np.array([1, 7]), positions=[[1.0, 2.0], [3.0, 4.0]])
    message = MakeDetectionsMessage(frame, utime=500)
    system.get_input_port().FixValue(context, _Raw(message, 1))
    _Update(system, context, 0.5)
    detections = system.GetOutputPort("detections").Eval(context)
    assert detections.time == 0.5  # stamped on this process's clock
    np.testing.assert_array_equal(detections.ids, [1])
    np.testing.assert_array_equal(detections.positions, [[1.0, 2.0]])
    counters = system.GetOutputPort("detections_status").Eval(context).counters
    assert counters.accepted == 1 and counters.rejected == {"unknown_id": 1}
    # The same utime again is not newer: rejected.
    system.get_input_port().FixValue(context, _Raw(message, 2))
    _Update(system, context, 0.505)
    counters = system.GetOutputPort("detections_status").Eval(context).counters
    assert counters.rejected["time_not_increasing"] == 1


def _Gate(mode, scale=1.0):
    return GateState(mode=mode, speed_scale=scale, state_utime=7, control_utime=9)


def test_robot_command_receiver_keeps_the_last_valid_command():
    system = RobotCommandReceiver(num_velocities=3, period=0.005)
    _Ports(system, {"lcm_message": None}, {"command_status": None})
    context = system.CreateDefaultContext()
    command = np.array([0.1, 0.2, 0.3, 1.0, 2.0, 3.0])
    message = MakeCommandMessage(command, _Gate(MODE_CONTROL), utime=100)
    system.get_input_port().FixValue(context, _Raw(message, 1))
    _Update(system, context, 0.01)
    status = system.GetOutputPort("command_status").Eval(context)
    np.testing.assert_array_equal(status.value.velocity, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(status.value.acceleration, [0.1, 0.2, 0.3])
    too_short = MakeCommandMessage(command[:4], _Gate(MODE_CONTROL), utime=200)
    system.get_input_port().FixValue(context, _Raw(too_short, 2))
    _Update(system, context, 0.015)
    status = system.GetOutputPort("command_status").Eval(context)
    assert status.counters.rejected == {"wrong_size": 1} and status.utime == 100


def _Fresh(value, now=0.0):
    return ReceiverState(
        utime=1, value=value, receive_time=now, receive_wall=time.time()
    )


def test_command_gate_passes_slows_and_stops(ridgeback):
    n, m = ridgeback.num_positions, ridgeback.num_velocities
    period = 0.1
    system = CommandGate(
        ridgeback,
        period=period,
        state_timeout=0.2,
        with_people=True,
        detection_timeout=0.25,
        detection_stop_timeout=1.0,
        stale_speed_scale=0.3,
    )
    _Ports(
        system,
        {
            "command": 2 * m,
            "robot_state": n + m,
            "state_status": None,
            "detections_status": None,
        },
        {"gated_command": 2 * m, "gate_status": None},
    )
    nu = 0.5 * ridgeback.nu_upper
    command = np.concatenate([0.1 * np.ones(m), 0.4 * ridgeback.nu_upper])
    gated = system.GetOutputPort("gated_command")

    def Decide(state_status, detection_age):
        context = system.CreateDefaultContext()
        system.GetInputPort("command").FixValue(context, command)
        system.GetInputPort("robot_state").FixValue(
            context, _State(ridgeback, None, nu)
        )
        system.GetInputPort("state_status").FixValue(context, state_status)
        detections = _Fresh(HumanDetections(), now=1.0 - detection_age)
        system.GetInputPort("detections_status").FixValue(context, detections)
        _Update(system, context, 1.0)
        return system.GetOutputPort("gate_status").Eval(context), gated.Eval(context)

    gate, out = Decide(_Fresh(np.zeros(n + m), now=1.0), 0.0)
    assert gate.mode == MODE_CONTROL and gate.counters.control == 1
    np.testing.assert_array_equal(out, command)
    # Detections 0.5 s old: ν_cmd scaled, u the acceleration reaching it.
    gate, out = Decide(_Fresh(np.zeros(n + m), now=1.0), 0.5)
    assert gate.mode == MODE_SLOWED and gate.speed_scale == 0.3
    nu_cmd = 0.3 * command[m:]
    np.testing.assert_allclose(out[m:], nu_cmd)
    u = np.clip((nu_cmd - nu) / period, -ridgeback.nudot_upper, ridgeback.nudot_upper)
    np.testing.assert_allclose(out[:m], u)
    # No robot state yet: brake within the limits, ν_cmd = 0.
    gate, out = Decide(ReceiverState(), 0.0)
    assert gate.mode == MODE_STOP and gate.counters.stale_state == 1
    np.testing.assert_array_equal(out[m:], 0.0)
    np.testing.assert_allclose(out[:m], -np.minimum(nu / period, ridgeback.nudot_upper))


def test_command_follower_tracks_the_command_and_brakes_without_one(stretch):
    n, m = stretch.num_positions, stretch.num_velocities
    h = 0.01
    system = CommandFollower(stretch, time_step=h, command_timeout=0.5)
    _Ports(system, {"command_status": None, "robot_state": n + m}, {"command": 2 * m})
    context = system.CreateDefaultContext()
    nu = 0.5 * stretch.nu_upper
    system.GetInputPort("robot_state").FixValue(context, _State(stretch, None, nu))
    velocity = nu + np.linspace(-0.004, 0.004, m)  # reachable within one step
    acceleration = np.full(m, 0.2)
    message = MakeCommandMessage(
        np.concatenate([acceleration, velocity]), _Gate(MODE_CONTROL), utime=1
    )
    system.GetInputPort("command_status").FixValue(context, _Fresh(message))
    u, nu_cmd = np.split(system.GetOutputPort("command").Eval(context), 2)
    np.testing.assert_allclose(nu_cmd, velocity)
    # (velocity − ν)/h, limited to the commanded rate 0.2.
    np.testing.assert_allclose(u, np.clip((velocity - nu) / h, -0.2, 0.2))
    assert np.any(np.abs(u) == 0.2) and np.any(np.abs(u) < 0.2)
    # No command: ν_cmd = 0 and the hardest braking the limits allow.
    system.GetInputPort("command_status").FixValue(context, ReceiverState())
    u, nu_cmd = np.split(system.GetOutputPort("command").Eval(context), 2)
    np.testing.assert_array_equal(nu_cmd, 0.0)
    np.testing.assert_allclose(u, -np.minimum(nu / h, stretch.nudot_upper))


def test_encoders_pack_what_the_decoders_read(stretch):
    n, m = stretch.num_positions, stretch.num_velocities
    command = np.arange(2 * m, dtype=float) / 10
    encoder = RobotCommandEncoder(m)
    _Ports(
        encoder, {"gated_command": 2 * m, "gate_status": None}, {"lcm_message": None}
    )
    context = encoder.CreateDefaultContext()
    encoder.GetInputPort("gated_command").FixValue(context, command)
    encoder.GetInputPort("gate_status").FixValue(context, _Gate(MODE_SLOWED, 0.3))
    data = encoder.GetOutputPort("lcm_message").Eval(context).encode()
    msg = DecodeRobotCommand(data, num_velocities=m)
    np.testing.assert_array_equal(msg.acceleration, command[:m])
    np.testing.assert_array_equal(msg.velocity, command[m:])
    assert (msg.mode, msg.speed_scale, msg.state_utime) == (MODE_SLOWED, 0.3, 7)
    assert abs(msg.utime - time.time() * 1e6) < 60e6  # the wall clock

    encoder = RobotStateEncoder(n, m)
    _Ports(encoder, {"state": n + m}, {"lcm_message": None})
    context = encoder.CreateDefaultContext()
    x = np.arange(n + m, dtype=float)
    encoder.get_input_port().FixValue(context, x)
    data = encoder.GetOutputPort("lcm_message").Eval(context).encode()
    _, q, v = DecodeRobotState(data, num_positions=n, num_velocities=m)
    np.testing.assert_array_equal(np.concatenate([q, v]), x)

    encoder = HumanDetectionsEncoder()
    _Ports(encoder, {"detections": None}, {"lcm_message": None})
    context = encoder.CreateDefaultContext()
    frame = HumanDetections(ids=np.array([3, 8]), positions=[[1.0, 2.0], [3.0, 4.0]])
    encoder.get_input_port().FixValue(context, frame)
    data = encoder.GetOutputPort("lcm_message").Eval(context).encode()
    _, ids, positions, dropped = DecodeHumanDetections(data)
    np.testing.assert_array_equal(ids, [3, 8])
    np.testing.assert_array_equal(positions, frame.positions)
    assert dropped == 0


def test_plan_encoder_packs_the_plan(ridgeback):
    encoder = PlanEncoder(time_step=0.2)
    _Ports(
        encoder,
        {"plan": None, "controller_state": None, "gate_status": None},
        {"lcm_message": None},
    )
    context = encoder.CreateDefaultContext()
    q = np.arange(3 * ridgeback.num_positions, dtype=float).reshape(3, -1)
    predictions = np.arange(12.0).reshape(3, 2, 2)
    solution = SimpleNamespace(
        q=q,
        p_WE=np.ones((3, 3)),
        human_predictions=predictions,
        human_slot_ids=np.array([-1, 4]),
    )
    controller = ControllerState(record=StepRecord(mode="solved", solve_time=0.01))
    encoder.GetInputPort("plan").FixValue(context, MpcPlan(solution=solution))
    encoder.GetInputPort("controller_state").FixValue(context, controller)
    encoder.GetInputPort("gate_status").FixValue(context, _Gate(MODE_CONTROL))
    msg = encoder.GetOutputPort("lcm_message").Eval(context)
    assert (msg.mode, msg.state_utime, msg.time_step) == ("solved", 7, 0.2)
    assert msg.num_steps == 3 and msg.num_humans == 1 and msg.human_ids == [4]
    np.testing.assert_array_equal(msg.base_pose, q[:, :3])
    np.testing.assert_array_equal(msg.human_positions[0], predictions[:, 1])
    # Without a plan: the record only.
    encoder.GetInputPort("plan").FixValue(context, MpcPlan())
    msg = encoder.GetOutputPort("lcm_message").Eval(context)
    assert msg.num_steps == 0 and msg.num_humans == 0 and msg.mode == "solved"


def test_command_monitor_counts_each_message_once():
    system = CommandMonitor(control_period=0.1, period=0.005)
    _Ports(system, {"lcm_message": None}, {})
    context = system.CreateDefaultContext()
    command = np.zeros(6)
    message = MakeCommandMessage(command, _Gate(MODE_SLOWED, 0.3), utime=100)
    system.get_input_port().FixValue(context, _Raw(message, 1))
    _Update(system, context, 0.01)
    _Update(system, context, 0.015)  # the same message: not counted again
    timing = system.GetTiming(context)
    assert timing.modes == {"control": 0, "slowed": 1, "stop": 0}
    assert timing.rejected == 0 and timing.utimes == [100]
    system.get_input_port().FixValue(context, _Raw(b"\xffnot a command", 2))
    _Update(system, context, 0.02)
    assert system.GetTiming(context).rejected == 1


def test_every_leaf_system_has_a_test():
    """The systems tested here are every LeafSystem in the package."""
    import importlib
    import inspect
    import pkgutil

    from pydrake.systems.framework import LeafSystem

    import sm2ith_drake

    found = set()
    for info in pkgutil.walk_packages(sm2ith_drake.__path__, "sm2ith_drake."):
        if "lcmtypes" in info.name or info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if issubclass(cls, LeafSystem) and cls.__module__ == info.name:
                found.add(cls.__name__)
    tested = {
        "KinematicRobot",
        "TaskPlanner",
        "CrowdSimulator",
        "MocapSensor",
        "HumanEstimator",
        "HumanPredictor",
        "HierarchicalMpc",
        "RunLogger",
        "PlanVisualizer",
        "HumanVisualizer",
        "RobotStateReceiver",
        "HumanDetectionsReceiver",
        "RobotCommandReceiver",
        "CommandGate",
        "CommandFollower",
        "RobotCommandEncoder",
        "PlanEncoder",
        "RobotStateEncoder",
        "HumanDetectionsEncoder",
        "CommandMonitor",
    }
    # LcmMessageReceiver is the receivers' common base (tested through them).
    assert found - {"LcmMessageReceiver"} == tested
