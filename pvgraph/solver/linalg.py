"""Iteration matrices and their LU factorisations for the DAE solver.

The BDF corrector and the consistent-initialisation Newton iterations both solve linear
systems with a matrix whose column j is ``cy[j] * dF/dy_j + cyp[j] * dF/dy'_j``. For the
corrector ``cy = 1`` and ``cyp = cj`` (the iteration matrix ``J = dF/dy + cj dF/dy'``); for
initialisation each column is either the ``y`` or the ``y'`` derivative. This module
evaluates such matrices from a user Jacobian or by finite differences (column-grouped by a
graph colouring of the sparsity pattern, so that one residual call serves many columns) and
factorises them with dense LAPACK LU for small systems or SuperLU for large sparse ones.

References
----------
.. [1] A. C. Hindmarsh et al., "User Documentation for IDA", SUNDIALS, section
   "Mathematical considerations" (difference-quotient Jacobian increments).
.. [2] A. R. Curtis, M. J. D. Powell, J. K. Reid, "On the estimation of sparse Jacobian
   matrices", J. Inst. Math. Appl. 13 (1974) 117-119.
"""

from __future__ import annotations

import math
import threading

import numpy as np
import scipy.sparse as sp
from scipy.linalg import get_lapack_funcs
from scipy.sparse.linalg import splu

__all__ = ["SPARSE_MIN_N", "column_groups", "JacobianEvaluator", "LUSolver"]

SPARSE_MIN_N = 100          # below this size dense LAPACK LU beats SuperLU
SQRT_UROUND = math.sqrt(np.finfo(float).eps)
ZERO_COLUMN_GROWTH = 1e6    # a difference column lost to rounding is retried this much larger
_GROWTHS = (1.0, ZERO_COLUMN_GROWTH, ZERO_COLUMN_GROWTH ** 2)   # ... and again

CLU_ORDER_MIN_N = 32        # the C LU orders columns to reduce fill from this size on
_COLUMN_ORDERS = {}         # the C LU's column orders by pattern and by pattern object
_COLUMN_ORDERS_LOCK = threading.Lock()
_GETRF, _GETRS = get_lapack_funcs(("getrf", "getrs"), (np.empty(1),))


def column_groups(pattern):
    """Partition columns into groups with no shared row (greedy colouring, largest first)."""
    s = sp.csc_matrix(pattern, dtype=float)
    s.data[:] = 1.0
    s.eliminate_zeros()
    n_col = s.shape[1]
    adjacency = (s.T @ s).tocsr()
    degree = np.diff(adjacency.indptr)
    colour = np.full(n_col, -1, dtype=np.intp)
    for j in np.argsort(-degree, kind="stable"):
        used = colour[adjacency.indices[adjacency.indptr[j]:adjacency.indptr[j + 1]]]
        used = set(used[used >= 0].tolist())
        c = 0
        while c in used:
            c += 1
        colour[j] = c
    return [np.flatnonzero(colour == c) for c in range(colour.max() + 1 if n_col else 0)]


def fd_increments(z, typical, direction):
    """Difference-quotient increments sqrt(eps) * max(|z|, typical size), signed.

    IDA's floor ``rtol |y| + atol`` (one unit of the error weight) is far too coarse for
    strongly nonlinear residuals: it is about 1 % of an orifice's pressure drop in a long
    chain, and on Robertson's problem it perturbs y2 ~ 1e-13 by 1e-8. The relative increment
    sqrt(eps) of the value, or of its typical size ``atol / rtol`` where the value is near
    zero, keeps the truncation and the cancellation errors both near sqrt(eps).
    """
    inc = np.maximum(np.abs(z), typical)
    inc *= SQRT_UROUND
    inc[direction < 0] *= -1.0
    return inc


def _compiled_owner(jac):
    """The System whose ``jacobian_dense`` or ``jacobian`` ``jac`` is, or None."""
    owner = getattr(jac, "__self__", None)
    if owner is None or not hasattr(owner, "jacobian_values"):
        return None
    from pvgraph.system import System
    if isinstance(owner, System) and getattr(jac, "__func__", None) in (
            System.jacobian_dense, System.jacobian):
        return owner
    return None


