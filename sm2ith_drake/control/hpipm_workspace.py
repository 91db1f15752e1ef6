"""A stage QP solved as an optimal-control QP by HPIPM (optional).

The stage QPs of the RTI (control/rti_solver.py) have the time structure of
an MPC: every variable belongs to one knot, every row couples at most two
neighbouring knots. HPIPM (control/hpipm_library.py) solves such QPs with a
Riccati recursion on dense per-stage blocks. This module casts a stage QP
into HPIPM's form, once per sparsity pattern, and writes the values in on
every solve:

- states x_k: the variables the layout marks as states at knot k (robot q,
  ν; people's positions). Variables with equal bounds (the measured state
  at knot 0, people a predictor fixes) are constants, moved into the rows;
- inputs u_k: the variables marked as inputs of step k (robot u; people's
  actions and ORCA multipliers). An input of step k − 1 that a row of step
  k reads (the people's previous action, in the ORCA-KKT rows) is carried
  into x_k as a copy;
- dynamics: the equality rows that reach the next knot's states, solved
  for them: x_{k+1} = A_k x_k + B_k u_k + b_k;
- every other row is a general constraint of the step whose inputs it
  reads (or of its first knot), with the next knot's states substituted by
  the dynamics (the DT-CBF rows read h at k and k + 1);
- the other variables (constraint slacks) must each sit in one row, ≥ 0,
  with a diagonal cost: HPIPM's soft constraints, with the same cost.

Equality rows that are not dynamics (the stationarity of the people's
ORCA QPs) are kept as two-sided rows widened by ``equality_relaxation``
(1e-7, a tenth of the QP tolerance): HPIPM's IPM stalls on rows with equal
bounds. A stage QP that does not have this structure raises ValueError when
its pattern is built.

Measured (README, Benchmark): ~3× cheaper per QP than PIQP with 3 people,
~3× dearer with 10 (dense stage blocks ~160 wide), hence qp_solver auto.
Solutions agree with PIQP's to ~1e-3 (degenerate QPs) and in optimal value
to ~1e-6 relative.
"""

from __future__ import annotations

import numpy as np

from sm2ith_drake.control.hpipm_library import OcpQp
from sm2ith_drake.control.hpipm_structure import OcpStructure
from sm2ith_drake.control.piqp_workspace import PiqpWorkspace
from sm2ith_drake.control.profiling import PROFILER

# HPIPM's IPM settings (HPIPM's argument names) and ours.
HPIPM_DEFAULT_SETTINGS = dict(
    mode="speed_abs",
    # Measured: the fast mode solves in 18–22 iterations (p99 29 with 3
    # people, 40 with 3 + 7) or stalls; after this many a QP goes to the
    # balanced mode (hpipm; at least 100 iterations) or to PIQP (auto).
    iter_max=50,
    mu0=1e4,
    tol_stat=1e-6,
    tol_eq=1e-6,
    tol_ineq=1e-6,
    tol_comp=1e-6,
    equality_relaxation=1e-7,
    # qp_solver auto: PIQP for a pattern whose dense work per IPM iteration
    # (Σ_k w³/3 + g w², w = states + inputs, g = rows of stage k) exceeds
    # this. Measured: HPIPM is faster at ~2.4–3.5e6 (3 people), even at
    # ~1.2–1.5e7 (5) and far slower at ~7.5e7 (10).
    auto_max_work=6e6,
)
# Stand-in for an infinite bound (its side is masked off).
_BIG = 1e9
# How far a row of fixed variables may lie outside its bounds (QP tolerance).
_CONSTANT_ROW_TOLERANCE = 1e-6


