"""The way out of a stall (ControllerConfig.recovery; not in the paper).

The MPC tracks its targets over a 2 s horizon, linearized at the last plan.
A differential drive with its arm out to one side, stopped beside a door's
jamb, can be where no plan within that horizon gets it closer to the goal
(to back off, turn and come at the door straight first makes things worse),
and at a standstill a turn in place does not move the base origin to first
order, so the linearization sees no use in turning. It then stands there
with every solve "solved".

Recovery watches for that: in ``stall_time`` the base has come less than
``stall_distance`` nearer its target (standing, or edging back and forth),
short of it, and nobody near is moving. Only a base task of the first
priority is recovered (below another task a base that stays put may be
what the hierarchy asks for). It then
plans a route for the robot's whole outline (control/route.py), the arm
held as it is, standing people kept off like walls, and drives it in place
of the MPC: a turn, a step back, a step ahead at a time. It hands back to
the MPC once the rest of the route is a drive ahead within ``EXIT_ANGLE`` of
the heading it has then, or when someone near starts to move, or when a
step would close in on a person or a wall faster than the DT-CBF allows,
or after ``max_time``.

Everything that lasts between steps is a RecoveryState, held in the
controller's state (and so in the Context).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from sm2ith_drake.control.route import (
    BACKWARD,
    FORWARD,
    SIDEWAYS,
    TURN,
    Footprint,
    FootprintClearance,
    PlanRoute,
    Route,
)
from sm2ith_drake.control.tasks import BasePose, BasePosition, WrapAngle
from sm2ith_drake.robots.planar_base import NUM_BASE_POSITIONS, NumBaseVelocities

# The route is handed back to the MPC once the rest of it is a drive ahead
# turning at most this much (rad).
EXIT_ANGLE = 0.5
# A route step counts as done within these (m, rad).
POSITION_TOLERANCE = 0.01
ANGLE_TOLERANCE = 0.03
# Gains of the route follower (1/s).
ANGLE_GAIN = 2.0
CROSS_GAIN = 2.0
# People this far from the base (m) are kept off by the route.
DISC_RANGE = 3.0
# With no route to the target (people standing in the way), the robot gives
# way: it drives back along its own trail to the last point it passed this
# far from where it stands (m), remembered for TRAIL_TIME (s), one point
# every TRAIL_STEP (s).
RETREAT_DISTANCE = 1.0
TRAIL_TIME = 30.0
TRAIL_STEP = 0.5


@dataclass
class RecoveryState:
    # Base positions (t, x, y) over the last stall_time.
    history: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    route: Route | None = None
    # The route's segments (runs of one kind of move): their kinds and end
    # poses; the one being driven.
    kinds: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    ends: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    segment: int = 0
    started: float = 0.0
    # The route gives way (drives back along the trail) rather than heading
    # for the target: driven to its end.
    retreat: bool = False
    # Base positions (t, x, y), one every TRAIL_STEP over TRAIL_TIME.
    trail: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    # Counters: routes driven; stalls with no route (the steps driven are
    # ControllerCounters.recovery_steps).
    routes: int = 0
    no_route: int = 0
    status: str = ""


def Segments(route: Route) -> tuple[np.ndarray, np.ndarray]:
    """A route's runs of one kind of move: kinds (G,) and end poses (G, 3)."""
    moves = route.moves  # the move into each of poses[1:]
    poses = route.poses[1:]
    if not len(moves):
        return np.zeros(0, dtype=int), np.zeros((0, 3))
    last = np.r_[np.nonzero(np.diff(moves))[0], len(moves) - 1]
    return moves[last].astype(int), poses[last]


def RetreatPoint(trail, position):
    """The last point of the trail (T, 3: t, x, y) at least
    RETREAT_DISTANCE from ``position``, else its oldest if that is at least
    a third of it away, else None."""
    if not len(trail):
        return None
    d = np.linalg.norm(trail[:, 1:] - position, axis=1)
    far = np.nonzero(d >= RETREAT_DISTANCE)[0]
    if len(far):
        return trail[far[-1], 1:]
    return trail[0, 1:] if d[0] >= RETREAT_DISTANCE / 3 else None


def DrivesAhead(kinds, ends, heading: float) -> bool:
    """Whether segments are only turns and steps ahead, every pose within
    EXIT_ANGLE of ``heading``."""
    if np.any((kinds == BACKWARD) | (kinds == SIDEWAYS)):
        return False
    return bool(np.all(np.abs(WrapAngle(ends[:, 2] - heading)) <= EXIT_ANGLE))


