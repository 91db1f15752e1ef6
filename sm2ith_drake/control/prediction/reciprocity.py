"""Each person's share of the avoidance toward the robot, estimated from how
they moved (``prediction.reciprocity``; not in the paper).

The paper's model has every person take a fixed share of the avoidance of
the robot (ORCA's reciprocity, ``prediction.robot_share`` = 0.5). People who
walk a route blind to the robot until it is close take none of it until
then; a model that counts on them giving way plans into them and then waits
(README, Doorway). The share enters each person's robot lines linearly: the
ORCA half-plane toward the robot is n·a ≥ n·(v + s u), so the relaxed-ORCA
QP's action a(s) moves, while one line is active, on the segment from a(0)
to a(1). Each control step, for every person who was in a slot at the last
step and is measured now:

- the last step's QP (its states, preferred velocity, neighbours, walls and
  the robot where it was then) is solved with s = 0 and s = 1;
- where ‖a(1) − a(0)‖ ≥ ``min_difference`` (the robot mattered to the
  person then), the measured velocity's projection on that segment,
  s = (v_now − a(0))·d / ‖d‖² clipped to [0, ``max_share``] with
  d = a(1) − a(0), is one observation, weighted w = ‖d‖²;
- the evidence (Σ w·s, Σ w) decays by exp(−period / ``memory``) per step,
  and the estimate is (w₀ s₀ + Σ w·s) / (w₀ + Σ w), with s₀ =
  ``robot_share`` and w₀ = ``prior_weight``.

A person who walks on while the robot is in their way (s → 0) is then
predicted to do so; one who yields as ORCA does keeps s ≈ 0.5. The evidence
is kept by id in the predictor's state (the Context), so a cloned Context
reproduces it.
"""

import numpy as np

from sm2ith_drake.control.prediction.base import PredictionMaxSpeeds
from sm2ith_drake.humans.messages import HumanEstimate, HumanPrediction


def _Measured(estimate: HumanEstimate | None) -> dict:
    """Finite measured velocities by id."""
    if estimate is None:
        return {}
    v = np.asarray(estimate.velocities, dtype=float).reshape(-1, 2)
    return {
        int(i): v[k] for k, i in enumerate(estimate.ids) if np.all(np.isfinite(v[k]))
    }


def ShareObservations(
    model,
    last: HumanPrediction | None,
    estimate: HumanEstimate | None,
    min_difference: float,
    max_share: float = 1.0,
) -> dict:
    """The observations {id: (s, w)} this step gives (module doc), s capped
    at ``max_share``: ``model`` is the OrcaModel, ``last`` the prediction
    made one control step ago (with its ``robot_state``), ``estimate`` the
    people measured now."""
    if last is None or last.robot_state is None or last.robot_shares is None:
        return {}
    measured = _Measured(estimate)
    slots = [
        j
        for j in np.nonzero(np.asarray(last.active, dtype=bool))[0]
        if int(last.slot_ids[j]) in measured
    ]
    p = np.asarray(last.positions, dtype=float)[0]
    v = np.asarray(last.velocities, dtype=float)
    v_pref = np.asarray(last.preferred_velocities, dtype=float)
    if not slots or not (
        np.all(np.isfinite(p[slots]))
        and np.all(np.isfinite(v[slots]))
        and np.all(np.isfinite(v_pref[slots]))
    ):
        return {}
    q, nu = last.robot_state
    robot = model.RobotView(np.asarray(q)[None], np.asarray(nu)[None])
    neighbors = np.asarray(last.neighbors, dtype=int).reshape(model.num_slots, -1)
    states, radius, _ = model.AgentStates(p[None], v[None], robot, neighbors)
    no, rho_o = model.StaticLines(p[None])
    actions = []
    for share in (0.0, 1.0):
        n, rho = model.AgentLines(*states, radius, share=model.Shares(share))
        sol = model.SolveHumanQps(
            v_pref[slots],
            v[slots],
            n[0, slots],
            rho[0, slots],
            no[0, slots],
            rho_o[0, slots],
            PredictionMaxSpeeds(last, model.config.max_speed)[slots],
        )
        actions.append(sol.velocity)
    a0, a1 = actions
    d = a1 - a0
    weight = np.sum(d * d, axis=1)
    now = np.array([measured[int(last.slot_ids[j])] for j in slots])
    out = {}
    for b, j in enumerate(slots):
        if weight[b] >= min_difference**2:
            s = (now[b] - a0[b]) @ d[b] / weight[b]
            s = float(np.clip(s, 0.0, min(max_share, 1.0)))
            out[int(last.slot_ids[j])] = (s, float(weight[b]))
    return out


def UpdateEvidence(previous: dict, observations: dict, ids, decay: float) -> dict:
    """The evidence {id: (Σ w·s, Σ w)} of the people ``ids`` (those tracked
    now; the others are forgotten) after one step: the previous evidence
    times ``decay``, plus this step's ``observations``."""
    out = {}
    for i in ids:
        i = int(i)
        total, weight = previous.get(i, (0.0, 0.0))
        total, weight = decay * total, decay * weight
        if i in observations:
            s, w = observations[i]
            total, weight = total + w * s, weight + w
        out[i] = (total, weight)
    return out


def EstimatedShares(evidence: dict, slot_ids, prior: float, prior_weight: float):
    """(H,) each slot's estimated share (the prior for an empty slot or a
    person without evidence)."""
    shares = np.full(len(slot_ids), float(prior))
    for j, i in enumerate(slot_ids):
        total, weight = evidence.get(int(i), (0.0, 0.0))
        if weight > 0.0:
            shares[j] = (prior_weight * prior + total) / (prior_weight + weight)
    return shares


def Overtaking(positions, preferred, active, robot_p, robot_v, config, kept=None):
    """(H,) whether each active slot's person overtakes the robot: the
    robot's base ``robot_p`` within ``config.angle`` (an OvertakingConfig)
    of the person's direction of travel (``preferred`` (H, 2), faster than
    ``config.min_person_speed``), and the base's velocity ``robot_v``
    (faster than ``config.min_robot_speed``) within ``config.angle`` of the
    direction away from the person. ``positions`` (H, 2) are the people's.
    Slots in ``kept`` (H,) (the people the rule applied to at the last
    step) are judged with ``config.keep_angle`` instead where it is wider:
    someone who stepped aside to pass the robot stays behind it."""
    active = np.asarray(active, dtype=bool)
    robot_p = np.asarray(robot_p, dtype=float)[:2]
    robot_v = np.asarray(robot_v, dtype=float)[:2]
    robot_speed = float(np.linalg.norm(robot_v))
    if not (np.isfinite(robot_speed) and robot_speed > config.min_robot_speed):
        return np.zeros(len(active), dtype=bool)
    angle = np.full(len(active), float(config.angle))
    if kept is not None:
        angle = np.where(kept, max(config.angle, config.keep_angle), angle)
    cos = np.cos(np.radians(angle))
    d = robot_p[None] - np.asarray(positions, dtype=float)
    dist = np.linalg.norm(d, axis=1)
    v = np.asarray(preferred, dtype=float)
    speed = np.linalg.norm(v, axis=1)
    with np.errstate(invalid="ignore"):
        ahead = np.sum(d * v, axis=1) >= cos * dist * speed
        away = d @ robot_v >= cos * dist * robot_speed
    return (
        active
        & np.isfinite(dist)
        & (dist > 1e-9)
        & (speed > config.min_person_speed)
        & ahead
        & away
    )
