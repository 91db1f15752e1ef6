"""ORCA half-planes and velocities against RVO2 (pyrvo) and hand-worked cases;
the MPC's vectorized agent lines against the reference implementation."""

import numpy as np
import pytest

from sm2ith_drake.humans import orca as O
from sm2ith_drake.humans.half_planes import orca_agent_half_planes
from sm2ith_drake.humans.orca import half_plane_normal_form, orca_half_planes
from sm2ith_drake.humans.orca_velocity import orca_velocity


def test_head_on_pair_by_hand():
    # A at the origin moving +x, B 2 m ahead moving −x, radii 0.5, τ = 2:
    # w = (1, 0) lies in the leg region; the right leg gives
    # direction (−√3/2, 1/2), u = (−1/2, −√3/2), point = v_A + u/2.
    pts, dirs, n_obs = orca_half_planes(
        [0, 0], [1, 0], 0.5, [[2, 0]], [[-1, 0]], [0.5], tau=2.0, time_step=0.1
    )
    assert n_obs == 0
    np.testing.assert_allclose(dirs[0], [-np.sqrt(3) / 2, 0.5], atol=1e-12)
    np.testing.assert_allclose(pts[0], [0.75, -np.sqrt(3) / 4], atol=1e-12)


def test_cutoff_circle_by_hand():
    # Two agents at rest 3 m apart (R = 1, τ = 2): the velocity obstacle's
    # cutoff circle is centred at (1.5, 0) with radius 0.5; A may approach B
    # at up to 0.5 m/s (half of the 1 m/s the pair may close at).
    pts, dirs, _ = orca_half_planes(
        [0, 0], [0, 0], 0.5, [[3, 0]], [[0, 0]], [0.5], tau=2.0, time_step=0.1
    )
    n, rho = half_plane_normal_form(pts, dirs)
    np.testing.assert_allclose(n[0], [-1, 0], atol=1e-12)
    np.testing.assert_allclose(rho[0], -0.5, atol=1e-12)


def test_colliding_pair_by_hand():
    # Overlapping at rest (distance 0.5 < R = 1), time step 0.1: w = −p/Δt =
    # (−5, 0), u = (R/Δt − |w|)·ŵ = (−5, 0): A must move away at 2.5 m/s.
    pts, dirs, _ = orca_half_planes(
        [0, 0], [0, 0], 0.5, [[0.5, 0]], [[0, 0]], [0.5], tau=2.0, time_step=0.1
    )
    n, rho = half_plane_normal_form(pts, dirs)
    np.testing.assert_allclose(n[0], [-1, 0], atol=1e-12)
    np.testing.assert_allclose(rho[0], 2.5, atol=1e-12)


def test_wall_by_hand():
    # A wall 1 m ahead, radius 0.3, τ_obs = 0.5: at most (1 − 0.3)/0.5 = 1.4 m/s
    # toward it.
    pts, dirs, n_obs = orca_half_planes(
        [0, 0],
        [0, 0],
        0.3,
        np.zeros((0, 2)),
        np.zeros((0, 2)),
        [],
        tau=2.0,
        tau_obs=0.5,
        time_step=0.1,
        obstacles=[[[1, -1], [1, 1]]],
    )
    assert n_obs == 1
    n, rho = half_plane_normal_form(pts, dirs)
    np.testing.assert_allclose(n[0], [-1, 0], atol=1e-12)
    np.testing.assert_allclose(rho[0], -1.4, atol=1e-12)


def test_free_agent_keeps_its_preferred_velocity_within_max_speed():
    v = orca_velocity(
        [0, 0],
        [0, 0],
        0.3,
        np.zeros((0, 2)),
        np.zeros((0, 2)),
        [],
        preferred_velocity=[3.0, 4.0],
        max_speed=1.5,
        time_step=0.1,
    )
    np.testing.assert_allclose(v, [0.9, 1.2], atol=1e-12)


def _RandomScene(rng, trial):
    M = int(rng.integers(1, 5))
    P = rng.uniform(-3, 3, (M + 1, 2))
    V = rng.uniform(-1, 1, (M + 1, 2))
    R = rng.uniform(0.2, 0.4, M + 1)
    if trial % 3 == 0:  # a colliding pair
        P[1] = P[0] + rng.normal(size=2) * 0.2
    obstacles = []
    if trial % 2 == 0:  # a wall segment
        a = rng.uniform(-3, 3, 2)
        obstacles = [np.array([a, a + rng.uniform(-2, 2, 2)])]
    if trial % 4 == 1:  # a box (counter-clockwise)
        a = rng.uniform(-3, 3, 2)
        w, h = rng.uniform(0.3, 1.5, 2)
        obstacles = [np.array([a, a + [w, 0], a + [w, h], a + [0, h]])]
    prefs = rng.uniform(-1.5, 1.5, (M + 1, 2))
    return P, V, R, obstacles, prefs


def _Violation(velocity, points, directions):
    """The largest violation of ORCA lines by a velocity (linearProgram3's
    objective)."""
    return max(O._Det(d, p - velocity) for p, d in zip(points, directions, strict=True))


