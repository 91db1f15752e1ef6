"""The planar base every mobile manipulator here has: q starts with its
pose (x, y, θ) and ν with its body-frame velocities (v_x, v_y, ω) for a
holonomic base or (v, ω) for a differential drive; the arm's joints follow
one to one in both."""

import numpy as np

# (x, y, θ): the first entries of q.
NUM_BASE_POSITIONS = 3


def NumBaseVelocities(robot) -> int:
    """The base's entries of ν (3 holonomic, 2 differential drive)."""
    return robot.num_velocities - (robot.num_positions - NUM_BASE_POSITIONS)


def BaseStoppingTime(robot) -> float:
    """How long the base takes to stop from its top speed at its
    acceleration limit, the slowest of its translational axes (v_x, v_y of
    a holonomic base; v of a differential drive) (s)."""
    axes = NumBaseVelocities(robot) - 1
    speed = np.maximum(np.abs(robot.nu_lower[:axes]), np.abs(robot.nu_upper[:axes]))
    limit = np.asarray(robot.model.base_acceleration_limit, dtype=float)[:axes]
    return float(np.max(speed / limit))


def ArmVelocityIndex(robot, arm_position_index):
    """The ν index of the arm joint at q index ``arm_position_index``."""
    return arm_position_index + robot.num_velocities - robot.num_positions


def VelocityMapPatterns(robot) -> tuple[np.ndarray, np.ndarray]:
    """The structural nonzeros of G(q) (n, m) and of ∂(G(q)ν)/∂q (n, n) for
    q̇ = G(q)ν: the base's rotation (or unicycle) block and the heading
    column, the arm's identity."""
    n, m = robot.num_positions, robot.num_velocities
    G = np.zeros((n, m), dtype=bool)
    if NumBaseVelocities(robot) == 3:
        G[:2, :2] = True
        G[2, 2] = True
    else:
        G[:2, 0] = True
        G[2, 1] = True
    arm = n - NUM_BASE_POSITIONS
    G[NUM_BASE_POSITIONS:, m - arm :] = np.eye(arm, dtype=bool)
    dG = np.zeros((n, n), dtype=bool)
    dG[:2, 2] = True
    return G, dG