class HpipmWorkspace:
    """A sparse QP with a fixed pattern and time structure, solved by HPIPM.

    Same interface as control/piqp_workspace.PiqpWorkspace, plus ``roles``:
    (role, knot) of every variable (VariableLayout.Roles). With
    ``piqp_settings`` (controller.qp_solver: auto) a pattern that lacks the
    time structure, or whose stages are too wide for dense blocks
    (``auto_max_work``), is solved by PIQP instead.
    """

    def __init__(
        self,
        *,
        num_variables: int,
        p_pattern: tuple[np.ndarray, np.ndarray],
        a_pattern: tuple[np.ndarray, np.ndarray],
        equality_rows: np.ndarray,
        settings: dict,
        roles: tuple[np.ndarray, np.ndarray],
        piqp_settings: dict | None = None,
    ):
        self.n = num_variables
        settings = {**HPIPM_DEFAULT_SETTINGS, **settings}
        self.relaxation = float(settings.pop("equality_relaxation"))
        self.max_work = float(settings.pop("auto_max_work"))
        self._piqp_settings = piqp_settings
        self._piqp = None
        self.mode = settings.pop("mode")
        self.settings = settings
        self.kind, self.knot = roles
        # P: upper triangle, duplicates merged (the values come in this order).
        rows, cols = p_pattern
        keep = rows <= cols
        pairs = np.unique(np.stack([rows[keep], cols[keep]], axis=1), axis=0)
        diag = np.arange(self.n)
        pairs = np.unique(np.concatenate([pairs, np.stack([diag, diag], 1)]), axis=0)
        self._p_rows, self._p_cols = pairs[:, 0], pairs[:, 1]
        self.p_diagonal = self._p_rows == self._p_cols
        self.p_diag_index = self._p_rows[self.p_diagonal]
        self.a_rows, self.a_cols = (np.asarray(a, dtype=int) for a in a_pattern)
        self.num_rows = int(self.a_rows.max()) + 1 if self.a_rows.size else 0
        self.equality = np.zeros(self.num_rows, dtype=bool)
        self.equality[equality_rows] = True
        self.N = int(self.knot.max())
        self._structures: dict = {}

    @property
    def p_pattern(self) -> tuple[np.ndarray, np.ndarray]:
        return self._p_rows, self._p_cols

    @PROFILER.Timed("hpipm")
    def Solve(self, p_values, q, a_values, x_lower, x_upper, lower, upper):
        """As PiqpWorkspace.Solve. Returns (x, status, iterations)."""
        pinned = x_lower == x_upper
        finite = tuple(np.isfinite(v) for v in (x_lower, x_upper, lower, upper))
        key = (pinned.tobytes(),) + tuple(f.tobytes() for f in finite)
        try:
            structure = self._structures.get(key)
            if structure is None:
                with PROFILER.Phase("hpipm_structure"):
                    structure = self._Build(pinned, finite)
                if len(self._structures) >= 4:
                    self._structures.pop(next(iter(self._structures)))
                self._structures[key] = structure
            args = (q, a_values, x_lower, x_upper, lower, upper)
            if structure is _USE_PIQP:
                piqp, order = self._Piqp()
                return piqp.Solve(p_values[order], *args)
            auto = self._piqp_settings is not None
            try:
                z, status, iterations = structure.Solve(p_values, *args, retry=not auto)
            except (ValueError, np.linalg.LinAlgError) as e:
                if not auto:
                    raise
                # Values HPIPM's form cannot take (a singular dynamics
                # block, a slack with a zero coefficient): PIQP.
                z, status, iterations = None, f"qp error: {e}", 0
            if status != "solved" and auto:
                # A QP HPIPM's fast mode did not solve (1–3 % with 3 + 7
                # people): PIQP, cheaper than HPIPM's balanced mode.
                piqp, order = self._Piqp()
                z, status, more = piqp.Solve(p_values[order], *args)
                iterations += more
            return z, status, iterations
        except (ValueError, np.linalg.LinAlgError) as e:
            return None, f"qp error: {e}", 0

    def _Build(self, pinned, finite):
        """The structure of a new pattern, or _USE_PIQP (auto)."""
        auto = self._piqp_settings is not None
        try:
            structure = OcpStructure(self, pinned, finite)
        except ValueError:
            if auto:
                return _USE_PIQP
            raise
        if auto and structure.work > self.max_work:
            return _USE_PIQP
        return _Structure(self, structure)

    def _Piqp(self):
        """The PIQP workspace of this pattern (auto), and the order of P's
        values it takes."""
        if self._piqp is None:
            piqp = PiqpWorkspace(
                num_variables=self.n,
                p_pattern=self.p_pattern,
                a_pattern=(self.a_rows, self.a_cols),
                equality_rows=np.nonzero(self.equality)[0],
                settings=dict(self._piqp_settings),
            )
            rows, cols = piqp.p_pattern
            order = np.searchsorted(
                self._p_rows * self.n + self._p_cols, rows * self.n + cols
            )
            self._piqp = piqp, order
        return self._piqp


# A pattern that auto hands to PIQP.
_USE_PIQP = object()


