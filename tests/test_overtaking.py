"""Overtakers predicted to keep clear of the robot
(prediction.overtaking, control/prediction/reciprocity.py Overtaking)."""

import numpy as np
import pytest

from sm2ith_drake.control.prediction.predict import HumanPredictorModel
from sm2ith_drake.control.prediction.reciprocity import Overtaking
from sm2ith_drake.humans.messages import HumanEstimate
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.scenario import PredictionConfig
from sm2ith_drake.scenario_options import OvertakingConfig, SafetyConfig

N, DT = 10, 0.2
ROBOT_P, ROBOT_V = np.array([0.0, 0.0]), np.array([0.0, 0.3])


def _Shares(p, v, robot_v=ROBOT_V, active=True, share=1.0, **config):
    """The share of a person at p walking v: ``share`` if they overtake."""
    behind = Overtaking(
        np.array([p], dtype=float),
        np.array([v], dtype=float),
        [active],
        ROBOT_P,
        robot_v,
        OvertakingConfig(enabled=True, **config),
    )[0]
    return share if behind else 0.5


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


def test_an_overtaker_who_steps_aside_stays_one_with_keep_angle():
    """A person 51° off the robot's way is not taken in at 45°; with
    keep_angle 90 they are if the rule applied at the last step, and not
    once level with the robot or walking away from it."""
    config = OvertakingConfig(enabled=True, keep_angle=90.0)
    # The third person is just past level with the robot (not on the
    # 90° boundary itself, where the test would rest on rounding).
    p = np.array([(2.5, -2.0), (2.5, -2.0), (2.0, 0.1), (0.0, -2.0)])
    v = np.array([(-1.25, 1.0), (-1.25, 1.0), (0.0, 1.4), (0.0, -1.4)])
    kept = np.array([False, True, True, True])
    behind = Overtaking(p, v, [True] * 4, ROBOT_P, ROBOT_V, config, kept=kept)
    np.testing.assert_array_equal(behind, [False, True, False, False])
    # keep_angle 0 (the default): no memory.
    config.keep_angle = 0.0
    assert not Overtaking(p, v, [True] * 4, ROBOT_P, ROBOT_V, config, kept=kept).any()


def _PredictTwo(overtaking=None, state=None, velocity=(1.4, 0.0), behind=2.5, **guards):
    """One prediction of two people near a Ridgeback–UR10 driving along +x
    at 0.3 m/s (its heading at default_q): id 3 catching up from ``behind``
    m behind its base's centre at ``velocity`` (m/s), id 4 coming head-on
    at 1.2 m/s, from the predictor's ``state`` (None: the initial one).
    Returns the prediction and the predictor's state after it."""
    robot = MobileManipulator("ridgeback_ur10")
    config = PredictionConfig(predictor="orca_kkt", max_humans=2)
    if overtaking is not None:
        config.overtaking = overtaking
    model = HumanPredictorModel(
        config, horizon=N, time_step=DT, control_period=DT, robot=robot, **guards
    )
    nu0 = np.zeros(robot.num_velocities)
    nu0[0] = 0.3
    q0 = np.array(robot.default_q, dtype=float)
    estimate = HumanEstimate(
        ids=[3, 4],
        positions=[q0[:2] + (-behind, 0.1), q0[:2] + (3.0, -0.1)],
        velocities=[velocity, (-1.2, 0.0)],
    )
    return model.Predict(
        model.InitialState() if state is None else state,
        estimate=estimate,
        q0=q0,
        nu0=nu0,
        warm_start_inputs=np.zeros((N, robot.num_velocities)),
    )


def _BySlot(prediction, values):
    return dict(zip((int(i) for i in prediction.slot_ids), values, strict=True))


def test_the_predictor_predicts_the_overtaker_with_the_share():
    """Through the predictor: the person behind the moving robot gets the
    share, the one ahead keeps robot_share, and the prediction the MPC's
    KKT embedding reads carries both."""
    prediction, _ = _PredictTwo(OvertakingConfig(enabled=True))
    shares = _BySlot(prediction, prediction.robot_shares)
    assert shares[3] == pytest.approx(1.0)
    assert shares[4] == pytest.approx(0.5)
    # Off: everyone the paper's share.
    prediction, _ = _PredictTwo(OvertakingConfig(enabled=False))
    np.testing.assert_allclose(prediction.robot_shares, [0.5, 0.5])
    assert not prediction.overtakers.any()


