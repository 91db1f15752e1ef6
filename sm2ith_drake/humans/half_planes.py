"""ORCA half-planes n·v ≥ ρ in the vectorized form the prediction model and
the simulated people share (eq. relaxed_orca_acc_argmin's constraints).
"""

import numpy as np

from sm2ith_drake.geometry import point_segment_distance_2d
from sm2ith_drake.humans.orca import orca_agent_lines


def orca_agent_half_planes(
    position,
    velocity,
    other_positions,
    other_velocities,
    combined_radius,
    share,
    *,
    tau,
    time_step,
):
    """Half-planes n·a ≥ ρ of ORCA, vectorized over leading axes.

    Returns n (..., 2) (unit, pointing into the allowed side) and ρ (...,).
    """
    u, d = orca_agent_lines(
        other_positions - position,
        velocity - other_velocities,
        combined_radius,
        tau=tau,
        time_step=time_step,
    )
    n = np.stack([-d[..., 1], d[..., 0]], axis=-1)
    point = velocity + np.asarray(share)[..., None] * u
    return n, np.sum(n * point, axis=-1)


def obstacle_half_planes(position, segments, radius, *, tau_obs):
    """Half-planes n·a ≥ ρ keeping an agent clear of static wall segments for
    τ_obs (van den Berg et al. 2011, Sec. 5.2, one line per segment): the
    velocities that do not reach the segment inflated by the radius within
    τ_obs. Vectorized: position (..., 2), segments (S, 2, 2) → n (..., S, 2),
    ρ (..., S).

    This is the conservative single-line form (the line through the closest
    point of the inflated segment, scaled by 1/τ_obs), not RVO2's full
    polygon-obstacle construction with its leg and "already covered" cases.
    """
    position = np.asarray(position, dtype=float)[..., None, :]
    dist, _, toward = point_segment_distance_2d(
        segments[:, 0], segments[:, 1], position
    )
    n = -toward  # away from the segment
    # a·(−n) ≤ (dist − r)/τ_obs  ⟺  n·a ≥ −(dist − r)/τ_obs.
    return n, -(dist - radius) / tau_obs
