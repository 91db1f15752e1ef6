"""prediction.max_speed_factor: each person's own speed limit in the ORCA
model (factor × their measured speed, within [max_speed_floor,
max_speed]), used alike by the forward simulation, the KKT rows and the
re-solved QPs that check them."""

import numpy as np

from sm2ith_drake.control.mpc_controller import MpcController
from sm2ith_drake.control.prediction.slots import HumanSlots, PersonalMaxSpeeds
from sm2ith_drake.humans.messages import HumanEstimate
from sm2ith_drake.humans.relaxed_orca import relaxed_orca_action, relaxed_orca_actions
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario import (
    ControllerConfig,
    PredictionConfig,
    SafetyConfig,
    TaskConfig,
)
from sm2ith_drake.scenario_loader import LoadScenario


def test_personal_max_speeds_scale_the_measured_speed_within_bounds():
    slots = HumanSlots(
        slot_ids=np.array([4, 5, 6, -1]),
        active=np.array([True, True, True, False]),
        p0=np.zeros((4, 2)),
        v0=np.array([[0.3, 0.4], [0.0, 0.0], [2.0, 0.0], [0.0, 0.0]]),
        v_pref=np.array([[0.0, 0.6], [0.1, 0.0], [0.0, 0.0], [0.0, 0.0]]),
    )
    off = PersonalMaxSpeeds(slots, PredictionConfig(max_speed=1.5))
    np.testing.assert_array_equal(off, [1.5, 1.5, 1.5, 1.5])
    cfg = PredictionConfig(max_speed=1.5, max_speed_factor=1.2, max_speed_floor=0.4)
    # 1.2 × max(0.5, 0.6); the floor; the ceiling; an empty slot keeps 1.5.
    np.testing.assert_allclose(PersonalMaxSpeeds(slots, cfg), [0.72, 0.4, 1.5, 1.5])


def test_batched_relaxed_orca_takes_one_speed_limit_per_human():
    """Per-human limits give, row by row, the scalar solver's solution with
    that human's limit, and the limits bind."""
    rng = np.random.default_rng(11)
    B, A = 40, 3
    v_pref = rng.uniform(-1.5, 1.5, (B, 2))
    v_t = v_pref + rng.normal(scale=0.2, size=(B, 2))
    normals = rng.normal(size=(B, A, 2))
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    offsets = rng.uniform(-0.5, 0.8, (B, A))
    limits = rng.uniform(0.3, 1.5, B)
    args = dict(max_accel=2.0, time_step=0.2, slack_weights=(10.0, 100.0))
    sol = relaxed_orca_actions(v_pref, v_t, normals, offsets, max_speed=limits, **args)
    binding = 0
    for b in range(B):
        ref = relaxed_orca_action(
            v_pref[b], v_t[b], normals[b], offsets[b], max_speed=limits[b], **args
        )
        np.testing.assert_allclose(sol.velocity[b], ref.velocity, rtol=0, atol=1e-7)
        assert np.linalg.norm(sol.velocity[b]) <= limits[b] + 1e-9
        binding += ref.multiplier_speed > 1e-6
    assert binding >= 5


def _Controller(factor):
    robot = MobileManipulator("ridgeback_ur10")
    tasks = [TaskConfig(kind="base_position", target=[4.0, 0.0])]
    prediction = PredictionConfig(
        predictor="orca_kkt", max_humans=1, max_speed_factor=factor
    )
    return robot, MpcController(
        robot, tasks, ControllerConfig(), prediction=prediction, safety=SafetyConfig()
    )


# A slow walker (0.5 m/s) head on, 1.4 m ahead of the robot, which drives
# toward them at 0.5 m/s: the model (max_speed 1.5) has them dodge faster
# than they walk.
SLOW = HumanEstimate(ids=[0], positions=[[1.4, 0.1]], velocities=[[-0.5, 0.0]])


def _Forward(robot):
    nu0 = np.zeros(robot.num_velocities)
    nu0[0] = 0.5
    return nu0


def _WarmStart(factor):
    robot, c = _Controller(factor)
    prediction, _ = c.human_predictor.Predict(
        c.human_predictor.InitialState(), estimate=SLOW
    )
    c.predictor.SetPrediction(prediction)
    z = c.WarmStart(c.InitialState(), robot.default_q, _Forward(robot))
    return c, z


def test_the_warm_start_is_an_exact_kkt_point_with_a_personal_speed_limit():
    """With factor 1 the person's limit is their own 0.5 m/s: the forward
    simulation keeps to it, the KKT rows read the same limit (the speed
    multiplier is active, so a row with 1.5 m/s would leave λ·c ≠ 0), and
    without the option the model lets them walk faster."""
    _, z_off = _WarmStart(0.0)
    c, z = _WarmStart(1.0)
    np.testing.assert_allclose(c.predictor.max_speed, [0.5])
    stat, cons, comp = c.predictor.Residuals(z, c.program.layout)
    assert np.max(np.abs(stat)) < 1e-6
    assert np.max(cons) < 1e-9
    assert np.max(np.abs(comp)) < 1e-6
    speed = np.linalg.norm(z[c.predictor.a][:, 0], axis=-1)
    assert np.max(speed) <= 0.5 + 1e-9
    assert np.max(z[c.predictor.lam][:, 0, 0]) > 1e-3  # λ_s: the limit binds
    speed_off = np.linalg.norm(z_off[c.predictor.a][:, 0], axis=-1)
    assert np.max(speed_off) > 0.55


def _Faithfulness(factor):
    scenario = LoadScenario(
        filename=str(GetDiagramsDir() / "crossing.scenarios.yaml"),
        scenario_name="crossing_ridgeback_ur10_3h",
        scenario_text="{controller: {check_predictions: true}, "
        f"prediction: {{max_speed_factor: {factor}}}}}",
    )
    assert scenario.prediction.max_speed_factor == factor
    result = RunSimulation(scenario, duration=4.0)
    assert result.metrics["fallbacks"] == 0
    errors = np.concatenate(
        [
            r.prediction_errors.ravel()
            for r in result.log.records
            if r.prediction_errors is not None
        ]
    )
    assert errors.size > 300
    return np.mean(errors <= 1e-2)


def test_a_run_with_personal_limits_keeps_its_predictions_faithful():
    """Through a scenario file and the Diagram (crossing, 3 people, 4 s,
    cold first steps included): with factor 1.2 the plans' predicted
    actions match the re-solved relaxed-ORCA QPs (with the same limits)
    about as often as with one limit for all (measured: 91.2 % and 92.1 %
    within 1e-2 m/s). Factor 1.0 would put a person walking at their
    preferred velocity on their own limit, a degenerate KKT point (79 %
    when measured)."""
    assert _Faithfulness(1.2) >= _Faithfulness(0.0) - 0.03
