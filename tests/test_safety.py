"""Closed-loop safety among people: crossing and corridor scenarios for each
robot, predictor, crowd model and number of people; the barrier among
people who walk exactly as the prediction model says; and the faithfulness
of the KKT embedding in closed loop.

The default suite runs a representative subset; ``pytest -m slow`` runs the
whole campaign (both robots × {orca_kkt, cvmm, react} × 1–3 people × ORCA
and social-force crowds × 2 seeds, and the corridors: 84 runs) and the
model-conforming people over 3 seeds.

Among the ORCA and social-force people (who do not follow the prediction
model: goal-directed, RVO2's own obstacle handling, ...) no robot body may
touch anyone; the barrier h ≥ 0 is asserted where it is a theorem, at the
control instants among people who walk as modelled (``relaxed_orca``, known
intents) on the holonomic Ridgeback–UR10, which can do its share of the
avoidance (between the instants h may dip by a few cm, within the margin). The
Stretch 3 (0.3 m/s, nonholonomic) cannot always: a person who takes only
half of the avoidance (ORCA's reciprocity) can make the barrier infeasible,
and there only contact is excluded.
"""

import itertools

import numpy as np
import pytest
from first_prediction import FirstPrediction, FirstStep

from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import LoadScenario

CROSSING = GetDiagramsDir() / "crossing.scenarios.yaml"


def _Run(name, *, predictor, behavior, seed, text="{}"):
    scenario = LoadScenario(filename=CROSSING, scenario_name=name, scenario_text=text)
    scenario.prediction.predictor = predictor
    scenario.random_seed = seed
    for human in scenario.humans:
        human.behavior = behavior
    result = RunSimulation(scenario)
    m = result.metrics
    # h of the DT-CBF at the true state: clearance beyond the margin.
    h_min = m["min_human_gap"] - scenario.safety.human_margin
    return scenario, m, h_min


def _CheckSafe(name, predictor, behavior, seed):
    scenario, m, h_min = _Run(name, predictor=predictor, behavior=behavior, seed=seed)
    label = f"{name} {predictor} {behavior} seed {seed}: gap {m['min_human_gap']:.3f}"
    print(label, f"h_min {h_min:.3f}", f"fallbacks {m['fallbacks']}")
    assert m["collision_samples"] == 0, label
    assert m["min_human_gap"] > 0.0, label
    assert m["solver_failures"] <= 0.01 * m["control_steps"] + 1, label


DEFAULT_CASES = [
    ("crossing_ridgeback_ur10_3h", "orca_kkt", "orca", 0),
    ("crossing_ridgeback_ur10_3h", "cvmm", "social_force", 0),
    ("crossing_stretch3_3h", "orca_kkt", "social_force", 0),
    ("crossing_stretch3_2h", "react", "orca", 0),
    ("corridor_ridgeback_ur10", "orca_kkt", "orca", 0),
]


@pytest.mark.parametrize("name,predictor,behavior,seed", DEFAULT_CASES)
def test_no_collision_subset(name, predictor, behavior, seed):
    _CheckSafe(name, predictor, behavior, seed)


PREDICTORS = ["orca_kkt", "cvmm", "react"]
FULL_CASES = [
    (f"crossing_{robot}_{n}h", predictor, behavior, seed)
    for predictor, robot, n, behavior, seed in itertools.product(
        PREDICTORS,
        ["ridgeback_ur10", "stretch3"],
        [1, 2, 3],
        ["orca", "social_force"],
        [0, 1],
    )
] + [
    (f"corridor_{robot}", predictor, behavior, 0)
    for predictor, robot, behavior in itertools.product(
        PREDICTORS, ["ridgeback_ur10", "stretch3"], ["orca", "social_force"]
    )
]