class JacobianEvaluator:
    """Evaluate ``diag-weighted`` combinations of dF/dy and dF/dy' (user function or FD).

    Parameters
    ----------
    fun : callable
        Residual ``fun(t, y, yp) -> ndarray (n,)``.
    n : int
        System size.
    jac : callable or None
        ``jac(t, y, yp, c) -> dF/dy + c dF/dy'`` as dense ndarray or scipy.sparse matrix.
    sparsity : sparse matrix or None
        Structural pattern of ``dF/dy + c dF/dy'``; used to group finite-difference columns.
        Without it (and without ``jac``) systems with n >= SPARSE_MIN_N get their pattern
        detected once, from two dense difference matrices (see ``detect_sparsity``).
    typical : ndarray (n,) or None
        Typical magnitude of each unknown (``atol / rtol``), the floor of the difference
        increments.
    """

    def __init__(self, fun, n, jac=None, sparsity=None, typical=None):
        self.fun = fun
        self.n = n
        self.jac = jac
        self.typical = np.ones(n) if typical is None else np.asarray(typical, dtype=float)
        self.detect = jac is None and sparsity is None and n >= SPARSE_MIN_N
        self.nfev = 0       # residual calls spent on finite differences
        self.nje = 0        # Jacobian evaluations (user calls or FD matrices)
        self.sparse = False
        self.dense_only = False     # dense matrices whatever the size (the C sparse LU)
        self.groups = None
        if sparsity is not None:
            self._use_pattern(sparsity)

    def _use_pattern(self, sparsity):
        """Store the pattern of the iteration matrix and, for differences, its column groups."""
        n, jac = self.n, self.jac
        if (sp.issparse(sparsity) and sparsity.format == "csc" and sparsity.dtype == float
                and sparsity.shape == (n, n) and sparsity.has_canonical_format
                and np.all(sparsity.data == 1.0)):
            pattern = sparsity      # already canonical (a System's): read, never written
        else:
            pattern = sp.csc_matrix(sparsity, dtype=float)
            if pattern.shape != (n, n):
                raise ValueError(f"jac_sparsity has shape {pattern.shape}, expected ({n}, {n})")
            pattern.data[:] = 1.0
            pattern.eliminate_zeros()
            pattern.sort_indices()
        self.pattern = pattern
        self.sparse = n >= SPARSE_MIN_N and not self.dense_only
        if jac is None:
            self.groups = column_groups(pattern)
            rows = pattern.indices
            cols = np.repeat(np.arange(n), np.diff(pattern.indptr))
            self._fd_rows = rows
            self._fd_cols = cols
            # nnz positions belonging to each group, in CSC order
            col_group = np.empty(n, dtype=np.intp)
            for g, members in enumerate(self.groups):
                col_group[members] = g
            pos_group = col_group[cols]
            self._group_pos = [np.flatnonzero(pos_group == g)
                               for g in range(len(self.groups))]

    @property
    def n_groups(self):
        """Residual calls per finite-difference Jacobian."""
        return self.n if self.groups is None else len(self.groups)

    def iteration_matrix(self, t, y, yp, r, cj, ewt, h):
        """Return J = dF/dy + cj dF/dy' at (t, y, yp); ``r`` is F(t, y, yp)."""
        if self.jac is not None:
            self.nje += 1
            return self._convert(self.jac(t, y, yp, cj))
        if self.detect:
            self._detect_pattern(t, y, yp, r, h)
        inc = fd_increments(np.maximum(np.abs(y), np.abs(h * yp)), self.typical, h * yp)
        inc = (y + inc) - y
        return self._finite_difference(t, y, yp, r, inc, inc, cj * inc)

    def _detect_pattern(self, t, y, yp, r, h):
        """Find the pattern of dF/dy + c dF/dy' once, then use grouped differences."""
        self.detect = False
        pattern = detect_sparsity(self.fun, t, y, yp, r, self.typical, h)
        self.nfev += 2 * self.n + 1       # the columns at both points and the shifted base
        self._use_pattern(pattern)

    def mixed_matrix(self, t, y, yp, r, cy, cyp, scale):
        """Return the matrix with column j = cy[j] dF/dy_j + cyp[j] dF/dy'_j.

        ``cy`` and ``cyp`` are 0/1 arrays selecting which derivative each column holds;
        ``scale`` is the typical size of each unknown, used for difference increments.
        """
        if self.detect:
            self._detect_pattern(t, y, yp, r, 1.0)
        if self.jac is not None:
            self.nje += 2
            system = _compiled_owner(self.jac)
            if system is not None and not self.sparse:
                # a System's Jacobian: the same arithmetic on its entries only (the other
                # entries are 0 * cy + 0 * cyp = 0 either way)
                v0 = system.jacobian_values(t, y, yp, 0.0)
                v1 = system.jacobian_values(t, y, yp, 1.0)
                cols = system._cols
                m = np.zeros((self.n, self.n))
                m[system._rows, cols] = v0 * cy[cols] + (v1 - v0) * cyp[cols]
                return m
            j0 = self._convert(self.jac(t, y, yp, 0.0))
            j1 = self._convert(self.jac(t, y, yp, 1.0))
            if self.sparse:
                return (j0 @ sp.diags(cy) + (j1 - j0) @ sp.diags(cyp)).tocsc()
            return j0 * cy + (j1 - j0) * cyp
        z = cy * y + cyp * yp
        inc = fd_increments(z, scale, np.ones_like(z))
        inc = (z + inc) - z
        return self._finite_difference(t, y, yp, r, inc, cy * inc, cyp * inc)

    def _convert(self, m):
        """Bring a user Jacobian to the storage the LU solver expects."""
        if sp.issparse(m):
            if not (self.sparse or self.dense_only or self.groups is not None) and \
                    self.n >= SPARSE_MIN_N:
                self.sparse = True      # a sparse Jacobian of the caller's, without a pattern
            return m.tocsc() if self.sparse else m.toarray()
        m = np.asarray(m, dtype=float)
        if m.shape != (self.n, self.n):
            raise ValueError(f"jac returned shape {m.shape}, expected ({self.n}, {self.n})")
        return sp.csc_matrix(m) if self.sparse else m

    def _finite_difference(self, t, y, yp, r, inc, dy, dyp):
        """Forward differences; column j perturbs y by dy[j] and yp by dyp[j] (scaled 1/inc)."""
        fun = self.fun
        n = self.n
        self.nje += 1
        dy = np.broadcast_to(dy, (n,))
        dyp = np.broadcast_to(dyp, (n,))
        if self.groups is None:
            out = np.empty((n, n))
            yt = y.copy()
            ypt = yp.copy()
            for j in range(n):
                for k, grow in enumerate(_GROWTHS):
                    yt[j] += grow * dy[j]
                    ypt[j] += grow * dyp[j]
                    got = np.asarray(fun(t, yt, ypt)) - r
                    yt[j] = y[j]
                    ypt[j] = yp[j]
                    self.nfev += 1
                    if k and not np.all(np.isfinite(got)):
                        break       # a grown increment overflowed: the column stays zero
                    col, used = got, grow
                    if col.any():
                        break
                out[:, j] = col / (used * inc[j])
            return sp.csc_matrix(out) if self.sparse else out
        data = np.empty(len(self._fd_rows))
        rows, cols = self._fd_rows, self._fd_cols
        for members, pos in zip(self.groups, self._group_pos):
            yt = y.copy()
            ypt = yp.copy()
            yt[members] += dy[members]
            ypt[members] += dyp[members]
            rr = np.asarray(fun(t, yt, ypt))
            data[pos] = (rr[rows[pos]] - r[rows[pos]]) / inc[cols[pos]]
        self.nfev += len(self.groups)
        lost = np.ones(n, dtype=bool)
        lost[cols[data != 0.0]] = False
        for j in np.flatnonzero(lost):
            # a column lost to rounding (an increment far below the residual's size, as for
            # y' of a tiny variable over a long interval) is retried alone, larger
            at = cols == j
            for grow in _GROWTHS[1:]:
                yt = y.copy()
                ypt = yp.copy()
                yt[j] += grow * dy[j]
                ypt[j] += grow * dyp[j]
                rr = np.asarray(fun(t, yt, ypt))
                self.nfev += 1
                got = (rr[rows[at]] - r[rows[at]]) / (grow * inc[j])
                if not np.all(np.isfinite(got)):
                    break       # a grown increment overflowed: the column stays zero
                if got.any():
                    data[at] = got
                    break
        if self.sparse:
            return sp.csc_matrix((data, self.pattern.indices, self.pattern.indptr),
                                 shape=(n, n))
        out = np.zeros((n, n))
        out[rows, cols] = data
        return out


