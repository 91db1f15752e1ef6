"""The time structure of a stage QP, as HPIPM's OCP QP needs it.

See control/hpipm_workspace.py: which variables are states, inputs and
slacks of which stage, which rows are dynamics and which general rows of
which stage, the copies of last step's inputs, and where every constraint
and cost entry goes in the padded per-stage blocks. Built once per sparsity
pattern (and set of fixed variables and finite bounds); raises ValueError
for a QP without this structure.
"""

from __future__ import annotations

import numpy as np

from sm2ith_drake.control.groups import INPUT, OTHER, STATE


class OcpStructure:
    """The OCP form of a pattern for one set of fixed variables and finite
    bounds (module doc). The per-stage blocks are padded to common sizes,
    so that the dynamics are solved and substituted for all stages at once.

    ``ws`` gives the pattern: n, N, kind, knot (VariableLayout.Roles),
    a_rows, a_cols, num_rows, equality, p_pattern."""

    def __init__(self, ws, pinned, finite):
        N, kind, knot, n = ws.N, ws.kind, ws.knot, ws.n
        self.ws, self.N = ws, N
        x_lower_finite, x_upper_finite, lower_finite, upper_finite = finite
        free = ~pinned
        state = (kind == STATE) & free
        inp = (kind == INPUT) & free
        other = (kind == OTHER) & free
        r, c = ws.a_rows, ws.a_cols
        nr = ws.num_rows
        # Slacks: one row each, bounds [0, ∞), no coupling cost.
        if np.any(np.bincount(c[other[c]], minlength=n)[other] != 1):
            raise ValueError("a slack variable must sit in exactly one row")
        if np.any(x_upper_finite[other]) or not np.all(x_lower_finite[other]):
            raise ValueError("a slack variable must have bounds [0, inf)")
        self.slacks = np.nonzero(other)[0]
        pr, pc = ws.p_pattern
        off = pr != pc
        if np.any(other[pr[off]] | other[pc[off]]):
            raise ValueError("a slack variable has a coupling cost")
        if np.any(np.bincount(r[other[c]], minlength=nr) > 1):
            raise ValueError("a row holds more than one slack variable")
        slack_of_row = np.full(nr, -1)
        slack_of_row[r[other[c]]] = c[other[c]]
        # The step of every row: of the inputs it reads, else its first knot
        # (fixed variables included: the measured state is knot 0's).
        big = N + 10
        e_state, e_input = kind[c] == STATE, kind[c] == INPUT
        max_input = np.full(nr, -1)
        np.maximum.at(max_input, r[e_input], knot[c[e_input]])
        min_input = np.full(nr, big)
        np.minimum.at(min_input, r[e_input], knot[c[e_input]])
        min_state = np.full(nr, big)
        np.minimum.at(min_state, r[e_state], knot[c[e_state]])
        max_state = np.full(nr, -1)
        np.maximum.at(max_state, r[e_state], knot[c[e_state]])
        step = np.where(max_input >= 0, max_input, min_state)
        # A row whose variables are all fixed (an empty slot's KKT rows) is
        # a constant: checked against its bounds at each solve, not handed
        # to HPIPM, whose IPM stalls on a row without free variables (it
        # ended 93 % of the stage QPs with 1 person in 3 slots at min_step).
        has_free = np.zeros(nr, dtype=bool)
        has_free[r[free[c]]] = True
        constant = (step < big) & ~has_free
        self.constant_rows = np.nonzero(constant)[0]
        self.constant_entries = np.nonzero(constant[r])[0]
        used = (step < big) & has_free
        if np.any(~used & (slack_of_row >= 0)):
            raise ValueError("a slack sits in a row without states or inputs")
        if np.any(used & ((max_state > step + 1) | (min_state < step))):
            raise ValueError("a row spans more than two knots")
        if np.any(used & (min_input < step - 1)):
            raise ValueError("a row reads inputs of more than two steps")
        # Dynamics: equality rows that give free states of the next knot.
        free_next = np.zeros(nr, dtype=bool)
        e = state[c] & (knot[c] == step[r] + 1)
        free_next[r[e]] = True
        dyn = ws.equality & used & free_next
        soft_row = used & ~dyn & (slack_of_row >= 0)
        if np.any(soft_row & upper_finite):
            raise ValueError("a slack must relax a row's lower bound only")
        self.dyn = dyn
        # Copies: inputs of step k − 1 read by rows of step k.
        prev = inp[c] & (knot[c] == step[r] - 1) & used[r]
        copies = [np.unique(c[prev & (step[r] == k)]) for k in range(N + 2)]
        states = [np.nonzero(state & (knot == k))[0] for k in range(N + 1)]
        self.X = [np.concatenate([states[k], copies[k]]) for k in range(N + 1)]
        self.ns = [len(x) for x in states]
        self.U = [np.nonzero(inp & (knot == k))[0] for k in range(N + 1)]
        if len(self.U[N]) or np.any(inp & (knot > N)):
            raise ValueError("inputs at the last knot")
        self.dyn_rows = [np.nonzero(dyn & (step == k))[0] for k in range(N + 1)]
        self.g_rows = [np.nonzero(used & ~dyn & (step == k))[0] for k in range(N + 1)]
        for k in range(N):
            if len(self.dyn_rows[k]) != self.ns[k + 1]:
                raise ValueError(
                    f"step {k}: {len(self.dyn_rows[k])} dynamics rows for "
                    f"{self.ns[k + 1]} states"
                )
        # Where the next knot's copies come from: positions in U.
        self.copy_pos = []
        for k in range(N):
            pos = np.searchsorted(self.U[k], copies[k + 1])
            if len(pos) and not np.array_equal(self.U[k][pos], copies[k + 1]):
                raise ValueError("a copied input is not an input of its step")
            self.copy_pos.append(pos)
        self.soft = [np.nonzero(slack_of_row[g] >= 0)[0] for g in self.g_rows]
        self.soft_vars = [
            slack_of_row[g[s]] for g, s in zip(self.g_rows, self.soft, strict=True)
        ]
        # The general rows that read the next knot's states (the DT-CBF's),
        # the only ones the dynamics are substituted into: their positions
        # in g_rows, per stage.
        self.g_next = [np.nonzero(free_next[g])[0] for g in self.g_rows]
        bounded = x_lower_finite | x_upper_finite
        self.idxbx = [np.nonzero(bounded[x])[0] for x in states]
        self.idxbu = [np.nonzero(bounded[u])[0] for u in self.U]
        # Padded sizes and the value buffer's blocks (C order).
        K = N + 1
        mX = max(len(x) for x in self.X)
        mU = max(len(u) for u in self.U)
        mD = max(self.ns)
        mG = max(len(g) for g in self.g_rows)
        mN = max(len(g) for g in self.g_next)
        shapes = dict(
            DN=(K, mD, mD), DX=(K, mD, mX), DU=(K, mD, mU), GX=(K, mG, mX),
            GU=(K, mG, mU), GN=(K, mN, mD), Q=(K, mX, mX), R=(K, mU, mU),
            S=(K, mU, mX),
        )  # fmt: skip
        # Where each GN row's substitution goes: (stage, slot) → row of GX.
        ks = [np.full(len(g), k) for k, g in enumerate(self.g_next)]
        slots = [np.arange(len(g)) for g in self.g_next]
        self.next_stage = np.concatenate(ks)
        self.next_slot = np.concatenate(slots)
        self.next_row = np.concatenate(self.g_next)
        self.offsets, size = {}, 0
        for name, shape in shapes.items():
            self.offsets[name] = size
            size += int(np.prod(shape))
        self.shapes, self.size = shapes, size
        self.block_slices = {
            name: (self.offsets[name], int(np.prod(shape)), shape)
            for name, shape in shapes.items()
        }
        self._MapEntries(free, other, state, knot, step, copies)
        # Padded dynamics rows: identity on the padding so they solve.
        pad = np.ones((K, mD), dtype=bool)
        for k in range(K):
            pad[k, : len(self.dyn_rows[k])] = False
        kk, ii = np.nonzero(pad)
        self.pad_index = self.offsets["DN"] + (kk * mD + ii) * mD + ii
        # Rows' bounds gathered padded: index nr is a zero.
        self.dyn_gather = np.full((K, mD), nr)
        self.g_gather = np.full((K, mG), nr)
        for k in range(K):
            self.dyn_gather[k, : len(self.dyn_rows[k])] = self.dyn_rows[k]
            self.g_gather[k, : len(self.g_rows[k])] = self.g_rows[k]
        self.states = states
        self.finite = finite
        # Dense work per IPM iteration, roughly (Σ_k w³/3 + g w²).
        width = np.array([len(x) + len(u) for x, u in zip(self.X, self.U, strict=True)])
        rows = np.array([len(g) for g in self.g_rows])
        self.work = float(np.sum(width**3 / 3 + rows * width**2))

    def _MapEntries(self, free, other, state, knot, step, copies):
        """Where each constraint and cost entry goes in the value buffer."""
        ws, N, n = self.ws, self.N, self.ws.n
        # Position of every free state in its knot's X, of every input in
        # its step's U, of every copied input in the next knot's X.
        pos_x = np.full(n, -1)
        pos_u = np.full(n, -1)
        pos_copy = np.full((N + 2, n), -1)
        for k in range(N + 1):
            pos_x[self.X[k][: self.ns[k]]] = np.arange(self.ns[k])
            pos_u[self.U[k]] = np.arange(len(self.U[k]))
            pos_copy[k, copies[k]] = self.ns[k] + np.arange(len(copies[k]))
        row_local = np.full(ws.num_rows, -1)
        next_local = np.full(ws.num_rows, -1)
        for k in range(N + 1):
            row_local[self.dyn_rows[k]] = np.arange(len(self.dyn_rows[k]))
            row_local[self.g_rows[k]] = np.arange(len(self.g_rows[k]))
            next_local[self.g_rows[k][self.g_next[k]]] = np.arange(len(self.g_next[k]))
        r, c = ws.a_rows, ws.a_cols
        sel = (row_local[r] >= 0) & free[c] & ~other[c]
        k, i, col = step[r], row_local[r], c
        d = self.dyn[r]
        this = state[c] & (knot[c] == k)
        nxt = state[c] & (knot[c] == k + 1)
        now = ~state[c] & (knot[c] == k)
        block = np.select(
            [d & this, d & nxt, d & now, this, nxt, now, d],
            [0, 1, 2, 3, 4, 5, 0],
            6,
        )  # 0 DX, 1 DN, 2 DU, 3 GX, 4 GN, 5 GU; 6 (else): GX (copies)
        j = np.select(
            [this | nxt, now],
            [pos_x[col], pos_u[col]],
            pos_copy[np.clip(k, 0, N + 1), col],
        )
        names = ["DX", "DN", "DU", "GX", "GN", "GU", "GX"]
        dest = np.full(r.size, -1)
        for b, name in enumerate(names):
            m = sel & (block == b)
            _, rows, cols = self.shapes[name]
            ii = next_local[r[m]] if name == "GN" else i[m]
            dest[m] = self.offsets[name] + (k[m] * rows + ii) * cols + j[m]
        if np.any(dest[sel] < 0) or np.any(j[sel] < 0):
            raise ValueError("an entry of a row has no place in its stage")
        self.a_dest, self.a_ok = dest, sel
        self.a_fixed = (row_local[r] >= 0) & ~free[c]
        self.a_slack = (row_local[r] >= 0) & other[c]
        # Cost entries (upper triangle) within one stage's X / U; the
        # mirrored entry too, off the diagonal.
        pr, pc = ws.p_pattern
        sel = free[pr] & free[pc] & ~other[pr] & ~other[pc]
        if np.any(knot[pr[sel]] != knot[pc[sel]]):
            raise ValueError("a cost couples two knots")
        kp = knot[pr]
        si, sj = state[pr], state[pc]
        dests = []
        for a, b in ((pr, pc), (pc, pr)):
            sa, sb = state[a], state[b]
            dq = (
                self.offsets["Q"]
                + (kp * self.shapes["Q"][1] + pos_x[a]) * (self.shapes["Q"][2])
                + pos_x[b]
            )
            dr = (
                self.offsets["R"]
                + (kp * self.shapes["R"][1] + pos_u[a]) * (self.shapes["R"][2])
                + pos_u[b]
            )
            ds = (
                self.offsets["S"]
                + (kp * self.shapes["S"][1] + pos_u[a]) * (self.shapes["S"][2])
                + pos_x[b]
            )
            dests.append(np.select([sa & sb, ~sa & ~sb, ~sa & sb], [dq, dr, ds], -1))
        first = np.where(sel, dests[0], -1)
        # The mirror: off the diagonal; an S entry is stored once (u, x).
        second = np.where(sel & (pr != pc), dests[1], -1)
        first = np.where(sel & si & ~sj, -1, first)  # (x, u): only its mirror
        second = np.where(sel & ~si & sj & (pr != pc), -1, second)
        self.p_first, self.p_second = first, second
        # Entries with one fixed variable: a linear term of the other.
        self.p_fixed = (free[pr] != free[pc]) & ~other[pr] & ~other[pc]

    def _Blocks(self, buf):
        """The padded blocks (views of ``buf``), by name."""
        return {
            name: buf[off : off + size].reshape(shape)
            for name, (off, size, shape) in self.block_slices.items()
        }