# Known regressions, kept as strict expected failures so that a fix shows.
# (SM²ITH's 4.8 mm contact in crossing_ridgeback_ur10_2h, seed 0, of
# 469abf3's defaults is gone since the joint rows between the knots of the
# seventeenth session: that run now keeps 78 mm from everyone.)
#
# With safety.turn_monitoring on by default (89b0a40), CVMM on the
# Ridgeback–UR10 touches an ORCA person by 5.6 mm for 0.1 s in seed 1 (34
# mm clear with it off): the run differs from 3.6 s on, and at the contact
# the base turns clockwise at ~0.5 rad/s and translates while the person,
# who changed course, passes its arm (traced: README, Contact).
KNOWN_CONTACTS = {
    ("crossing_ridgeback_ur10_1h", "cvmm", "orca", 1): (
        "89b0a40: 5.6 mm contact among ORCA people with the turn monitoring"
        " (README, Contact)"
    ),
}


def _Cases(cases, known):
    return [
        pytest.param(*c, marks=pytest.mark.xfail(strict=True, reason=known[c]))
        if c in known
        else c
        for c in cases
    ]


@pytest.mark.slow
@pytest.mark.parametrize(
    "name,predictor,behavior,seed", _Cases(FULL_CASES, KNOWN_CONTACTS)
)
def test_no_collision_campaign(name, predictor, behavior, seed):
    _CheckSafe(name, predictor, behavior, seed)


def _RunModelPeople(name, seed, predictor="orca_kkt"):
    """People who walk exactly as the SM²ITH prediction model says (crowd
    behaviour relaxed_orca, stepped at the MPC's Δt), seen perfectly with
    their intents; the seed moves their starts. The model is the paper's
    (prediction.overtaking off): relaxed_orca people do not wait behind
    the robot as the overtaking rule predicts, so with it they would walk
    outside the model the barrier's guarantee assumes."""
    from sm2ith_drake.experiments.campaign import ApplySeed

    scenario = LoadScenario(
        filename=CROSSING,
        scenario_name=name,
        scenario_text=(
            "{crowd_time_step: 0.2, prediction: {overtaking: {enabled: false}}}"
        ),
    )
    scenario.prediction.predictor = predictor
    scenario.perception.estimator = "truth"
    for human in scenario.humans:
        human.behavior = "relaxed_orca"
    scenario = ApplySeed(scenario, seed)
    result = RunSimulation(scenario)
    m = result.metrics
    m["h_min_at_control_instants"] = _BarrierAtControlInstants(result, scenario)
    return m, m["min_human_gap"] - scenario.safety.human_margin


def _BarrierAtControlInstants(result, scenario):
    """The smallest barrier value h (gap minus the margin) at the control
    instants, where the DT-CBF constrains it (between them the robot and
    the people move on, and h may dip: the margin absorbs that)."""
    from sm2ith_drake.humans.robot_view import HumanDistances

    robot = result.diagram.GetSubsystemByName("controller").controller.robot
    log = result.log
    times = np.asarray(log.times)
    period = scenario.controller.control_period or scenario.controller.time_step
    at = np.abs(times / period - np.round(times / period)) < 1e-6
    dist = HumanDistances(
        robot, np.asarray(log.states)[at], np.asarray(log.human_positions)[at]
    )
    radii = np.array([h.radius for h in scenario.humans])
    return float(np.min(dist - radii[None, :]) - scenario.safety.human_margin)


MODEL_CASES = [
    "crossing_ridgeback_ur10_1h",
    "crossing_ridgeback_ur10_2h",
    "crossing_ridgeback_ur10_3h",
    "corridor_ridgeback_ur10",
]


def scenario_margin(name):
    return LoadScenario(filename=CROSSING, scenario_name=name).safety.human_margin


def _CheckBarrier(name, seed):
    m, h_min = _RunModelPeople(name, seed)
    label = f"{name} seed {seed}: h_min {h_min:.4f}"
    print(label)
    label += f", at the control instants {m['h_min_at_control_instants']:.4f}"
    assert m["collision_samples"] == 0, label
    # The DT-CBF h(x_{k+1}) ≥ (1 − γ) h(x_k) keeps h ≥ 0 at the true state
    # at every control instant; between them the margin keeps contact out.
    assert m["h_min_at_control_instants"] >= -1e-3, label
    assert h_min > -scenario_margin(name), label
    assert m["solver_failures"] == 0, label


