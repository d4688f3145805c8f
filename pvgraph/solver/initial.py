"""Consistent initial conditions for F(t, y, y') = 0, in the manner of IDACalcIC.

Two problems are solved, as in IDA:

* ``"algebraic"`` (IDA_YA_YDP_INIT): the differential components of y are given; solve for
  the algebraic components of y and for y' of the differential ones. The unknown vector z
  has ``z_j = y_j`` for algebraic j and ``z_j = y'_j`` otherwise, so the Newton matrix has
  column j equal to dF/dy_j or dF/dy'_j.
* ``"all"`` (IDA_Y_INIT): y' is given; solve for all of y with the matrix dF/dy.

Newton's method is used with an exact (or finite-difference) matrix at every iteration and a
backtracking line search on the weighted norm of the Newton step (IDA's merit function).
Convergence is declared when that norm is below 0.01 * 0.33, the same margin IDA uses
below the corrector's convergence constant. ``check_consistency`` serves
``calc_initial=None``: it measures how far the given values are from consistent in units of
the tolerance over a first step, and raises when the distance exceeds one.

References
----------
.. [1] P. N. Brown, A. C. Hindmarsh, L. R. Petzold, "Consistent initial condition
   calculation for differential-algebraic systems", SIAM J. Sci. Comput. 19 (1998)
   1495-1512.
.. [2] A. C. Hindmarsh et al., "User Documentation for IDA", SUNDIALS, section
   "Consistent initial conditions".
"""

from __future__ import annotations

import numpy as np

from pvgraph.errors import InitializationError
from pvgraph.solver.ida import dominant_names, wrms_norm
from pvgraph.solver.linalg import LUSolver

__all__ = ["start_values", "consistent_initial_conditions", "check_consistency", "consistency_distance",
           "derivative_free_columns"]

IC_TOL = 0.01 * 0.33        # weighted Newton-step norm accepted as converged
IC_MAX_ITERS = 30
IC_TIME_FRACTION = 1e-3     # time scale of y' unknowns: this fraction of the interval
AS_IS_DISTANCE = 0.1        # a start this close to consistent (tolerance units) is kept
LINE_SEARCH_MIN = 1e-4      # smallest line-search factor
ARMIJO = 1e-4


def start_values(fun, t0, y0, yp0, mode, algebraic, alg_given, jacobian, rtol, atol,
                 t_span_length, h0, var_names=None, lu_kind="lapack", lu_pattern=None,
                 lu=None):
    """Consistent (y, y') at t0 for the integrators, according to ``calc_initial``.

    ``mode`` None checks the given values and keeps them. ``"algebraic"`` without an
    ``algebraic`` list first measures the given values: a start already consistent to
    within a tenth of the tolerance is kept as it is (a singular, non-diagonal dF/dy' such
    as the Transistor Amplifier's has no variable-wise split to solve for); otherwise the
    variables whose y' has an identically zero column in dF/dy' are taken as algebraic.
    ``lu_kind`` and ``lu_pattern`` make the ``LUSolver`` of the Newton matrices, unless one
    is given as ``lu`` (a caller starting many times reuses it).
    """
    if lu is None:
        lu = LUSolver(lu_kind, pattern=lu_pattern)
    if mode is None:
        check_consistency(fun, t0, y0, yp0, jacobian, lu, h0, rtol, atol, var_names)
        return y0.copy(), yp0.copy()
    mask = algebraic
    if mode == "algebraic" and not alg_given:
        r = np.asarray(fun(t0, y0, yp0), dtype=float)
        dist = consistency_distance(fun, t0, y0, yp0, jacobian, lu, h0, rtol, atol, r)[0]
        if dist is not None and dist <= AS_IS_DISTANCE:
            return y0.copy(), yp0.copy()
        mask = np.zeros(y0.size, dtype=bool)
        mask[derivative_free_columns(jacobian, t0, y0, yp0, r)] = True
    try:
        return consistent_initial_conditions(fun, t0, y0, yp0, mode, mask, jacobian, rtol,
                                             atol, t_span_length, var_names, lu_kind=lu_kind,
                                             lu_pattern=lu_pattern, lu=lu)
    except InitializationError as exc:
        if "singular" not in str(exc):
            raise
        # a DAE of index two (0 = y1 - sin t with y1' = y2): no Newton matrix of the
        # algebraic variables is regular, but a given start that satisfies F is kept as it
        # is, as SUNDIALS IDA does without IDACalcIC (the integration then needs the
        # algebraic variables out of the error test, suppress_alg=True)
        r = np.asarray(fun(t0, y0, yp0), dtype=float)
        dist = consistency_distance(fun, t0, y0, yp0, jacobian, lu, h0, rtol, atol, r)[0]
        if dist is not None and dist <= AS_IS_DISTANCE:
            return y0.copy(), yp0.copy()
        raise InitializationError(
            f"{exc} A DAE of index two starts only from values that satisfy it (hidden "
            f"constraints included, y' too): give such y0 and yp0 and they are kept.") from None