def detect_sparsity(fun, t, y, yp, r, typical, h):
    """Pattern of dF/dy + c dF/dy' from dense differences at (y, y') and at a nearby point.

    An entry that vanishes at one point by accident (a product with a variable that starts
    at zero) rarely vanishes at a randomly displaced second point; non-finite differences
    count as entries. The diagonal is always kept. Costs 2 n + 1 residual calls, once.
    """
    n = y.size
    rng = np.random.default_rng(12345)
    rows = [[] for _ in range(n)]
    shift = 1e-3 * np.maximum(np.abs(y), typical) * rng.uniform(0.5, 1.0, n)
    for yb in (y, y + shift):
        rb = r if yb is y else np.asarray(fun(t, yb, yp), dtype=float)
        inc = fd_increments(yb, typical, np.ones(n))
        dpp = fd_increments(yp, typical / max(abs(h), 1e-300), np.ones(n))
        for j in range(n):
            yt = yb.copy()
            ypt = yp.copy()
            yt[j] += inc[j]
            ypt[j] += dpp[j]
            col = np.asarray(fun(t, yt, ypt), dtype=float) - rb
            rows[j].append(np.flatnonzero((col != 0.0) | ~np.isfinite(col)))
    indices = [np.unique(np.concatenate(rj + [np.array([j])])) for j, rj in enumerate(rows)]
    indptr = np.concatenate([[0], np.cumsum([ix.size for ix in indices])])
    return sp.csc_matrix((np.ones(indptr[-1]), np.concatenate(indices).astype(np.intp), indptr),
                         shape=(n, n))


