"""MobileManipulator: a URDF arm on a planar base, with fast kinematics.

Configuration q = (x, y, θ, q_arm) ∈ Rⁿ and pseudo-velocities
ν = (ν_base, q̇_arm) ∈ Rᵐ with q̇ = G(q) ν (Section III of the paper):

- holonomic base: ν_base = (v_x, v_y, ω) in the base frame, m = n;
- differential base: ν_base = (v, ω) along the base x axis, m = n − 1, so
  the base can never move sideways.

Kinematics for the MPC. The controller evaluates the end-effector position,
every capsule endpoint and their Jacobians at all N + 1 knots of the horizon
many times per control step. MultibodyPlant does this one configuration at a
time (about 20 µs per call and frame from Python, times N·frames·stages);
instead the kinematic tree is read once from the finalized plant (fixed
joint offsets, axes, types) and evaluated here for all knots at once with
vectorized numpy, with analytic geometric Jacobians. The tests hold both
against MultibodyPlant and the UR10 against its closed-form DH model.

A controlled joint may drive several URDF joints in fixed ratios (the
Stretch's telescoping arm: one extension, four segments each moving a
quarter of it), so :attr:`plant` can have more positions than q:
``PlantPositions(q) = plant_positions_from_q @ q``. ``plant_from_q`` (square)
poses the drawing plant of :meth:`AddToSceneGraph`.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import SceneGraph
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import (
    PlanarJoint,
)

from sm2ith_drake.resources import GetModelsDir
from sm2ith_drake.robots.body_steps import ReadBodySteps
from sm2ith_drake.robots.kinematics_kernel import PackedSteps
from sm2ith_drake.robots.models import BASE_KINDS, MODELS
from sm2ith_drake.robots.packaged import PREPARERS, AddPackagePaths


@dataclass
class Kinematics:
    """Kinematics at K configurations (arrays lead with K)."""

    # End-effector position in the world and its Jacobian w.r.t. q.
    p_WE: np.ndarray  # (K, 3)
    J_WE: np.ndarray  # (K, 3, n)
    # Base origin (on the floor) in the world.
    p_WB: np.ndarray  # (K, 3)
    # Capsule segment endpoints in the world and their Jacobians w.r.t. q.
    capsule_points: np.ndarray  # (K, C, 2, 3)
    capsule_jacobians: np.ndarray  # (K, C, 2, 3, n)


class MobileManipulator:
    """A mobile manipulator built from a URDF plus a :class:`RobotModel`.

    Args:
        model: a shipped model name (see ``MODELS``: "stretch3" and
            "ridgeback_ur10" from the manufacturers' packages, and their
            primitive fallbacks) or a RobotModel describing your own robot.
        urdf_path: a URDF replacing the model's (same link and joint names).

    The URDF must have a root link ``base_link``; the planar base joint is
    added here as a Drake ``PlanarJoint``. Every movable joint of the URDF
    must be listed in ``model.arm_joints`` or ``model.coupled_joints`` and
    carry position limits; velocity and acceleration limits come from the
    URDF (``drake:acceleration``) unless the model gives them.
    """

    def __init__(self, model="ridgeback_ur10", *, urdf_path: str | None = None):
        if isinstance(model, str):
            if model not in MODELS:
                raise ValueError(
                    f"unknown robot model '{model}'; known: {sorted(MODELS)}"
                )
            model = MODELS[model]
        if model.base_kind not in BASE_KINDS:
            raise ValueError(
                f"base_kind must be one of {BASE_KINDS}, got '{model.base_kind}'"
            )
        self.model = model
        self.name = model.name
        self.base_kind = model.base_kind
        if urdf_path:
            path = Path(urdf_path)
        elif model.package:
            keep = list(model.arm_joints) + list(model.coupled_joints)
            path = PREPARERS[model.package](keep)
        else:
            path = Path(model.urdf)
        if not path.is_absolute() and not path.exists():
            path = GetModelsDir() / path
        if not path.exists():
            raise FileNotFoundError(f"robot URDF not found: {path}")
        self.urdf_path = str(path)
        self.plant = self._MakePlant(self.urdf_path, None)
        self._ReadTree()
        self._ReadLimits()
        self.default_q = np.concatenate(
            [np.zeros(3), np.asarray(model.default_arm_q, dtype=float)]
        )
        if self.default_q.size != self.num_positions:
            raise ValueError(
                f"default_arm_q needs {self.num_positions - 3} entries, "
                f"got {len(model.default_arm_q)}"
            )
        self._ReadCapsules()
        self._PruneSteps()
        self._packed = PackedSteps(
            self._steps,
            self._num_bodies,
            np.concatenate([[self._ee_slot], self._capsule_slots.reshape(-1)]),
            np.concatenate([self._p_BE[None], self._capsule_local.reshape(-1, 3)]),
            self._ancestors,
            self._revolute_column,
        )
        moved = self._ancestors[self._capsule_slots].any(axis=1).astype(float)
        self.capsule_joint_masks = moved @ np.abs(self.plant_positions_from_q) > 0

    # ------------------------------------------------------------------ setup

    @staticmethod
    def _MakePlant(urdf_path, scene_graph):
        plant = MultibodyPlant(0.0)
        if scene_graph is not None:
            plant.RegisterAsSourceForSceneGraph(scene_graph)
        parser = Parser(plant)
        AddPackagePaths(parser.package_map())
        parser.AddModels(urdf_path)
        if not plant.HasBodyNamed("base_link"):
            raise ValueError(f"{urdf_path} has no link named 'base_link'")
        base = plant.GetBodyByName("base_link")
        plant.AddJoint(
            PlanarJoint("base", plant.world_frame(), base.body_frame(), np.zeros(3))
        )
        plant.Finalize()
        return plant

    def AddToSceneGraph(self, scene_graph: SceneGraph) -> MultibodyPlant:
        """A new finalized plant of this robot registered with ``scene_graph``
        for drawing; its positions are ``plant_from_q @ q`` (every coupled
        joint moves: the Stretch's telescope is drawn segment by segment)."""
        return self._MakePlant(self.urdf_path, scene_graph)

    def _ReadTree(self):
        plant, model = self.plant, self.model
        self.position_names = ["base_x", "base_y", "base_theta"] + list(
            model.arm_joints
        )
        self.num_positions = len(self.position_names)
        if model.base_kind == "holonomic":
            base_v = ["base_vx", "base_vy", "base_omega"]
        else:
            base_v = ["base_v", "base_omega"]
        self.velocity_names = base_v + [f"{j}dot" for j in model.arm_joints]
        self.num_velocities = len(self.velocity_names)
        self.arm_joint_names = list(model.arm_joints)

        # Which of our q drives each movable plant joint, and by what ratio.
        arm_index = {name: 3 + k for k, name in enumerate(model.arm_joints)}
        drive = {}
        for i in plant.GetJointIndices():
            joint = plant.get_joint(i)
            if joint.num_positions() == 0 or joint.name() == "base":
                continue
            name = joint.name()
            if name in arm_index:
                drive[name] = (arm_index[name], 1.0)
            elif name in model.coupled_joints:
                arm, ratio = model.coupled_joints[name]
                if arm not in arm_index:
                    raise ValueError(
                        f"coupled joint '{name}' names '{arm}', not an arm joint"
                    )
                drive[name] = (arm_index[arm], float(ratio))
            else:
                movable = [
                    plant.get_joint(j).name()
                    for j in plant.GetJointIndices()
                    if plant.get_joint(j).num_positions() > 0
                ]
                raise ValueError(
                    f"the URDF's movable joints {movable} do not match arm_joints "
                    f"{list(model.arm_joints)} (plus the planar base)"
                )
        driven = {k for k, _ in drive.values()}
        for name, k in arm_index.items():
            if k not in driven:
                raise ValueError(f"joint '{name}' is not in {self.urdf_path}")
        self._drive = drive
        # q → plant positions (drawing uses the same plant).
        n, n_plant = self.num_positions, plant.num_positions()
        base_joint = plant.GetJointByName("base")
        self.plant_positions_from_q = np.zeros((n_plant, n))
        for i in range(3):
            self.plant_positions_from_q[base_joint.position_start() + i, i] = 1.0
        for name, (k, ratio) in drive.items():
            start = plant.GetJointByName(name).position_start()
            self.plant_positions_from_q[start, k] = ratio
        self.plant_from_q = self.plant_positions_from_q

        tree = ReadBodySteps(plant)
        self._slot, self._num_bodies = tree.slot, tree.num_bodies
        self._steps = tree.steps
        self._ancestors, self._revolute_column = tree.ancestors, tree.revolute_column
        ee = self.model.ee_frame
        if not plant.HasFrameNamed(ee):
            raise ValueError(f"end-effector frame '{ee}' is not in {self.urdf_path}")
        frame = plant.GetFrameByName(ee)
        self._ee_slot = self._slot[int(frame.body().index())]
        self._p_BE = frame.GetFixedPoseInBodyFrame().translation().copy()
        self._base_slot = self._slot[int(plant.GetBodyByName("base_link").index())]

    def _ReadLimits(self):
        plant, model = self.plant, self.model
        lower, upper, v_max, a_max = [], [], [], []
        for k, name in enumerate(model.arm_joints):
            lo, hi, v, a = -np.inf, np.inf, np.inf, np.inf
            for joint_name, (index, ratio) in self._drive.items():
                if index != 3 + k:
                    continue
                j = plant.GetJointByName(joint_name)
                # Plant position = ratio · q: every driven joint within its range.
                bounds = np.array(
                    [j.position_lower_limits()[0], j.position_upper_limits()[0]]
                )
                bounds = np.sort(bounds / ratio)
                lo, hi = max(lo, bounds[0]), min(hi, bounds[1])
                v = min(v, j.velocity_upper_limits()[0] / abs(ratio))
                a = min(a, j.acceleration_upper_limits()[0] / abs(ratio))
            v = model.velocity_limits.get(name, v)
            a = model.acceleration_limits.get(name, a)
            for what, value in (("velocity", v), ("acceleration", a)):
                if not np.isfinite(value) or value <= 0:
                    raise ValueError(
                        f"joint '{name}' needs a finite {what} limit in the URDF "
                        "(<limit velocity=... drake:acceleration=...>) or in the "
                        f"RobotModel ({what}_limits)"
                    )
            lower.append(lo)
            upper.append(hi)
            v_max.append(v)
            a_max.append(a)
        nb = 3 if model.base_kind == "holonomic" else 2
        bv = np.asarray(model.base_velocity_limit, dtype=float)
        ba = np.asarray(model.base_acceleration_limit, dtype=float)
        if bv.size != nb or ba.size != nb:
            raise ValueError(
                f"a {model.base_kind} base needs {nb} velocity and acceleration limits"
            )
        inf3 = np.full(3, np.inf)
        self.q_lower = np.concatenate([-inf3, lower])
        self.q_upper = np.concatenate([inf3, upper])
        self.nu_upper = np.concatenate([bv, v_max])
        self.nu_lower = -self.nu_upper
        self.nudot_upper = np.concatenate([ba, a_max])
        self.nudot_lower = -self.nudot_upper

    def NarrowJointLimits(self, limits: dict) -> None:
        """Narrows arm joint position limits: ``limits`` maps a joint name to
        [lower, upper], which must lie within the URDF's limits.

        Raises:
            ValueError: an unknown joint, a malformed pair, or a range outside
                the URDF's.
        """
        for name, pair in limits.items():
            if name not in self.arm_joint_names:
                raise ValueError(
                    f"robot.joint_limits: unknown joint '{name}'; arm joints: "
                    + ", ".join(self.arm_joint_names)
                )
            pair = np.asarray(pair, dtype=float)
            i = 3 + self.arm_joint_names.index(name)
            lo, hi = self.q_lower[i], self.q_upper[i]
            if (
                pair.shape != (2,)
                or not np.all(np.isfinite(pair))
                or not (lo <= pair[0] < pair[1] <= hi)
            ):
                raise ValueError(
                    f"robot.joint_limits.{name} must be [lower, upper] with "
                    f"{lo:g} ≤ lower < upper ≤ {hi:g}, got {pair.tolist()}"
                )
            self.q_lower[i], self.q_upper[i] = pair

    def _ReadCapsules(self):
        plant = self.plant
        self.capsules = list(self.model.capsules)
        self.capsule_names = [c.name for c in self.capsules]
        index = {name: i for i, name in enumerate(self.capsule_names)}
        if len(index) != len(self.capsules):
            raise ValueError("capsule names must be unique")
        slots, local = [], []
        for c in self.capsules:
            ends = []
            for body in (c.body, c.body_B or c.body):
                if not plant.HasBodyNamed(body):
                    raise ValueError(f"capsule '{c.name}': no link '{body}'")
                ends.append(self._slot[int(plant.GetBodyByName(body).index())])
            slots.append(ends)
            local.append([c.p_A, c.p_B])
        self._capsule_slots = np.array(slots, dtype=int).reshape(-1, 2)
        self._capsule_local = np.asarray(local, dtype=float).reshape(-1, 2, 3)
        self.capsule_radii = np.array([c.radius for c in self.capsules])
        pairs = []
        for a, b in self.model.self_collision_pairs:
            if a not in index or b not in index:
                raise ValueError(f"self-collision pair ({a}, {b}): unknown capsule")
            pairs.append((index[a], index[b]))
        self.self_collision_pairs = pairs

    def _PruneSteps(self):
        """Keeps only the bodies that pose a point we evaluate (the end
        effector, the capsules, the base) and their ancestors: a packaged
        description has many more (sensor frames, markers)."""
        parent = {st.body: st.parent for st in self._steps}
        needed = set()
        for slot in [self._ee_slot, self._base_slot, *self._capsule_slots.ravel()]:
            while slot >= 0 and slot not in needed:
                needed.add(int(slot))
                slot = parent[slot]
        self._steps = [st for st in self._steps if st.body in needed]

    # ------------------------------------------------------------- the model

    def PlantPositions(self, q: np.ndarray) -> np.ndarray:
        """The generalized positions of :attr:`plant` for our q."""
        return self.plant_positions_from_q @ q

    def G(self, q: np.ndarray) -> np.ndarray:
        """q̇ = G(q) ν, an (n, m) matrix (one row of :meth:`GStack`)."""
        return self.GStack(np.asarray(q)[None])[0]

    def dGnu_dq(self, q: np.ndarray, nu: np.ndarray) -> np.ndarray:
        """∂(G(q) ν)/∂q, an (n, n) matrix (only the θ column is nonzero; one
        row of :meth:`dGnu_dqStack`)."""
        return self.dGnu_dqStack(np.asarray(q)[None], np.asarray(nu)[None])[0]

    def GStack(self, qs: np.ndarray) -> np.ndarray:
        """q̇ = G(q) ν at the K rows of ``qs``: (K, n, m)."""
        qs = np.atleast_2d(qs)
        K, n, m = qs.shape[0], self.num_positions, self.num_velocities
        c, s = np.cos(qs[:, 2]), np.sin(qs[:, 2])
        G = np.zeros((K, n, m))
        arm = np.arange(3, n)
        if self.base_kind == "holonomic":
            G[:, 0, 0], G[:, 0, 1], G[:, 1, 0], G[:, 1, 1] = c, -s, s, c
            G[:, 2, 2] = 1.0
            G[:, arm, arm] = 1.0
        else:
            G[:, 0, 0], G[:, 1, 0], G[:, 2, 1] = c, s, 1.0
            G[:, arm, arm - 1] = 1.0
        return G

    def dGnu_dqStack(self, qs: np.ndarray, nus: np.ndarray) -> np.ndarray:
        """∂(G(q) ν)/∂q at the K rows of ``qs`` and ``nus``: (K, n, n), only
        the θ column nonzero."""
        qs, nus = np.atleast_2d(qs), np.atleast_2d(nus)
        n = self.num_positions
        c, s = np.cos(qs[:, 2]), np.sin(qs[:, 2])
        out = np.zeros((qs.shape[0], n, n))
        if self.base_kind == "holonomic":
            vx, vy = nus[:, 0], nus[:, 1]
            out[:, 0, 2] = -s * vx - c * vy
            out[:, 1, 2] = c * vx - s * vy
        else:
            out[:, 0, 2] = -s * nus[:, 0]
            out[:, 1, 2] = c * nus[:, 0]
        return out

    def CalcKinematics(self, qs: np.ndarray) -> Kinematics:
        """End-effector and capsule kinematics at the K rows of ``qs``."""
        qs = np.atleast_2d(np.asarray(qs, dtype=float))
        K, n = qs.shape
        if n != self.num_positions:
            raise ValueError(f"q needs {self.num_positions} entries, got {n}")
        qp = qs @ self.plant_positions_from_q.T  # plant positions (K, n_plant)
        # Points: the end effector, then both ends of every capsule.
        points, jac_plant, origins = self._packed.Evaluate(qp)
        # ∂p/∂q = ∂p/∂(plant positions) · plant_positions_from_q.
        jac = jac_plant @ self.plant_positions_from_q
        C, n = len(self.capsules), self.num_positions
        return Kinematics(
            p_WE=points[:, 0],
            J_WE=jac[:, 0],
            p_WB=origins[:, self._base_slot],
            capsule_points=points[:, 1:].reshape(K, C, 2, 3),
            capsule_jacobians=jac[:, 1:].reshape(K, C, 2, 3, n),
        )

    def __repr__(self):
        return (
            f"MobileManipulator('{self.name}', {self.base_kind}, "
            f"n={self.num_positions}, m={self.num_velocities})"
        )
