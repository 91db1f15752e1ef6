"""Robot models and kinematics against independent references."""

import numpy as np
import pytest
from pydrake.multibody.tree import JacobianWrtVariable

from sm2ith_drake.geometry import (
    capsule_distance_and_gradient,
    einsum,
    segment_closest_points,
)
from sm2ith_drake.robots import MobileManipulator, RobotModel
from sm2ith_drake.robots.models import STRETCH3, STRETCH3_PRIMITIVE


@pytest.fixture(scope="module")
def ridgeback():
    return MobileManipulator("ridgeback_ur10")


@pytest.fixture(scope="module")
def stretch():
    return MobileManipulator("stretch3")


def _RandomQ(robot, rng, count):
    lo = np.maximum(robot.q_lower, -np.pi)
    hi = np.minimum(robot.q_upper, np.pi)
    lo[:2], hi[:2] = -3.0, 3.0
    return rng.uniform(lo, hi, size=(count, robot.num_positions))


def test_joint_counts_and_names(ridgeback, stretch):
    assert (stretch.num_positions, stretch.num_velocities) == (7, 6)
    assert (ridgeback.num_positions, ridgeback.num_velocities) == (9, 9)
    assert stretch.base_kind == "differential"
    assert ridgeback.base_kind == "holonomic"
    assert stretch.position_names == [
        "base_x",
        "base_y",
        "base_theta",
        "joint_lift",
        "joint_arm",
        "joint_wrist_yaw",
        "joint_wrist_pitch",
    ]
    assert ridgeback.position_names[3:] == [
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "elbow_joint",
        "wrist_1_joint",
        "wrist_2_joint",
        "wrist_3_joint",
    ]


def test_limits_match_the_public_specs(ridgeback, stretch):
    # Stretch 3: base 0.3 m/s; lift 1.1 m, arm 0.52 m of travel.
    assert stretch.nu_upper[0] == pytest.approx(0.3)
    np.testing.assert_allclose(stretch.q_lower[3:], [0.0, 0.0, -1.75, -1.57])
    np.testing.assert_allclose(stretch.q_upper[3:], [1.1, 0.52, 4.0, 0.56])
    # UR10: ±360° except the elbow (±180°); 120°/s base and shoulder,
    # 180°/s elbow and wrists; Ridgeback 1.1 m/s.
    np.testing.assert_allclose(
        ridgeback.q_upper[3:],
        [6.2832, 6.2832, 3.1416, 6.2832, 6.2832, 6.2832],
        rtol=1e-5,
    )
    np.testing.assert_allclose(
        ridgeback.nu_upper[3:], np.deg2rad([120, 120, 180, 180, 180, 180]), rtol=1e-4
    )
    np.testing.assert_allclose(ridgeback.nu_upper[:2], [1.1, 1.1])
    for robot in (ridgeback, stretch):
        assert np.all(np.isinf(robot.q_lower[:3]))
        assert np.all(robot.nudot_upper > 0) and np.all(np.isfinite(robot.nudot_upper))
        np.testing.assert_array_equal(robot.nu_lower, -robot.nu_upper)


def _DhTransform(theta, d, a, alpha):
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0, sa, ca, d],
            [0, 0, 0, 1],
        ]
    )


def test_ur10_forward_kinematics_matches_closed_form_dh(ridgeback):
    """tool0 from the URDF equals the product of the UR10's published DH
    transforms (standard convention), at 100 random configurations."""
    d = [0.1273, 0, 0, 0.163941, 0.1157, 0.0922]
    a = [0, -0.612, -0.5723, 0, 0, 0]
    alpha = [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0]
    plant = ridgeback.plant
    context = plant.CreateDefaultContext()
    base = plant.GetFrameByName("ur_base")
    tool0 = plant.GetFrameByName("tool0")
    rng = np.random.default_rng(7)
    worst = 0.0
    for q in _RandomQ(ridgeback, rng, 100):
        q[3:] = rng.uniform(-2 * np.pi, 2 * np.pi, 6)
        q[5] = rng.uniform(-np.pi, np.pi)
        plant.SetPositions(context, ridgeback.PlantPositions(q))
        X = tool0.CalcPose(context, base)
        T = np.eye(4)
        for i in range(6):
            T = T @ _DhTransform(q[3 + i], d[i], a[i], alpha[i])
        worst = max(worst, np.max(np.abs(X.translation() - T[:3, 3])))
        np.testing.assert_allclose(X.rotation().matrix(), T[:3, :3], atol=1e-9)
    assert worst < 1e-6