class LUSolver:
    """LU factorisation of an iteration matrix, dense (LAPACK getrf) or sparse (SuperLU).

    ``factor`` returns 0 on success, ``j + 1`` when column ``j`` has a zero pivot, or -1
    when a sparse factorisation reports exact singularity without a column.

    ``kind="c"`` factorises dense matrices with :class:`pvgraph.solver.clu.SparseLU` instead
    of getrf (the same partial pivoting, sparse elimination in C, a column order chosen for
    ``pattern``, or for the nonzeros of the first matrix); sparse matrices still go to SuperLU.
    """

    def __init__(self, kind="lapack", pattern=None):
        if kind not in ("lapack", "c"):
            raise ValueError(f"LUSolver kind {kind!r}: use 'lapack' or 'c'")
        self.kind = kind
        self.pattern = pattern
        self.nlu = 0
        self._lu = None
        self._piv = None
        self._splu = None
        self._clu = None
        if kind == "c":
            from pvgraph.solver import clu
            if not clu.available():
                from pvgraph.cbackend import CBackendError
                raise CBackendError(f"LUSolver(kind='c') needs the sparse LU kernel "
                                    f"(pvgraph/solver/clu.c): {clu.load_error()}")

    def factor(self, m):
        """Factorise m in place (dense) or by SuperLU (sparse); return the status code."""
        self.nlu += 1
        if sp.issparse(m):
            try:
                self._splu = splu(sp.csc_matrix(m))
            except RuntimeError:
                self._splu = None
                return _singular_column(m)
            self._lu = None
            return 0
        self._splu = None
        if not np.all(np.isfinite(m)):
            return -1
        if self.kind == "c":
            return self._factor_c(m)
        lu, piv, info = _GETRF(m, overwrite_a=True)
        self._lu, self._piv = lu, piv
        return int(info)

    def _factor_c(self, m):
        """The dense matrix m by the C sparse LU (a column order made for the first size)."""
        n = m.shape[0]
        if self._clu is None or self._clu.n != n:
            self._clu = self.c_factoriser(n)
        self._lu = None
        return self._clu.factor(m)

    def c_factoriser(self, n):
        """The :class:`~pvgraph.solver.clu.SparseLU` of ``kind="c"`` for n x n matrices, its
        column order chosen for ``pattern`` (remembered for the pattern: the solvers of one
        system share it), or the natural order without one and below ``CLU_ORDER_MIN_N``
        unknowns (where a fill-reducing order saves nothing: the factors pivot as LAPACK's)."""
        from pvgraph.solver.clu import SparseLU, column_order
        if self._clu is not None and self._clu.n == n:
            return self._clu
        pattern = self.pattern
        if pattern is None or pattern.shape != (n, n) or n < CLU_ORDER_MIN_N:
            self._clu = SparseLU(n)
            return self._clu
        known = _COLUMN_ORDERS.get(id(pattern))
        if known is not None and known[0] is pattern:   # the same pattern object again
            perm = known[1]
        else:
            csc = sp.csc_matrix(pattern)
            key = (n, csc.indptr.tobytes(), csc.indices.tobytes())
            perm = _COLUMN_ORDERS.get(key)
            if perm is None:
                perm = column_order(csc)
            with _COLUMN_ORDERS_LOCK:        # runs in threads share the cache
                while len(_COLUMN_ORDERS) >= 128:
                    _COLUMN_ORDERS.pop(next(iter(_COLUMN_ORDERS)))
                _COLUMN_ORDERS[key] = perm
                _COLUMN_ORDERS[id(pattern)] = (pattern, perm)
        self._clu = SparseLU(n, perm_c=perm)
        return self._clu

    def solve(self, b):
        """Solve with the last factorisation."""
        if self._splu is not None:
            return self._splu.solve(b)
        if self._lu is None and self._clu is not None:
            return self._clu.solve(b)
        x, _ = _GETRS(self._lu, self._piv, b)
        return x


def _singular_column(m):
    """Best guess at a structurally empty column of a singular sparse matrix (1-based)."""
    m = sp.csc_matrix(m)
    empty = np.flatnonzero(np.diff(m.indptr) == 0)
    if empty.size:
        return int(empty[0]) + 1
    return -1
