"""What the human predictor remembers between control steps, and the pure
functions that update it.

The MPC has a fixed number H of human slots (``max_humans``). Tracked people
are assigned to slots by id and kept there while they are tracked, so warm
starts stay aligned; empty slots are parked far away, where no constraint is
active. Each person's preferred velocity (the ORCA model's v_pref) is their
measured velocity, optionally low-pass filtered, or the intent a simulation
knows. Each person reacts to at most K others (RVO2's ``maxNeighbors``),
chosen with hysteresis so the sets (and the QP's pattern) do not flicker.

All of it lives in the HumanPredictor's Context as a :class:`PredictorState`.
"""

from dataclasses import dataclass, field

import numpy as np

from sm2ith_drake.humans.messages import HumanEstimate, HumanIntents

# Where empty human slots are parked (m): far from anything, finite.
PARKED = np.array([1.0e3, 1.0e3])
_EPS = 1e-9


def ParkedPositions(num_slots: int) -> np.ndarray:
    """(H, 2) parking spots of empty slots, 10 m apart."""
    return np.tile(PARKED, (num_slots, 1)) + 10.0 * np.arange(num_slots)[:, None]


def DefaultNeighbors(num_slots: int, num_neighbors: int) -> np.ndarray:
    """(H, K): every slot's first K other slots (the initial sets)."""
    H, K = num_slots, num_neighbors
    return np.array(
        [[i for i in range(H) if i != j][:K] for j in range(H)], dtype=int
    ).reshape(H, K)


@dataclass
class PredictorState:
    """The predictor's persistent state (held in the Context)."""

    # Human id per slot, −1 = empty.
    slot_ids: np.ndarray
    # neighbors[j]: the slots whose ORCA lines slot j has (sorted).
    neighbors: np.ndarray
    # The preferred velocity of every tracked human, by id.
    preferred_velocities: dict = field(default_factory=dict)
    # Control steps each guarded human stays guarded, by id.
    guard_steps: dict = field(default_factory=dict)
    # The evidence on each person's share of the avoidance toward the robot,
    # by id: (Σ w·s, Σ w) (control/prediction/reciprocity.py).
    share_evidence: dict = field(default_factory=dict)
    # The last prediction made (for drawing; not used to predict).
    last_prediction: object = None


@dataclass
class HumanSlots:
    """The tracked people in their slots at one control step."""

    slot_ids: np.ndarray  # (H,) id, −1 = empty
    active: np.ndarray  # (H,) bool
    p0: np.ndarray  # (H, 2) positions (parked where empty)
    v0: np.ndarray  # (H, 2) velocities (0 where empty)
    v_pref: np.ndarray  # (H, 2) preferred velocities (0 where empty)
    # The model's speed limit per slot (H,) (PersonalMaxSpeeds); None: the
    # configured max_speed.
    max_speed: np.ndarray | None = None
    dropped: int = 0  # tracked people neither in a slot nor an extra
    # People without a slot whom the barrier still keeps out of (E of them,
    # PredictionConfig.max_extra_humans): id (−1: none), position, velocity.
    extra_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    extra_p0: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    extra_v0: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


def FilterPreferredVelocities(
    previous: dict,
    estimate: HumanEstimate | None,
    intents: HumanIntents | None,
    alpha: float,
) -> dict:
    """Each tracked human's v_pref by id: the measured velocity low-pass
    filtered with gain ``alpha`` (1: the latest measurement; a new id starts
    from its measurement; a non-finite measurement keeps the previous
    value), or the intent the simulation knows (``intents``, NaN: unknown)."""
    if estimate is None:
        return {}
    known = {}
    if intents is not None:
        known = {
            int(i): v
            for i, v in zip(intents.ids, intents.preferred_velocities, strict=True)
            if np.all(np.isfinite(v))
        }
    out = {}
    for hid, v in zip(estimate.ids, estimate.velocities, strict=True):
        hid = int(hid)
        if hid in known:
            out[hid] = np.array(known[hid], dtype=float)
            continue
        old = previous.get(hid)
        if not np.all(np.isfinite(v)):
            if old is not None:
                out[hid] = old
            continue
        out[hid] = np.array(v, dtype=float) if old is None else old + alpha * (v - old)
    return out