@pytest.mark.parametrize("name", ["ridgeback_ur10", "stretch3"])
def test_vectorized_kinematics_match_multibody_plant(name):
    robot = MobileManipulator(name)
    plant = robot.plant
    context = plant.CreateDefaultContext()
    ee = plant.GetFrameByName(robot.model.ee_frame)
    qs = _RandomQ(robot, np.random.default_rng(3), 25)
    kin = robot.CalcKinematics(qs)
    for k, q in enumerate(qs):
        plant.SetPositions(context, robot.PlantPositions(q))
        np.testing.assert_allclose(
            kin.p_WE[k], ee.CalcPoseInWorld(context).translation(), atol=1e-12
        )
        J = plant.CalcJacobianTranslationalVelocity(
            context,
            JacobianWrtVariable.kQDot,
            ee,
            np.zeros(3),
            plant.world_frame(),
            plant.world_frame(),
        )
        np.testing.assert_allclose(
            kin.J_WE[k], J @ robot.plant_positions_from_q, atol=1e-12
        )
        for c, capsule in enumerate(robot.capsules):
            ends = (
                (capsule.body, capsule.p_A),
                (capsule.body_B or capsule.body, capsule.p_B),
            )
            for e, (body, p) in enumerate(ends):
                X = plant.GetBodyByName(body).body_frame().CalcPoseInWorld(context)
                np.testing.assert_allclose(
                    kin.capsule_points[k, c, e], X @ np.array(p), atol=1e-12
                )


@pytest.mark.parametrize("name", ["ridgeback_ur10", "stretch3"])
def test_jacobians_match_finite_differences(name):
    robot = MobileManipulator(name)
    rng = np.random.default_rng(11)
    q = _RandomQ(robot, rng, 1)[0]
    kin = robot.CalcKinematics(q)
    h = 1e-6
    for i in range(robot.num_positions):
        dq = np.zeros(robot.num_positions)
        dq[i] = h
        plus, minus = robot.CalcKinematics(q + dq), robot.CalcKinematics(q - dq)
        np.testing.assert_allclose(
            kin.J_WE[0, :, i], (plus.p_WE - minus.p_WE)[0] / (2 * h), atol=1e-7
        )
        np.testing.assert_allclose(
            kin.capsule_jacobians[0, ..., i],
            (plus.capsule_points - minus.capsule_points)[0] / (2 * h),
            atol=1e-7,
        )


@pytest.mark.parametrize("name", ["ridgeback_ur10", "stretch3"])
def test_dGnu_dq_matches_finite_differences(name):
    robot = MobileManipulator(name)
    rng = np.random.default_rng(5)
    q = _RandomQ(robot, rng, 1)[0]
    nu = rng.uniform(robot.nu_lower, robot.nu_upper)
    h = 1e-6
    fd = np.column_stack(
        [
            (robot.G(q + h * e) @ nu - robot.G(q - h * e) @ nu) / (2 * h)
            for e in np.eye(robot.num_positions)
        ]
    )
    np.testing.assert_allclose(robot.dGnu_dq(q, nu), fd, atol=1e-8)


@pytest.mark.parametrize("name", ["ridgeback_ur10", "stretch3"])
def test_stacked_G_matches_one_configuration_at_a_time(name):
    robot = MobileManipulator(name)
    rng = np.random.default_rng(8)
    qs = _RandomQ(robot, rng, 7)
    nus = rng.uniform(robot.nu_lower, robot.nu_upper, (7, robot.num_velocities))
    G, dG = robot.GStack(qs), robot.dGnu_dqStack(qs, nus)
    for k in range(7):
        np.testing.assert_array_equal(G[k], robot.G(qs[k]))
        np.testing.assert_allclose(dG[k], robot.dGnu_dq(qs[k], nus[k]), atol=1e-15)


def test_differential_drive_has_no_sideways_velocity(stretch):
    """Whatever ν, the Stretch base velocity is along its heading."""
    rng = np.random.default_rng(2)
    for _ in range(50):
        q = _RandomQ(stretch, rng, 1)[0]
        nu = rng.uniform(-1, 1, stretch.num_velocities)
        qdot = stretch.G(q) @ nu
        sideways = -np.sin(q[2]) * qdot[0] + np.cos(q[2]) * qdot[1]
        assert abs(sideways) < 1e-12