class Recovery:
    """Decides, each control step, whether the robot drives a route instead
    of the MPC's plan, and the command for that step (RecoveryConfig)."""

    def __init__(self, robot, tasks, config, *, walls, safety, period: float):
        self.robot = robot
        self.config = config
        self.walls = np.asarray(walls, dtype=float).reshape(-1, 2, 2)
        self.safety = safety
        self.period = float(period)
        # Only a base task of the first priority is recovered: under a higher
        # task (an EE held in place, say) a base that stays put may be what
        # the hierarchy asks for, and the route, arm held, would break it.
        first = tasks[0] if len(tasks) else None
        base = isinstance(first, BasePose) or (
            isinstance(first, BasePosition) and not first.offset
        )
        self._base = first.name if base else None
        self._holonomic = NumBaseVelocities(robot) == 3

    def GoalTolerance(self, done_tolerances: dict | None) -> float:
        """How near its target the base counts as at its goal, given the
        control step's phase tolerances by task (the task sequence's; None
        or {}: none): ``goal_tolerance``, or the phase's where smaller (a
        base short of its target by more than its phase's tolerance is not
        at its goal)."""
        phase = (done_tolerances or {}).get(self._base, np.inf)
        return min(self.config.goal_tolerance, float(phase))

    def InitialState(self) -> RecoveryState:
        return RecoveryState()

    def Footprint(self, q) -> Footprint:
        """The robot's outline in its base frame, the arm as in ``q``."""
        q = np.array(q, dtype=float)
        q[:NUM_BASE_POSITIONS] = 0.0
        kin = self.robot.CalcKinematics(q[None])
        return Footprint(kin.capsule_points[0, :, :, :2], self.robot.capsule_radii)

    def WallBarrier(self, q) -> float:
        """h of the DT-CBF against the walls: the outline's clearance less
        the obstacle margin (+inf without walls)."""
        footprint = self.Footprint(q)
        pose = np.asarray(q, dtype=float)[:NUM_BASE_POSITIONS]
        clear = FootprintClearance(footprint, pose, self.walls)[0]
        return clear - self.safety.obstacle_margin

    def Step(
        self,
        state: RecoveryState,
        *,
        time_now,
        q0,
        targets,
        humans,
        done_tolerances=None,
    ):
        """Returns (new state, the base velocity to drive (its ν entries) or
        None for the MPC to plan this step). ``done_tolerances``:
        TaskReferences.done_tolerances (see GoalTolerance)."""
        cfg = self.config
        if not cfg.enabled or self._base is None or not np.all(np.isfinite(q0)):
            return state, None
        new = dataclasses.replace(state, status="")
        history = np.vstack([state.history, [[time_now, q0[0], q0[1]]]])
        new.history = history[history[:, 0] >= time_now - cfg.stall_time - 1e-9]
        if not len(state.trail) or time_now - state.trail[-1, 0] >= TRAIL_STEP - 1e-9:
            trail = np.vstack([state.trail, [[time_now, q0[0], q0[1]]]])
            new.trail = trail[trail[:, 0] >= time_now - TRAIL_TIME]
        target = np.asarray(targets[self._base], dtype=float)[:2]
        people_p, people_v = _People(humans)
        near = np.linalg.norm(people_p - q0[:2], axis=1) <= cfg.people_distance
        moving = np.linalg.norm(people_v, axis=1) > cfg.people_speed
        someone_moving = bool(np.any(near & moving))
        if new.route is not None:
            end = None
            if someone_moving:
                end = "someone near moves"
            elif time_now - new.started > cfg.max_time:
                end = "out of time"
            elif not new.retreat and DrivesAhead(
                new.kinds[new.segment :], new.ends[new.segment :], q0[2]
            ):
                end = "the rest drives ahead"
            if end is None:
                nu = self._Follow(new, q0)
                if nu is not None:
                    return new, nu
                end = "route driven"
            new.route, new.status = None, f"recovery ended: {end}"
            new.history = new.history[-1:]
            return new, None
        # No progress: in the last stall_time the base never came
        # stall_distance nearer the target than it was at the start (a base
        # that stands, or edges back and forth).
        distance = np.linalg.norm(new.history[:, 1:] - target, axis=1)
        stalled = (
            new.history[0, 0] <= time_now - cfg.stall_time + 1e-9
            and distance[0] - np.min(distance) < cfg.stall_distance
        )
        if not stalled or someone_moving:
            return new, None
        goal_tolerance = self.GoalTolerance(done_tolerances)
        if np.linalg.norm(target - q0[:2]) <= goal_tolerance:
            return new, None
        new.history = new.history[-1:]  # the next try after another stall
        keep = np.linalg.norm(people_p - q0[:2], axis=1) <= DISC_RANGE
        reach = self.safety.human_radius + self.safety.human_margin
        discs = np.column_stack([people_p[keep], np.full(int(keep.sum()), reach)])
        route = self._Route(new, q0, target, discs, goal_tolerance)
        retreat = False
        if route is None and len(discs):
            back = RetreatPoint(new.trail, q0[:2])
            if back is not None:
                route, retreat = self._Route(new, q0, back, discs, 0.15), True
        if route is None:
            new.no_route += 1
            new.status = new.status or "no route"
            return new, None
        kinds, ends = Segments(route)
        if not retreat and DrivesAhead(kinds, ends, q0[2]):
            new.status = "stalled, but the route drives ahead"
            return new, None
        new.route, new.kinds, new.ends, new.segment = route, kinds, ends, 0
        new.started, new.routes, new.retreat = time_now, new.routes + 1, retreat
        new.status = "recovery started" + (": giving way" if retreat else "")
        nu = self._Follow(new, q0)
        if nu is None:
            new.route = None
        return new, nu

    def _Route(self, new, q0, goal, discs, tolerance):
        """PlanRoute from the base pose to ``goal`` keeping the clearance,
        else keeping only half the obstacle margin (a stuck robot may have
        to squeeze out); None: no route either way."""
        margin = self.safety.obstacle_margin
        for clearance in (margin + self.config.clearance, 0.5 * margin):
            try:
                route = PlanRoute(
                    self.Footprint(q0),
                    self.walls,
                    np.asarray(q0, dtype=float)[:NUM_BASE_POSITIONS],
                    goal,
                    goal_tolerance=tolerance,
                    clearance=clearance,
                    discs=discs,
                    holonomic=self._holonomic,
                )
            except ValueError as e:
                new.status = f"no route: {e}"
                return None
            if route is not None:
                return route
        return None

    def _Follow(self, state: RecoveryState, q0):
        """The base velocity toward the current segment's end, advancing
        past finished segments (in ``state``); None once all are done."""
        while state.segment < len(state.kinds):
            kind = state.kinds[state.segment]
            goal = state.ends[state.segment]
            nu = self._Toward(kind, goal, q0)
            if nu is not None:
                return nu
            state.segment += 1
        return None

    def _Toward(self, kind, goal, q0):
        """Base ν (body frame) driving one segment, or None once done."""
        x, y, theta = q0[:NUM_BASE_POSITIONS]
        c, s = np.cos(theta), np.sin(theta)
        e = goal[:2] - (x, y)
        ahead, aside = c * e[0] + s * e[1], -s * e[0] + c * e[1]
        turn = WrapAngle(goal[2] - theta)
        lower = self.robot.nu_lower[: NumBaseVelocities(self.robot)]
        upper = self.robot.nu_upper[: NumBaseVelocities(self.robot)]
        fraction = self.config.speed_fraction
        w_max = fraction * min(-lower[-1], upper[-1])
        v_max = fraction * min(-lower[0], upper[0])
        a_max = fraction * min(-self.robot.nudot_lower[0], self.robot.nudot_upper[0])
        nu = np.zeros(len(lower))
        if kind == TURN:
            if abs(turn) <= ANGLE_TOLERANCE:
                return None
            nu[-1] = np.clip(ANGLE_GAIN * turn, -w_max, w_max)
            return nu
        if kind == SIDEWAYS:
            sign = 1.0 if aside >= 0 else -1.0
            remaining = abs(aside)
        else:
            sign = 1.0 if kind == FORWARD else -1.0
            remaining = sign * ahead
        if remaining <= POSITION_TOLERANCE:
            return None
        speed = min(v_max, np.sqrt(2.0 * a_max * remaining), remaining / self.period)
        if kind == SIDEWAYS:
            nu[1] = sign * speed
            nu[-1] = np.clip(ANGLE_GAIN * turn, -w_max, w_max)
            return nu
        nu[0] = sign * speed
        # Steer back onto the segment's line (a unicycle's cross-track law).
        correction = ANGLE_GAIN * turn + CROSS_GAIN * aside * sign
        nu[-1] = np.clip(correction, -w_max, w_max)
        return nu


def _People(humans):
    """Tracked positions and velocities (P, 2) (none: empty)."""
    if humans is None or not len(humans.positions):
        return np.zeros((0, 2)), np.zeros((0, 2))
    p = np.asarray(humans.positions, dtype=float).reshape(-1, 2)
    v = np.nan_to_num(np.asarray(humans.velocities, dtype=float).reshape(-1, 2))
    ok = np.all(np.isfinite(p), axis=1)
    return p[ok], v[ok]
