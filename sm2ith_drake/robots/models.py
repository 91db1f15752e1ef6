"""The shipped robot models: what the URDFs cannot say.

A URDF describes the arm; a :class:`RobotModel` adds what a URDF cannot
express: the planar base (its kind and body-frame velocity limits), the
end-effector frame, the arm joints in the controller's order, joints driven
together by one controlled joint, the limits the manufacturer's URDF leaves
out, the collision capsules of the MPC and the self-collision pairs.

``stretch3`` and ``ridgeback_ur10`` are the manufacturers' descriptions from
the package index (see packaged.py); ``stretch3_primitive`` and
``ridgeback_ur10_primitive`` are our boxes-and-cylinders URDFs in models/,
kept as a fallback and as examples of a URDF of your own.
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
    # If set, p_B is fixed to this body instead (a capsule spanning a
    # telescope: from its fixed sleeve to its moving end).
    body_B: str = ""


@dataclass
class RobotModel:
    """Everything MobileManipulator needs beyond the URDF."""

    name: str
    # File name inside models/ (or an absolute path); unused with ``package``.
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
    # The description comes from a package on the index, prepared by
    # packaged.PREPARERS[package] (then ``urdf`` is unused).
    package: str = ""
    # URDF joints driven by a controlled joint: {urdf_joint: (arm_joint,
    # ratio)}, plant position = ratio · q[arm_joint]. Every other movable URDF
    # joint not in arm_joints is held fixed by the preparation.
    coupled_joints: dict = field(default_factory=dict)
    # Limits of arm joints that replace the URDF's (manufacturers' URDFs
    # carry placeholders or no acceleration limits).
    velocity_limits: dict = field(default_factory=dict)
    acceleration_limits: dict = field(default_factory=dict)

    def replace(self, **changes) -> "RobotModel":
        return dataclasses.replace(self, **changes)


# Stretch 3. Base: differential drive, |v| ≤ 0.3 m/s (the paper and the
# Hello Robot hardware guide); |ω| ≤ 1.0 rad/s and the acceleration limits
# (0.5 m/s², 1.5 rad/s²) follow stretch_body's default base motion profile,
# rounded down.
STRETCH3_PRIMITIVE = RobotModel(
    name="stretch3_primitive",
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

# The Ridgeback–UR10's self-collision pairs (both models' capsule names).
_UR10_SELF_COLLISION_PAIRS = (
    ("forearm", "base"),
    ("wrist", "base"),
    ("gripper", "base"),
    ("wrist", "mount"),
    ("gripper", "mount"),
    ("gripper", "upper_arm"),
)

# Ridgeback–UR10. Base: holonomic, |v_x|, |v_y| ≤ 1.1 m/s (Ridgeback
# datasheet maximum speed); |ω| ≤ 2.0 rad/s and 1.0 m/s², 2.0 rad/s² are
# conservative choices of ours (Clearpath publishes no acceleration limits).
RIDGEBACK_UR10_PRIMITIVE = RobotModel(
    name="ridgeback_ur10_primitive",
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
    self_collision_pairs=list(_UR10_SELF_COLLISION_PAIRS),
    base_radius=0.62,
)

STRETCH3 = RobotModel(
    name="stretch3",
    urdf="",
    package="stretch3",
    base_kind="differential",
    base_velocity_limit=(0.3, 1.0),
    base_acceleration_limit=(0.5, 1.5),
    arm_joints=["joint_lift", "joint_arm", "joint_wrist_yaw", "joint_wrist_pitch"],
    # The telescoping arm: four segments, each moving a quarter of the
    # extension (0.13 m of the 0.52 m each), as on the robot.
    coupled_joints={f"joint_arm_l{i}": ("joint_arm", 0.25) for i in (3, 2, 1, 0)},
    # The packaged URDF has 1.0 for every velocity and no accelerations:
    # stretch_body's default "max" motion profiles, rounded down.
    velocity_limits={
        "joint_lift": 0.2,
        "joint_arm": 0.25,
        "joint_wrist_yaw": 1.0,
        "joint_wrist_pitch": 1.0,
    },
    acceleration_limits={
        "joint_lift": 0.4,
        "joint_arm": 0.4,
        "joint_wrist_yaw": 2.0,
        "joint_wrist_pitch": 2.0,
    },
    ee_frame="link_grasp_center",
    default_arm_q=[0.5, 0.05, 0.0, 0.0],
    # Capsules fitted to Hello Robot's meshes (tests/test_robot_models.py
    # checks every vertex within 3 cm at random configurations): the base
    # with its wheels, the mast, the head, the lift carriage, the telescoping
    # arm from the back of its fixed sleeve (l4) to the front of its last
    # segment (l0), and the DW3 wrist with the SG3 gripper.
    capsules=[
        Capsule("base", "base_link", (-0.10, 0.0, 0.088), (0.0, 0.0, 0.088), 0.19),
        Capsule("mast", "link_mast", (0.0, 0.065, 0.0), (0.0, 1.35, 0.0), 0.03),
        Capsule(
            "head", "link_head", (0.03, 0.035, 0.042), (0.132, 0.095, -0.052), 0.09
        ),
        Capsule(
            "lift", "link_lift", (-0.056, 0.079, 0.021), (-0.004, -0.017, 0.028), 0.09
        ),
        Capsule(
            "arm",
            "link_arm_l4",
            (0.0, 0.0, -0.196),
            (0.0, 0.0, 0.0),
            0.05,
            body_B="link_arm_l0",
        ),
        Capsule(
            "gripper",
            "link_gripper_s3_body",
            (0.0, 0.015, 0.169),
            (0.0, 0.024, -0.04),
            0.07,
        ),
    ],
    self_collision_pairs=[("gripper", "base"), ("gripper", "mast")],
    # Every vertex of the base's meshes (base, wheels, mast, head) lies within
    # 0.277 m of the base origin in the plane (tests/test_robot_models.py).
    base_radius=0.28,
)

# Ridgeback–UR10: ur_description's UR10 on our Ridgeback (models/ridgeback.urdf).
# Velocity limits: the UR10 (CB3) technical specifications, 120 °/s base and
# shoulder, 180 °/s elbow and wrists (the packaged URDF says 2.16 and 3.2
# rad/s). Universal Robots publishes no joint acceleration limits; 2.0 rad/s²
# is a conservative choice of ours.
_UR10_JOINTS = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
]
RIDGEBACK_UR10 = RobotModel(
    name="ridgeback_ur10",
    urdf="",
    package="ridgeback_ur10",
    base_kind="holonomic",
    base_velocity_limit=(1.1, 1.1, 2.0),
    base_acceleration_limit=(1.0, 1.0, 2.0),
    arm_joints=list(_UR10_JOINTS),
    velocity_limits=dict(
        zip(_UR10_JOINTS, np.deg2rad([120, 120, 180, 180, 180, 180]), strict=True)
    ),
    acceleration_limits={j: 2.0 for j in _UR10_JOINTS},
    ee_frame="ee",
    # The UR's base is turned +90° on the mount, so pan = π/2 points the arm
    # ahead: elbow up, the gripper ahead of the base centre.
    default_arm_q=[np.pi / 2, -2.2, -1.4, -1.1, np.pi / 2, 0.0],
    # The base and the mount column are our boxes; the arm capsules are
    # fitted to ur_description's meshes (every vertex within 3 cm, see
    # tests/test_robot_models.py); "gripper" is a notional tool to the EE.
    capsules=[
        Capsule("base", "base_link", (-0.2, 0.0, 0.15), (0.2, 0.0, 0.15), 0.42),
        Capsule("mount", "base_link", (0.27, 0.01, 0.3), (0.27, 0.01, 0.78), 0.11),
        Capsule(
            "upper_arm", "upper_arm_link", (0.0, -0.046, 0.0), (0.0, -0.046, 0.64), 0.11
        ),
        Capsule("forearm", "forearm_link", (0.0, 0.0, 0.0), (0.0, 0.0, 0.5723), 0.07),
        Capsule("wrist", "wrist_1_link", (0.0, 0.11, -0.06), (0.0, 0.11, 0.06), 0.06),
        Capsule("gripper", "wrist_3_link", (0.0, 0.0, 0.0), (0.0, 0.16, 0.0), 0.06),
    ],
    self_collision_pairs=list(_UR10_SELF_COLLISION_PAIRS),
    base_radius=0.62,
)

MODELS = {
    m.name: m
    for m in (STRETCH3, RIDGEBACK_UR10, STRETCH3_PRIMITIVE, RIDGEBACK_UR10_PRIMITIVE)
}
