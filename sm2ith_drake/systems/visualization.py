"""PlanVisualizer: draws targets and the planned base (orange) and EE (blue)
paths in Meshcat, also into a Meshcat recording for the HTML replay."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import Box, Cylinder, Rgba, Sphere
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import LeafSystem

from sm2ith_drake.humans.messages import HumanEstimate, HumanPrediction, MpcPlan
from sm2ith_drake.planning.sequence import TaskReferences

ORANGE = Rgba(1.0, 0.55, 0.0, 1.0)
BLUE = Rgba(0.1, 0.35, 1.0, 1.0)
TARGET = Rgba(1.0, 0.85, 0.0, 0.9)


class PlanVisualizer(LeafSystem):
    """Shows the controller's plan and the task targets.

    .. pydrake_system::

        name: PlanVisualizer
        input_ports:
        - plan
        - task_references

    The plans are drawn as chains of small spheres whose poses are updated
    (so they animate in a Meshcat recording, unlike line geometry).
    """

    def __init__(
        self, meshcat, tasks, *, horizon: int, period: float, prefix: str = "sm2ith"
    ):
        super().__init__()
        self._meshcat = meshcat
        self._tasks = list(tasks)
        self._N = horizon
        self._prefix = prefix
        self._plan = self.DeclareAbstractInputPort(
            "plan", AbstractValue.Make(MpcPlan())
        )
        self._refs = self.DeclareAbstractInputPort(
            "task_references", AbstractValue.Make(TaskReferences())
        )
        for k in range(horizon + 1):
            meshcat.SetObject(self._Path("base_plan", k), Sphere(0.03), ORANGE)
            meshcat.SetObject(self._Path("ee_plan", k), Sphere(0.025), BLUE)
        for task in self._tasks:
            name = type(task).__name__
            if name == "EePosition":
                meshcat.SetObject(
                    self._Path("targets", task.name), Sphere(0.06), TARGET
                )
            elif name in ("BasePosition", "BasePose"):
                meshcat.SetObject(
                    self._Path("targets", task.name), Cylinder(0.15, 0.01), TARGET
                )
        self.DeclarePeriodicPublishEvent(period, 0.0, self._Draw)
        self.DeclareForcedPublishEvent(self._Draw)

    def _Path(self, group, k):
        return f"/{self._prefix}/{group}/{k}"

    def _Draw(self, context):
        t = context.get_time()
        meshcat = self._meshcat
        refs = self._refs.Eval(context)
        for task in self._tasks:
            target = np.asarray(refs.targets.get(task.name, []), dtype=float)
            if target.ndim == 2:
                target = target[0]
            name = type(task).__name__
            if name == "EePosition":
                meshcat.SetTransform(
                    self._Path("targets", task.name), RigidTransform(target), t
                )
            elif name in ("BasePosition", "BasePose"):
                meshcat.SetTransform(
                    self._Path("targets", task.name),
                    RigidTransform([target[0], target[1], 0.005]),
                    t,
                )
        plan = self._plan.Eval(context).solution
        if plan is None:
            return
        for k in range(min(self._N + 1, len(plan.q))):
            x, y = plan.q[k, 0], plan.q[k, 1]
            meshcat.SetTransform(
                self._Path("base_plan", k), RigidTransform([x, y, 0.03]), t
            )
            meshcat.SetTransform(
                self._Path("ee_plan", k), RigidTransform(plan.p_WE[k]), t
            )


GREEN = Rgba(0.1, 0.75, 0.2, 1.0)
HUMAN = Rgba(0.85, 0.45, 0.35, 0.9)
OBSTACLE = Rgba(0.55, 0.5, 0.45, 1.0)
HUMAN_HEIGHT = 1.7
GREY = Rgba(0.45, 0.45, 0.45, 0.8)
AMBER = Rgba(0.95, 0.65, 0.1, 0.9)


class HumanVisualizer(LeafSystem):
    """Draws the humans (cylinders), the MPC's refined predictions of their
    paths (green, from the plan), the HumanPredictor's prediction before the
    MPC refined it (small grey dots) and the static obstacles, as in the
    paper's figures. With ``max_extra_humans``, the people beyond the slots
    whom the DT-CBF keeps out of (PredictionConfig.max_extra_humans) get
    amber dots: where the controller assumes them over the horizon (at
    their measured velocity, steps of ``time_step``; React holds them).

    .. pydrake_system::

        name: HumanVisualizer
        input_ports:
        - human_truth
        - plan
        - human_prediction
    """

    def __init__(
        self,
        meshcat,
        humans,
        obstacles,
        *,
        horizon: int,
        max_humans: int,
        period: float,
        prefix: str = "sm2ith",
        max_extra_humans: int = 0,
        time_step: float = 0.0,
    ):
        super().__init__()

        self._meshcat = meshcat
        self._prefix = prefix
        self._N = horizon
        self._H = max_humans
        self._E = max_extra_humans
        self._dt = time_step
        self._truth = self.DeclareAbstractInputPort(
            "human_truth", AbstractValue.Make(HumanEstimate())
        )
        self._plan = self.DeclareAbstractInputPort(
            "plan", AbstractValue.Make(MpcPlan())
        )
        self._prediction = self.DeclareAbstractInputPort(
            "human_prediction", AbstractValue.Make(HumanPrediction())
        )
        for j, h in enumerate(humans):
            meshcat.SetObject(
                f"/{prefix}/humans/{j}", Cylinder(h.radius, HUMAN_HEIGHT), HUMAN
            )
        for slot in range(max_humans):
            for k in range(horizon + 1):
                meshcat.SetObject(self._PredictionPath(slot, k), Sphere(0.06), GREEN)
                meshcat.SetObject(self._PredictorPath(slot, k), Sphere(0.03), GREY)
        for slot in range(max_extra_humans):
            for k in range(horizon + 1):
                meshcat.SetObject(self._ExtraPath(slot, k), Sphere(0.04), AMBER)
        for i, o in enumerate(obstacles):
            v = np.asarray(o.vertices, dtype=float)
            edges = (
                [v]
                if len(v) == 2
                else [np.array([v[e], v[(e + 1) % len(v)]]) for e in range(len(v))]
            )
            for e, (a, b) in enumerate(edges):
                length = float(np.linalg.norm(b - a))
                path = f"/{prefix}/obstacles/{i}/{e}"
                meshcat.SetObject(
                    path, Box(max(length, 0.01), 0.05, o.height), OBSTACLE
                )
                yaw = np.arctan2(*(b - a)[::-1])
                mid = 0.5 * (a + b)
                meshcat.SetTransform(
                    path,
                    RigidTransform(
                        RotationMatrix.MakeZRotation(yaw),
                        [mid[0], mid[1], o.height / 2],
                    ),
                )
        self.DeclarePeriodicPublishEvent(period, 0.0, self._Draw)
        self.DeclareForcedPublishEvent(self._Draw)

    def _PredictionPath(self, slot, k):
        return f"/{self._prefix}/human_predictions/{slot}/{k}"

    def _PredictorPath(self, slot, k):
        return f"/{self._prefix}/predictor_output/{slot}/{k}"

    def _ExtraPath(self, slot, k):
        return f"/{self._prefix}/extra_humans/{slot}/{k}"

    def _DrawPaths(self, positions, active, path, height, t, slots=None):
        """Per slot and step, a dot at the predicted position (hidden below
        the floor for empty slots)."""
        slots = self._H if slots is None else slots
        for slot in range(min(slots, positions.shape[1])):
            for k in range(min(self._N + 1, positions.shape[0])):
                p = positions[k, slot]
                z = height if active[slot] else -10.0
                self._meshcat.SetTransform(
                    path(slot, k), RigidTransform([p[0], p[1], z]), t
                )

    def _DrawExtras(self, prediction, t):
        ids = np.asarray(prediction.extra_ids, dtype=int).reshape(-1)
        if not self._E or not ids.size:
            return
        p0 = np.asarray(prediction.extra_positions, dtype=float).reshape(-1, 2)
        v0 = prediction.ExtraVelocities()
        times = self._dt * np.arange(self._N + 1)
        positions = p0[None] + times[:, None, None] * v0[None]
        self._DrawPaths(positions, ids >= 0, self._ExtraPath, 0.04, t, self._E)

    def _Draw(self, context):
        t = context.get_time()
        meshcat = self._meshcat
        truth = self._truth.Eval(context) if self._truth.HasValue(context) else None
        for j, p in (
            [] if truth is None else zip(truth.ids, truth.positions, strict=True)
        ):
            meshcat.SetTransform(
                f"/{self._prefix}/humans/{j}",
                RigidTransform([p[0], p[1], HUMAN_HEIGHT / 2]),
                t,
            )
        if self._prediction.HasValue(context):
            prediction = self._prediction.Eval(context)
            if prediction.positions.shape[1]:
                self._DrawPaths(
                    prediction.positions,
                    prediction.active,
                    self._PredictorPath,
                    0.03,
                    t,
                )
            self._DrawExtras(prediction, t)
        plan = self._plan.Eval(context).solution
        if plan is None or plan.human_predictions is None:
            return
        self._DrawPaths(
            plan.human_predictions,
            plan.human_slot_ids >= 0,
            self._PredictionPath,
            0.06,
            t,
        )