@pytest.mark.parametrize("name", MODEL_CASES)
def test_barrier_holds_among_people_who_walk_as_modelled(name):
    _CheckBarrier(name, 0)


# On 469abf3, crossing_ridgeback_ur10_3h with seed 1 kept h ≥ 0.016 at the
# control instants but dipped 0.13 mm into a person between them (a strict
# expected failure then); with guard_gap 0.2 (e176d82) it keeps 23 mm from
# everyone (h_min −0.0765 against the 0.1 m margin).
@pytest.mark.slow
@pytest.mark.parametrize("name,seed", list(itertools.product(MODEL_CASES, [1, 2, 3])))
def test_barrier_holds_among_people_who_walk_as_modelled_seeds(name, seed):
    _CheckBarrier(name, seed)


@pytest.mark.slow
@pytest.mark.parametrize(
    "name,seed",
    list(
        itertools.product(
            [
                "crossing_stretch3_1h",
                "crossing_stretch3_2h",
                "crossing_stretch3_3h",
                "corridor_stretch3",
            ],
            [0, 1, 2],
        )
    ),
)
def test_stretch_never_touches_people_who_walk_as_modelled(name, seed):
    m, h_min = _RunModelPeople(name, seed)
    print(f"{name} seed {seed}: h_min {h_min:.4f}")
    assert m["collision_samples"] == 0
    assert m["min_human_gap"] > 0.0


def test_kkt_predictions_match_resolved_orca_in_closed_loop():
    """After every closed-loop solve, each human's relaxed-ORCA QP re-solved at
    the predicted states reproduces the predicted action (within 1e-2 m/s)
    for at least 95 % of the predicted actions."""
    _, m, _ = _Run(
        "crossing_ridgeback_ur10_3h",
        predictor="orca_kkt",
        behavior="orca",
        seed=0,
        text="{controller: {check_predictions: true}}",
    )
    print(
        "consistency",
        m["prediction_consistency"],
        "p95 error",
        m["prediction_error_p95"],
    )
    assert m["prediction_consistency"] >= 0.95


def test_adversarial_human_is_not_hit():
    """A person walking straight at the Stretch: the robot gives way and is
    never hit (the person stops at contact distance of the base)."""
    scenario, m, _ = _Run(
        "adversarial_stretch3", predictor="orca_kkt", behavior="adversarial", seed=0
    )
    assert m["collision_samples"] == 0
    assert np.isfinite(m["min_human_gap"])


def _replay_controller():
    from sm2ith_drake.control.mpc_controller import MpcController
    from sm2ith_drake.scenario_loader import MakeRobot

    scenario = LoadScenario(
        filename=CROSSING, scenario_name="crossing_ridgeback_ur10_1h"
    )
    robot = MakeRobot(scenario)
    controller = MpcController.FromScenario(robot, scenario)
    return scenario, robot, controller


def _Gap0(robot, q, position):
    from sm2ith_drake.humans.robot_view import HumanDistances

    return HumanDistances(robot, q[None], np.array([[position]]))[0, 0]


