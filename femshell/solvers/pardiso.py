"""MKL PARDISO through pypardiso: discovery, MKL's threads, one factorisation handle.

pypardiso's own ``factorize``/``solve`` re-run the analysis for every new matrix; here the
phases are called directly: analysis (phase 11) once per pattern, numerical factorisation
(phase 22) per refactorisation, solves (phase 33), release (phase −1). MKL is loaded on first
use, after its threading layer is chosen (:func:`_mkl_environment`), never at import.
"""

from __future__ import annotations

import copy
import ctypes
import ctypes.util
import glob
import os
import sys
import time
import weakref

import numpy as np
import scipy.sparse as sp

from .._interrupts import run_handles_signals
from ..config import REPRODUCIBLE_ENV, element_threads
from .sparse_matrix import _SINGULAR_HINT, LinearSolverError

#: PARDISO's symmetric-indefinite mode replaces pivots smaller than 10^-13 ‖K‖ by
#: ±10^-13 ‖K‖ ("perturbed pivots"). MKL's default (10^-8) perturbed matrices with
#: condition number 1e11 and returned solutions with 10–40 % residuals that
#: iterative refinement did not repair (measured), so femshell sets 13 (iparm(10)).
PARDISO_PERTURBATION_EXPONENT = 13
#: PARDISO runs single-threaded below this many stored (upper-triangle) non-zeros and
#: with all of MKL's threads above (``MKL_NUM_THREADS``: the CPUs this process may use by
#: default, one in the reproducible mode, see _mkl_environment). Below it, idle OpenMP
#: threads spin and compete on a shared machine; above it (a 25k-vertex shell Hessian, 4.2M
#: non-zeros), two threads refactorise about twice as fast as one.
PARALLEL_MIN_NNZ = 2_000_000

_PARDISO_STATE = {"checked": False, "ok": False, "why": "", "template": None, "layer": None}


def _mkl_environment():
    """MKL's threading layer and thread count, chosen just before MKL is first loaded.

    Unless the environment names a layer: MKL's GNU OpenMP layer (where installed) on
    ``MKL_NUM_THREADS`` threads, by default as many as the element kernels use
    (:func:`femshell.config.element_threads`: the CPUs this process may use), so large
    factorisations use every core. The same factorisation then differs in its last bits from
    one process to the next, so a resumed run continues the uninterrupted one to round-off.
    The sequential layer (``MKL_THREADING_LAYER=SEQUENTIAL``, which the reproducible mode of
    :func:`femshell.configure` sets, and the fall-back without the GNU layer) comes with strict
    conditional numerical reproducibility (``MKL_CBWR=AUTO,STRICT``): bit-for-bit the same
    results in every process, so a resume repeats the uninterrupted run exactly. (Strict mode
    is left off with threads: it only slows PARDISO down there.)
    """
    if "MKL_THREADING_LAYER" not in os.environ:
        gnu = glob.glob(os.path.join(sys.prefix, "lib", "libmkl_gnu_thread.so*"))
        os.environ["MKL_THREADING_LAYER"] = "GNU" if gnu and ctypes.util.find_library("gomp") else "SEQUENTIAL"
    if os.environ["MKL_THREADING_LAYER"].strip().upper() == "SEQUENTIAL":
        os.environ.setdefault("MKL_CBWR", REPRODUCIBLE_ENV["MKL_CBWR"])
    else:
        os.environ.setdefault("MKL_NUM_THREADS", str(element_threads()))
    _PARDISO_STATE["layer"] = os.environ["MKL_THREADING_LAYER"].strip().upper()


def mkl_reproducible_or_unloaded() -> bool:
    """Whether MKL is not loaded yet in this process, or was loaded in the reproducible mode."""
    st = _PARDISO_STATE
    strict = os.environ.get("MKL_CBWR", "").replace(" ", "").upper() == REPRODUCIBLE_ENV["MKL_CBWR"]
    return not st["checked"] or (st["layer"] == "SEQUENTIAL" and strict)


def _pardiso_available() -> bool:
    """Whether pypardiso finds MKL; the first call loads it (after :func:`_mkl_environment`)."""
    st = _PARDISO_STATE
    if not st["checked"]:
        st["checked"] = True
        _mkl_environment()
        try:
            import pypardiso   # deferred: loading MKL reads the environment set just above

            st["template"] = pypardiso.PyPardisoSolver()   # loads mkl_rt: fails if MKL is missing
            st["ok"] = True
        except Exception as exc:                  # ImportError, OSError from ctypes
            st["ok"], st["why"] = False, f"{type(exc).__name__}: {exc}"
    return st["ok"]


