"""Overtakers predicted to keep clear of the robot
(prediction.overtaking, control/prediction/reciprocity.py OvertakingShares)."""

import numpy as np
import pytest

from sm2ith_drake.control.prediction.predict import HumanPredictorModel
from sm2ith_drake.control.prediction.reciprocity import OvertakingShares
from sm2ith_drake.humans.messages import HumanEstimate
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.scenario import PredictionConfig
from sm2ith_drake.scenario_options import OvertakingConfig

N, DT = 10, 0.2
ROBOT_P, ROBOT_V = np.array([0.0, 0.0]), np.array([0.0, 0.3])


def _Shares(p, v, robot_v=ROBOT_V, active=True, **config):
    return OvertakingShares(
        [0.5],
        np.array([p], dtype=float),
        np.array([v], dtype=float),
        [active],
        ROBOT_P,
        robot_v,
        OvertakingConfig(enabled=True, **config),
    )[0]


@pytest.mark.parametrize(
    "p, v, share",
    [
        ((0.0, -2.0), (0.0, 1.4), 1.0),  # behind, same way: overtakes
        ((0.5, -2.0), (-0.2, 1.4), 1.0),  # behind, a little to the side
        ((0.0, 2.0), (0.0, -1.4), 0.5),  # head-on
        ((-2.0, 0.0), (1.4, 0.0), 0.5),  # crossing in front
        ((0.0, -2.0), (0.0, -1.4), 0.5),  # behind, walking away
        ((2.5, -2.0), (-1.25, 1.0), 0.5),  # behind, 51° off the robot's way
        ((0.0, -2.0), (0.0, 0.05), 0.5),  # too slow to have a direction
    ],
)
def test_who_overtakes(p, v, share):
    assert _Shares(p, v) == pytest.approx(share)


def test_only_a_moving_robot_is_overtaken_and_only_active_slots():
    assert _Shares((0.0, -2.0), (0.0, 1.4), robot_v=(0.0, 0.01)) == 0.5
    assert _Shares((0.0, -2.0), (0.0, 1.4), robot_v=(0.0, -0.3)) == 0.5
    assert _Shares((0.0, -2.0), (0.0, 1.4), active=False) == 0.5
    assert _Shares((0.0, -2.0), (0.0, 1.4), share=0.8) == pytest.approx(0.8)
    # The angle is the cones' half-width: 60° takes in the walker 51° off.
    assert _Shares((2.5, -2.0), (-1.25, 1.0), angle=60.0) == 1.0
    assert _Shares((0.0, -2.0), (0.0, np.nan)) == 0.5


def test_the_predictor_predicts_the_overtaker_with_the_share():
    """Through the predictor: the person behind the moving robot gets the
    share, the one ahead keeps robot_share, and the prediction the MPC's
    KKT embedding reads carries both."""
    robot = MobileManipulator("ridgeback_ur10")
    config = PredictionConfig(
        predictor="orca_kkt",
        max_humans=2,
        overtaking=OvertakingConfig(enabled=True),
    )
    model = HumanPredictorModel(
        config, horizon=N, time_step=DT, control_period=DT, robot=robot
    )
    nu0 = np.zeros(robot.num_velocities)
    nu0[0] = 0.3  # the base drives along +x (its heading at default_q)
    q0 = np.array(robot.default_q, dtype=float)
    estimate = HumanEstimate(
        ids=[3, 4],
        positions=[q0[:2] + (-2.5, 0.1), q0[:2] + (3.0, -0.1)],
        velocities=[(1.4, 0.0), (-1.2, 0.0)],
    )
    inputs = np.zeros((N, robot.num_velocities))
    prediction, _ = model.Predict(
        model.InitialState(),
        estimate=estimate,
        q0=q0,
        nu0=nu0,
        warm_start_inputs=inputs,
    )
    shares = dict(zip(prediction.slot_ids, prediction.robot_shares, strict=True))
    assert shares[3] == pytest.approx(1.0)
    assert shares[4] == pytest.approx(0.5)
    # Off (the default): everyone the paper's share.
    model = HumanPredictorModel(
        PredictionConfig(predictor="orca_kkt", max_humans=2),
        horizon=N,
        time_step=DT,
        control_period=DT,
        robot=robot,
    )
    prediction, _ = model.Predict(
        model.InitialState(),
        estimate=estimate,
        q0=q0,
        nu0=nu0,
        warm_start_inputs=inputs,
    )
    np.testing.assert_allclose(prediction.robot_shares, [0.5, 0.5])