def test_stale_plan_is_not_replayed_into_a_person():
    from sm2ith_drake.humans.messages import HumanEstimate

    scenario, robot, controller = _replay_controller()
    reach = scenario.safety.human_radius + scenario.safety.human_margin
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    nu0[0] = 0.5  # driving forward (+x) at 0.5 m/s
    u = np.zeros(robot.num_velocities)
    # A person standing 5 cm outside the barrier, straight ahead of the base.
    ahead = np.array([2.0, 0.0])
    while _Gap0(robot, q0, ahead) - reach > 0.05:
        ahead[0] -= 0.005
    standing = HumanEstimate(ids=[1], positions=[ahead], velocities=[[0.0, 0.0]])
    # 0.2 s at 0.5 m/s closes 0.1 m: h from 0.05 to −0.05 < (1 − γ)·0.05.
    assert not controller.ReplayIsSafe(q0, nu0, u, standing)
    leaving = HumanEstimate(ids=[1], positions=[ahead], velocities=[[0.6, 0.0]])
    assert controller.ReplayIsSafe(q0, nu0, u, leaving)
    far = HumanEstimate(ids=[1], positions=[[5.0, 4.0]], velocities=[[0.0, 0.0]])
    assert controller.ReplayIsSafe(q0, nu0, u, far)

    # In a control step: the solver fails after a plan was made with the
    # person far away; now the person stands ahead, so the robot brakes.
    state = controller.InitialState()
    targets = {t.name: np.asarray(t.target, dtype=float) for t in controller.tasks}
    state = controller.Step(
        state,
        time_now=0.0,
        q0=q0,
        nu0=nu0,
        targets=targets,
        prediction=FirstPrediction(controller, far),
    )
    assert state.record.mode == "solved"

    class FailingSolver:
        def Solve(self, **kwargs):
            raise RuntimeError("forced failure")

    controller.solver = FailingSolver()  # the declared seam
    q1 = q0.copy()
    nu1 = state.plan.nu[controller.shift]
    # The plan itself would be replayed (it matches the measured state)…
    assert controller.ReplayPlan(state, nu1) is not None
    state = controller.Step(
        state,
        time_now=0.2,
        q0=q1,
        nu0=nu1,
        targets=targets,
        prediction=FirstPrediction(controller, standing),
    )
    # …but not into the person.
    assert state.record.mode == "brake"
    assert state.counters.unsafe_replays == 1


def test_guard_holds_over_its_steps_against_a_person_who_does_not_yield():
    from sm2ith_drake.control.mpc_controller import MpcController
    from sm2ith_drake.humans.messages import HumanEstimate
    from sm2ith_drake.humans.robot_view import HumanDistances

    scenario, robot, _ = _replay_controller()
    safety = scenario.safety
    reach = safety.human_radius + safety.human_margin
    a = 1.0 - safety.gamma
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    nu0[0] = 0.5  # driving at a person who walks straight at the robot
    ahead = np.array([3.0, 0.0])
    while _Gap0(robot, q0, ahead) - reach > 0.6:
        ahead[0] -= 0.01
    walking = np.array([-0.6, 0.0])
    person = HumanEstimate(ids=[1], positions=[ahead], velocities=[walking])

    def barrier(guard_steps, guard_gamma=0.0):
        safety.guard_steps = guard_steps
        safety.guard_gamma = guard_gamma  # 0: the barrier's γ
        safety.guard_stopping_time = False  # guard_steps as given
        safety.static_guard_steps = 0  # the moving guard alone
        controller = MpcController(
            robot,
            scenario.tasks,
            scenario.controller,
            prediction=scenario.prediction,
            safety=safety,
        )
        targets = {t.name: np.asarray(t.target, dtype=float) for t in controller.tasks}
        plan = _FirstStep(controller, person, q0, nu0, targets).plan
        # h against the person walking on at the measured velocity.
        k = np.arange(len(plan.q))[:, None]
        P = ahead[None] + controller.period * k * walking[None]
        h = HumanDistances(robot, plan.q, P[:, None])[:, 0] - reach
        cbf = controller.program.cbf
        guard = plan.z[cbf.slack][cbf.num_rows - cbf.num_guard :]
        slots = scenario.prediction.max_humans
        assert guard.size == guard_steps * slots * robot.capsule_radii.size
        return h, guard

    h, guard = barrier(3)
    assert guard.max() < 1e-6  # the guard rows hold without slack
    for k in range(3):
        assert h[k + 1] >= a * h[k] - 2e-3, (k, h[: k + 2])
    # Guarding the first step only, the plan closes in faster afterwards
    # (it counts on the person giving way, as ORCA predicts).
    h1, _ = barrier(1)
    assert h1[1] >= a * h1[0] - 5e-3
    assert min(h1[2] - a * h1[1], h1[3] - a * h1[2]) < -1e-2
    # With guard_gamma 1 (the default) the guarded steps keep h ≥ 0 only.
    h_1, guard_1 = barrier(3, guard_gamma=1.0)
    assert guard_1.max() < 1e-6 and np.all(h_1[1:4] >= -2e-3), h_1[:4]