def test_holonomic_base_velocity_is_in_the_body_frame(ridgeback):
    q = ridgeback.default_q.copy()
    q[2] = np.pi / 2
    nu = np.zeros(ridgeback.num_velocities)
    nu[0] = 1.0  # forward in the base frame = +y in the world
    np.testing.assert_allclose(ridgeback.G(q) @ nu, np.eye(9)[1], atol=1e-12)


def test_segment_closest_points_against_brute_force():
    rng = np.random.default_rng(0)
    grid = np.linspace(0, 1, 401)
    for trial in range(60):
        p1, q1, p2, q2 = rng.normal(size=(4, 3))
        if trial % 10 == 0:  # parallel segments
            q2 = p2 + (q1 - p1) * 0.7
        if trial % 15 == 1:  # a degenerate segment
            q1 = p1.copy()
        s, t, c1, c2 = segment_closest_points(p1, q1, p2, q2)
        A = p1 + grid[:, None] * (q1 - p1)
        B = p2 + grid[:, None] * (q2 - p2)
        brute = np.min(np.linalg.norm(A[:, None] - B[None], axis=-1))
        assert 0 <= s <= 1 and 0 <= t <= 1
        assert np.linalg.norm(c1 - c2) <= brute + 1e-12
        assert np.linalg.norm(c1 - c2) >= brute - 5e-3


def test_self_collision_gradient_matches_finite_differences(ridgeback):
    rng = np.random.default_rng(4)
    q = ridgeback.default_q + rng.normal(scale=0.3, size=ridgeback.num_positions)
    pairs = ridgeback.self_collision_pairs
    d, grad = capsule_distance_and_gradient(
        ridgeback, ridgeback.CalcKinematics(q), pairs
    )
    h = 1e-6
    for i in range(ridgeback.num_positions):
        dq = np.eye(ridgeback.num_positions)[i] * h
        dp, _ = capsule_distance_and_gradient(
            ridgeback, ridgeback.CalcKinematics(q + dq), pairs
        )
        dm, _ = capsule_distance_and_gradient(
            ridgeback, ridgeback.CalcKinematics(q - dq), pairs
        )
        np.testing.assert_allclose(grad[0, :, i], (dp - dm)[0] / (2 * h), atol=1e-6)


def test_default_configurations_are_collision_free(ridgeback, stretch):
    for robot in (ridgeback, stretch):
        d, _ = capsule_distance_and_gradient(
            robot, robot.CalcKinematics(robot.default_q), robot.self_collision_pairs
        )
        assert np.all(d > 0.1)


def test_bad_models_give_clear_errors(tmp_path):
    with pytest.raises(ValueError, match="unknown robot model 'spot'"):
        MobileManipulator("spot")
    with pytest.raises(FileNotFoundError, match="robot URDF not found"):
        MobileManipulator("stretch3", urdf_path=str(tmp_path / "missing.urdf"))
    bad = RobotModel(
        **{**STRETCH3_PRIMITIVE.__dict__, "arm_joints": ["joint_lift", "joint_arm"]}
    )
    with pytest.raises(ValueError, match="do not match arm_joints"):
        MobileManipulator(bad)
    bad = STRETCH3.replace(self_collision_pairs=[("gripper", "tail")])
    with pytest.raises(ValueError, match="unknown capsule"):
        MobileManipulator(bad)


def test_einsum_is_exactly_zero_over_an_empty_axis():
    """geometry.einsum: np.einsum's values where every operand has entries,
    exactly zero where the contracted axis is empty (no static lines); numpy
    returned uninitialized memory there in one of our runs."""
    rng = np.random.default_rng(3)
    lam, lines = rng.normal(size=(10, 2, 3)), rng.normal(size=(10, 2, 3, 2))
    expected = np.einsum("kho,khod->khd", lam, lines)
    assert np.array_equal(einsum("kho,khod->khd", lam, lines), expected)
    for _ in range(50):
        # Heap churn with NaN, then the empty contraction, on views as in
        # the KKT groups (λ's static-line columns of a wider array).
        junk = [np.full(n, np.nan) for n in rng.integers(1, 400, 20)]
        del junk
        wide = rng.normal(size=(10, 2, 4))
        out = einsum("kho,khodx->khdx", wide[..., 4:], np.ones((10, 2, 0, 2, 2)))
        assert out.shape == (10, 2, 2, 2)
        assert np.array_equal(out, np.zeros_like(out))
    with pytest.raises(ValueError):
        einsum("kho,khod->khd", np.zeros((10, 2, 0)), np.zeros((10, 2, 0)))
