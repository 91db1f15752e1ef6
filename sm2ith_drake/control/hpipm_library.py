"""HPIPM's OCP QP interior-point solver through ctypes (optional).

HPIPM (the Riccati-structured interior-point QP solver acados uses) and its
linear algebra, BLASFEO, come as shared libraries inside the
``comma-deps-acados`` wheel (``pip install 'sm2ith_drake[hpipm]'``, Python
≥ 3.12). This module loads them and wraps the calls one OCP QP needs:
dimensions, data by field name, a solve, the solution. Nothing is compiled
here. See control/hpipm_workspace.py for how a stage QP becomes an OCP QP.
"""

from __future__ import annotations

import ctypes
import importlib.util
import os
from dataclasses import dataclass
from functools import cache

import numba
import numpy as np

from sm2ith_drake.errors import UserError

# HPIPM's modes (enum hpipm_mode).
MODES = {"speed_abs": 0, "speed": 1, "balance": 2, "robust": 3}
# HPIPM's IPM arguments by name, with the C type each takes (HPIPM's
# d_ocp_qp_ipm_arg_set exits the process on a name it does not know).
IPM_ARGUMENTS = {
    **dict.fromkeys(
        (
            "iter_max warm_start pred_corr cond_pred_corr ric_alg comp_dual_sol_eq "
            "comp_res_exit comp_res_pred split_step var_init_scheme t_lam_min "
            "t0_init update_fact_exit"
        ).split(),
        int,
    ),
    **dict.fromkeys(
        (
            "alpha_min mu0 tol_stat tol_eq tol_ineq tol_comp tol_dual_gap reg_prim "
            "lam_min t_min tau_min lam0_min t0_min"
        ).split(),
        float,
    ),
}
# HPIPM's exit status codes.
STATUS = {0: "solved", 1: "max_iter_reached", 2: "min_step", 3: "nan"}

_DOUBLE_P = ctypes.POINTER(ctypes.c_double)


class HpipmUnavailable(UserError):
    """The HPIPM libraries are not installed."""


@cache
def Library():
    """The loaded libhpipm (BLASFEO loaded first, globally)."""
    spec = importlib.util.find_spec("acados")
    locations = list(spec.submodule_search_locations or []) if spec else []
    for root in locations:
        libdir = os.path.join(root, "install", "lib")
        path = os.path.join(libdir, "libhpipm.so")
        if os.path.exists(path):
            ctypes.CDLL(os.path.join(libdir, "libblasfeo.so"), mode=ctypes.RTLD_GLOBAL)
            lib = ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)
            break
    else:
        raise HpipmUnavailable(
            "controller.qp_solver: hpipm needs HPIPM, which comes with the "
            "optional extra: pip install 'sm2ith_drake[hpipm]' (Python >= 3.12)"
        )
    for name in (
        "d_ocp_qp_dim_strsize",
        "d_ocp_qp_strsize",
        "d_ocp_qp_sol_strsize",
        "d_ocp_qp_ipm_arg_strsize",
        "d_ocp_qp_ipm_ws_strsize",
        "d_ocp_qp_dim_memsize",
        "d_ocp_qp_memsize",
        "d_ocp_qp_sol_memsize",
        "d_ocp_qp_ipm_arg_memsize",
        "d_ocp_qp_ipm_ws_memsize",
    ):
        getattr(lib, name).restype = ctypes.c_size_t
    lib.d_ocp_qp_sol_get.argtypes = [
        ctypes.c_char_p,
        ctypes.c_int,
        ctypes.c_void_p,
        ctypes.c_void_p,
    ]
    lib.d_ocp_qp_sol_get.restype = None
    return lib


def Available() -> bool:
    try:
        Library()
    except (HpipmUnavailable, OSError):
        return False
    return True


def StageQpSolver(qp_solver: str) -> str:
    """The solver controller.qp_solver runs the stage QPs with: auto is
    piqp for every QP where HPIPM is not installed (it comes with Python
    >= 3.12 only, comma-deps-acados)."""
    return "piqp" if qp_solver == "auto" and not Available() else qp_solver


# NUL-terminated field names, kept alive for the compiled call loops.
_FIELD_NAMES: dict = {}


def FieldName(field: str) -> int:
    """The address of ``field`` as a C string (for CallTable)."""
    if field not in _FIELD_NAMES:
        _FIELD_NAMES[field] = ctypes.create_string_buffer(field.encode())
    return ctypes.addressof(_FIELD_NAMES[field])


@dataclass
class CallTable:
    """Many calls of HPIPM's generic setter d_ocp_qp_set (or getter
    d_ocp_qp_sol_get) in one compiled loop: field name addresses
    (FieldName), stages and data addresses into arrays the caller keeps
    alive. One ctypes call costs ~1 µs of Python; a stage QP makes ~200."""

    fields: np.ndarray  # uint64
    stages: np.ndarray  # int32
    addresses: np.ndarray  # uint64

    @staticmethod
    def Of(calls) -> CallTable:
        """From (field, stage, address) triples."""
        fields, stages, addresses = zip(*calls, strict=True) if calls else ((), (), ())
        return CallTable(
            np.array([FieldName(f) for f in fields], dtype=np.uint64),
            np.array(stages, dtype=np.int32),
            np.array(addresses, dtype=np.uint64),
        )