def derivative_free_columns(jacobian, t, y, yp, r):
    """Indices j whose y'_j does not appear in F at (t, y, yp): algebraic by structure."""
    n = y.size
    m = jacobian.mixed_matrix(t, y, yp, r, np.zeros(n), np.ones(n),
                              np.maximum(np.abs(yp), 1.0))
    m = m.toarray() if hasattr(m, "toarray") else m
    return np.flatnonzero(np.all(m == 0.0, axis=0))


def _equation_names(r, var_names, count=3):
    """Describe the equations with the largest |residual| (indices and matching names)."""
    order = np.argsort(-np.where(np.isfinite(r), np.abs(r), np.inf), kind="stable")[:count]
    parts = []
    for i in order:
        label = f"equation {i}"
        if var_names is not None:
            label += f" (row of {var_names[i]!r})"
        parts.append(f"{label}: residual {r[i]:.3g}")
    return "; ".join(parts)


def consistent_initial_conditions(fun, t0, y0, yp0, mode, algebraic, jacobian, rtol, atol,
                                  t_span_length, var_names=None, lu_kind="lapack",
                                  lu_pattern=None, lu=None):
    """Solve for consistent (y, y') at t0.

    Parameters
    ----------
    fun : callable
        Residual ``fun(t, y, yp)`` (already counting its calls).
    t0 : float
        Initial time.
    y0, yp0 : ndarray (n,)
        Starting guesses; the given parts (differential y for ``"algebraic"``, all of y'
        for ``"all"``) are kept.
    mode : {"algebraic", "all"}
        Which unknowns to solve for.
    algebraic : ndarray of bool (n,)
        Algebraic components (their y' does not appear in F).
    jacobian : linalg.JacobianEvaluator
        Source of derivative matrices.
    rtol, atol : float, ndarray
        Tolerances defining the weights.
    t_span_length : float
        Length of the integration interval; sets the time scale of y' unknowns.
    var_names : list of str or None
        Names used in error messages.
    lu_kind : {"lapack", "c"}
        The ``LUSolver`` kind of the Newton matrices.
    lu_pattern : sparse matrix, optional
        Their sparsity pattern (the C LU's column order is chosen for it).
    lu : linalg.LUSolver, optional
        The LU solver to use instead of a new one of ``lu_kind``.

    Returns
    -------
    y, yp : ndarray (n,)
        Consistent values.
    """
    y = np.array(y0, dtype=float)
    yp = np.array(yp0, dtype=float)
    n = y.size
    if mode == "all":
        cy = np.ones(n)
    elif mode == "algebraic":
        cy = np.asarray(algebraic, dtype=float)
    else:
        raise ValueError(f"calc_initial must be 'algebraic', 'all' or None, got {mode!r}")
    cyp = 1.0 - cy
    hic = IC_TIME_FRACTION * abs(t_span_length)
    if lu is None:
        lu = LUSolver(lu_kind, pattern=lu_pattern)
    r = np.asarray(fun(t0, y, yp), dtype=float)
    for it in range(IC_MAX_ITERS):
        if not np.all(np.isfinite(r)):
            raise InitializationError(
                f"consistent initialisation at t = {t0:.9g}: the residual is not finite; "
                + _equation_names(r, var_names))
        ewt = 1.0 / (rtol * np.abs(y) + atol)
        wz = ewt * (cy + hic * cyp)
        scale = 1.0 / (rtol * wz)      # typical size of each unknown: atol/rtol + |y|
        m = jacobian.mixed_matrix(t0, y, yp, r, cy, cyp, scale)
        info = lu.factor(m)
        if info != 0:
            _raise_singular(info, mode, cy, t0, var_names, m,
                            moved=_moved_text(y0, yp0, y, yp, cy, var_names) if it else None)
        dz = lu.solve(r)
        merit = wrms_norm(dz, wz)
        if merit <= IC_TOL:
            y -= cy * dz
            yp -= cyp * dz
            if mode == "algebraic" and cy.any():
                algebraic_rates(fun, t0, y, yp, cy, lu, t_span_length)
            return y, yp
        lam = 1.0
        while True:
            y_try = y - lam * cy * dz
            yp_try = yp - lam * cyp * dz
            r_try = np.asarray(fun(t0, y_try, yp_try), dtype=float)
            if np.all(np.isfinite(r_try)):
                merit_try = wrms_norm(lu.solve(r_try), wz)
                if merit_try <= (1.0 - ARMIJO * lam) * merit:
                    break
            if lam <= LINE_SEARCH_MIN:
                if np.all(np.isfinite(r_try)):
                    break
                raise InitializationError(
                    f"consistent initialisation at t = {t0:.9g}: every Newton step leads to "
                    "a non-finite residual; " + _equation_names(r_try, var_names))
            lam *= 0.5
        y, yp, r = y_try, yp_try, r_try
    names = dominant_names(dz * wz, var_names)
    raise InitializationError(
        f"consistent initialisation at t = {t0:.9g} did not converge in {IC_MAX_ITERS} "
        f"Newton iterations; the largest corrections are in {', '.join(map(repr, names))}; "
        + _equation_names(r, var_names)
        + ". Check the algebraic mask and give better starting values for these variables.")


