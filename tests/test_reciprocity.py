"""The online estimate of each person's share of the avoidance toward the
robot (control/prediction/reciprocity.py, prediction.reciprocity)."""

import numpy as np
import pytest

from sm2ith_drake.control.prediction.orca_kkt import OrcaKkt
from sm2ith_drake.control.prediction.predict import HumanPredictorModel
from sm2ith_drake.humans.messages import HumanEstimate
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.scenario import PredictionConfig, ReciprocityConfig

N, DT = 10, 0.2


def _Model(**reciprocity):
    robot = MobileManipulator("ridgeback_ur10")
    config = PredictionConfig(
        predictor="orca_kkt",
        max_humans=1,
        reciprocity=ReciprocityConfig(enabled=True, **reciprocity),
    )
    model = HumanPredictorModel(
        config, horizon=N, time_step=DT, control_period=DT, robot=robot
    )
    return robot, model


def _Predict(robot, model, state, p, v):
    estimate = HumanEstimate(ids=[7], positions=[p], velocities=[v])
    return model.Predict(
        state,
        estimate=estimate,
        q0=robot.default_q,
        nu0=np.zeros(robot.num_velocities),
        warm_start_inputs=np.zeros((N, robot.num_velocities)),
    )


def _OrcaAction(model, prediction, share):
    """The action of the person in slot 0 under ``share`` toward the robot,
    from the prediction's states (what an ORCA person with that share does)."""
    orca = model.orca
    q, nu = prediction.robot_state
    robot = orca.RobotView(q[None], nu[None])
    p = prediction.positions[0]
    states, radius, _ = orca.AgentStates(
        p[None], prediction.velocities[None], robot, prediction.neighbors
    )
    n, rho = orca.AgentLines(*states, radius, share=orca.Shares(share))
    no, rho_o = orca.StaticLines(p[None])
    sol = orca.SolveHumanQps(
        prediction.preferred_velocities[:1],
        prediction.velocities[:1],
        n[0, :1],
        rho[0, :1],
        no[0, :1],
        rho_o[0, :1],
    )
    return sol.velocity[0]


@pytest.mark.parametrize("true_share", [0.0, 0.25, 0.5, 1.0])
def test_one_step_recovers_the_share_the_person_moved_with(true_share):
    """A person head-on who moves exactly as ORCA with share s* gives one
    observation s* (the robot line is the only active constraint, so the
    action is linear in the share)."""
    robot, model = _Model(prior_weight=0.0)
    p, v = np.array([2.2, 0.15]), np.array([-1.0, 0.0])
    first, state = _Predict(robot, model, model.InitialState(), p, v)
    np.testing.assert_allclose(first.robot_shares, [0.5])  # no evidence yet
    a = _OrcaAction(model, first, true_share)
    second, _ = _Predict(robot, model, state, p + DT * a, a)
    total, weight = second.share_evidence[7]
    assert weight > 0.1**2
    assert total / weight == pytest.approx(true_share, abs=1e-3)
    assert second.robot_shares[0] == pytest.approx(true_share, abs=1e-3)


def test_observations_are_capped_at_max_share():
    """A person who steps aside wholly counts as max_share, no more."""
    robot, model = _Model(prior_weight=0.0, max_share=0.5)
    p, v = np.array([2.2, 0.15]), np.array([-1.0, 0.0])
    first, state = _Predict(robot, model, model.InitialState(), p, v)
    a = _OrcaAction(model, first, 1.0)
    second, _ = _Predict(robot, model, state, p + DT * a, a)
    assert second.robot_shares[0] == pytest.approx(0.5)


def test_a_person_who_walks_on_is_predicted_to_walk_on():
    """Walking straight at the robot, step after step, drives the estimate
    from the prior toward 0; a person who yields as ORCA does keeps ≈ 0.5."""
    robot, model = _Model()
    state = model.InitialState()
    p, v = np.array([3.0, 0.15]), np.array([-1.0, 0.0])
    for _ in range(8):
        prediction, state = _Predict(robot, model, state, p, v)
        p = p + DT * v
    assert prediction.robot_shares[0] < 0.1

    state = model.InitialState()
    p = np.array([3.0, 0.15])
    prediction, state = _Predict(robot, model, state, p, v)
    for _ in range(6):
        a = _OrcaAction(model, prediction, 0.5)
        p = p + DT * a
        prediction, state = _Predict(robot, model, state, p, a)
    assert prediction.robot_shares[0] == pytest.approx(0.5, abs=0.05)


def test_the_estimate_is_forgotten_and_reaches_the_kkt_model():
    """Without new evidence the estimate returns to the prior at the rate
    ``memory`` sets; the controller's KKT model is handed the same shares."""
    robot, model = _Model(memory=1.0)
    state = model.InitialState()
    p, v = np.array([3.0, 0.15]), np.array([-1.0, 0.0])
    for _ in range(8):
        prediction, state = _Predict(robot, model, state, p, v)
        p = p + DT * v
    low = prediction.robot_shares[0]
    assert low < 0.2
    # The controller's KKT model predicts with the prediction's shares.
    kkt = OrcaKkt(model.config, horizon=N, time_step=DT, robot=robot)
    kkt.SetPrediction(prediction)
    np.testing.assert_array_equal(kkt.model.robot_shares, [low])
    # Walking away from the robot: nothing to observe, the evidence decays.
    away = np.array([1.0, 0.0])
    far = np.array([8.0, 5.0])
    for _ in range(15):
        prediction, state = _Predict(robot, model, state, far, away)
        far = far + DT * away
    assert low < prediction.robot_shares[0] < 0.5
    t1 = prediction.share_evidence[7][1]
    prediction, state = _Predict(robot, model, state, far, away)
    assert prediction.share_evidence[7][1] == pytest.approx(t1 * np.exp(-DT / 1.0))


def test_bad_measurements_give_no_evidence():
    """A NaN velocity, a person who vanished, or no robot state: no
    observation, no crash, the prior stands."""
    robot, model = _Model()
    p, v = np.array([2.2, 0.15]), np.array([-1.0, 0.0])
    first, state = _Predict(robot, model, model.InitialState(), p, v)
    second, _ = _Predict(robot, model, state, p, [np.nan, np.nan])
    assert second.share_evidence == {7: (0.0, 0.0)}
    assert second.robot_shares[0] == 0.5
    gone, _ = model.Predict(state, estimate=HumanEstimate())
    assert gone.share_evidence == {}
    blind, blind_state = model.Predict(
        state,
        estimate=HumanEstimate(ids=[7], positions=[p], velocities=[v]),
        q0=np.full(robot.num_positions, np.nan),
        nu0=np.zeros(robot.num_velocities),
    )
    assert blind.robot_state is None
    # The step after one without a robot state observes nothing.
    after, _ = _Predict(robot, model, blind_state, p + DT * v, v)
    decay = np.exp(-DT / ReciprocityConfig().memory)
    assert after.share_evidence[7][1] == pytest.approx(
        decay * blind.share_evidence[7][1]
    )