def PersonalMaxSpeeds(slots: HumanSlots, config) -> np.ndarray:
    """(H,) each slot's speed limit in the ORCA model: ``config.max_speed``,
    or with ``config.max_speed_factor`` > 0 that factor times the person's
    measured speed (the larger norm of their measured and preferred
    velocities), within [max_speed_floor, max_speed]."""
    H = len(slots.slot_ids)
    out = np.full(H, float(config.max_speed))
    if config.max_speed_factor > 0:
        speed = np.maximum(
            np.linalg.norm(slots.v0, axis=1), np.linalg.norm(slots.v_pref, axis=1)
        )
        own = np.clip(
            config.max_speed_factor * speed, config.max_speed_floor, config.max_speed
        )
        out = np.where(slots.active, own, out)
    return out


def AssignSlots(
    previous_slot_ids: np.ndarray,
    estimate: HumanEstimate | None,
    preferred_velocities: dict,
    *,
    distances: np.ndarray | None = None,
    hysteresis: float = 0.0,
    num_extra: int = 0,
) -> HumanSlots:
    """Assigns the tracked humans to slots, stable by id. People with a
    non-finite position, velocity or v_pref are left out; a person's v_pref
    defaults to the measured velocity.

    With more people than slots, ``distances`` (each estimate entry's
    distance to the robot; None: unknown) decides who has one: free slots go
    to the nearest first, and someone without a slot takes the farthest
    incumbent's when nearer by more than ``hysteresis``. The nearest
    ``num_extra`` of the rest are the extras; anyone else is dropped."""
    estimate = estimate or HumanEstimate()
    H = len(previous_slot_ids)
    pref = np.array(
        [
            preferred_velocities.get(int(i), v)
            for i, v in zip(estimate.ids, estimate.velocities, strict=True)
        ]
    ).reshape(-1, 2)
    ok = (
        np.all(np.isfinite(estimate.positions), axis=1)
        & np.all(np.isfinite(estimate.velocities), axis=1)
        & np.all(np.isfinite(pref), axis=1)
    )
    ids = estimate.ids[ok]
    pos, vel, pref = estimate.positions[ok], estimate.velocities[ok], pref[ok]
    dist = np.zeros(len(ids))
    if distances is not None:
        dist = np.asarray(distances, dtype=float)[ok]
        dist = np.where(np.isfinite(dist), dist, np.inf)
    slot_ids = np.array(previous_slot_ids, dtype=int)
    slot_ids[~np.isin(slot_ids, ids)] = -1
    # Without a slot, nearest first (in estimate order without overflow).
    waiting = [i for i in range(len(ids)) if ids[i] not in slot_ids]
    overflow = len(ids) > H
    if overflow:
        waiting.sort(key=lambda i: dist[i])
    for i in list(waiting):
        free = np.nonzero(slot_ids < 0)[0]
        if ids[i] in slot_ids:  # a repeated id: its first entry has the slot
            waiting.remove(i)
        elif free.size:
            slot_ids[free[0]] = ids[i]
            waiting.remove(i)
    where = {}  # id → its first entry
    for i, hid in enumerate(ids):
        where.setdefault(int(hid), i)
    if overflow and waiting and H:
        for i in list(waiting):
            held = [where[int(hid)] for hid in slot_ids]
            farthest = max(range(H), key=lambda s: dist[held[s]])
            if dist[i] + hysteresis < dist[held[farthest]]:
                waiting.remove(i)
                waiting.append(held[farthest])
                slot_ids[farthest] = ids[i]
        waiting.sort(key=lambda i: dist[i])
    p0 = ParkedPositions(H)
    v0 = np.zeros((H, 2))
    v_pref = np.zeros((H, 2))
    for slot, hid in enumerate(slot_ids):
        if hid >= 0:
            i = where[int(hid)]
            p0[slot], v0[slot], v_pref[slot] = pos[i], vel[i], pref[i]
    E = max(int(num_extra), 0)
    extra = waiting[:E]
    extra_ids = np.full(E, -1)
    extra_p0 = np.zeros((E, 2))
    extra_v0 = np.zeros((E, 2))
    extra_ids[: len(extra)] = ids[extra]
    extra_p0[: len(extra)] = pos[extra]
    extra_v0[: len(extra)] = vel[extra]
    return HumanSlots(
        slot_ids=slot_ids,
        active=slot_ids >= 0,
        p0=p0,
        v0=v0,
        v_pref=v_pref,
        dropped=len(waiting) - len(extra),
        extra_ids=extra_ids,
        extra_p0=extra_p0,
        extra_v0=extra_v0,
    )


