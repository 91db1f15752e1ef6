"""Option groups of the scenario (sm2ith_drake/scenario.py): the nested ones
and the safety group, kept here so that scenario.py stays short."""

from dataclasses import dataclass


@dataclass
class RecoveryConfig:
    """The way out of a stall (control/recovery.py, not in the paper): when
    the base has come less than ``stall_distance`` nearer its target in
    ``stall_time`` (standing, or edging back and forth), more than
    ``goal_tolerance`` from it, and nobody within
    ``people_distance`` moves faster than ``people_speed``, the robot drives
    a route for its whole outline (control/route.py: back off, turn, come
    at the door straight) with its arm held, until the rest of the route is
    a drive ahead; then the MPC takes over again. Standing people are kept
    ``clearance`` away like walls; anyone moving near ends it, as do
    ``max_time`` seconds and a step the barriers would refuse."""

    enabled: bool = False
    stall_time: float = 3.0
    stall_distance: float = 0.05
    goal_tolerance: float = 0.3
    people_distance: float = 1.5
    people_speed: float = 0.25
    # Kept from walls and standing people, on top of safety.obstacle_margin (m).
    clearance: float = 0.02
    max_time: float = 20.0
    # Speeds while driving the route (fractions of the robot's limits).
    speed_fraction: float = 0.5


@dataclass
class ReciprocityConfig:
    """Each person's share of the avoidance toward the robot, estimated
    online (control/prediction/reciprocity.py, not in the paper; the paper
    fixes it at ``prediction.robot_share``).

    At every control step the last step's relaxed-ORCA QP of each person is
    solved twice, with the person taking none and all of the avoidance of
    the robot; where the two actions differ by ``min_difference`` (m/s) or
    more, the measured velocity's position between them is one observation
    of the share (in [0, 1]), weighted by the squared difference. The
    estimate is the weighted mean of the observations, forgotten with the
    time constant ``memory`` (s), and of ``prediction.robot_share``, which
    counts as ``prior_weight`` ((m/s)²) of evidence. A person about whom
    nothing is known yet is predicted with ``prediction.robot_share``.
    Observations are capped at ``max_share``: people who walk blind to the
    robot and then step aside wholly when it is close would otherwise be
    predicted to give way more than ORCA's half, early."""

    enabled: bool = False
    memory: float = 4.0
    prior_weight: float = 0.1
    min_difference: float = 0.1
    max_share: float = 1.0


@dataclass
class OvertakingConfig:
    """Who overtakes keeps clear (control/prediction/reciprocity.py, not in
    the paper): a person walking toward the moving robot from behind it,
    the two going the same way, is predicted to take ``share`` of the
    avoidance of the robot instead of ``prediction.robot_share``, as the
    rule of the road has an overtaker keep clear. "From behind" is: the
    robot's base within ``angle`` (degrees) of the person's direction of
    travel (their preferred velocity), and the base moving (faster than
    ``min_robot_speed``, m/s) within ``angle`` of the direction away from
    the person. Everyone else (head-on, crossing, a standing robot) keeps
    the configured share. With reciprocity on, the rule overrides its
    estimate while it applies. With ``wait``, such a person is also
    predicted to wait behind the robot (their preferred velocity zero while
    the rule applies), as people do behind someone going through a door.
    Without ``guard``, the safety guard (SafetyConfig.guard_steps) leaves
    such a person out while the rule applies: the robot, driving away from
    them, does not close in on them, and the guard's constant-velocity rows
    would have it evade someone it cannot outrun, as CVMM does. Once the
    rule applies to a person it keeps applying while both angles stay
    within ``keep_angle`` (when wider than ``angle``; 0: no memory), as a
    person who steps aside to pass is still behind the robot."""

    # On by default since 2026-11-28 (README, Doorway): with it SM²ITH's
    # prediction is no longer the paper's; enabled: false restores it.
    enabled: bool = True
    share: float = 1.0
    wait: bool = True
    guard: bool = False
    # Without ``guard``: still hold an overtaker measured within
    # SafetyConfig.guard_gap of the robot (as the guard holds anyone that
    # close), so the robot does not back or turn into someone at its back.
    # Measured in the doorway (README, Contact in the safe variant).
    guard_close: bool = False
    angle: float = 45.0
    keep_angle: float = 90.0
    min_robot_speed: float = 0.05
    # People slower than this (m/s) have no direction of travel.
    min_person_speed: float = 0.1