@pytest.mark.parametrize("predictor", ["cvmm", "orca_kkt"])
def test_static_guard_keeps_the_robot_from_following_a_person_who_leaves(predictor):
    """A person 0.2 m outside the barrier walks away from a robot driving at
    them: both predictions have the gap grow, so without the static guard
    the plan closes in on where the person is now faster than the barrier
    allows; with it (safe variant, 2 steps) the first two steps keep the
    barrier against the person standing where measured."""
    import dataclasses

    from sm2ith_drake.control.mpc_controller import MpcController
    from sm2ith_drake.humans.messages import HumanEstimate
    from sm2ith_drake.humans.robot_view import HumanDistances

    scenario, robot, _ = _replay_controller()
    reach = scenario.safety.human_radius + scenario.safety.human_margin
    a = 1.0 - scenario.safety.gamma
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    nu0[0] = 0.5  # driving at the person (+x)
    ahead = np.array([3.0, 0.0])
    while _Gap0(robot, q0, ahead) - reach > 0.2:
        ahead[0] -= 0.005
    leaving = HumanEstimate(ids=[1], positions=[ahead], velocities=[[0.6, 0.0]])
    prediction = dataclasses.replace(scenario.prediction, predictor=predictor)

    def plan(static_guard_steps):
        safety = dataclasses.replace(
            scenario.safety, static_guard_steps=static_guard_steps
        )
        controller = MpcController(
            robot,
            scenario.tasks,
            scenario.controller,
            prediction=prediction,
            safety=safety,
        )
        targets = {t.name: np.asarray(t.target, dtype=float) for t in controller.tasks}
        # The base's goal lies beyond the person: it wants to drive on.
        for name in targets:
            if name.startswith("base"):
                targets[name][:2] = ahead + [3.0, 0.0]
        state = _FirstStep(controller, leaving, q0, nu0, targets)
        cbf = controller.program.cbf
        assert cbf.static_guard_steps == static_guard_steps
        # h against the person standing where measured.
        h = HumanDistances(robot, state.plan.q, ahead[None, None])[:, 0] - reach
        return h

    h = plan(2)
    for k in range(2):
        assert h[k + 1] >= a * h[k] - 2e-3, (k, h[:3])
    h0 = plan(0)
    assert min(h0[1] - a * h0[0], h0[2] - a * h0[1]) < -1e-2, h0[:3]