def _mkl_threads(n=None):
    """Set MKL's thread count for the calling thread (n = 0: back to the global one).

    Returns the previous thread-local value; with n None only reports MKL's maximum.
    No-op (returning 0) if this MKL lacks the service functions.
    """
    lib = _PARDISO_STATE["template"].libmkl
    try:
        if n is None:
            f = lib.MKL_Get_Max_Threads
            f.restype = ctypes.c_int
            return int(f())
        f = lib.MKL_Set_Num_Threads_Local
        f.restype, f.argtypes = ctypes.c_int, [ctypes.c_int]
        return int(f(int(n)))
    except AttributeError:  # pragma: no cover - other MKL builds
        return 0


def _new_pardiso_solver(mtype):
    """A fresh PyPardisoSolver sharing the loaded MKL library.

    PyPardisoSolver() searches for mkl_rt on every construction (a recursive glob over
    sys.prefix when ctypes' find_library fails, as here: 0.5 s, measured); a shallow
    copy of one loaded solver with its own handle and parameter arrays avoids that.
    """
    _pardiso_available()
    s = copy.copy(_PARDISO_STATE["template"])
    s.pt = np.zeros(64, dtype=s._pt_type[1])     # the PARDISO handle: must be private
    s.iparm = np.zeros(64, dtype=np.int32)
    s.perm = np.zeros(0, dtype=np.int32)
    s.factorized_A = sp.csr_matrix((0, 0))
    s.set_matrix_type(mtype)
    s.set_phase(13)
    return s


_PARDISO_ERRORS = {
    -1: "input inconsistent", -2: "not enough memory", -3: "reordering problem",
    -4: "zero pivot in the numerical factorisation", -5: "unclassified internal error",
    -6: "reordering failed", -7: "diagonal matrix is singular", -8: "32-bit integer overflow",
    -9: "not enough memory for out-of-core", -10: "cannot open out-of-core files",
    -11: "out-of-core read/write error",
}


def _free_pardiso(solver):
    try:
        solver.free_memory(everything=True)   # phase −1: every factor held by this handle
    except Exception:  # pragma: no cover - interpreter shutdown
        pass


#: PARDISO handles of factorisations the garbage collector took during a run: freed at the next
#: factorisation, not in the collector's callback. A SIGTERM or Ctrl-C whose KeyboardInterrupt is
#: raised inside such a callback is printed and dropped by Python; phase −1 on a large factor takes
#: milliseconds (1-7 ms at 4 000 vertices, measured), long enough to lose a stop that way; an append
#: takes none. Outside a run (no run's signal handler installed) the callback frees at once.
_COLLECTED: list = []


def _collected(solver):
    if run_handles_signals():
        _COLLECTED.append(solver)
    else:
        _free_pardiso(solver)


def _free_collected():
    while _COLLECTED:
        _free_pardiso(_COLLECTED.pop())


