"""The people's relaxed-ORCA model as SM²ITH predicts them (eq.
relaxed_orca_acc_argmin), on arrays: the ORCA half-planes of every person at
every step, their derivatives, the batched QPs, and the forward simulation
of everyone against a robot trajectory.

Each person has the lines of its K neighbours (RVO2's ``maxNeighbors``), of
the robot's base, and of the robot's body nearest to it (humans/robot_view.py,
as the simulated people see the robot, so an outstretched arm is avoided
too), and one line per static wall segment.
"""

import numpy as np

from sm2ith_drake.control.profiling import PROFILER
from sm2ith_drake.humans import kernels
from sm2ith_drake.humans.half_planes import obstacle_half_planes, orca_agent_half_planes
from sm2ith_drake.humans.relaxed_orca import relaxed_orca_actions
from sm2ith_drake.humans.robot_view import NearestBodies, RobotView


class OrcaModel:
    """The relaxed-ORCA prediction model of H human slots (module doc)."""

    def __init__(
        self,
        config,
        *,
        horizon: int,
        time_step: float,
        robot,
        obstacles=(),
        human_radius: float = 0.3,
    ):
        """``config`` is a PredictionConfig; ``obstacles`` (S, 2, 2) wall
        segments; ``human_radius`` the radius people are modelled with."""
        # The compiled ORCA kernels, loaded before the first control step.
        kernels.Compile()
        self.config = config
        self.N = horizon
        self.dt = time_step
        self.robot = robot
        self.num_slots = H = int(config.max_humans)
        self.segments = np.asarray(obstacles, dtype=float).reshape(-1, 2, 2)
        self.human_radius = float(human_radius)
        self.robot_radius = robot.model.base_radius
        # Human neighbours per human, then the robot's base and its body
        # nearest to the person; then one line per static segment.
        self.num_neighbors = max(0, min(int(config.max_neighbors), H - 1))
        self.num_agent_lines = self.num_neighbors + 2
        self.num_static_lines = len(self.segments)
        # Constraints (multipliers) per human: speed, acceleration, lines.
        self.num_multipliers = 2 + self.num_agent_lines + self.num_static_lines
        # The steps whose actions solve the relaxed-ORCA QP; later ones hold
        # the last of them (SICNav's ``orca_kkt_horiz``; 0: the horizon).
        steps = int(config.kkt_steps)
        self.kkt_steps = horizon if steps <= 0 else min(steps, horizon)
        K = self.num_neighbors
        # Combined radii (the nearest body's is set per person and step).
        self._radius = np.full(self.num_agent_lines, 2 * self.human_radius)
        self._radius[K] = self.human_radius + self.robot_radius
        # Each person's share of the avoidance of each line's other agent:
        # half toward people, robot_share (or its estimate) toward the robot.
        self._share = np.full((H, self.num_agent_lines), 0.5)
        self._share[:, K:] = config.robot_share

    @property
    def robot_shares(self) -> np.ndarray:
        """(H,) each slot's share of the avoidance toward the robot."""
        return self._share[:, -1].copy()

    def SetRobotShares(self, shares) -> None:
        """Sets each slot's share of the avoidance toward the robot (H,);
        None: ``config.robot_share`` for every slot."""
        if shares is None:
            shares = np.full(self.num_slots, self.config.robot_share)
        self._share[:, self.num_neighbors :] = np.asarray(shares, dtype=float)[:, None]

    def Shares(self, robot_share: float) -> np.ndarray:
        """(H, A) the lines' shares with every slot taking ``robot_share``
        of the avoidance toward the robot."""
        share = self._share.copy()
        share[:, self.num_neighbors :] = robot_share
        return share

    def RobotView(self, q, nu, kin=None) -> RobotView:
        """The robot as the people see it at the configurations q (T, n) and
        velocities ν (T, m): its base, and its bodies for the nearest-body
        agent. ``kin``: the kinematics of configurations whose first T rows
        are q, if the caller has them already."""
        robot = self.robot
        G = robot.GStack(q)  # (T, n, m)
        if kin is None:
            with PROFILER.Phase("kinematics"):
                kin = robot.CalcKinematics(q)
        T = len(q)
        return RobotView(
            q=q,
            nu=nu,
            p=q[:, :2],
            v=np.einsum("knm,km->kn", G[:, :2], nu),
            ends=kin.capsule_points[:T, ..., :2],
            ends_jacobian=kin.capsule_jacobians[:T, ..., :2, :],
            radii=robot.capsule_radii,
        )

    def AgentStates(
        self, positions, velocities, robot: RobotView, neighbors, derivatives=False
    ):
        """Each line's own and other agent's states, (T, H, A, 2) each (own
        p, own v, other p, other v), the combined radii (T, H, A) and the
        nearest robot bodies. The lines are the K neighbours', the robot
        base's, and the robot's nearest body's: the closest point on the
        axis of the capsule nearest to the person, moving with the base."""
        T, H, A = positions.shape[0], self.num_slots, self.num_agent_lines
        shape = (T, H, A, 2)
        body = NearestBodies(robot, positions, derivatives)
        robot_p = np.broadcast_to(robot.p[:, None, None], (T, H, 1, 2))
        robot_v = np.broadcast_to(robot.v[:, None, None], (T, H, 2, 2))
        nb = neighbors
        radius = np.empty((T, H, A))
        radius[:] = self._radius
        radius[..., -1] = self.human_radius + body.radius
        states = (
            np.broadcast_to(positions[:, :, None], shape),
            np.broadcast_to(velocities[:, :, None], shape),
            np.concatenate([positions[:, nb], robot_p, body.point[:, :, None]], axis=2),
            np.concatenate([velocities[:, nb], robot_v], axis=2),
        )
        return states, radius, body

    def AgentLines(self, own_p, own_v, other_p, other_v, radius, share=None):
        """ORCA agent half-planes (n, ρ) of the given states (AgentStates);
        ``share`` (H, A) overrides the lines' shares (Shares)."""
        return orca_agent_half_planes(
            own_p,
            own_v,
            other_p,
            other_v,
            radius,
            self._share if share is None else share,
            tau=self.config.tau,
            time_step=self.dt,
        )

    def StaticLines(self, positions):
        """Static half-planes (n (T, H, S, 2), ρ (T, H, S))."""
        if self.num_static_lines:
            return obstacle_half_planes(
                positions, self.segments, self.human_radius, tau_obs=self.config.tau_obs
            )
        T, H = positions.shape[:2]
        return np.zeros((T, H, 0, 2)), np.zeros((T, H, 0))

    def HalfPlanes(self, positions, velocities, robot: RobotView, neighbors):
        """Agent lines (n (T, H, A, 2), ρ (T, H, A)) and static lines
        (n (T, H, S, 2), ρ (T, H, S)) for human states of shape (T, H, 2)
        and the RobotView of the same T steps."""
        states, radius, _ = self.AgentStates(positions, velocities, robot, neighbors)
        n, rho = self.AgentLines(*states, radius)
        return (n, rho) + self.StaticLines(positions)

    @PROFILER.Timed("orca_line_derivatives")
    def HalfPlaneDerivatives(self, p, v, robot: RobotView, neighbors, h=1e-6):
        """Half-planes and their central-difference derivatives.

        Each agent line depends on its own human's state and on one other
        agent's, so all lines are differenced at once in those 8 inputs:
        dn (T, H, A, 2, 8), dρ (T, H, A, 8), in the order own p, own v,
        other p, other v (the nearest body's point is an input here; its
        own dependence on the configuration and the person's position is
        applied by the chain rule in KktBlocks). Static lines depend on the
        own position only: dn_o (T, H, S, 2, 2), dρ_o (T, H, S, 2). Also
        returns the NearestBodies."""
        states, radius, body = self.AgentStates(p, v, robot, neighbors, True)
        # All 16 perturbed copies of the inputs (±h in each of the 8
        # coordinates) and the unperturbed one, in one vectorized call.
        stacked = np.broadcast_to(np.stack(states), (17,) + np.shape(states))
        stacked = stacked.copy()  # (17, 4, T, H, A, 2)
        for which in range(4):
            for c in range(2):
                k = 2 * (2 * which + c)
                stacked[1 + k, which, ..., c] += h
                stacked[2 + k, which, ..., c] -= h
        n_all, rho_all = self.AgentLines(*np.moveaxis(stacked, 1, 0), radius)
        n, rho = n_all[0], rho_all[0]
        # (8, T, H, A, ...) → derivative axis last.
        dn = np.moveaxis((n_all[1::2] - n_all[2::2]) / (2 * h), 0, -1)
        drho = np.moveaxis((rho_all[1::2] - rho_all[2::2]) / (2 * h), 0, -1)
        if self.num_static_lines:
            q = np.broadcast_to(p, (5,) + p.shape).copy()
            for c in range(2):
                q[1 + 2 * c, ..., c] += h
                q[2 + 2 * c, ..., c] -= h
            no_all, rho_o_all = self.StaticLines(q)
            no, rho_o = no_all[0], rho_o_all[0]
            dno = np.moveaxis((no_all[1::2] - no_all[2::2]) / (2 * h), 0, -1)
            drho_o = np.moveaxis((rho_o_all[1::2] - rho_o_all[2::2]) / (2 * h), 0, -1)
        else:
            no, rho_o = self.StaticLines(p)
            T, H = p.shape[0], self.num_slots
            dno = np.zeros((T, H, 0, 2, 2))
            drho_o = np.zeros((T, H, 0, 2))
        return (n, rho, no, rho_o), (dn, drho, dno, drho_o), body

    def SolveHumanQps(self, v_pref, v, n, rho, no, rho_o, max_speed=None):
        """The relaxed-ORCA QPs (humans/relaxed_orca.py) of B humans,
        batched: their preferred and current velocities v_pref, v (B, 2) and
        half-planes (agents n (B, A, 2), ρ (B, A); static no (B, S, 2),
        ρ_o (B, S)); ``max_speed``: their speed limits (B,) (None: the
        configured one). Without the costs and stationarity residuals."""
        cfg = self.config
        return relaxed_orca_actions(
            v_pref,
            v,
            n,
            rho,
            max_speed=cfg.max_speed if max_speed is None else max_speed,
            max_accel=cfg.max_acceleration,
            time_step=self.dt,
            slack_weights=(cfg.slack_weight_acceleration, cfg.slack_weight_velocity),
            static_normals=no,
            static_offsets=rho_o,
            diagnostics=False,
        )

    def ForwardSimulate(self, slots, neighbors, robot: RobotView, p0=None):
        """Rolls the humans in ``slots`` (a HumanSlots, or the OrcaKkt
        predictor, which has the same p0, v0, v_pref, active and max_speed)
        forward with the
        standalone relaxed-ORCA QP against the robot's trajectory ``robot``
        (a RobotView of steps 0 … N−1). Returns positions (N+1, H, 2),
        actions (N, H, 2) and multipliers (N, H, R): an exact KKT point of
        every human's QP for the first ``kkt_steps`` steps, after which
        every human holds its last action (multipliers 0). ``p0`` overrides
        the slots' start positions."""
        N, H, R = self.N, self.num_slots, self.num_multipliers
        positions = np.empty((N + 1, H, 2))
        actions = np.empty((N, H, 2))
        multipliers = np.empty((N, H, R))
        positions[0] = slots.p0 if p0 is None else p0
        v = slots.v0.copy()
        active = np.nonzero(slots.active)[0]
        v_pref = slots.v_pref[active]
        max_speed = None if slots.max_speed is None else slots.max_speed[active]
        # The lines of one step at a time, compiled (HalfPlanes' arithmetic).
        A, S = self.num_agent_lines, self.num_static_lines
        n, rho = np.empty((1, H, A, 2)), np.empty((1, H, A))
        no, rho_o = np.empty((1, H, S, 2)), np.empty((1, H, S))
        nb = np.ascontiguousarray(neighbors, dtype=np.int64).reshape(H, -1)
        ends = np.ascontiguousarray(robot.ends)
        robot_p, robot_v = np.ascontiguousarray(robot.p), np.ascontiguousarray(robot.v)
        for k in range(N):
            p = positions[k]
            if k >= self.kkt_steps:
                actions[k] = actions[k - 1]
                multipliers[k] = 0.0
                positions[k + 1] = p + self.dt * actions[k]
                continue
            with PROFILER.Phase("orca_lines"):
                kernels.step_half_planes(
                    p,
                    v,
                    nb,
                    robot_p[k],
                    robot_v[k],
                    ends[k],
                    robot.radii,
                    self._radius,
                    self._share,
                    self.segments,
                    self.human_radius,
                    self.config.tau,
                    self.dt,
                    self.config.tau_obs,
                    n[0],
                    rho[0],
                    no[0],
                    rho_o[0],
                )
            a = np.zeros((H, 2))
            lam = np.zeros((H, R))
            with PROFILER.Phase("human_qps"):
                sol = self.SolveHumanQps(
                    v_pref,
                    v[active],
                    n[0, active],
                    rho[0, active],
                    no[0, active],
                    rho_o[0, active],
                    max_speed,
                )
            a[active] = sol.velocity
            lam[active] = np.concatenate(
                [
                    sol.multiplier_speed[:, None],
                    sol.multiplier_acceleration[:, None],
                    sol.multipliers_agents,
                    sol.multipliers_static,
                ],
                axis=1,
            )
            actions[k] = a
            multipliers[k] = lam
            positions[k + 1] = p + self.dt * a
            v = a
        return positions, actions, multipliers