def test_people_beyond_the_slots_go_by_distance_and_extras_keep_a_barrier():
    """More people tracked than slots: the nearest have the slots, an
    incumbent keeps its slot against a newcomer nearer by less than the
    hysteresis, the nearest of the rest are the extras and anyone beyond
    is dropped; without overflow the slots fill in the estimate's order."""
    from sm2ith_drake.control.prediction.slots import AssignSlots
    from sm2ith_drake.humans.messages import HumanEstimate

    estimate = HumanEstimate(
        ids=[5, 6, 7, 8],
        positions=[[9.0, 0.0], [1.0, 0.0], [4.0, 0.0], [2.0, 0.0]],
        velocities=[[0.0, 0.0], [0.1, 0.0], [0.2, 0.0], [0.3, 0.0]],
    )
    distances = np.array([9.0, 1.0, 4.0, 2.0])
    empty = np.full(2, -1)
    slots = AssignSlots(empty, estimate, {}, distances=distances, num_extra=1)
    assert slots.slot_ids.tolist() == [6, 8]
    assert slots.extra_ids.tolist() == [7] and slots.dropped == 1
    np.testing.assert_allclose(slots.extra_p0, [[4.0, 0.0]])
    np.testing.assert_allclose(slots.extra_v0, [[0.2, 0.0]])
    # Incumbents 7 (4 m) and 5 (9 m): 6 (1 m) takes 5's slot, then 8 (2 m)
    # takes 7's; each is nearer by more than the hysteresis.
    incumbents = np.array([7, 5])
    moved = AssignSlots(incumbents, estimate, {}, distances=distances, hysteresis=0.5)
    assert moved.slot_ids.tolist() == [8, 6]
    # 8 is 2 m nearer than 7: it takes 7's slot only if 2 m beats it.
    sticky = AssignSlots(
        np.array([7, 6]), estimate, {}, distances=distances, hysteresis=2.5
    )
    assert sticky.slot_ids.tolist() == [7, 6] and sticky.dropped == 2
    swapped = AssignSlots(
        np.array([7, 6]), estimate, {}, distances=distances, hysteresis=1.5
    )
    assert swapped.slot_ids.tolist() == [8, 6]
    # Enough slots: the estimate's order, whatever the distances.
    roomy = AssignSlots(np.full(4, -1), estimate, {}, distances=distances)
    assert roomy.slot_ids.tolist() == [5, 6, 7, 8] and roomy.dropped == 0


@pytest.mark.parametrize("predictor", ["cvmm", "orca_kkt"])
def test_extra_rows_keep_the_robot_from_a_person_without_a_slot(predictor):
    """One slot, two people: the nearer stands behind the robot and has the
    slot; the other walks at the robot from ahead. As an extra
    (max_extra_humans 1) the barrier holds against them walking on over
    the whole horizon; without extras they are dropped, and the plan drives
    into where they will be."""
    import dataclasses

    from sm2ith_drake.control.mpc_controller import MpcController
    from sm2ith_drake.humans.messages import HumanEstimate
    from sm2ith_drake.humans.robot_view import HumanDistances

    scenario, robot, _ = _replay_controller()
    reach = scenario.safety.human_radius + scenario.safety.human_margin
    a = 1.0 - scenario.safety.gamma
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    nu0[0] = 0.5  # driving forward (+x)
    ahead, behind = np.array([3.0, 0.0]), np.array([-3.0, 0.0])
    while _Gap0(robot, q0, ahead) - reach > 0.6:
        ahead[0] -= 0.01
    while _Gap0(robot, q0, behind) - reach > 0.3:
        behind[0] += 0.01
    walking = np.array([-0.6, 0.0])
    people = HumanEstimate(
        ids=[1, 2], positions=[ahead, behind], velocities=[walking, [0.0, 0.0]]
    )

    def plan(extra):
        prediction = dataclasses.replace(
            scenario.prediction, predictor=predictor, max_humans=1,
            max_extra_humans=extra,
        )  # fmt: skip
        controller = MpcController(
            robot,
            scenario.tasks,
            scenario.controller,
            prediction=prediction,
            safety=dataclasses.replace(scenario.safety, guard_steps=0),
        )
        targets = {t.name: np.asarray(t.target, dtype=float) for t in controller.tasks}
        for name in targets:  # the base's goal lies beyond the walker
            if name.startswith("base"):
                targets[name][:2] = ahead + [3.0, 0.0]
        predicted = FirstPrediction(controller, people, q0, nu0)
        assert predicted.slot_ids.tolist() == [2]
        assert predicted.dropped == 1 - extra
        q = _FirstStep(controller, people, q0, nu0, targets).plan.q
        k = np.arange(len(q))[:, None]
        P = ahead[None] + controller.period * k * walking[None]
        return HumanDistances(robot, q, P[:, None])[:, 0] - reach

    h = plan(1)
    for k in range(len(h) - 1):
        assert h[k + 1] >= a * h[k] - 2e-3, (k, h[: k + 2])
    h0 = plan(0)
    assert np.min(h0[1:] - a * h0[:-1]) < -1e-2, h0


