"""Sparse LU with LAPACK's partial pivoting, in C, for matrices of modest size (``clu.c``).

The iteration matrices of hydraulic circuits have a few entries per column (the PVG 32 rig:
91 unknowns, about 310 entries), yet dense LAPACK ``getrf`` does n^3 / 3 operations on them.
:class:`SparseLU` factorises ``P A Q = L U`` with a column order ``Q`` fixed once per sparsity
pattern (COLAMD by default, the order SuperLU would use) and LAPACK's row pivoting: at every
step the pivot is the entry of largest magnitude in the eliminated column, the first in
LAPACK's row order on ties, so the pivot sequence is the one ``getrf`` takes on ``A[:, Q]``
and the factorisation is as stable. The elimination is left-looking (Gilbert and Peierls),
its work proportional to the arithmetic, plus one pass over the dense input.

The kernel reads the structure from the nonzero entries of each matrix it factorises: an entry
outside the pattern the column order was chosen for is factorised correctly, only with more
fill. Matrices are given dense, column major (``a[j*n + i] = A[i, j]``).

For C code elsewhere (function pointers and a context):

* ``int64_t pv_lu_factor(void *ctx, const double *a)``: 0; ``j + 1`` when column ``j`` of A
  has an exactly zero pivot (LAPACK's ``info`` for the natural order); -1 for a non-finite
  entry; -2 when memory for the factors cannot be allocated. ``a`` is not modified.
* ``void pv_lu_solve(const void *ctx, double *b)``: ``A x = b`` in place with the last
  successful factorisation (one solve at a time per context: it uses the context's scratch).

``SparseLU.ctx``, ``SparseLU.factor_address`` and ``SparseLU.solve_address`` are these as
integers; the context lives as long as its ``SparseLU``. Its layout (``pv_lu`` in ``clu.c``,
mirrored by :class:`_Context`): int64 ``n, status, step, lnz, unz, anz, lcap, ucap, acap,
reuse, nreused, restart``, then int32 arrays ``q, p, pinv, ipiv`` (column order, pivot rows,
their inverse, LAPACK's 0-based ``ipiv``), L, U and A's structure by columns (``Lp, Li, Up, Ui,
Ap, Ai`` int32), ``Lx, Ux, Ud`` (double), scratch.

A factorisation starts on the structure of the last successful one: while a column has the
same nonzero rows and takes the same pivot, it is eliminated without a search; from the first
column that differs, with the searches (in a run of the PVG 32 rig test 2, 15 of 46
factorisations needed no search at all). The factors are those of a factorisation from
scratch, bit for bit, either way.

References
----------
.. [1] J. R. Gilbert, T. Peierls, "Sparse partial pivoting in time proportional to arithmetic
   operations", SIAM J. Sci. Stat. Comput. 9 (1988) 862-874.
.. [2] T. A. Davis, S. Rajamanickam, W. M. Sid-Lakhdar, "A survey of direct methods for
   sparse linear systems", Acta Numerica 25 (2016) 383-566 (orderings for partial pivoting).
"""

from __future__ import annotations

import ctypes
import weakref
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from pvgraph.cbackend import LoadOnce

__all__ = ["SparseLU", "available", "load_error", "column_order"]

N_MAX = 46340       # PV_LU_NMAX in clu.c: n * n fits its 32-bit indices
ORDERINGS = ("COLAMD", "MMD_ATA", "MMD_AT_PLUS_A", "NATURAL")
_i64, _vp = ctypes.c_int64, ctypes.c_void_p
_i32p = ctypes.POINTER(ctypes.c_int32)
_dp = ctypes.POINTER(ctypes.c_double)


class _Context(ctypes.Structure):
    """The leading fields of ``pv_lu`` (clu.c)."""

    _fields_ = ([(k, _i64) for k in ("n", "status", "step", "lnz", "unz", "anz", "lcap",
                                     "ucap", "acap", "reuse", "nreused", "restart")]
                + [(k, _i32p) for k in ("q", "p", "pinv", "ipiv", "Lp", "Li", "Up", "Ui", "Ap",
                                        "Ai")]
                + [(k, _dp) for k in ("Lx", "Ux", "Ud")])


_fn_addresses = None


def _load():
    from pvgraph import cbackend
    source = Path(__file__).with_name("clu.c").read_text()
    lib = ctypes.CDLL(str(cbackend.compiled(source, "the sparse LU kernel", opt="-O3")))
    lib.pv_lu_new.argtypes = [_i64, _vp]
    lib.pv_lu_new.restype = _vp
    lib.pv_lu_free.argtypes = [_vp]
    lib.pv_lu_free.restype = None
    lib.pv_lu_factor.argtypes = [_vp, _vp]
    lib.pv_lu_factor.restype = _i64
    lib.pv_lu_solve.argtypes = [_vp, _vp]
    lib.pv_lu_solve.restype = None
    return lib