def algebraic_rates(fun, t0, y, yp, cy, lu, t_span_length):
    """Set y' of the algebraic variables (``cy`` = 1) to their rates at a consistent point.

    The residual does not read them, but the first BDF step predicts with them: a variable
    driven by the time (a position set by a sine, a pressure source following a table) that
    starts with y' = 0 fails the first error tests until the step is tiny (SUNDIALS IDA gives
    up). Along the solution, d/dt F(t, y, y') = 0 gives, with the differential y' known,
    ``M z = -(F_t + F_y,d y'_d)`` for z = (y'_a, y''_d), where M is the matrix of the
    consistent initialisation (columns dF/dy_a and dF/dy'_d), already factorised in ``lu``.
    The right side is one forward difference of F along (1, y'_d, 0). ``yp`` is changed in
    place; where anything is not finite it is left as it was.
    """
    delta = 1e-8 * max(abs(t0), abs(t_span_length), 1e-6)
    move = (1.0 - cy) * yp
    r0 = np.asarray(fun(t0, y, yp), dtype=float)
    r1 = np.asarray(fun(t0 + delta, y + delta * move, yp), dtype=float)
    rhs = (r1 - r0) / delta
    if not np.all(np.isfinite(rhs)):
        return
    z = lu.solve(rhs)
    if not np.all(np.isfinite(z)):
        return
    alg = cy != 0.0
    yp[alg] = -z[alg]


#: largest system whose singular initialisation matrix is explained by its null vector
NULL_VECTOR_MAX_N = 3000


def _moved_text(y0, yp0, y, yp, cy, var_names):
    """Where the Newton iterates of the initialisation took the unknowns furthest from the
    values given (for a failure at an iterate rather than at the start)."""
    y0 = np.asarray(y0, dtype=float)
    yp0 = np.asarray(yp0, dtype=float)
    given = np.where(cy != 0.0, y0, yp0)
    now = np.where(cy != 0.0, y, yp)
    change = np.abs(now - given) / (np.abs(given) + 1.0)
    parts = []
    for j in np.argsort(-change)[:3]:
        if not change[j] > 0.0:
            break
        name = var_names[j] if var_names is not None else f"y[{j}]"
        what = "y" if cy[j] else "y'"
        parts.append(f"{what} of {name!r} from {given[j]:.6g} to {now[j]:.6g}")
    return ", ".join(parts)