@pytest.mark.parametrize("model", ["react", "cvmm"])
def test_the_extras_move_on_at_their_measured_velocity_except_for_react(model):
    """What the barrier assumes of an extra: CVMM's constant velocity, or
    held where measured for React (which predicts no one moving); a slot
    without a person (id −1) is not active."""
    from sm2ith_drake.control.prediction.base import Cvmm, React
    from sm2ith_drake.humans.messages import HumanPrediction
    from sm2ith_drake.scenario import PredictionConfig

    config = PredictionConfig(predictor=model, max_humans=1, max_extra_humans=2)
    predictor = {"react": React, "cvmm": Cvmm}[model](config, horizon=3, time_step=0.2)
    predictor.SetPrediction(
        HumanPrediction(
            model=model,
            slot_ids=np.array([-1]),
            active=np.array([False]),
            positions=np.zeros((4, 1, 2)),
            extra_ids=np.array([4, -1]),
            extra_positions=np.array([[1.0, 2.0], [0.0, 0.0]]),
            extra_velocities=np.array([[0.4, -0.2], [0.0, 0.0]]),
        )
    )
    assert predictor.extra_active.tolist() == [True, False]
    np.testing.assert_array_equal(predictor.extra_p0[0], [1.0, 2.0])
    expected = [0.0, 0.0] if model == "react" else [0.4, -0.2]
    np.testing.assert_array_equal(predictor.extra_v0[0], expected)


def _FirstStep(controller, estimate, q0, nu0, targets):
    """The controller's first step with the people of ``estimate``; it must
    solve."""
    state = FirstStep(controller, estimate, q0, nu0, targets)
    assert state.record.mode == "solved"
    return state


@pytest.mark.parametrize(
    "robot_name, stopping, steps", [("ridgeback_ur10", 1.1, 6), ("stretch3", 0.6, 3)]
)
def test_guard_stopping_time_holds_the_guard_until_the_base_can_stop(
    robot_name, stopping, steps
):
    """safety.guard_stopping_time: the guard covers the base's stopping time
    from its top speed (Ridgeback–UR10 1.1 m/s at 1.0 m/s², Stretch 3 0.3
    m/s at 0.5 m/s²), in the program's DT-CBF rows; guard_steps 0 stays off
    and the flag off keeps guard_steps."""
    from sm2ith_drake.control.mpc_controller import MpcController
    from sm2ith_drake.robots import MobileManipulator
    from sm2ith_drake.robots.planar_base import BaseStoppingTime
    from sm2ith_drake.scenario import (
        ControllerConfig,
        PredictionConfig,
        SafetyConfig,
        TaskConfig,
    )

    robot = MobileManipulator(robot_name)
    assert BaseStoppingTime(robot) == pytest.approx(stopping)

    def rows(**safety):
        controller = MpcController(
            robot,
            [TaskConfig(kind="base_position", target=[2.0, 0.0])],
            ControllerConfig(),
            prediction=PredictionConfig(predictor="orca_kkt", max_humans=1),
            safety=SafetyConfig(**safety),
        )
        cbf = controller.program.cbf
        assert cbf.num_guard == cbf.guard_steps * robot.capsule_radii.size
        return cbf.guard_steps

    assert rows() == steps  # the default
    assert rows(guard_stopping_time=True) == steps
    assert rows(guard_stopping_time=False) == 3
    assert rows(guard_stopping_time=True, guard_steps=0) == 0
    assert rows(guard_stopping_time=True, guard_steps=8) == 8
    # Only the guarded (interactive) prediction gets the rows.
    assert rows(guard_stopping_time=True, mode="paper") == 0
