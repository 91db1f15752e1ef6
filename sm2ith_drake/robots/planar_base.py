"""The planar base every mobile manipulator here has: q starts with its
pose (x, y, θ) and ν with its body-frame velocities (v_x, v_y, ω) for a
holonomic base or (v, ω) for a differential drive; the arm's joints follow
one to one in both."""

# (x, y, θ): the first entries of q.
NUM_BASE_POSITIONS = 3


def NumBaseVelocities(robot) -> int:
    """The base's entries of ν (3 holonomic, 2 differential drive)."""
    return robot.num_velocities - (robot.num_positions - NUM_BASE_POSITIONS)


def ArmVelocityIndex(robot, arm_position_index):
    """The ν index of the arm joint at q index ``arm_position_index``."""
    return arm_position_index + robot.num_velocities - robot.num_positions