def _raise_singular(info, mode, cy, t0, var_names, m=None, moved=None):
    """Explain a singular initialisation matrix: by the unknowns of its null vector (the
    combination the equations leave undetermined: a loop that fixes none of its members,
    two parts pushing one quantity), else by the column where the factorisation stopped.
    ``moved``: where the Newton iterates took the unknowns, when the matrix is not the
    start's."""
    def label(j):
        name = var_names[j] if var_names is not None else f"y[{j}]"
        return f"{'y' if cy[j] else 'y' + chr(39)} of {name!r}"
    if m is not None:
        from .ida import _nonfinite_entries
        bad = _nonfinite_entries(m)
        if bad is not None:
            rows, cols = bad
            where = ("the start (a square root or power at zero, a division by zero), or "
                     "the given jac returns NaN there") if not moved else (
                f"a Newton iterate, not at the values given: the iteration moved {moved}, "
                f"where the equations overflow or are undefined. Give start values nearer the "
                f"solution")
            raise InitializationError(
                f"consistent initialisation ({mode!r}) at t = {t0:.9g}: the Jacobian is not "
                f"finite (NaN or inf) in equation(s) {rows[:5]}, column(s) of "
                f"{', '.join(label(j) for j in cols[:5])}: a derivative is undefined at "
                f"{where}.")
    null = _null_columns(m)
    if null:
        raise InitializationError(
            f"consistent initialisation ({mode!r}) at t = {t0:.9g}: the Newton matrix is "
            f"singular: the equations do not determine the combination of "
            f"{', '.join(label(j) for j in null)}: they hold for every value of it, or for "
            f"none (an algebraic loop with gain 1, two components fixing one quantity, or "
            f"an index above one), or at "
            f"{'these values' if moved else 'the values given'} they change too little with "
            f"it to tell (far out on the flat side of an exponential, a saturation or a "
            f"closed valve: give start values nearer the solution).")
    col = info - 1
    if col < 0:
        raise InitializationError(
            f"consistent initialisation at t = {t0:.9g}: the Newton matrix is singular.")
    hint = ("; if it is algebraic (its derivative does not appear), say so (solve_dae's "
            "`algebraic`)" if mode == "algebraic" and not cy[col] else
            "; the equations may not determine it (structural singularity or index > 1)")
    raise InitializationError(
        f"consistent initialisation ({mode!r}) at t = {t0:.9g}: the Newton matrix is "
        f"singular in the column of {label(col)}{hint}.")


def _null_columns(m, k=4) -> list:
    """The columns (up to ``k``, largest first) of the null vector of a singular matrix,
    from its SVD with the columns scaled to unit norm; [] when that cannot be told."""
    if m is None:
        return []
    try:
        import scipy.sparse as sp
        a = m.toarray() if sp.issparse(m) else np.asarray(m, dtype=float)
        n = a.shape[1]
        if n == 0 or n > NULL_VECTOR_MAX_N or not np.all(np.isfinite(a)):
            return []
        norms = np.linalg.norm(a, axis=0)
        if np.any(norms == 0.0):        # an empty column is the answer by itself
            return [int(j) for j in np.flatnonzero(norms == 0.0)[:k]]
        _, sv, vt = np.linalg.svd(a / norms)
        if sv[-1] > 1e-8 * sv[0]:
            return []
        v = np.abs(vt[-1])
        order = [int(j) for j in np.argsort(-v) if v[j] > 0.1 * v.max()]
        return order[:k]
    except (ValueError, np.linalg.LinAlgError, MemoryError):
        return []


def consistency_distance(fun, t0, y0, yp0, jacobian, lu, h0, rtol, atol, r=None):
    """How far (y0, yp0) is from consistent, in tolerance units: (distance, dz, ewt, r).

    The measure is the Newton correction a first BDF step of size h0 would have to make,
    ``J^-1 F`` with ``J = dF/dy + dF/dy' / h0``, in the weighted RMS norm. The distance is
    None when J is singular (left to the caller).
    """
    if r is None:
        r = np.asarray(fun(t0, y0, yp0), dtype=float)
    ewt = 1.0 / (rtol * np.abs(y0) + atol)
    if not np.all(np.isfinite(r)):
        return np.inf, None, ewt, r
    m = jacobian.iteration_matrix(t0, y0, yp0, r, 1.0 / h0, ewt, h0)
    if lu.factor(m) != 0:
        return None, None, ewt, r
    dz = lu.solve(r)
    return wrms_norm(dz, ewt), dz, ewt, r


def check_consistency(fun, t0, y0, yp0, jacobian, lu, h0, rtol, atol, var_names=None):
    """Raise InitializationError when (y0, yp0) is inconsistent beyond the tolerance.

    See ``consistency_distance``; above one the given values are not consistent to within
    the tolerance. A singular J is left to the integrator, which reports it with the
    offending column.
    """
    dist, dz, ewt, r = consistency_distance(fun, t0, y0, yp0, jacobian, lu, h0, rtol, atol)
    if dist is not None and not np.isfinite(dist):
        raise InitializationError(
            f"the initial residual at t = {t0:.9g} is not finite; "
            + _equation_names(r, var_names))
    if dist is not None and dist > 1.0:
        names = dominant_names(dz * ewt, var_names)
        raise InitializationError(
            f"the initial values at t = {t0:.9g} are not consistent (distance {dist:.3g} "
            f"tolerance units); the worst variables are {', '.join(map(repr, names))}; the "
            f"worst equations: {_equation_names(r, var_names)}. Use calc_initial="
            "'algebraic' or 'all', or correct y0/yp0.")
    return r
