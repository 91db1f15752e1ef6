"""The per-solve data path of a stage QP solved by HPIPM (optional).

control/hpipm_workspace.py decides which stage QPs go to HPIPM and keeps
one HpipmStageQp per pattern; control/hpipm_structure.py finds the time
structure. This module writes a stage QP's values into HPIPM's OCP QP,
solves it and reads the solution back.

Every solve writes the same positions: the constraint and cost entries go
straight into two arrays kept between solves (the padded blocks the
dynamics are solved with, and the fields laid end to end that HPIPM's
setters read from), so that a solve allocates no array of the blocks'
size. The arrays carry nothing from one solve to the next: every position
a solve reads is written by that solve or is a constant (padding).
"""

from __future__ import annotations

import numba
import numpy as np

from sm2ith_drake.control.batched_solve import solve_batched
from sm2ith_drake.control.hpipm_library import CallTable, OcpQp
from sm2ith_drake.control.hpipm_structure import OcpStructure
from sm2ith_drake.control.profiling import PROFILER

# Stand-in for an infinite bound (its side is masked off).
_BIG = 1e9
# How far a row of fixed variables may lie outside its bounds (QP tolerance).
_CONSTANT_ROW_TOLERANCE = 1e-6


class HpipmStageQp(OcpStructure):
    """An OcpStructure with its HPIPM QP and the per-solve data path (made
    from a built OcpStructure: its attributes are taken over)."""

    def __init__(self, ws, structure: OcpStructure):
        self.__dict__.update(structure.__dict__)
        self.ws = ws
        self.last_token = None  # Solve's warm_token
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
            i, j = np.arange(rows)[:, None], np.arange(cols)[None, :]
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
        lengths = [len(e[3]) for e in entries]
        offsets = np.cumsum([0] + lengths)
        self.staging = np.zeros(max(int(offsets[-1]), 1))
        base = self.staging.ctypes.data
        calls = zip(entries, offsets[:-1], strict=True)
        self.set_calls = CallTable.Of(
            [(e[0], e[1], base + 8 * int(o)) for e, o in calls]
        )
        # One gather per solve, from all sources laid end to end (then a 0
        # and a 1: the padding and the copies' identity): every entry's
        # indices at once, each with its source's start and size.
        self.source_order = list(sizes)
        starts = np.cumsum([0] + [sizes[name] for name in self.source_order])
        zero, one = starts[-1], starts[-1] + 1
        order = [self.source_order.index(e[2]) for e in entries]
        i = np.concatenate(
            [np.zeros(0, int)] + [np.asarray(e[3], int) for e in entries]
        )
        size = np.repeat(np.array([sizes[e[2]] for e in entries], dtype=int), lengths)
        start = np.repeat(starts[order], lengths)
        self.gather_index = np.where(
            i == size, zero, np.where(i == size + 1, one, start + i)
        )
        # The fields laid end to end, then the 0 and the 1, kept between
        # solves: the cost blocks and the general rows' blocks are written
        # into their fields in place; the dynamics' blocks (and the rows'
        # next-knot blocks) into ``blocks``, with ones on the padding.
        self.flat = np.zeros(zero + 2)
        self.flat[one] = 1.0
        self.fields = {
            name: self.flat[start : start + sizes[name]]
            for name, start in zip(self.source_order, starts[:-1], strict=True)
        }
        self.blocks = np.zeros(self.size)
        self.blocks[self.pad_index] = 1.0
        self.B = self._Blocks(self.blocks)
        # Every constraint entry and both halves of the cost entries: where
        # they go (block positions) and which value (a_values, p_values).
        a_sel = np.nonzero(self.a_ok)[0]
        p1, p2 = np.nonzero(self.p_first >= 0)[0], np.nonzero(self.p_second >= 0)[0]
        na = self.ws.a_rows.size
        dest = np.concatenate([self.a_dest[a_sel], self.p_first[p1], self.p_second[p2]])
        src = np.concatenate([a_sel, na + p1, na + p2])
        # The blocks moved into their fields: (block, field).
        moved = (("GX", "C"), ("GU", "D"), ("Q", "Q"), ("R", "R"), ("S", "S"))
        in_flat = np.zeros(dest.size, dtype=bool)
        target = dest.copy()
        for block, field in moved:
            offset, size, _ = self.block_slices[block]
            m = (dest >= offset) & (dest < offset + size)
            in_flat |= m
            target[m] += starts[self.source_order.index(field)] - offset
        self.scatters = [
            (self.flat, *_Scatter(target[in_flat], src[in_flat])),
            (self.blocks, *_Scatter(dest[~in_flat], src[~in_flat])),
        ]
        # The general rows the dynamics are substituted into: reset before
        # the entries are written (they are added to).
        C, D = self.fields["C"], self.fields["D"]
        rows = np.unique(self.next_stage * mG + self.next_row)[:, None]
        self.reset = np.concatenate(
            [
                starts[self.source_order.index(f)] + rows * w + np.arange(w)
                for f, w in (("C", mX), ("D", mU))
            ],
            axis=None,
        )
        self.C = C.reshape(K, mG, mX)
        self.D = D.reshape(K, mG, mU)
        # The positions of ``flat`` a solve writes (whole fields, the
        # entries scattered into the others, the rows the dynamics are
        # substituted into); the rest keep their values (0, or the padding's
        # 0 and 1). Only those are gathered per solve, the others staged once.
        live = np.zeros(self.flat.size, dtype=bool)
        for name in ("A", "B", "b", "q", "lb", "ub", "lg", "ug", "Zl", "zl"):
            start = starts[self.source_order.index(name)]
            live[start : start + sizes[name]] = True
        for array, first, _, more, _ in self.scatters:
            if array is self.flat:
                live[first] = live[more] = True
        live[self.reset] = True
        moving = live[self.gather_index]
        self.gather_to = np.nonzero(moving)[0]
        self.gather_from = self.gather_index[moving]
        np.take(self.flat, self.gather_index, out=self.staging[: moving.size])
        # The solution: x (free states, not the copies), u, slacks.
        calls, targets, positions, offset = [], [], [], 0
        size = sum(
            len(x) + len(u) + len(s)
            for x, u, s in zip(self.X, self.U, self.soft_vars, strict=True)
        )
        self.out = np.zeros(max(size, 1))
        base = self.out.ctypes.data
        for k in range(K):
            for field, vars_, keep in (
                ("x", self.X[k], self.ns[k]),
                ("u", self.U[k], len(self.U[k])),
                ("sl", self.soft_vars[k], len(self.soft_vars[k])),
            ):
                if len(vars_):
                    calls.append((field, k, base + 8 * offset))
                    targets.append(vars_[:keep])
                    positions.append(offset + np.arange(keep))
                    offset += len(vars_)
        self.get_calls = CallTable.Of(calls)
        self.out_targets = np.concatenate(targets) if targets else np.zeros(0, int)
        self.out_positions = (
            np.concatenate(positions) if positions else np.zeros(0, int)
        )
        # A primal starting point (Solve's ``guess``): x with the copies,
        # u, the slacks (sl, scaled per solve) and su = 0 (the buffer's
        # tail, never written).
        calls, targets, offset, slack_positions = [], [], 0, []
        for k in range(K):
            for field, vars_ in (
                ("x", self.X[k]),
                ("u", self.U[k]),
                ("sl", self.soft_vars[k]),
            ):
                if len(vars_):
                    calls.append((field, k, field, vars_, offset))
                    if field == "sl":
                        slack_positions.append(offset + np.arange(len(vars_)))
                    offset += len(vars_)
        zeros = offset
        self.guess = np.zeros(zeros + max([len(v) for v in self.soft_vars] + [1]))
        base = self.guess.ctypes.data
        table = []
        for field, k, _, vars_, start in calls:
            table.append((field, k, base + 8 * start))
            targets.append(vars_)
            if field == "sl":
                table.append(("su", k, base + 8 * zeros))
        self.guess_calls = CallTable.Of(table)
        self.guess_targets = np.concatenate(targets) if targets else np.zeros(0, int)
        self.guess_slacks = (
            np.concatenate(slack_positions) if slack_positions else np.zeros(0, int)
        )

    def Solve(
        self,
        p_values,
        q,
        a_values,
        x_lower,
        x_upper,
        lower,
        upper,
        retry=True,
        warm_token=None,
        guess=None,
    ):
        """``retry``: a QP the fast mode does not solve is re-solved in
        the balanced mode. ``warm_token``: a solve given the same token as
        this pattern's last solve starts from that solve's primal solution
        (the second SQP pass of a control step from its first); any other
        starts cold, so a solve never depends on an earlier control step.
        ``guess`` (a point over z; before the token): the solve starts from
        it (HPIPM's primal warm start; every primal entry HPIPM starts from
        is written, so the solve depends on nothing earlier either)."""
        warm = warm_token is not None and warm_token is self.last_token
        self.last_token = warm_token
        ws, qp = self.ws, self.qp
        if np.any(x_lower[self.slacks] != 0):
            raise ValueError("a slack variable must have bounds [0, inf)")
        fixed_values = np.where(x_lower == x_upper, x_lower, 0.0)
        r, c = ws.a_rows, ws.a_cols
        pr, pc = ws.p_pattern
        weights = np.concatenate([a_values, p_values])
        self.flat[self.reset] = 0.0
        for array, first, first_src, more, more_src in self.scatters:
            # As a sum from 0 in entry order (duplicates summed).
            array[first] = weights[first_src] + 0.0
            np.add.at(array, more, weights[more_src])
        B, F = self.B, self.fields
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
        lin = F["q"]
        lin[:] = q
        pf = self.p_fixed
        lin += np.bincount(pr[pf], p_values[pf] * fixed_values[pc[pf]], minlength=ws.n)
        lin += np.bincount(pc[pf], p_values[pf] * fixed_values[pr[pf]], minlength=ws.n)
        p_diag = np.zeros(ws.n)
        p_diag[ws.p_diag_index] = p_values[ws.p_diagonal]
        # Dynamics of all steps at once: x⁺ = A x + B u + b.
        K, mX, mU = B["DX"].shape[0], B["DX"].shape[2], B["DU"].shape[2]
        rhs = np.concatenate(
            [B["DX"], B["DU"], lo[self.dyn_gather][:, :, None]], axis=2
        )
        solved = solve_batched(B["DN"], rhs)
        A_all = np.negative(solved[:, :, :mX], out=F["A"].reshape(K, -1, mX))
        B_all = np.negative(solved[:, :, mX : mX + mU], out=F["B"].reshape(K, -1, mU))
        b_all = solved[:, :, -1]
        F["b"][:] = b_all.ravel()
        # Substituted into the rows that read the next knot's states.
        k, slot, row = self.next_stage, self.next_slot, self.next_row
        GN = B["GN"]
        self.C[k, row] += (GN @ A_all)[k, slot]
        self.D[k, row] += (GN @ B_all)[k, slot]
        shift = np.einsum("kgd,kd->kg", GN, b_all)[k, slot]
        g_lo, g_hi = lo[self.g_gather], hi[self.g_gather]
        g_lo[k, row] -= shift
        g_hi[k, row] -= shift
        if np.any(slack_coef[self.slacks] <= 0):
            raise ValueError("a slack must enter its row positively")
        # ½ P s² + c s with the row's slack sl = coef · s.
        coef = np.where(slack_coef != 0, slack_coef, 1.0)
        np.maximum(x_lower, -_BIG, out=F["lb"])
        np.minimum(x_upper, _BIG, out=F["ub"])
        np.maximum(g_lo.ravel(), -_BIG, out=F["lg"])
        np.minimum(g_hi.ravel(), _BIG, out=F["ug"])
        np.divide(p_diag, coef**2, out=F["Zl"])
        np.divide(lin, coef, out=F["zl"])
        gather(self.staging, self.gather_to, self.flat, self.gather_from)
        qp.SetFrom(self.set_calls)
        if guess is not None:
            n_guess = self.guess_targets.size
            self.guess[:n_guess] = guess[self.guess_targets]
            self.guess[self.guess_slacks] *= coef[self.guess_targets[self.guess_slacks]]
            qp.SetSolutionFrom(self.guess_calls)
            warm = True
        with PROFILER.Phase("hpipm_ipm"):
            status, iterations = qp.Solve(warm=warm)
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


def Compile() -> None:
    """Compiles (or loads from the cache) the gather and the batched
    solve, ahead of a controller's first step (loading the solve took ~12
    ms of the first step)."""
    empty = np.zeros(0, dtype=np.int64)
    gather(np.zeros(1), empty, np.zeros(1), empty)
    solve_batched(np.eye(2)[None], np.ones((1, 2, 1)))


@numba.njit(cache=True)
def gather(dst, dst_index, src, src_index):  # pragma: no cover
    """dst[dst_index] = src[src_index], in one compiled pass."""
    for i in range(dst_index.size):
        dst[dst_index[i]] = src[src_index[i]]


def _Scatter(dest, src):
    """Entries (position, value index) split for a sum from 0 in entry
    order: each position's first entry (assigned), then the others (added
    in order; np.add.at adds in index order)."""
    _, first = np.unique(dest, return_index=True)
    is_first = np.zeros(dest.size, dtype=bool)
    is_first[first] = True
    return dest[is_first], src[is_first], dest[~is_first], src[~is_first]