@cache
def _CallLoops():
    """Compiled loops over HPIPM's generic setter and getter (pointer
    arguments as 64-bit integers). Compiled once per process (~0.5 s: the
    library's address is a constant of the code, so it is not cached on
    disk)."""
    lib = Library()
    proto = ctypes.CFUNCTYPE(
        None, ctypes.c_uint64, ctypes.c_int, ctypes.c_uint64, ctypes.c_uint64
    )
    set_ = proto(ctypes.cast(lib.d_ocp_qp_set, ctypes.c_void_p).value)
    get = proto(ctypes.cast(lib.d_ocp_qp_sol_get, ctypes.c_void_p).value)
    put = proto(ctypes.cast(lib.d_ocp_qp_sol_set, ctypes.c_void_p).value)

    # Explicit signatures: compiled here, not at the first call.
    @numba.njit("void(uint64[::1], int32[::1], uint64[::1], uint64)")
    def SetAll(fields, stages, addresses, qp):  # pragma: no cover
        for i in range(fields.size):
            set_(fields[i], stages[i], addresses[i], qp)

    @numba.njit("void(uint64[::1], int32[::1], uint64, uint64[::1])")
    def GetAll(fields, stages, sol, addresses):  # pragma: no cover
        for i in range(fields.size):
            get(fields[i], stages[i], sol, addresses[i])

    @numba.njit("void(uint64[::1], int32[::1], uint64, uint64[::1])")
    def PutAll(fields, stages, sol, addresses):  # pragma: no cover
        for i in range(fields.size):
            put(fields[i], stages[i], addresses[i], sol)

    return SetAll, GetAll, PutAll


def CheckIpmArguments(settings: dict) -> dict:
    """``settings`` (HPIPM's IPM arguments by name, and ``mode``) as the
    types HPIPM takes: a number YAML read as text ("1e-4") becomes a number.
    Raises UserError on a name HPIPM does not have or a value that is not a
    number of its type."""
    checked = {}
    for key, value in settings.items():
        if key == "mode":
            if value not in MODES:
                raise UserError(f"HPIPM mode {value!r}: one of {', '.join(MODES)}")
            checked[key] = value
            continue
        kind = IPM_ARGUMENTS.get(key)
        if kind is None:
            raise UserError(
                f"HPIPM setting {key!r}: not an HPIPM IPM argument (one of "
                f"mode, {', '.join(sorted(IPM_ARGUMENTS))})"
            )
        checked[key] = Number(f"HPIPM setting {key!r}", value, kind)
    return checked


def Number(what: str, value, kind: type):
    """``value`` as a ``kind`` (int or float), from a number or its text."""
    if isinstance(value, bool):
        if kind is int:  # (e.g. warm_start: true)
            return int(value)
        raise UserError(f"{what}: {value!r} is not a number")
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = None
    if number is None or not np.isfinite(number):
        raise UserError(f"{what}: {value!r} is not a finite number")
    if kind is int:
        if number != int(number):
            raise UserError(f"{what}: {value!r} is not a whole number")
        return int(number)
    return number


def Compile() -> None:
    """Compiles the call loops (once per process), ahead of a controller's
    first step."""
    _CallLoops()


def _Memory(size) -> ctypes.Array:
    return ctypes.create_string_buffer(max(int(size), 1))