class _Structure(OcpStructure):
    """An OcpStructure with its HPIPM QP and the per-solve data path (made
    from a built OcpStructure: its attributes are taken over)."""

    def __init__(self, ws: HpipmWorkspace, structure: OcpStructure):
        self.__dict__.update(structure.__dict__)
        self.ws = ws
        states, K = self.states, self.N + 1
        x_lower_finite, x_upper_finite, lower_finite, upper_finite = self.finite
        self.qp = OcpQp(
            [len(x) for x in self.X],
            [len(u) for u in self.U],
            [len(i) for i in self.idxbx],
            [len(i) for i in self.idxbu],
            [len(g) for g in self.g_rows],
            [len(s) for s in self.soft],
            mode=ws.mode,
            settings=ws.settings,
        )
        # Fixed data: bound indices, soft rows, which bound sides exist.
        for k in range(K):
            x, u, g = states[k], self.U[k], self.g_rows[k]
            for name, idx, v in (("x", self.idxbx[k], x), ("u", self.idxbu[k], u)):
                if len(idx):
                    self.qp.Set("idxb" + name, k, idx)
                    self.qp.Set(f"lb{name}_mask", k, x_lower_finite[v[idx]])
                    self.qp.Set(f"ub{name}_mask", k, x_upper_finite[v[idx]])
            if len(g):
                self.qp.Set("lg_mask", k, lower_finite[g])
                self.qp.Set("ug_mask", k, upper_finite[g])
            if len(self.soft[k]):
                nb = len(self.idxbx[k]) + len(self.idxbu[k])
                ones = np.ones(len(self.soft[k]))
                self.qp.Set("idxs", k, nb + self.soft[k])
                # The rows' upper sides are off: their slacks stay 0.
                self.qp.Set("Zu", k, ones)
                self.qp.Set("zu", k, ones)
        self._Plan(self.states)

    def _Plan(self, states):
        """The per-solve data path: every field of every stage is gathered
        from a source array (padded blocks, vectors over z) into one staging
        array at a fixed address, then handed to HPIPM; the solution comes
        back into one array the same way."""
        N, K, sh, n = self.N, self.N + 1, self.shapes, self.ws.n
        mD, mX, mU = sh["DX"][1], sh["DX"][2], sh["DU"][2]
        mG = sh["GX"][1]
        sizes = dict(
            A=K * mD * mX, B=K * mD * mU, b=K * mD, Q=K * mX * mX, R=K * mU * mU,
            S=K * mU * mX, C=K * mG * mX, D=K * mG * mU, lg=K * mG, ug=K * mG,
            q=n, lb=n, ub=n, Zl=n, zl=n,
        )  # fmt: skip
        # (field, stage, source, indices into the source in HPIPM's
        # column-major order; sizes[source] and + 1 stand for 0 and 1).
        entries = []

        def Block(k, rows, cols, m1, m2):
            i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
            return ((k * m1 + i) * m2 + j).ravel(order="F")

        for k in range(K):
            X, U, ns, nX, nU = (
                self.X[k],
                self.U[k],
                self.ns[k],
                len(self.X[k]),
                len(self.U[k]),
            )
            nG = len(self.g_rows[k])
            if k < N:
                nD, nX1 = self.ns[k + 1], len(self.X[k + 1])
                if nX:
                    M = np.full((nX1, nX), sizes["A"])
                    M[:nD] = Block(k, nD, nX, mD, mX).reshape((nD, nX), order="F")
                    entries.append(("A", k, "A", M.ravel(order="F")))
                zero, one = sizes["B"], sizes["B"] + 1
                M = np.full((nX1, nU), zero)
                M[:nD] = Block(k, nD, nU, mD, mU).reshape((nD, nU), order="F")
                M[nD + np.arange(nX1 - nD), self.copy_pos[k]] = one
                entries.append(("B", k, "B", M.ravel(order="F")))
                v = np.full(nX1, sizes["b"])
                v[:nD] = k * mD + np.arange(nD)
                entries.append(("b", k, "b", v))
            if nX:
                entries.append(("Q", k, "Q", Block(k, nX, nX, mX, mX)))
                v = np.full(nX, sizes["q"])
                v[:ns] = X[:ns]
                entries.append(("q", k, "q", v))
            if nU:
                entries.append(("R", k, "R", Block(k, nU, nU, mU, mU)))
                entries.append(("r", k, "q", U))
                if nX:
                    entries.append(("S", k, "S", Block(k, nU, nX, mU, mX)))
            for name, idx, v in (
                ("x", self.idxbx[k], states[k]),
                ("u", self.idxbu[k], U),
            ):
                if len(idx):
                    entries.append(("lb" + name, k, "lb", v[idx]))
                    entries.append(("ub" + name, k, "ub", v[idx]))
            if nG:
                if nX:
                    entries.append(("C", k, "C", Block(k, nG, nX, mG, mX)))
                if nU:
                    entries.append(("D", k, "D", Block(k, nG, nU, mG, mU)))
                entries.append(("lg", k, "lg", k * mG + np.arange(nG)))
                entries.append(("ug", k, "ug", k * mG + np.arange(nG)))
            if len(self.soft[k]):
                entries.append(("Zl", k, "Zl", self.soft_vars[k]))
                entries.append(("zl", k, "zl", self.soft_vars[k]))
        total = sum(len(e[3]) for e in entries)
        self.staging = np.zeros(max(total, 1))
        base, offset = self.staging.ctypes.data, 0
        gathers: dict = {}
        self.set_calls = []
        for field, k, source, indices in entries:
            positions = offset + np.arange(len(indices))
            gathers.setdefault(source, ([], []))
            gathers[source][0].append(positions)
            gathers[source][1].append(indices)
            self.set_calls.append((self.qp.Setter(field), k, base + 8 * offset))
            offset += len(indices)
        # One gather per solve, from all sources laid end to end (then a 0
        # and a 1: the padding and the copies' identity).
        self.source_order = list(sizes)
        starts = np.cumsum([0] + [sizes[name] for name in self.source_order])
        zero, one = starts[-1], starts[-1] + 1
        index = np.zeros(offset, dtype=int)
        for name, (positions, indices) in gathers.items():
            start, size = starts[self.source_order.index(name)], sizes[name]
            for p, i in zip(positions, indices, strict=True):
                index[p] = np.where(
                    i == size, zero, np.where(i == size + 1, one, start + i)
                )
        self.gather_index = index
        # The blocks' values in one bincount: constraint entries, both
        # halves of the cost entries, ones on the dynamics' padding.
        a_sel = np.nonzero(self.a_ok)[0]
        p1, p2 = np.nonzero(self.p_first >= 0)[0], np.nonzero(self.p_second >= 0)[0]
        na, npv = self.ws.a_rows.size, self.ws.p_pattern[0].size
        self.buf_dest = np.concatenate(
            [self.a_dest[a_sel], self.p_first[p1], self.p_second[p2], self.pad_index]
        )
        self.buf_src = np.concatenate(
            [a_sel, na + p1, na + p2, np.full(self.pad_index.size, na + npv)]
        )
        # The solution: x (free states, not the copies), u, slacks.
        getter = self.qp.lib.d_ocp_qp_sol_get
        calls, targets, positions, offset = [], [], [], 0
        size = sum(
            len(x) + len(u) + len(s)
            for x, u, s in zip(self.X, self.U, self.soft_vars, strict=True)
        )
        self.out = np.zeros(max(size, 1))
        base = self.out.ctypes.data
        for k in range(K):
            for field, vars_, keep in (
                (b"x", self.X[k], self.ns[k]),
                (b"u", self.U[k], len(self.U[k])),
                (b"sl", self.soft_vars[k], len(self.soft_vars[k])),
            ):
                if len(vars_):
                    calls.append((getter, field, k, base + 8 * offset))
                    targets.append(vars_[:keep])
                    positions.append(offset + np.arange(keep))
                    offset += len(vars_)
        self.get_calls = calls
        self.out_targets = np.concatenate(targets) if targets else np.zeros(0, int)
        self.out_positions = (
            np.concatenate(positions) if positions else np.zeros(0, int)
        )

    def Solve(self, p_values, q, a_values, x_lower, x_upper, lower, upper, retry=True):
        """``retry``: a QP the fast mode does not solve is re-solved in
        the balanced mode."""
        ws, qp = self.ws, self.qp
        if np.any(x_lower[self.slacks] != 0):
            raise ValueError("a slack variable must have bounds [0, inf)")
        fixed_values = np.where(x_lower == x_upper, x_lower, 0.0)
        r, c = ws.a_rows, ws.a_cols
        pr, pc = ws.p_pattern
        weights = np.concatenate([a_values, p_values, [1.0]])
        buf = np.bincount(self.buf_dest, weights[self.buf_src], minlength=self.size)
        B = self._Blocks(buf)
        # Rows: constants from the fixed variables; equalities widened.
        f = self.a_fixed
        const = np.bincount(
            r[f], a_values[f] * fixed_values[c[f]], minlength=ws.num_rows
        )
        lo, hi = lower - const, upper - const
        # Rows of fixed variables only (not HPIPM's): within their bounds.
        e, cr = self.constant_entries, self.constant_rows
        if cr.size:
            value = np.bincount(
                r[e], a_values[e] * fixed_values[c[e]], minlength=ws.num_rows
            )[cr]
            tol = _CONSTANT_ROW_TOLERANCE
            if np.any(value < lower[cr] - tol) or np.any(value > upper[cr] + tol):
                return None, "primal_infeasible (a row of fixed variables)", 0
        relax = (lo == hi) & ~self.dyn
        lo = np.append(np.where(relax, lo - ws.relaxation, lo), 0.0)
        hi = np.append(np.where(relax, hi + ws.relaxation, hi), 0.0)
        slack_coef = np.zeros(ws.n)
        slack_coef[c[self.a_slack]] = a_values[self.a_slack]
        # Cost: linear terms from the fixed variables.
        lin = np.array(q, dtype=float)
        pf = self.p_fixed
        lin += np.bincount(pr[pf], p_values[pf] * fixed_values[pc[pf]], minlength=ws.n)
        lin += np.bincount(pc[pf], p_values[pf] * fixed_values[pr[pf]], minlength=ws.n)
        p_diag = np.zeros(ws.n)
        p_diag[ws.p_diag_index] = p_values[ws.p_diagonal]
        # Dynamics of all steps at once: x⁺ = A x + B u + b.
        mX, mU = B["DX"].shape[2], B["DU"].shape[2]
        rhs = np.concatenate(
            [B["DX"], B["DU"], lo[self.dyn_gather][:, :, None]], axis=2
        )
        solved = np.linalg.solve(B["DN"], rhs)
        A_all, B_all = -solved[:, :, :mX], -solved[:, :, mX : mX + mU]
        b_all = solved[:, :, -1]
        # Substituted into the rows that read the next knot's states.
        k, slot, row = self.next_stage, self.next_slot, self.next_row
        GN = B["GN"]
        C_all, D_all = B["GX"].copy(), B["GU"].copy()
        C_all[k, row] += (GN @ A_all)[k, slot]
        D_all[k, row] += (GN @ B_all)[k, slot]
        shift = np.einsum("kgd,kd->kg", GN, b_all)[k, slot]
        g_lo, g_hi = lo[self.g_gather], hi[self.g_gather]
        g_lo[k, row] -= shift
        g_hi[k, row] -= shift
        if np.any(slack_coef[self.slacks] <= 0):
            raise ValueError("a slack must enter its row positively")
        # ½ P s² + c s with the row's slack sl = coef · s.
        coef = np.where(slack_coef != 0, slack_coef, 1.0)
        sources = dict(
            A=A_all, B=B_all, b=b_all, Q=B["Q"], q=lin, R=B["R"], S=B["S"],
            lb=np.maximum(x_lower, -_BIG), ub=np.minimum(x_upper, _BIG),
            C=C_all, D=D_all, lg=np.maximum(g_lo, -_BIG),
            ug=np.minimum(g_hi, _BIG), Zl=p_diag / coef**2, zl=lin / coef,
        )  # fmt: skip
        flat = np.concatenate(
            [sources[name].ravel() for name in self.source_order] + [[0.0, 1.0]]
        )
        np.take(flat, self.gather_index, out=self.staging[: self.gather_index.size])
        qp.SetFrom(self.set_calls)
        with PROFILER.Phase("hpipm_ipm"):
            status, iterations = qp.Solve()
            if status != "solved" and retry:
                # Rare (a cold start): the balanced mode, on the same data.
                status, more = qp.Solve(robust=True)
                iterations += more
        qp.GetInto(self.get_calls)
        z = fixed_values
        z[self.out_targets] = self.out[self.out_positions]
        z[self.slacks] /= coef[self.slacks]
        if not np.all(np.isfinite(z)):
            return None, "nan", iterations
        return z, status, iterations