def UpdateGuards(
    previous: dict,
    estimate: HumanEstimate | None,
    predicted: dict,
    *,
    deviation: float,
    hold_steps: int,
    close=(),
) -> dict:
    """Control steps each tracked human stays guarded (SafetyConfig), by id:
    ``hold_steps`` from a step where their measured position is more than
    ``deviation`` from ``predicted`` (id → the position the last plan
    predicted for now; people it did not predict are not judged) or where
    they are in ``close`` (the ids measured within SafetyConfig.guard_gap of
    the robot), counting down otherwise; every person, always, with
    deviation 0."""
    close = {int(i) for i in close}
    if estimate is None:
        return {}
    out = {}
    for hid, p in zip(estimate.ids, estimate.positions, strict=True):
        hid = int(hid)
        left = max(previous.get(hid, 0) - 1, 0)
        expected = predicted.get(hid)
        if deviation <= 0 or hid in close:
            left = hold_steps
        elif (
            expected is not None
            and np.all(np.isfinite(p))
            and np.linalg.norm(np.asarray(p) - expected) > deviation
        ):
            left = hold_steps
        if left > 0:
            out[hid] = left
    return out


def PredictedNow(solution, elapsed: float, time_step: float) -> dict:
    """id → where ``solution`` (an MpcSolution or None; a failed one
    predicts nothing) predicted each person ``elapsed`` s after it was
    made, interpolated along its predicted positions."""
    if solution is None or not getattr(solution, "success", False):
        return {}
    positions = getattr(solution, "human_predictions", None)
    ids = getattr(solution, "human_slot_ids", None)
    if positions is None or ids is None or len(positions) < 2:
        return {}
    s = min(max(elapsed / time_step, 0.0), len(positions) - 1.0)
    k = min(int(s), len(positions) - 2)
    at = positions[k] + (s - k) * (positions[k + 1] - positions[k])
    return {int(hid): at[j] for j, hid in enumerate(ids) if hid >= 0}


def SelectNeighbors(
    previous: np.ndarray,
    slots: HumanSlots,
    *,
    horizon_time: float,
    hysteresis: float,
) -> np.ndarray:
    """Each slot's K neighbours (K = previous.shape[1]): the humans that come
    closest to it within the horizon if everyone keeps their velocity
    (active humans before empty slots), incumbents favoured by
    ``hysteresis``."""
    H, K = previous.shape
    if K == 0:
        return np.zeros((H, 0), dtype=int)
    if K == H - 1:
        return previous
    p0, v0 = slots.p0, slots.v0
    r = p0[None, :] - p0[:, None]  # (H, H, 2): i relative to j
    w = v0[None, :] - v0[:, None]
    t = np.clip(
        -np.sum(r * w, axis=-1) / np.maximum(np.sum(w * w, axis=-1), _EPS),
        0.0,
        horizon_time,
    )
    d = np.linalg.norm(r + t[..., None] * w, axis=-1)
    d[:, ~slots.active] += 1e6  # empty slots only as fillers
    np.fill_diagonal(d, np.inf)
    rows = np.arange(H)[:, None]
    d[rows, previous] -= hysteresis
    chosen = np.argsort(d, axis=1, kind="stable")[:, :K]
    return np.sort(chosen, axis=1)