_kernel = LoadOnce(_load)


def library():
    """The loaded kernel (a ctypes library), or None when it cannot be built."""
    return _kernel.get()


def _addresses(lib):
    """(pv_lu_factor, pv_lu_solve) as integers, for C callers (worked out once)."""
    global _fn_addresses
    if _fn_addresses is None:
        _fn_addresses = (ctypes.cast(lib.pv_lu_factor, _vp).value,
                         ctypes.cast(lib.pv_lu_solve, _vp).value)
    return _fn_addresses


def available():
    """Whether the sparse LU kernel can be used (a C compiler built it)."""
    return library() is not None


def load_error():
    """Why the kernel is unavailable (None when it loaded)."""
    library()
    return _kernel.error


def column_order(pattern, ordering="COLAMD"):
    """A fill-reducing column order for LU with partial pivoting of matrices with ``pattern``.

    SuperLU's ordering (``splu(...).perm_c``: COLAMD, or a minimum degree on A^T A or
    A^T + A, followed by its elimination-tree postorder), computed on the pattern with random
    values; ``"NATURAL"`` is the identity. A pattern SuperLU finds singular gets its diagonal
    added first; if that fails too, the natural order.
    """
    s = sp.csc_matrix(pattern, dtype=float)
    n = s.shape[0]
    if s.shape != (n, n):
        raise ValueError(f"the pattern has shape {s.shape}; a square matrix is needed")
    if ordering not in ORDERINGS:
        raise ValueError(f"unknown column ordering {ordering!r}; choose one of {ORDERINGS}")
    if ordering == "NATURAL" or n == 0:
        return np.arange(n, dtype=np.int64)
    s.data[:] = 1.0
    s.eliminate_zeros()
    rng = np.random.default_rng(2009)
    for m in (s, (s + sp.identity(n, format="csc")).tocsc()):
        m = m.copy()
        m.data[:] = rng.uniform(1.0, 2.0, m.nnz)
        try:
            position = splu(m, permc_spec=ordering).perm_c   # column j goes to position[j]
            return np.argsort(position).astype(np.int64)
        except RuntimeError:      # exactly singular with these values
            continue
    return np.arange(n, dtype=np.int64)


