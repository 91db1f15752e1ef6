"""Robot models: MobileManipulator and the shipped model descriptions."""

from sm2ith_drake.robots.mobile_manipulator import Kinematics, MobileManipulator
from sm2ith_drake.robots.models import MODELS, Capsule, RobotModel

__all__ = ["Capsule", "Kinematics", "MODELS", "MobileManipulator", "RobotModel"]
