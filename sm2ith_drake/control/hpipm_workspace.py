"""A stage QP solved as an optimal-control QP by HPIPM (optional).

The stage QPs of the RTI (control/rti_solver.py) have the time structure of
an MPC: every variable belongs to one knot, every row couples at most two
neighbouring knots. HPIPM (control/hpipm_library.py) solves such QPs with a
Riccati recursion on dense per-stage blocks. This module casts a stage QP
into HPIPM's form, once per sparsity pattern (control/hpipm_structure.py),
and writes the values in on every solve (control/hpipm_stage_qp.py):

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

from sm2ith_drake.control import hpipm_library, hpipm_stage_qp
from sm2ith_drake.control.hpipm_stage_qp import HpipmStageQp
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
# The settings above that are ours, not HPIPM's.
_OWN_SETTINGS = ("equality_relaxation", "auto_max_work")


def CheckHpipmSettings(settings: dict) -> dict:
    """The solver_options entry "HPIPM" checked (HPIPM's IPM arguments,
    ``mode`` and ours above): numbers YAML read as text become numbers;
    UserError on an unknown name or a value that is not a number."""
    checked = hpipm_library.CheckIpmArguments(
        {k: v for k, v in settings.items() if k not in _OWN_SETTINGS}
    )
    for key in _OWN_SETTINGS:
        if key in settings:
            checked[key] = hpipm_library.Number(f"HPIPM {key}", settings[key], float)
    return checked


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
        hpipm_library.Compile()
        hpipm_stage_qp.Compile()
        settings = {**HPIPM_DEFAULT_SETTINGS, **settings}
        self.relaxation = float(settings.pop("equality_relaxation"))
        self.max_work = float(settings.pop("auto_max_work"))
        self._piqp_settings = piqp_settings
        self._piqp = None
        # PIQP's iterations in the last Solve (a QP handed over; see Solve).
        self.piqp_iterations = 0
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
    def Solve(self, p_values, q, a_values, x_lower, x_upper, lower, upper, **start):
        """As PiqpWorkspace.Solve. Returns (x, status, iterations).
        ``start``: warm_token, guess (see HpipmStageQp.Solve; PIQP starts
        cold), lazy_rows, far_rows, far_entries and max_iterations (PIQP's
        only: HPIPM solves with every row and entry, in at most its own
        iter_max). ``piqp_iterations`` is then the iterations of PIQP on a
        QP too wide for HPIPM (what controller.qp_iteration_budget counts),
        0 for HPIPM's QPs, also where PIQP finishes one its fast mode
        failed."""
        lazy_rows = start.pop("lazy_rows", None)
        # Only for the QPs too wide for HPIPM: its small QPs, when its fast
        # mode fails them, are PIQP's with every line and without a cap
        # (their plans as before; the budget counts HPIPM's QPs out).
        wide = dict(
            lazy_rows=lazy_rows,
            far_rows=start.pop("far_rows", None),
            far_entries=start.pop("far_entries", None),
            max_iterations=start.pop("max_iterations", None),
        )
        self.piqp_iterations = 0
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
                x, status, iterations = piqp.Solve(p_values[order], *args, **wide)
                self.piqp_iterations = iterations
                return x, status, iterations
            auto = self._piqp_settings is not None
            try:
                z, status, iterations = structure.Solve(
                    p_values, *args, retry=not auto, **start
                )
            except (ValueError, np.linalg.LinAlgError) as e:
                if not auto:
                    raise
                # Values HPIPM's form cannot take (a singular dynamics
                # block, a slack with a zero coefficient): PIQP.
                z, status, iterations = None, f"qp error: {e}", 0
            if status != "solved" and auto:
                # A QP HPIPM's fast mode did not solve (1–3 % with 3 + 7
                # people): PIQP, cheaper than HPIPM's balanced mode. Its
                # iterations count as HPIPM's (piqp_iterations stays 0).
                piqp, order = self._Piqp()
                z, status, more = piqp.Solve(
                    p_values[order], *args, lazy_rows=lazy_rows
                )
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
        return HpipmStageQp(self, structure)

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