class SparseLU:
    """LU factorisation with partial pivoting of n x n matrices with a given sparsity pattern.

    Parameters
    ----------
    n : int
        Size of the matrices.
    pattern : array_like or sparse matrix, optional
        Nonzero structure the column order is chosen for (entries outside it are allowed).
        Without it, and without ``perm_c``, the natural order.
    perm_c : array_like of int, optional
        The column order itself: ``perm_c[k]`` is the column eliminated at step k.
    ordering : str
        ``"COLAMD"`` (default), ``"MMD_ATA"``, ``"MMD_AT_PLUS_A"`` or ``"NATURAL"``.
    reuse : bool
        Start each factorisation on the structure of the last one (default; the factors are
        the same either way, only the time differs).

    Raises
    ------
    pvgraph.cbackend.CBackendError
        When the kernel cannot be built (no C compiler, or it fails).
    """

    def __init__(self, n, pattern=None, *, perm_c=None, ordering="COLAMD", reuse=True):
        lib = library()
        if lib is None:
            from pvgraph.cbackend import CBackendError
            raise CBackendError(f"the sparse LU kernel (pvgraph/solver/clu.c) is unavailable: "
                                f"{_kernel.error}")
        n = int(n)
        if not 1 <= n <= N_MAX:
            raise ValueError(f"SparseLU needs 1 <= n <= {N_MAX}, got {n}")
        if pattern is not None and np.shape(pattern) != (n, n):
            raise ValueError(f"SparseLU: the pattern has shape {np.shape(pattern)}, expected "
                             f"({n}, {n})")
        if perm_c is None:
            perm_c = (column_order(pattern, ordering) if pattern is not None
                      else np.arange(n, dtype=np.int64))
        perm_c = np.ascontiguousarray(perm_c, dtype=np.int64)
        if perm_c.shape != (n,):
            raise ValueError(f"perm_c must be a permutation of 0..{n - 1}")
        ctx = lib.pv_lu_new(n, perm_c.ctypes.data)      # checks the permutation
        if not ctx:
            if not np.array_equal(np.sort(perm_c), np.arange(n)):
                raise ValueError(f"perm_c must be a permutation of 0..{n - 1}")
            raise MemoryError(f"pv_lu_new({n}) could not allocate its context")
        self.n = n
        self.perm_c = perm_c
        self.ctx = int(ctx)
        self._finalizer = weakref.finalize(self, lib.pv_lu_free, ctx)
        self._c = _Context.from_address(self.ctx)
        self._c.reuse = 1 if reuse else 0
        self._factor = lib.pv_lu_factor
        self._solve = lib.pv_lu_solve
        self.factor_address, self.solve_address = _addresses(lib)
        self.info = None
        # buffers whose addresses are taken once (numpy's .ctypes costs a microsecond a call)
        self._a = np.empty((n, n), order="F")
        self._a_addr = self._a.ctypes.data
        self._x = np.empty(n)
        self._x_addr = self._x.ctypes.data

    def factor(self, m):
        """Factorise the dense matrix ``m`` (not modified); return 0, j + 1 or -1.

        ``j + 1``: column ``j`` has an exactly zero pivot; -1: an entry is not finite.
        """
        a = np.asarray(m, dtype=np.float64)
        if a.shape != (self.n, self.n):
            raise ValueError(f"SparseLU.factor: matrix of shape {a.shape}, expected "
                             f"({self.n}, {self.n})")
        if a.flags.f_contiguous:
            addr = a.ctypes.data
        else:
            self._a[...] = a
            addr = self._a_addr
        info = int(self._factor(self.ctx, addr))
        if info == -2:
            raise MemoryError("SparseLU.factor: no memory for the LU factors")
        self.info = info
        return info

    def solve(self, b):
        """Solve A x = b (b of shape (n,)) with the last factorisation; a new array.

        One solve at a time: the right-hand side goes through a buffer of this object.
        """
        if self.info != 0:
            from pvgraph.errors import SolverError
            raise SolverError("SparseLU.solve: no successful factorisation to solve with "
                              f"(last factor returned {self.info})")
        b = np.asarray(b)
        if b.shape != self._x.shape:
            raise ValueError(f"SparseLU.solve: right-hand side of shape {b.shape}, expected "
                             f"({self.n},)")
        x = self._x
        x[...] = b
        self._solve(self.ctx, self._x_addr)
        return x.copy()

    # ---- the factors, for inspection ----------------------------------------------------

    @property
    def nreused(self):
        """Factorisations done entirely on the previous structure (no search)."""
        return int(self._c.nreused)

    @property
    def restart(self):
        """Step where the last factorisation began to search: 0 from scratch, -1 none."""
        return int(self._c.restart)

    @property
    def nnz(self):
        """Entries of L and U (U's diagonal included, L's unit diagonal not)."""
        return int(self._c.lnz + self._c.unz) + self.n

    @property
    def ipiv(self):
        """LAPACK's 0-based ``ipiv`` of the last factorisation: the pivots of A[:, perm_c]."""
        return np.ctypeslib.as_array(self._c.ipiv, (self.n,)).astype(np.intp)

    @property
    def perm_r(self):
        """``perm_r[k]``: the row of A pivoted at step k."""
        return np.ctypeslib.as_array(self._c.p, (self.n,)).astype(np.intp)

    def factors(self):
        """(L, U) as scipy.sparse CSC matrices with ``A[perm_r][:, perm_c] = L @ U``."""
        if self.info != 0:
            from pvgraph.errors import SolverError
            raise SolverError(f"SparseLU.factors: the last factorisation failed ({self.info})")
        c, n = self._c, self.n
        lp = np.ctypeslib.as_array(c.Lp, (n + 1,)).copy()
        up = np.ctypeslib.as_array(c.Up, (n + 1,)).copy()
        li = np.ctypeslib.as_array(c.Li, (max(int(lp[-1]), 1),))[:lp[-1]].copy()
        ui = np.ctypeslib.as_array(c.Ui, (max(int(up[-1]), 1),))[:up[-1]].copy()
        lx = np.ctypeslib.as_array(c.Lx, (max(int(lp[-1]), 1),))[:lp[-1]].copy()
        ux = np.ctypeslib.as_array(c.Ux, (max(int(up[-1]), 1),))[:up[-1]].copy()
        ud = np.ctypeslib.as_array(c.Ud, (n,)).copy()
        low = sp.csc_matrix((lx, li, lp), shape=(n, n)) + sp.identity(n, format="csc")
        upp = sp.csc_matrix((ux, ui, up), shape=(n, n)) + sp.diags(ud, format="csc")
        return low.tocsc(), upp.tocsc()
