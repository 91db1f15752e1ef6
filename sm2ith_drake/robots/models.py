"""The shipped robot models: what the URDFs cannot say.

A URDF describes the arm; a :class:`RobotModel` adds what a URDF cannot
express: the planar base (its kind and body-frame velocity limits), the
end-effector frame, the arm joints in the controller's order, the collision
capsules of the MPC and the self-collision pairs.
"""

import dataclasses
from dataclasses import dataclass, field

import numpy as np

BASE_KINDS = ("holonomic", "differential")


@dataclass
class Capsule:
    """A capsule fixed to a body: the segment p_A–p_B (body frame) swept by a
    sphere of ``radius``."""

    name: str
    body: str
    p_A: tuple
    p_B: tuple
    radius: float


@dataclass
class RobotModel:
    """Everything MobileManipulator needs beyond the URDF."""

    name: str
    # File name inside models/ (or an absolute path).
    urdf: str
    # "holonomic": ν_base = (v_x, v_y, ω) in the base frame;
    # "differential": ν_base = (v, ω), no sideways motion.
    base_kind: str
    # Symmetric limits of ν_base and of its rate (body frame).
    base_velocity_limit: tuple
    base_acceleration_limit: tuple
    # The non-base joints, in the order of q and ν.
    arm_joints: list
    ee_frame: str
    # Nominal arm configuration (the base starts at the origin).
    default_arm_q: list
    capsules: list = field(default_factory=list)
    # Pairs of capsule names that must keep self_collision_distance apart.
    self_collision_pairs: list = field(default_factory=list)
    # Radius of the disc around the base origin that contains the base
    # footprint (used for human interaction).
    base_radius: float = 0.5

    def replace(self, **changes) -> "RobotModel":
        return dataclasses.replace(self, **changes)


# Stretch 3. Base: differential drive, |v| ≤ 0.3 m/s (the paper and the
# Hello Robot hardware guide); |ω| ≤ 1.0 rad/s and the acceleration limits
# (0.5 m/s², 1.5 rad/s²) follow stretch_body's default base motion profile,
# rounded down.
STRETCH3 = RobotModel(
    name="stretch3",
    urdf="stretch3.urdf",
    base_kind="differential",
    base_velocity_limit=(0.3, 1.0),
    base_acceleration_limit=(0.5, 1.5),
    arm_joints=["joint_lift", "joint_arm", "joint_wrist_yaw", "joint_wrist_pitch"],
    ee_frame="ee",
    default_arm_q=[0.5, 0.05, 0.0, 0.0],
    capsules=[
        Capsule("base", "base_link", (-0.12, 0.0, 0.11), (0.0, 0.0, 0.11), 0.17),
        Capsule("mast", "base_link", (-0.17, 0.12, 0.25), (-0.17, 0.12, 1.35), 0.06),
        Capsule("arm", "link_arm", (0.0, 0.0, 0.0), (0.0, 0.5, 0.0), 0.03),
        Capsule(
            "gripper", "link_wrist_pitch", (0.0, -0.05, 0.0), (0.0, -0.19, 0.0), 0.045
        ),
    ],
    self_collision_pairs=[("gripper", "base"), ("gripper", "mast")],
    base_radius=0.25,
)

# Ridgeback–UR10. Base: holonomic, |v_x|, |v_y| ≤ 1.1 m/s (Ridgeback
# datasheet maximum speed); |ω| ≤ 2.0 rad/s and 1.0 m/s², 2.0 rad/s² are
# conservative choices of ours (Clearpath publishes no acceleration limits).
RIDGEBACK_UR10 = RobotModel(
    name="ridgeback_ur10",
    urdf="ridgeback_ur10.urdf",
    base_kind="holonomic",
    base_velocity_limit=(1.1, 1.1, 2.0),
    base_acceleration_limit=(1.0, 1.0, 2.0),
    arm_joints=[
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "elbow_joint",
        "wrist_1_joint",
        "wrist_2_joint",
        "wrist_3_joint",
    ],
    ee_frame="ee",
    # Elbow up, the gripper 1.26 m ahead of the base centre at 0.77 m height.
    default_arm_q=[0.0, -2.2, -1.4, -1.1, np.pi / 2, 0.0],
    capsules=[
        Capsule("base", "base_link", (-0.2, 0.0, 0.15), (0.2, 0.0, 0.15), 0.42),
        Capsule("mount", "base_link", (0.27, 0.0, 0.3), (0.27, 0.0, 0.7), 0.11),
        Capsule(
            "upper_arm", "upper_arm_link", (0.0, 0.0, 0.176), (-0.612, 0.0, 0.176), 0.07
        ),
        Capsule(
            "forearm", "forearm_link", (0.0, 0.0, 0.045), (-0.5723, 0.0, 0.045), 0.055
        ),
        Capsule("wrist", "wrist_2_link", (0.0, 0.0, -0.06), (0.0, 0.0, 0.06), 0.06),
        Capsule("gripper", "wrist_3_link", (0.0, 0.0, 0.0), (0.0, 0.0, 0.15), 0.07),
    ],
    self_collision_pairs=[
        ("forearm", "base"),
        ("wrist", "base"),
        ("gripper", "base"),
        ("wrist", "mount"),
        ("gripper", "mount"),
        ("gripper", "upper_arm"),
    ],
    base_radius=0.62,
)

MODELS = {m.name: m for m in (STRETCH3, RIDGEBACK_UR10)}