@dataclass
class SafetyConfig:
    """DT-CBF collision avoidance (eq. smith_avoid_coll)."""

    # h(x_{k+1}) ≥ (1 − γ) h(x_k), γ ∈ (0, 1].
    gamma: float = 0.3
    # Extra clearance to humans and static obstacles (m).
    human_margin: float = 0.1
    obstacle_margin: float = 0.05
    # Radius the controller assumes for a tracked human (m).
    human_radius: float = 0.3
    # Also hold the barrier over the first guard_steps steps against every
    # human moving on at its measured velocity, whatever the prediction
    # expects: an interactive model may count on people giving way, but the
    # robot never closes in on one who does not faster than the barrier
    # allows (0: off; 1: the first step only). More steps keep the plan from
    # building up speed toward a person that a later first step cannot
    # brake. Measured on the three studies (150 runs) with the predicted
    # people avoiding the robot's nearest body: with 3 steps 2 runs brushed
    # a person, by ≤ 0.34 cm; with 1 step 3 of the 60 banner/cup runs did,
    # by up to 2.3 cm. (With predicted people who avoided the base only, 3
    # steps had caused a 31 cm hit in one adversarial run: README.)
    guard_steps: int = 3
    # The guard rows' own γ (not in the paper; 0: safety.gamma). With 1 a
    # guard row asks only h ≥ 0 at each guarded step (the person moving on
    # never within the margin) instead of h decaying no faster than 1 − γ
    # per step, so it binds near the person rather than at ~1.5 m, where
    # with γ it has the plan evade a person walking on as CVMM does. 1 by
    # default since 2026-11-28 (with prediction.overtaking; README, Doorway).
    guard_gamma: float = 1.0
    # The guard rows where the robot is already inside the margin of the
    # person moving on (h_k < 0 at the linearization point; not in the
    # paper): "exit" asks h_{k+1} ≥ (1 − guard_gamma) h_k (with
    # guard_gamma 1: out at once), "hold" asks h_{k+1} ≥ h_k (no closer).
    # "hold" measured on 2026-11-29 and not kept: in the Stretch 3's
    # doorway the robot closed in during a contact in more runs (53 against
    # 43 of 120; docs/experiments/guard-hold-c5f5f76).
    guard_inside: str = "exit"
    # Speed-and-separation monitoring of the base's turn (not in the paper;
    # `safe` only, every method alike; control/separation.py): near a
    # tracked person the yaw rate is bounded so that every body could stop
    # turning before it reaches the person's margin (turning away is free),
    # |ω| ≤ √(2αθ), θ the last clear angle of its braking sweep, but
    # never below turn_speed_floor (rad/s). The default since 2026-11-29
    # (twelfth session). Measured on SM²ITH's `safe` runs among ORCA
    # people, 30 seeds, 420 runs, paired with it off
    # (docs/experiments/turn-monitoring/seeds-30-restore): runs with
    # contact 86 against 100, the robot closing in during a contact 44
    # against 56, arrivals 370 against 372, 1 failed step against none.
    # A floor of 0.2 measured on the final controller: fewer contacts in
    # the Stretch 3's doorway on the final re-run's seeds, not on 30 new
    # ones, new ones on the Ridgeback–UR10 (docs/experiments/
    # turn-floor-b55d319); 0.4 kept.
    turn_monitoring: bool = True
    turn_speed_floor: float = 0.4
    # Hold the guard over at least the base's stopping time (not in the
    # paper): max(guard_steps, ⌈stopping time / time_step⌉) steps, where the
    # stopping time is the slowest translational axis's top speed over its
    # acceleration limit (Ridgeback–UR10 1.1 s: 6 steps of 0.2 s; Stretch
    # 3 0.6 s: 3, as guard_steps, so the same controller). A plan that
    # counts on a person giving way can otherwise build up speed toward
    # them that the guarded steps cannot brake: two traced doorway contacts
    # of the Ridgeback–UR10 at its top speed (241 and 260 mm). Measured on
    # its SM²ITH `safe` runs (180, paired): robot-closing contacts 2 → 0,
    # clearance up, time to goal up by 0.2–3 s (README, Contact in the
    # safe variant). The default since 2026-11-27; false: guard_steps.
    guard_stopping_time: bool = True
    # Whom the guard holds: a person whose measured position has deviated
    # from the last plan's prediction for them by more than guard_deviation
    # (m) at a control step, for the guard_hold (s) after it. People who
    # move as predicted keep the interactive prediction alone, so the guard
    # does not turn SM²ITH into CVMM. React predicts nothing and CVMM's
    # prediction already is the guard's motion, so neither is guarded.
    # 0: every person, always (the guard of earlier versions).
    guard_deviation: float = 0.05
    guard_hold: float = 1.0
    # The guard also holds, for guard_hold, a person whose measured gap to
    # the robot's nearest body (surface to surface) is below guard_gap (m),
    # so a person already near the robot is not closed in on by trusting a
    # prediction that has them give way (0: off). A person who keeps not
    # yielding by less than guard_deviation per step is otherwise never
    # held, and the plan can sweep into them: traced in the doorway, the
    # Stretch 3 turning in place toward the door swept its gripper 37 mm
    # into a person standing at the jamb, whom the model had stepping back
    # (README, Contact in the safe variant). 0.2 by default since
    # 2026-11-28 (the barrier's 0.1 m margin and as much again); measured
    # on the Stretch 3 doorway, 30 seeds per count, `safe`: with instructed
    # people 102 arrivals of 120 against 104 and no contact against 1; with
    # ORCA people 71 against 75 and 81 runs with contact against 82 (all
    # n.d.; docs/experiments/guard-gap-2026-11-28). 0.1 (inside the margin
    # only) did not reach that contact.
    guard_gap: float = 0.2
    # With guard_approach > 0 (m/s), the guard gap holds only a person
    # walking toward the robot: whose measured velocity, held for one
    # control period, shrinks their gap to the robot's nearest body faster
    # than guard_approach (not in the paper; 0: everyone within the gap).
    # 0.2 by default since 2026-12-03: held within the gap, a person
    # standing at a door jamb or walking away kept the Stretch 3 out of
    # the door. Measured on its doorway among ORCA people, `safe`, 30
    # seeds per count: arrivals 78 of 120 against 68 (+0.083 [+0.008,
    # +0.158]), at or above CVMM and React at every count; runs with
    # contact 83 against 79 and the robot closing in 46 against 40 (n.d.);
    # the pursuer 0 contacts in 10 as before; pick-and-place's contacts
    # unchanged (docs/experiments/guard-approach-b55d319). In the final
    # re-run on one machine (docs/experiments/final-e4dec26) that cell
    # gave SM²ITH 75 arrivals against CVMM's 62 and React's 60.
    guard_approach: float = 0.2
    # Optional (0: off, the default): also hold the barrier over the first
    # static_guard_steps steps against every tracked person standing still
    # where measured, for SM²ITH and CVMM (React's barrier already is
    # this), so a prediction that has a person move away never lets the
    # robot close in on where they are now faster than the barrier allows.
    # Measured with 2 steps on the doorway (Stretch 3, ORCA people, seeds
    # 0–9, 1/2/3/5 people): SM²ITH reached the goal in 20 of 40 runs (21
    # without), touched someone in 21 (19) and closed in itself during a
    # contact in 14 (16); CVMM 23/21/6 (27/23/7). The contacts
    # it left are squeezes between two people or a person and a wall, where
    # every barrier cannot hold at once (README, "Contact in the safe
    # variant"). Not the default.
    static_guard_steps: int = 0
    # Optional (0: off, the default; `safe` only, every method alike): every
    # tracked person measured within no_closer_gap (m, surface to surface)
    # of the robot's nearest body is held no closer where they stand, over
    # the base's stopping time: the nearest capsule's barrier against them
    # must not fall from step to step (h_{k+1} ≥ h_k), under an exact
    # penalty of no_closer_slack_weight per metre (above a person's
    # margin, below a wall). In a jam the robot then stands rather than
    # edging into one person to get away from another (README, Contact in
    # the safe variant).
    no_closer_gap: float = 0.0
    no_closer_slack_weight: float = 1e5
    # no_closer_speed (m/s) 0: every person within no_closer_gap is held;
    # > 0: only those measured slower than it, so a person walking past or
    # away does not hold the robot where they were (nineteenth
    # session). Measured with 0.2 on the Stretch 3's doorway (SM²ITH, ORCA
    # people, 120 runs): as the gap alone, fewer runs closing in but not
    # the arrivals or freezing time back; off (docs/experiments/
    # no-closer-b55d319).
    no_closer_speed: float = 0.0
    # Optional (0: off, the default; `safe` only, every method alike): the
    # exact-penalty weight (per metre) of the barrier slacks of a tracked
    # person not walking toward the robot (measured velocity toward the
    # base below approach_speed, m/s), in place of human_slack_weight. In a
    # jam between two people, where every barrier cannot hold at once, the
    # plan then gives up the margin of the one walking into the robot
    # rather than edge into one who stands (traced in the doorway,
    # docs/experiments/final-b55d319/contact-kinds). Below a wall's.
    # Measured with 1e5 and 5e5 (Stretch 3 doorway, SM²ITH, ORCA people,
    # 120 paired runs): the robot closes in as often, at 5e5 farther; off
    # (docs/experiments/still-slack-b55d319).
    still_slack_weight: float = 0.0
    approach_speed: float = 0.05
    # "safe": the shipped safety mechanism on top of the paper's DT-CBF (the
    # guards above); "paper": the paper's formulation, the DT-CBF against the
    # prediction only (guard_steps and static_guard_steps ignored). Studies
    # run both variants.
    mode: str = "safe"
    # Exact-penalty weights (per metre) of the barrier rows' slacks against
    # people and walls; walls must outrank people (README, Doorway).
    human_slack_weight: float = 1e4
    obstacle_slack_weight: float = 1e6
    # The barrier rows where the plan is already inside a barrier's margin
    # (h_k < 0 at the linearization point), which only plans that need
    # slack reach: "decay" keeps the paper's row h_{k+1} ≥ (1 − γ) h_k
    # there too, so a plan that is inside pays per step only for going
    # deeper faster than the decay (a squeezed plan may sweep an arm
    # through a person's margin); "exit" asks h_{k+1} ≥ 0, so the slack
    # paid is the depth at every step (README, Doorway).
    inside_barrier: str = "decay"
    # Optional (off by default; "safe" mode only): the backup-trajectory
    # filter (control/backup.py). A solved step's command, held for one
    # period and followed by braking to a standstill, is checked against
    # every tracked person moving on at the measured velocity (React's:
    # held where measured) and every wall; where it would come within
    # backup_margin (m) of a person's disc
    # (human_radius), or within half the obstacle margin of a wall, and
    # nearer than braking at once would, the robot brakes at once instead
    # (README, "Contact in the safe variant").
    backup_filter: bool = False
    backup_margin: float = 0.1