def test_the_defaults_are_the_measured_doorway_configuration():
    """On by default since 2026-11-28 (README, Doorway): overtakers are
    predicted to take all of the avoidance and wait, left out of the guard,
    kept while within 90°; the guard's rows ask only h ≥ 0, and it holds
    everyone measured within 0.2 m of the robot."""
    config = PredictionConfig()
    o = config.overtaking
    assert (o.enabled, o.share, o.wait, o.guard, o.angle, o.keep_angle) == (
        True,
        1.0,
        True,
        False,
        45.0,
        90.0,
    )
    assert not o.guard_close
    assert SafetyConfig().guard_gamma == 1.0
    assert SafetyConfig().guard_gap == 0.2
    assert SafetyConfig().guard_approach == 0.2


def test_with_wait_the_overtaker_is_predicted_to_stop():
    """With wait the overtaker alone is predicted with v_pref 0 and slows to
    a stop; the filtered preferred velocity (the predictor's state) is
    kept."""
    prediction, state = _PredictTwo(OvertakingConfig(enabled=True, wait=True))
    preferred = _BySlot(prediction, prediction.preferred_velocities)
    np.testing.assert_allclose(preferred[3], [0.0, 0.0])
    np.testing.assert_allclose(preferred[4], [-1.2, 0.0])
    slot = {int(i): j for j, i in enumerate(prediction.slot_ids)}
    speeds = np.linalg.norm(prediction.actions[:, slot[3]], axis=-1)
    assert speeds[-1] < 0.05 and np.all(np.diff(speeds) <= 1e-6)
    np.testing.assert_allclose(state.preferred_velocities[3], [1.4, 0.0])


@pytest.mark.parametrize("guard", [True, False])
def test_without_guard_the_overtaker_is_left_out_of_the_guard(guard):
    """guard_deviation 0 guards everyone; with overtaking.guard false the
    person behind the moving robot is left out, the one ahead is not."""
    prediction, _ = _PredictTwo(
        OvertakingConfig(enabled=True, wait=True, guard=guard),
        guard_deviation=0.0,
        guard_hold=0.6,
    )
    assert (3 in prediction.guard_steps_by_id) == guard
    assert 4 in prediction.guard_steps_by_id
    guarded = _BySlot(prediction, prediction.guarded)
    assert guarded[3] == guard and guarded[4]


@pytest.mark.parametrize("behind, held", [(1.2, True), (2.5, False)])
def test_with_guard_close_an_overtaker_at_the_robots_back_is_held(behind, held):
    """overtaking.guard_close: an overtaker measured within guard_gap of the
    robot's nearest body stays in the guard (as anyone that close is held),
    one farther back is still left out; without it both are left out.
    Person 3's gap to the base: ~0.3 m at 1.2 m, ~1.6 m at 2.5 m, against
    a guard_gap of 1 m; the deviation rule holds no one (deviation 1 m)."""
    guards = dict(guard_deviation=1.0, guard_hold=0.6, guard_gap=1.0)
    for guard_close, expected in ((True, held), (False, False)):
        prediction, _ = _PredictTwo(
            OvertakingConfig(enabled=True, guard_close=guard_close),
            behind=behind,
            **guards,
        )
        assert bool(_BySlot(prediction, prediction.overtakers)[3])
        assert (3 in prediction.guard_steps_by_id) == expected
        assert _BySlot(prediction, prediction.guarded)[3] == expected


def test_the_predictor_remembers_its_overtakers_by_id():
    """The prediction names the overtaker, and the next step judges them
    with keep_angle: the person who has turned 51° off the robot's way is
    still behind it, the one ahead still is not."""
    config = OvertakingConfig(enabled=True, keep_angle=90.0)
    prediction, state = _PredictTwo(config)
    assert _BySlot(prediction, prediction.overtakers) == {3: True, 4: False}
    # 60° off the robot's way (toward −y): outside 45°, inside 90°.
    turned = 1.4 * np.array([np.cos(np.radians(60)), -np.sin(np.radians(60))])
    later, _ = _PredictTwo(config, state=state, velocity=turned)
    assert _BySlot(later, later.overtakers) == {3: True, 4: False}
    # Without the memory (a fresh state) the same person is not one.
    fresh, _ = _PredictTwo(config, velocity=turned)
    assert _BySlot(fresh, fresh.overtakers) == {3: False, 4: False}