class _Pardiso:
    def __init__(self, kind, matching=True):
        self.mtype = 2 if kind == "spd" else -2
        self.solver = _new_pardiso_solver(self.mtype)
        ip = self.solver.iparm
        ip[:] = 0
        ip[0] = 1                   # iparm(1): we supply the parameters below
        ip[1] = 3                   # iparm(2): parallel (OpenMP) METIS nested dissection (MKL's own choice)
        ip[4] = 2                   # iparm(5): return the fill-in permutation in perm (to name unknowns)
        # iparm(8) = 0: iterative refinement (two steps) only after perturbed pivots; a fixed
        # number of steps tripled the solve time for no gain on SPD matrices (measured)
        ip[7] = 0
        ip[9] = PARDISO_PERTURBATION_EXPONENT   # iparm(10): perturb pivots < 10^-13 ‖K‖
        # iparm(11), iparm(13): symmetric scaling and weighted matching for the indefinite
        # mode. Without them PARDISO perturbed 6 pivots of a well-conditioned (|λ| ≥ 0.014,
        # ‖K‖ = 7) random matrix with zero diagonal entries and returned a residual of
        # 1e-4; with them, none (measured). They are computed from the values seen in the
        # analysis; a refactorisation that then perturbs pivots re-analyses (Factorization).
        ip[10] = ip[12] = int(self.mtype == -2 and matching)
        ip[17] = -1                 # iparm(18): report non-zeros in the factor
        # iparm(21) = 3: Bunch–Kaufman 1×1 and 2×2 pivots, the variant after which
        # iterative refinement converges: with 1 (MKL's default) refinement stalled at
        # residuals 1e-4 after perturbed pivots, with 3 it reached 1e-14 (measured)
        ip[20] = 3
        ip[34] = 0                  # iparm(35): one-based indices (pypardiso converts)
        ip[55] = 1                  # iparm(56): keep the factor's diagonal for pardiso_getdiag
        self.solver.perm = np.zeros(0, np.int32)
        self._finalizer = None
        self.analysed = False
        self.threads = 1

    def _call(self, phase, U, b):
        self.solver.set_phase(phase)
        # every phase runs on the thread count pinned at the analysis: a factorisation on
        # fewer threads than the analysis, or a refactorisation after solves on fewer
        # threads, crashed PARDISO (segfault in the threaded Cholesky, measured with
        # MKL_THREADING_LAYER=GNU and INTEL). Solves lose nothing (0.09 s either way at 150k unknowns).
        prev = _mkl_threads(self.threads)
        try:
            return self.solver._call_pardiso(U, b)
        except Exception as exc:
            code = getattr(exc, "value", None)
            if code is None:
                raise
            msg = _PARDISO_ERRORS.get(code, "unknown error")
            if code == -4 and self.mtype == 2:
                raise LinearSolverError(
                    "PARDISO Cholesky found a zero or negative pivot: the matrix is not positive definite "
                    f"(use kind='symmetric_indefinite' for an indefinite matrix) or {_SINGULAR_HINT}") from None
            if code == -4:
                raise LinearSolverError(f"PARDISO found a zero pivot: {_SINGULAR_HINT}") from None
            raise LinearSolverError(f"PARDISO failed with error {code} ({msg}) in phase {phase}") from None
        finally:
            _mkl_threads(prev)

    def factor(self, U, analyse: bool):
        n = U.shape[0]
        b = np.zeros((n, 1))
        _free_collected()
        if analyse:
            if self.analysed:
                self.solver.free_memory(everything=True)
            self.solver.perm = np.zeros(n, np.int32)
            self.threads = 1 if U.nnz < PARALLEL_MIN_NNZ else max(_mkl_threads(), 1)
            t0 = time.perf_counter()
            self._call(11, U, b)
            t_an = time.perf_counter() - t0
            self.perm = self.solver.perm.astype(np.int64) - 1
            self.analysed = True
            if self._finalizer is None:
                self._finalizer = weakref.finalize(self, _collected, self.solver)
        else:
            t_an = 0.0
        t0 = time.perf_counter()
        self._call(22, U, b)
        return t_an, time.perf_counter() - t0

    def pivots(self):
        """Factor diagonal d and matrix diagonal a, both in the original numbering of the unknowns."""
        n = len(self.perm)
        df, da = np.zeros(n), np.zeros(n)
        err = ctypes.c_int32(0)
        s = self.solver
        s.libmkl.pardiso_getdiag(s.pt.ctypes.data_as(ctypes.c_void_p), df.ctypes.data_as(ctypes.c_void_p),
                                 da.ctypes.data_as(ctypes.c_void_p), ctypes.byref(ctypes.c_int32(1)),
                                 ctypes.byref(err))
        if err.value != 0:
            return None, None
        # getdiag returns them in elimination order: entry k belongs to unknown perm[k]
        d, a = np.empty(n), np.empty(n)
        d[self.perm] = df
        a[self.perm] = da
        return d, a

    def set_refinement(self, perturbed: bool):
        # iparm(8): 0 = two refinement steps only after perturbed pivots. With perturbed
        # pivots allow up to 20 (PARDISO stops when converged): 2 left a residual of
        # 2e-4 on zero-diagonal test matrices, 7–10 steps reached 1e-14 (measured).
        self.solver.iparm[7] = 20 if perturbed else 0

    def inertia(self):
        ip = self.solver.iparm
        return int(ip[21]), int(ip[22]), int(ip[13])      # positive, negative, perturbed

    def factor_nnz(self):
        return int(self.solver.iparm[17])

    def solve(self, U, b):
        return self._call(33, U, b)

    def free(self):
        if self._finalizer is not None:
            self._finalizer.detach()
            self._finalizer = None
            _free_pardiso(self.solver)
        self.analysed = False
