"""The MPC program's building blocks: the decision-variable layout, the
linearization point, and constraint groups with fixed sparsity patterns.

The program is described once, as groups of vector-valued functions with a
fixed sparsity pattern: each group evaluates its values g(z̄) and the
nonzeros of ∂g/∂z at a point z̄. The stage solvers consume that description
(the real-time iteration linearizes every group and solves sparse QPs; the
nonlinear path hands the same functions and Jacobians to SNOPT or IPOPT).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# Roles of decision variables (VariableLayout.AddVariables).
OTHER, STATE, INPUT = 0, 1, 2


class VariableLayout:
    """Indices of the decision variables in the flat vector z."""

    def __init__(self, *, num_positions: int, num_velocities: int, horizon: int):
        n, m, N = num_positions, num_velocities, horizon
        self.n, self.m, self.N = n, m, N
        self.num_variables = 0
        self._roles: list[tuple[np.ndarray, int]] = []
        self.q = self.AddVariables("q", (N + 1, n), role=STATE)
        self.nu = self.AddVariables("nu", (N + 1, m), role=STATE)
        self.u = self.AddVariables("u", (N, m), role=INPUT)
        self.robot_variables = self.num_variables

    def AddVariables(
        self, name: str, shape: tuple[int, ...], role: int = OTHER
    ) -> np.ndarray:
        """Appends variables to z; returns their indices with the given shape.

        ``role``: STATE (shape (N + 1, ...): the state at each knot), INPUT
        (shape (N, ...): the input of each step) or OTHER (e.g. slacks). The
        roles let a QP solver use the time structure (Roles)."""
        count = int(np.prod(shape))
        idx = np.arange(self.num_variables, self.num_variables + count).reshape(shape)
        self.num_variables += count
        expected = {STATE: self.N + 1, INPUT: self.N}.get(role)
        if expected is not None and shape[0] != expected:
            raise ValueError(f"{name}: a {role=} block must have {expected} rows")
        self._roles.append((idx, role))
        return idx

    def Roles(self) -> tuple[np.ndarray, np.ndarray]:
        """(role, knot) of every variable: the role each block was added
        with and, for states and inputs, the knot or step (else −1)."""
        role = np.full(self.num_variables, OTHER)
        knot = np.full(self.num_variables, -1)
        for idx, r in self._roles:
            role[idx.ravel()] = r
            if r != OTHER:
                steps = np.arange(idx.shape[0]).reshape((-1,) + (1,) * (idx.ndim - 1))
                knot[idx.ravel()] = np.broadcast_to(steps, idx.shape).ravel()
        return role, knot

    def Split(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return z[self.q], z[self.nu], z[self.u]


@dataclass
class LinearizationPoint:
    """A point z̄ with everything the groups need, computed once per point."""

    z: np.ndarray
    q: np.ndarray  # (N+1, n)
    nu: np.ndarray  # (N+1, m)
    u: np.ndarray  # (N, m)
    kin: object  # robot.CalcKinematics(q)
    # Task targets by task name: (s,) or per step (N+1, s).
    targets: dict = field(default_factory=dict)
    # Memo of task evaluations (name → (e, J)), filled lazily.
    task_cache: dict = field(default_factory=dict)


class ConstraintGroup:
    """lower ≤ g(z) ≤ upper with a fixed Jacobian sparsity pattern.

    Subclasses set ``num_rows``, ``rows`` and ``cols`` (the nonzeros of ∂g/∂z,
    local row index and global column index) and implement :meth:`Eval`.
    """

    name = "group"
    num_rows: int
    rows: np.ndarray
    cols: np.ndarray

    # Which entries of a dense block pattern the group keeps (None: all);
    # see KeepStructuralNonzeros.
    _keep: np.ndarray | None = None
    # The controller setting (ControllerConfig) whose value FarRows takes.
    lazy_setting = "lazy_barrier_distance"
    # Whether FarRows may be left out of every QP PIQP solves (True), or only
    # of those too wide for HPIPM (False: the small QPs HPIPM's fast mode
    # fails keep them, and their plans stay HPIPM's).
    far_rows_in_small_qps = True

    def Eval(self, point: LinearizationPoint) -> tuple[np.ndarray, np.ndarray]:
        """Returns g(z̄) (num_rows,) and the Jacobian nonzeros (nnz,)."""
        raise NotImplementedError

    def FarRows(self, point: LinearizationPoint, distance: float) -> np.ndarray | None:
        """The rows (num_rows,) bool that are far from binding at ``point``
        by ``distance`` in the group's own terms (None: none is). A QP
        solver may leave them out and check them at its solution
        (PiqpWorkspace.Solve's ``lazy_rows``)."""
        return None

    def FarEntries(
        self, point: LinearizationPoint, threshold: float
    ) -> np.ndarray | None:
        """The Jacobian entries (nnz,) bool that a sparse QP solver may drop
        where FarRows at ``threshold`` leaves rows out (None: none)."""
        return None

    def KeepStructuralNonzeros(self, keep: np.ndarray) -> None:
        """Drops the entries of the pattern (``rows``, ``cols``) that are
        zero at every point (``keep`` False; e.g. a joint that does not move
        a capsule): the QPs then factor fewer nonzeros. The group computes
        its Jacobian on the dense blocks as before and passes it through
        :meth:`Structural`."""
        keep = np.asarray(keep, dtype=bool)
        if keep.shape != self.rows.shape:
            raise ValueError("the mask must have one entry per pattern entry")
        self.rows, self.cols = self.rows[keep], self.cols[keep]
        self._keep = keep

    def Structural(self, values: np.ndarray) -> np.ndarray:
        """The kept entries of the dense-block Jacobian ``values``."""
        return values if self._keep is None else values[self._keep]

    def DenseJacobian(self, values: np.ndarray, num_variables: int) -> np.ndarray:
        J = np.zeros((self.num_rows, num_variables))
        np.add.at(J, (self.rows, self.cols), values)
        return J


def BlockPattern(row_blocks, col_blocks):
    """Pattern of dense blocks: row_blocks[i] × col_blocks[i] (index arrays)."""
    rows, cols = [], []
    for r, c in zip(row_blocks, col_blocks, strict=True):
        rr, cc = np.meshgrid(r, c, indexing="ij")
        rows.append(rr.ravel())
        cols.append(cc.ravel())
    return np.concatenate(rows), np.concatenate(cols)
