"""The kinematic tree of a MultibodyPlant as a list of body steps: how each
body is posed from its parent, in topological order, for the vectorized
forward kinematics of MobileManipulator."""

from dataclasses import dataclass

import numpy as np
from pydrake.multibody.tree import (
    PlanarJoint,
    PrismaticJoint,
    RevoluteJoint,
    WeldJoint,
)

WELD, REVOLUTE, PRISMATIC, PLANAR = range(4)


@dataclass
class BodyStep:
    """How one body is posed from its parent (one joint of the tree)."""

    body: int  # index into the pose arrays
    parent: int  # -1 for the world
    kind: int
    R_PF: np.ndarray
    p_PF: np.ndarray
    R_MC: np.ndarray
    p_MC: np.ndarray
    axis_F: np.ndarray
    column: int  # this joint's Jacobian column (-1: welded); planar: 3 columns


@dataclass
class BodySteps:
    """The plant's bodies in topological order (parents before children)."""

    slot: dict  # body index → position in the pose arrays
    num_bodies: int
    steps: list  # BodyStep per body
    ancestors: np.ndarray  # (bodies, plant positions): which positions move it
    revolute_column: np.ndarray  # (plant positions,): rotational positions


def ParentBody(plant, body):
    for i in plant.GetJointIndices():
        joint = plant.get_joint(i)
        if joint.child_body().index() == body.index():
            return joint.parent_body()
    return plant.world_body()


def ReadBodySteps(plant) -> BodySteps:
    """Reads the finalized plant's tree once."""
    n_plant = plant.num_positions()
    # Bodies in topological order (parents before children).
    joint_of_child = {}
    for i in plant.GetJointIndices():
        joint = plant.get_joint(i)
        joint_of_child[int(joint.child_body().index())] = joint
    world = int(plant.world_body().index())
    order, frontier = [], [world]
    children = {}
    for child, joint in joint_of_child.items():
        children.setdefault(int(joint.parent_body().index()), []).append(child)
    while frontier:
        b = frontier.pop(0)
        for c in sorted(children.get(b, [])):
            order.append(c)
            frontier.append(c)
    slot = {b: s for s, b in enumerate(order)}
    num_bodies = len(order)
    steps = []
    for b in order:
        joint = joint_of_child[b]
        X_PF = joint.frame_on_parent().GetFixedPoseInBodyFrame()
        X_CM = joint.frame_on_child().GetFixedPoseInBodyFrame()
        X_MC = X_CM.inverse()
        column = joint.position_start() if joint.num_positions() else -1
        if isinstance(joint, WeldJoint):
            kind, axis = WELD, np.zeros(3)
            X_PF = X_PF.multiply(joint.X_FM())
        elif isinstance(joint, RevoluteJoint):
            kind, axis = REVOLUTE, np.asarray(joint.revolute_axis())
        elif isinstance(joint, PrismaticJoint):
            kind, axis = PRISMATIC, np.asarray(joint.translation_axis())
        elif isinstance(joint, PlanarJoint):
            kind, axis = PLANAR, np.array([0.0, 0.0, 1.0])
        else:
            raise ValueError(
                f"joint '{joint.name()}' of type {joint.type_name()} is not "
                "supported (use revolute, prismatic or fixed joints)"
            )
        parent = int(joint.parent_body().index())
        steps.append(
            BodyStep(
                body=slot[b],
                parent=-1 if parent == world else slot[parent],
                kind=kind,
                R_PF=X_PF.rotation().matrix(),
                p_PF=X_PF.translation().copy(),
                R_MC=X_MC.rotation().matrix(),
                p_MC=X_MC.translation().copy(),
                axis_F=axis,
                column=column,
            )
        )
    # Which plant positions move each body (its ancestors' joints).
    ancestors = np.zeros((num_bodies, n_plant), dtype=bool)
    revolute_column = np.zeros(n_plant, dtype=bool)
    for st in steps:
        if st.parent >= 0:
            ancestors[st.body] = ancestors[st.parent]
        if st.kind == PLANAR:
            ancestors[st.body, st.column : st.column + 3] = True
            revolute_column[st.column + 2] = True  # the heading
        elif st.kind != WELD:
            ancestors[st.body, st.column] = True
            revolute_column[st.column] = st.kind == REVOLUTE
    return BodySteps(slot, num_bodies, steps, ancestors, revolute_column)