class OcpQp:
    """One OCP QP of fixed dimensions with HPIPM's IPM workspace.

    Stages k = 0..N with states x_k (nx[k]) and inputs u_k (nu[k]):
    min Σ ½[u;x]ᵀ[R S; Sᵀ Q][u;x] + rᵀu + qᵀx + slack costs
    s.t. x_{k+1} = A_k x_k + B_k u_k + b_k, box bounds on some entries of
    u_k and x_k, lg − sl ≤ C_k x_k + D_k u_k ≤ ug + su on general rows, some
    of them soft (slacks sl, su ≥ 0 with costs ½Z s² + z s).
    """

    def __init__(self, nx, nu, nbx, nbu, ng, nsg, *, mode: str, settings: dict):
        lib = self.lib = Library()
        N = len(nx) - 1
        self.N = N
        self.nx, self.nu = list(nx), list(nu)
        self._dim = _Memory(lib.d_ocp_qp_dim_strsize())
        self._dim_mem = _Memory(lib.d_ocp_qp_dim_memsize(ctypes.c_int(N)))
        lib.d_ocp_qp_dim_create(ctypes.c_int(N), self._dim, self._dim_mem)
        for k in range(N + 1):
            for field, values in (
                ("nx", nx),
                ("nu", nu),
                ("nbx", nbx),
                ("nbu", nbu),
                ("ng", ng),
                ("nsg", nsg),
            ):
                lib.d_ocp_qp_dim_set(
                    field.encode(),
                    ctypes.c_int(k),
                    ctypes.c_int(int(values[k])),
                    self._dim,
                )
        self._qp = _Memory(lib.d_ocp_qp_strsize())
        self._qp_mem = _Memory(lib.d_ocp_qp_memsize(self._dim))
        lib.d_ocp_qp_create(self._dim, self._qp, self._qp_mem)
        self._qp_address = ctypes.addressof(self._qp)
        self._setters: dict = {}
        self._sol = _Memory(lib.d_ocp_qp_sol_strsize())
        self._sol_mem = _Memory(lib.d_ocp_qp_sol_memsize(self._dim))
        lib.d_ocp_qp_sol_create(self._dim, self._sol, self._sol_mem)
        # IPM arguments and workspaces: the mode asked for, and a robust
        # one for a QP that mode does not solve (Solve(robust=True)).
        # The robust one is made at its first use (auto never uses it).
        self._robust = {**settings, "iter_max": max(100, settings.get("iter_max", 0))}
        self._ipm = [self._Ipm(mode, settings), None]

    def _Ipm(self, mode: str, settings: dict):
        lib = self.lib
        arg = _Memory(lib.d_ocp_qp_ipm_arg_strsize())
        arg_mem = _Memory(lib.d_ocp_qp_ipm_arg_memsize(self._dim))
        lib.d_ocp_qp_ipm_arg_create(self._dim, arg, arg_mem)
        lib.d_ocp_qp_ipm_arg_set_default(ctypes.c_int(MODES[mode]), arg)
        for key, value in settings.items():
            self._SetArgument(arg, key, value)
        ws = _Memory(lib.d_ocp_qp_ipm_ws_strsize())
        ws_mem = _Memory(lib.d_ocp_qp_ipm_ws_memsize(self._dim, arg))
        lib.d_ocp_qp_ipm_ws_create(self._dim, arg, ws, ws_mem)
        return arg, arg_mem, ws, ws_mem

    def _SetArgument(self, arg, key: str, value) -> None:
        """An IPM argument by HPIPM's name (iter_max, mu0, tol_stat, ...;
        see CheckIpmArguments)."""
        kind = IPM_ARGUMENTS[key]
        c_value = ctypes.c_int(int(value)) if kind is int else ctypes.c_double(value)
        self.lib.d_ocp_qp_ipm_arg_set(key.encode(), ctypes.byref(c_value), arg)

    def Setter(self, field: str):
        """HPIPM's setter of one field: f(stage, address, qp)."""
        setter = self._setters.get(field)
        if setter is None:
            setter = getattr(self.lib, "d_ocp_qp_set_" + field)
            setter.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p]
            setter.restype = None
            self._setters[field] = setter
        return setter

    def Set(self, field: str, stage: int, value) -> None:
        """QP data by HPIPM's field name (A, b, lbx_mask, idxs, ...);
        matrices are passed column-major."""
        if field.startswith("idx"):
            array = np.ascontiguousarray(value, dtype=np.int32)
        else:
            array = np.asfortranarray(value, dtype=np.float64)
        self.Setter(field)(stage, array.ctypes.data, self._qp_address)

    def SetFrom(self, table: CallTable) -> None:
        """Many fields at once (d_ocp_qp_set's field names)."""
        _CallLoops()[0](
            table.fields, table.stages, table.addresses, np.uint64(self._qp_address)
        )

    def Solve(self, robust: bool = False, warm: bool = False) -> tuple[str, int]:
        """Returns (status, iterations); ``robust``: in the balanced mode;
        ``warm``: from the primal solution of the last solve (HPIPM's
        warm_start 1), not from HPIPM's cold start."""
        if robust and self._ipm[1] is None:
            self._ipm[1] = self._Ipm("balance", self._robust)
        arg, _, ws, _ = self._ipm[int(robust)]
        if warm:
            self._SetArgument(arg, "warm_start", 1)
        try:
            self.lib.d_ocp_qp_ipm_solve(self._qp, self._sol, arg, ws)
        finally:
            if warm:
                self._SetArgument(arg, "warm_start", 0)
        status, iterations = ctypes.c_int(), ctypes.c_int()
        self.lib.d_ocp_qp_ipm_get_status(ws, ctypes.byref(status))
        self.lib.d_ocp_qp_ipm_get_iter(ws, ctypes.byref(iterations))
        return STATUS.get(status.value, f"status {status.value}"), iterations.value

    def SetSolutionFrom(self, table: CallTable) -> None:
        """A primal point into the solution (d_ocp_qp_sol_set's field
        names: x, u, sl, su), where Solve(warm=True) starts from."""
        sol = np.uint64(ctypes.addressof(self._sol))
        _CallLoops()[2](table.fields, table.stages, sol, table.addresses)

    def GetInto(self, table: CallTable) -> None:
        """Solution vectors into caller-kept arrays (d_ocp_qp_sol_get's
        field names: x, u, sl, ...)."""
        sol = np.uint64(ctypes.addressof(self._sol))
        _CallLoops()[1](table.fields, table.stages, sol, table.addresses)