def test_against_rvo2_on_random_scenes():
    """RVO2 itself (the pyrvo bindings; single precision) on 400 scenes with
    and without collisions, walls and boxes."""
    pyrvo = pytest.importorskip("pyrvo")
    rng = np.random.default_rng(0)
    dt, tau, tau_obs, vmax = 0.1, 2.0, 0.5, 1.5
    worst_line, close, lp3 = 0.0, 0, 0
    scenes = 400
    for trial in range(scenes):
        P, V, R, obstacles, prefs = _RandomScene(rng, trial)
        sim = pyrvo.RVOSimulator()
        sim.set_time_step(dt)
        for i in range(len(P)):
            sim.add_agent(
                tuple(P[i]), 100.0, 20, tau, tau_obs, float(R[i]), vmax, tuple(V[i])
            )
            sim.set_agent_pref_velocity(i, tuple(prefs[i]))
        for ob in obstacles:
            sim.add_obstacle([tuple(p) for p in ob])
        sim.process_obstacles()
        sim.do_step()
        # pyrvo returns each line as (direction, point).
        ref = [
            sim.get_agent_orca_line(0, k)
            for k in range(sim.get_agent_num_orca_lines(0))
        ]
        ref_dirs = np.array([r[0] for r in ref]).reshape(-1, 2)
        ref_pts = np.array([r[1] for r in ref]).reshape(-1, 2)
        ref_v = np.array(sim.get_agent_velocity(0).to_tuple())
        pts, dirs, n_obs = orca_half_planes(
            P[0],
            V[0],
            R[0],
            P[1:],
            V[1:],
            R[1:],
            tau=tau,
            tau_obs=tau_obs,
            time_step=dt,
            obstacles=obstacles,
            max_speed=vmax,
        )
        assert len(pts) == len(ref_pts), trial
        worst_line = max(
            worst_line,
            np.max(np.abs(pts - ref_pts), initial=0),
            np.max(np.abs(dirs - ref_dirs), initial=0),
        )
        v = orca_velocity(
            P[0],
            V[0],
            R[0],
            P[1:],
            V[1:],
            R[1:],
            preferred_velocity=prefs[0],
            max_speed=vmax,
            tau=tau,
            tau_obs=tau_obs,
            time_step=dt,
            obstacles=obstacles,
        )
        if np.max(np.abs(v - ref_v)) <= 1e-4:
            close += 1
            continue
        # Otherwise the lines are infeasible and linearProgram3 minimizes the
        # largest violation of the agent lines (obstacle lines kept), which
        # is ill-conditioned for nearly parallel lines: ours must be at least
        # as good by that measure.
        lp3 += 1

        agents = (pts[n_obs:], dirs[n_obs:])
        assert _Violation(v, *agents) <= _Violation(ref_v, *agents) + 1e-6, trial
        assert np.max(np.abs(v - ref_v)) < 1e-2, trial
    assert worst_line < 1e-4
    assert close >= 0.99 * scenes, (close, lp3)


def test_a_time_horizon_per_agent_gives_each_agent_its_own_lines():
    """With τ given per other agent, each agent's line is the one a call
    with its τ alone builds, in the same (nearest-first) order."""
    rng = np.random.default_rng(11)
    for trial in range(50):
        P, V, R, _, _ = _RandomScene(rng, trial)
        M = len(P) - 1
        taus = rng.choice([0.7, 2.0, 3.5], size=M)
        shares = rng.choice([0.5, 1.0], size=M)
        args = (P[0], V[0], R[0], P[1:], V[1:], R[1:])
        pts, dirs, n_obs = orca_half_planes(
            *args, tau=taus, time_step=0.2, shares=shares
        )
        assert n_obs == 0 and len(pts) == M
        order = np.argsort(np.sum((P[1:] - P[0]) ** 2, axis=1), kind="stable")
        for row, i in enumerate(order):
            p_i, d_i, _ = orca_half_planes(
                *args, tau=taus[i], time_step=0.2, shares=shares
            )
            np.testing.assert_array_equal(pts[row], p_i[row])
            np.testing.assert_array_equal(dirs[row], d_i[row])


def test_vectorized_agent_lines_match_the_reference():
    """The MPC's half-planes (normal form, shares, per-pair batching over
    (k, j, i)) equal the reference lines; the shared geometry itself is held
    against RVO2 above."""
    rng = np.random.default_rng(5)
    for trial in range(300):
        P, V, R, _, _ = _RandomScene(rng, trial)
        pts, dirs, _ = orca_half_planes(
            P[0], V[0], R[0], P[1:], V[1:], R[1:], tau=2.0, time_step=0.2
        )
        n_ref, rho_ref = half_plane_normal_form(pts, dirs)
        order = np.argsort(np.sum((P[1:] - P[0]) ** 2, axis=1), kind="stable")
        n, rho = orca_agent_half_planes(
            P[0], V[0], P[1:], V[1:], R[0] + R[1:], 0.5, tau=2.0, time_step=0.2
        )
        np.testing.assert_allclose(n[order], n_ref, atol=1e-9)
        np.testing.assert_allclose(rho[order], rho_ref, atol=1e-9)
