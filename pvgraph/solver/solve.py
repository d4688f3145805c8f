"""``solve_dae``: integrate F(t, y, y') = 0 with the IDA-style BDF method of ``ida.py``.

The driver owns everything around the stepping: argument checks, consistent initial
conditions, output at internal steps or at ``t_eval`` (interpolated), events with their
location, recording, terminal stops and mode-switching actions (followed by a new
consistent initialisation and a restart at order 1), dense output and statistics.
"""

from __future__ import annotations

import functools
import math
import warnings

import numpy as np

from pvgraph.errors import (InitializationError, PlausibilityWarning, SolverError,
                            outside_stacklevel)
from pvgraph.solver.events import (CHATTER_EVENTS, EventTracker, atol_vector, check_times,
                                   normalize_events, stopping_event)
from pvgraph.solver.cstep import ADV_END, ADV_PAUSE, make_integrator
from pvgraph.solver.cstep import c_run as _c_run, c_system_of as _c_system_of
from pvgraph.solver.ida import ERROR_FAIL, SOLVER_NAME, UROUND, dominant_names, initial_step
from pvgraph.solver.initial import start_values
from pvgraph.solver.linalg import JacobianEvaluator, LUSolver
from pvgraph.solver.result import DAEResult, DenseOutput, EventRecord

__all__ = ["solve_dae"]

END_FUZZ = 100.0            # reaching t_end within END_FUZZ * eps * (|t| + |h|) is reaching it


class _Counted:
    """Residual wrapper that counts calls and guarantees a float ndarray result."""

    def __init__(self, fun, convert):
        self.fun = fun
        self.convert = convert
        self.calls = 0

    def __call__(self, t, y, yp):
        self.calls += 1
        r = self.fun(t, y, yp)
        return np.asarray(r, dtype=float) if self.convert else r


def _as_mask(algebraic, n, what="algebraic"):
    """Boolean mask of algebraic components from a mask or an index list (``what`` names the
    argument in the messages)."""
    if algebraic is None:
        return np.zeros(n, dtype=bool)
    a = np.asarray(algebraic)
    if a.dtype == bool:
        if a.shape != (n,):
            raise ValueError(f"{what} mask has shape {a.shape}, expected ({n},)")
        return a.copy()
    mask = np.zeros(n, dtype=bool)
    if a.size:
        if a.dtype.kind not in "iu" and not (a.dtype.kind == "f" and np.all(a == np.round(a))):
            raise ValueError(f"{what} must be a boolean mask of {n} values or a list of "
                             f"indices, got {algebraic!r}")
        idx = a.astype(int).ravel()
        if idx.size == n and n > 1 and set(idx.tolist()) <= {0, 1} and \
                len(set(idx.tolist())) < idx.size:
            raise ValueError(f"{what} = {list(algebraic)!r} reads as a list of indices "
                             f"(y[0], y[1]), not as a mask: give indices "
                             f"({np.flatnonzero(idx).tolist()}) or booleans")
        if idx.min() < -n or idx.max() >= n:
            raise ValueError(f"{what} indices {idx.tolist()} out of range for n = {n}")
        mask[idx] = True
    return mask


def solve_dae(residual, t_span, y0, yp0, *, rtol=1e-6, atol=1e-8, algebraic=None, jac=None,
              jac_sparsity=None, events=None, t_eval=None, max_step=None, first_step=None,
              calc_initial="algebraic", max_order=5, max_steps=100_000, var_names=None,
              dense_output=False, suppress_alg=False, no_growth_after_failure=None,
              nonnegative=None, newton_iterate_retry=None, c_step=None, linear_solver=None):
    """Solve the implicit DAE F(t, y, y') = 0 of index at most one.

    A semi-explicit DAE of index two (Hessenberg form: a constraint on differential
    variables, 0 = x u + y v for a pendulum's velocities, with its multiplier algebraic) runs
    too from a start that satisfies it, with its algebraic variables named (``algebraic=``)
    and left out of the error test (``suppress_alg=True``), as SUNDIALS IDA runs it.

    Parameters
    ----------
    residual : callable
        ``residual(t, y, yp) -> ndarray (n,)``.
    t_span : (float, float)
        Start and end time, ``t_span[1] > t_span[0]``.
    y0, yp0 : array_like (n,)
        Initial values and derivatives (corrected according to ``calc_initial``).
    rtol : float
        Relative tolerance.
    atol : float or array_like (n,)
        Absolute tolerance(s), positive.
    algebraic : array_like of bool (n,) or of int, optional
        Algebraic variables (their derivative does not appear in F). They are solved for by
        ``calc_initial="algebraic"`` and, with ``suppress_alg=True``, left out of the local
        error test. If None and the initial calculation needs them, a start already
        consistent is kept as it is, otherwise the variables whose derivative has an
        identically zero column in dF/dy' at t0 are taken as algebraic for the
        initialisation only.
    suppress_alg : bool
        Leave the algebraic variables out of the error test (IDA's suppressalg). Off by
        default, as in IDA: measured on the IVP Test Set it loses 0.4-0.9 digits on Akzo
        Nobel and 0.3 on Robertson against IDA, and on the PVG 32 rig test 2 (rtol 1e-6)
        it halves the steps (295 against 616) but leaves a 5x larger error (217 against 45
        tolerance units against an rtol 1e-9 run), because algebraic values between steps
        are not error-controlled. Pass True where speed matters more.
    no_growth_after_failure : bool, optional
        Forbid a step increase right after a failed attempt (CVODE's rule); default
        ``ida.NO_GROWTH_AFTER_FAILURE`` (off, IDA's behaviour; see ``ida.py``).
    newton_iterate_retry : bool, optional
        After a fresh Jacobian at the predictor fails to contract, refresh it once at the last
        Newton iterate before cutting the step; default ``ida.NEWTON_ITERATE_RETRY`` (off,
        IDA's behaviour; ``simulate`` switches it on, see ``ida.py``).
    c_step : bool, optional
        Take the steps in C (:mod:`pvgraph.solver.cstep`: the same numbers as the Python
        step, bit for bit). None (default): where it applies -- the residual is a C-route
        ``System.residual`` of at least 2 unknowns and no variable is ``nonnegative`` -- and
        a C compiler is found (sparse iteration matrices are solved by SuperLU, called back
        from C); False: always the Python step; True: the C step, ValueError where it does
        not apply.
    linear_solver : {None, "lapack", "c"}
        How the iteration matrix is factorised. ``"lapack"``: dense LAPACK ``getrf`` below
        100 unknowns (or without a sparsity pattern), SuperLU above. ``"c"``: the sparse LU
        with LAPACK's partial pivoting in C (:mod:`pvgraph.solver.clu`) up to ``CLU_MAX_N``
        unknowns, SuperLU above; needs a C compiler. None (default): ``"c"`` where the
        residual is a C-route ``System.residual`` and the kernel builds, otherwise
        ``"lapack"``. Both pivot alike, so results differ only by rounding; the Python
        and the C step give the same numbers bit for bit with either.
    jac : callable, optional
        ``jac(t, y, yp, c) -> dF/dy + c dF/dy'`` as ndarray or scipy.sparse matrix. Finite
        differences when None.
    jac_sparsity : sparse matrix or array, optional
        Pattern of ``dF/dy + c dF/dy'``; finite differences then perturb groups of
        structurally independent columns together, and systems with n >= 100 use SuperLU.
        Without ``jac`` and ``jac_sparsity``, systems with n >= 100 have their pattern
        detected once from dense differences at two nearby points (2 n residual calls).
        Difference increments are sqrt(eps) max(|y|, atol / rtol): ``atol / rtol`` is
        taken as each variable's typical size.
    events : list of Event or scipy-style callables, optional
        Zero crossings to locate; see ``Event``.
    t_eval : array_like, optional
        Sorted output times inside t_span, interpolated from the BDF history (which keeps
        the equations' linear relations on every row). With ``suppress_alg`` the algebraic
        variables are not error-controlled, so where events are located between steps they
        are solved from the equations at the interpolated states, where that is the better
        value (``stats["nlu_events"]``: the matrices that took). By default every internal
        step (and both sides of every event with an action) is output.
    max_step : float, optional
        Largest step size. A forcing term that switches (a pulse from 1 s to 1.001 s) is
        seen only where a step lands in it: the steps may jump over a short one (the
        error test sees nothing before it). Give its edges as events (a non-terminal
        ``Event(lambda t, y, yp: t - 1.001, action=lambda t, y, yp: None)`` restarts
        there, as IDA's stop time), or a ``max_step`` below its length.
    first_step : float, optional
        First step size (otherwise IDA's estimate).
    calc_initial : {"algebraic", "all", None}
        ``"algebraic"``: solve algebraic y and all y' for the given differential y
        (IDA_YA_YDP_INIT); ``"all"``: solve all y for the given y' (IDA_Y_INIT); None: use
        the given values after checking they are consistent to within the tolerance.
    max_order : int
        Highest BDF order (1 to 5).
    max_steps : int
        Most steps allowed.
    var_names : list of str, optional
        Variable names for error messages.
    dense_output : bool
        Provide ``result.sol(t)``: the steps' interpolating polynomials, kept after the run,
        for every variable, as the rows at ``t_eval``.
    nonnegative : array_like of int or bool, optional
        Variables that must stay >= 0 (concentrations, amounts), as IDA's constraints:
        a step that makes one negative is retried shorter, and the run stops with
        SolverError if no step can avoid it. The local error test alone allows a
        component far below its ``atol`` to change sign, and some problems are unstable
        there. Robertson's reactions to t = 4e10 at ``rtol=1e-4`` and ``atol=(1e-6, 1e-10,
        1e-6)``: at t = 1.3e10 a doubled order-1 step extrapolates y1 (2.6e-7, true value
        1.6e-7) below zero and the corrector converges to the second, negative root of the
        BDF equation (y1 = -5.2e-7, within atol, so the error test passes). For y1 < 0 the
        reactions blow up in finite time (with y2 = 4e-6 y1 in quasi-steady state,
        y1' = -4.8e-4 y1^2, singular after 2083 / |y1| s), and the run ends at y1 = -6.0e5,
        y3 = +6.0e5. SUNDIALS IDA given the same Jacobian and stop time takes the same 632
        steps to the same values; with its difference-quotient Jacobian it misses this
        case but drifts away (y1 = -1.9e7 to -8e146) at 8 of 49 pairs of one rtol in
        1e-2..1e-8 and one atol in 1e-4..1e-10, rtol = atol = 1e-4 among them. Declared non-negative, every rtol in 1e-2..1e-8 with atol in 1e-4..1e-10
        stays >= 0 and within 2 tolerance units of the reference. ``True``: all of them.

    Returns
    -------
    DAEResult

    Raises
    ------
    InitializationError
        No consistent initial values were found, or the given ones are inconsistent.
    SolverError
        The integration failed; the message gives t, h and the dominating variables.

    References
    ----------
    .. [1] A. C. Hindmarsh et al., "User Documentation for IDA", SUNDIALS.
    """
    t0, t_end, y0, yp0, rtol, atol, var_names = check_arguments(
        t_span, y0, yp0, rtol, atol, max_steps, var_names)
    n = y0.size
    if calc_initial not in ("algebraic", "all", None):
        raise ValueError(f"calc_initial must be 'algebraic', 'all' or None, got {calc_initial!r}")
    alg_mask = _as_mask(algebraic, n)
    if suppress_alg and algebraic is None:
        warnings.warn("suppress_alg=True leaves out of the error test the variables named by "
                      "algebraic=, and none are named: every variable stays in it",
                      RuntimeWarning, stacklevel=2)
    event_list = normalize_events(events)
    t_eval = check_times(t0, t_end, t_eval, max_step, first_step)
    nonneg = _nonnegative(nonnegative, n, y0, var_names)

    with np.errstate(all="ignore"):
        return _integrate(residual, t0, t_end, y0, yp0, rtol, atol, alg_mask,
                          algebraic is not None, bool(suppress_alg), jac, jac_sparsity, event_list, t_eval,
                          max_step, first_step, calc_initial, int(max_order), int(max_steps),
                          var_names, dense_output, no_growth_after_failure, nonneg,
                          newton_iterate_retry, c_step, linear_solver)


def check_arguments(t_span, y0, yp0, rtol, atol, max_steps, var_names):
    """The arguments ``solve_dae`` and ``solve_dae_sundials`` share, checked and converted:
    ``(t0, t_end, y0, yp0, rtol, atol, var_names)``; a bad one raises naming it."""
    try:
        t0, t_end = (float(t) for t in t_span)
    except (TypeError, ValueError):
        raise ValueError(f"t_span must be two numbers (t0, t_end), got {t_span!r}") from None
    if not (np.isfinite(t0) and np.isfinite(t_end) and t_end > t0):
        raise ValueError(f"t_span must be finite and increasing, got {t_span!r}")
    for name, value in (("y0", y0), ("yp0", yp0)):
        if np.ndim(value) > 1:
            raise ValueError(f"{name} must be one-dimensional (one value per variable), got "
                             f"shape {np.shape(value)}")
    y0 = np.array(y0, dtype=float).ravel()
    yp0 = np.array(yp0, dtype=float).ravel()
    n = y0.size
    if n == 0:
        raise ValueError("y0 is empty: there is nothing to integrate")
    if yp0.size != n:
        raise ValueError(f"y0 has {n} entries but yp0 has {yp0.size}")
    if not (np.all(np.isfinite(y0)) and np.all(np.isfinite(yp0))):
        raise InitializationError("y0 and yp0 must be finite")
    try:
        rtol = float(rtol)
    except (TypeError, ValueError):
        raise ValueError(f"rtol must be one positive number (as IDA's: one relative "
                         f"tolerance for every variable; give per-variable tolerances "
                         f"through atol), got {rtol!r}") from None
    if not rtol > 0.0 or not np.isfinite(rtol):
        raise ValueError(f"rtol must be positive and finite, got {rtol}")
    if rtol < RTOL_MIN:
        # below this the error test asks for digits the arithmetic does not have: the steps
        # shrink to rounding (scipy's solvers raise rtol to the same floor)
        warnings.warn(f"rtol = {rtol:g} is below {RTOL_MIN:g} (100 machine epsilons); using "
                      f"{RTOL_MIN:g}", RuntimeWarning, stacklevel=3)
        rtol = RTOL_MIN
    atol = atol_vector(atol, n)
    bad = np.flatnonzero(~(atol > 0.0) | ~np.isfinite(atol))
    if bad.size:
        which = ", ".join(f"{'y[%d]' % j if var_names is None else repr(str(var_names[j]))} = "
                          f"{float(atol[j])!r}" for j in bad[:3])
        raise ValueError(f"atol must be positive and finite for every variable; got {which}")
    if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or \
            max_steps < 1:
        raise ValueError(f"max_steps must be a positive integer, got {max_steps!r}")
    if var_names is not None:
        var_names = [str(v) for v in var_names]
        if len(var_names) != n:
            raise ValueError(f"var_names has {len(var_names)} names for {n} variables")
    return t0, t_end, y0, yp0, rtol, atol, var_names


RTOL_MIN = 100.0 * np.finfo(float).eps   # smallest rtol taken (scipy's floor too)
CLU_MAX_N = 600     # largest system the C sparse LU takes (it is given dense matrices)


def _lu_kind(linear_solver, residual, n):
    """The LUSolver kind for ``linear_solver`` (see solve_dae)."""
    if linear_solver not in (None, "lapack", "c"):
        raise ValueError(f"linear_solver must be None, 'lapack' or 'c', got {linear_solver!r}")
    if linear_solver == "lapack" or n > CLU_MAX_N:
        return "lapack"
    from pvgraph.solver import clu
    if linear_solver == "c":
        if not clu.available():
            from pvgraph.cbackend import CBackendError
            raise CBackendError("linear_solver='c' needs the sparse LU kernel "
                                f"(pvgraph/solver/clu.c): {clu.load_error()}")
        return "c"
    return "c" if _c_system_of(residual) is not None and clu.available() else "lapack"


#: a run whose error-test failures pass this count and this fraction of its steps is warned
#: about (an index-2 DAE run with its multiplier in the error test: 98 % of 96 000 steps)
THRASH_MIN_FAILURES = 1000
THRASH_FRACTION = 0.5

#: a point where events are evaluated keeps its interpolated values where the first Newton
#: correction of its algebraic variables (weighted RMS, in tolerance units) is below this;
#: it is solved to it otherwise
CONSISTENT_TOL = 1e-2
CONSISTENT_ITERS = 6
#: an algebraic variable whose solved value would carry more than this many of its tolerance
#: units from one unit of error in the states keeps its interpolated value
AMPLIFICATION_MAX = 3.0


def _consistent_interpolant(integ, fun, jacobian, lu, alg_mask, rtol, atol, counter):
    """The step's interpolant with the algebraic variables solved at each time asked (for
    the functions of events between steps).

    With the algebraic variables out of the error test (``suppress_alg``) the BDF interpolant
    of a step is error-controlled for the states only: across a kink of an algebraic variable
    (a saturation, a valve closing) the interpolated value can be far from the equations at
    the interpolated states. Event functions are taken at ``(y, y')`` with the states
    interpolated and the algebraic variables, with the states' rates, solved from
    ``F(t, y, y') = 0``, as IDA's consistent initial conditions are found
    (``IDA_YA_YDP_INIT``): Newton with the matrix of columns ``dF/dy_a`` (algebraic) and
    ``dF/dy'_d`` (states), factorised in ``lu`` and kept while it contracts fast (made again
    at the point where it does not). The solved values are kept only where they are the
    better ones: an algebraic variable whose solved value would carry more than
    ``AMPLIFICATION_MAX`` of its tolerance units from one unit of error in the states (a
    small chamber's port flow, the difference of two orifice flows) keeps its interpolated
    value, and so do the states' rates. A point whose first correction is small (one residual
    and one solve) stays as interpolated; one whose iteration does not contract on a fresh
    matrix stays as interpolated too. What is decided depends on the points asked only, so
    the Python and C steps agree bit for bit. ``counter`` counts the residual evaluations
    (``"nre"``) and the matrices (``"nlu"``).
    """
    alg = np.flatnonzero(alg_mask)
    states = np.flatnonzero(~alg_mask)
    cy = alg_mask.astype(float)
    cyp = 1.0 - cy
    inv_n = 1.0 / max(alg_mask.size, 1)
    made = {"ok": None}     # None: no matrix yet; True: factorised; False: singular
    # which algebraic variables the equations determine better than the interpolant does:
    # one solved from states that are right to their tolerance inherits their error times
    # its sensitivity to them (a small chamber's port flow, the difference of two orifice
    # flows at its interpolated pressure, was 1000 tolerance units off); it keeps its
    # interpolated value. Estimated at each new matrix from a few fixed random directions.
    trusted = {"a": np.ones(alg.size, dtype=bool)}
    probes = np.random.default_rng(20261124).choice([-1.0, 1.0], size=(3, states.size))
    n_all = alg_mask.size

    def size(d, ewt):
        """The part of a correction on the algebraic variables kept solved, weighted RMS in
        tolerance units."""
        keep = alg[trusted["a"]]
        v = d[keep] * ewt[keep]
        return math.sqrt(float(np.dot(v, v)) * inv_n)

    def refresh(t, y, yp, r):
        scale = np.abs(y) + atol / rtol
        m = jacobian.mixed_matrix(t, y, yp, r, cy, cyp, scale)
        made["ok"] = lu.factor(m) == 0
        counter["nlu"] += 1
        if made["ok"] and alg.size and states.size:
            # the algebraic variables' error from one tolerance unit of error in each state
            # (RMS over the probe directions), in their own tolerance units
            dfdy = jacobian.mixed_matrix(t, y, yp, r, np.ones(n_all), np.zeros(n_all), scale)
            ewt = 1.0 / (rtol * np.abs(y) + atol)
            on_states = dfdy[:, states]
            spread = np.zeros(n_all)
            for signs in probes:
                z = lu.solve(np.asarray(on_states @ (signs / ewt[states])).ravel())
                spread += z * z
            amp = np.sqrt(spread[alg] / len(probes)) * ewt[alg]
            trusted["a"] = ~(amp > AMPLIFICATION_MAX)
        return made["ok"]


    def _solve(t, y, yp):
        if made["ok"] is not None and not trusted["a"].any():
            return y, yp        # every algebraic variable keeps its interpolated value
        ewt = 1.0 / (rtol * np.abs(y) + atol)
        r = fun(t, y, yp)
        counter["nre"] += 1
        if not np.all(np.isfinite(r)):
            return y, yp
        fresh = False
        if made["ok"] is None:
            fresh = refresh(t, y, yp, r)
        if not made["ok"]:
            return y, yp
        y_a, yp_s = y[alg].copy(), yp[states].copy()
        last = math.inf
        for k in range(CONSISTENT_ITERS):
            d = lu.solve(r)
            got = size(d, ewt)
            if k == 0 and got <= CONSISTENT_TOL:
                return y, yp
            if not got < (0.9 if fresh else 0.25) * last:
                if fresh or k == 0 or not refresh(t, y, yp, r):
                    break
                fresh, last = True, math.inf
                continue
            y[alg] -= d[alg]
            yp[states] -= d[states]
            if got <= CONSISTENT_TOL:
                return kept(y, yp, y_a, yp_s)
            last = got
            r = fun(t, y, yp)
            counter["nre"] += 1
            if not np.all(np.isfinite(r)):
                break
        y[alg], yp[states] = y_a, yp_s
        return y, yp

    def kept(y, yp, y_a, yp_s):
        """The solved row with the interpolated values put back where they are the better
        ones: the algebraic variables too sensitive to the states' errors, and the states'
        rates (a rate solved from the equations carries the states' error times the
        system's eigenvalues)."""
        out = ~trusted["a"]
        if out.any():
            y[alg[out]] = y_a[out]
        yp[states] = yp_s
        return y, yp

    def interpolate(t):
        y, yp = integ.interpolate(t)
        y, yp = np.array(y, dtype=float), np.array(yp, dtype=float)
        try:
            return _solve(t, y.copy(), yp.copy())
        except (ArithmeticError, ValueError, SolverError):
            # a residual that cannot be evaluated near the interpolated point (a user's
            # function raising off its domain): the point stays as interpolated
            return y, yp

    return interpolate


def _first_hit(found, event_list, interpolate, records, t_old, t_new):
    """Record the crossings ``found`` in a step up to the first one that stops the step (an
    action or a terminal event), with every crossing at that same instant.

    Returns ``(te, indices, event, y, yp)``: the indices of the events with an action (or
    terminal) whose zero is at ``te``, in declaration order, and ``event`` the first of them
    (terminal if any is); or None. Two events with one zero (two steps at one t_step) are
    located apart only by rounding; both fire.
    """
    for k, (te, i, direction) in enumerate(found):
        ev = event_list[i]
        ye, ype = interpolate(te)
        records.append(EventRecord(te, i, ev.name, ye, ype, direction))
        if not (ev.terminal or ev.action is not None):
            continue
        tol = 2.0 * (8.0 * UROUND * max(abs(te), abs(t_new)) + 1e-14 * abs(t_new - t_old))
        fired = [i]
        for tj, j, dj in found[k + 1:]:
            if tj - te > tol:
                break
            other = event_list[j]
            records.append(EventRecord(te, j, other.name, ye, ype, dj))
            if other.terminal or other.action is not None:
                fired.append(j)
        fired.sort()
        return te, fired, stopping_event(fired, event_list), ye, ype
    return None


def _chattering(state, te, fired, event_list, h, solver_name=SOLVER_NAME, ulps=64.0):
    """``(first time, count)`` of the actions in a row with no time between them (their zeros
    apart by rounding only: ``ulps`` units of ``max(|t|, |h|)``; IDA locates a root to 100
    units of ``|t| + |h|``); SolverError once the count reaches CHATTER_EVENTS."""
    t_first, count, t_last = state if state is not None else (te, 0, te)
    if te - t_last > ulps * UROUND * max(abs(te), abs(h), 1e-300):
        t_first, count = te, 0
    count += 1
    if count >= CHATTER_EVENTS:
        names = ", ".join(repr(event_list[j].name) for j in fired)
        raise SolverError(
            f"{solver_name}: event {names} fired {count} times in a row between t = "
            f"{t_first:.12g} and {te:.12g}, with no time between its zeros: the model switches "
            f"without end (a sliding mode or Zeno behaviour, e.g. a relay without hysteresis "
            f"whose switch reverses the motion that triggered it). Give the switch a "
            f"hysteresis or a smooth law.", t=te)
    return t_first, count, te


def _why_many_steps(integ, var_names) -> str:
    """What held the step size, for the message of a run out of steps: the share of steps
    that failed the local error test and the variables whose error estimate dominates, or the
    usual suspects."""
    nst, netf = max(int(getattr(integ, "nst", 0)), 1), int(getattr(integ, "netf", 0))
    fail = getattr(integ, "_fail", None)    # (kind, weighted error) of the last failure
    if netf < 0.3 * nst or fail is None or fail[0] != ERROR_FAIL:
        return "check the model for fast oscillations or chattering events."
    names = dominant_names(np.abs(np.asarray(fail[1])), var_names)
    return (f"loosen the tolerances: {netf} of the {nst} steps failed the local error test "
            f"(order {integ.kused} at the end), the step size is held by the local error of "
            f"{', '.join(map(repr, names))}. An algebraic variable that amplifies the error of "
            f"a state (it reads a state times a large gain) does this; leave it out of the "
            f"error test (suppress_alg=True) or tighten atol of that state. So does a DAE of "
            f"index two or more (an algebraic equation that fixes a differential variable, "
            f"0 = y1 - sin t with y1' = y2): name the algebraic variables (algebraic=...) to "
            f"have it checked, or reduce the index (pvgraph.dae.compile_dae).")


MAX_RESCUES = 20           # restarts past a failed corrector in one run (see _rescue): more
                           # mean a node the run keeps failing on, whose values are not to be
                           # trusted (a trapped pressure between closed valves): it stops there
RESCUE_TRIES = 4           # ... each tried at 1/4, 1/40, 1/400, 1/4000 of the last step


def _rescue(exc, integ, initialise, t_end, rescue, tracker):
    """``(y, y', t, t_last)`` a quarter of the last step beyond the last accepted one (the
    history's prediction for the states, the algebraic variables solved with a line search;
    nearer where none is found there), or
    ``exc`` raised where that does not apply: not a corrector failure, too many rescues, an
    event crossing within it, or no consistent values there."""
    from .ida import NEWTON_FAIL
    fail = getattr(integ, "_fail", None)
    if rescue["count"] >= MAX_RESCUES or fail is None or fail[0] != NEWTON_FAIL or \
            "corrector failures" not in str(exc):
        raise exc
    t_r = integ.tn
    delta = 0.25 * abs(integ.hused) if integ.hused else rescue["delta"]
    delta = min(delta, t_end - t_r)
    if not delta > 16.0 * UROUND * max(abs(t_r), 1.0):
        raise exc
    for _ in range(RESCUE_TRIES):     # nearer to the last step where none is found
        t_new = t_r + delta
        y_p, yp_p = integ.interpolate(t_new)
        try:
            y_new, yp_new = initialise(t_new, np.array(y_p, dtype=float),
                                       np.array(yp_p, dtype=float), "algebraic")
            break
        except (InitializationError, SolverError):
            delta *= 0.1
            if not delta > 16.0 * UROUND * max(abs(t_r), 1.0):
                raise exc from None
    else:
        raise exc
    if tracker is not None and tracker.crossings(t_r, t_new, tracker.evaluate(t_new, y_new,
                                                                              yp_new),
                                                 integ.interpolate):
        raise exc
    rescue["count"] += 1
    rescue["delta"] = delta
    rescue.setdefault("first", (t_r, list(getattr(exc, "culprits", []))[:3]))
    integ.nrescue = getattr(integ, "nrescue", 0) + 1
    return y_new, yp_new, t_new, t_r


def _apply_actions(fired, event_list, te, ye, ype, initialise, mode):
    """The state after the actions of the events ``fired`` at ``te`` (in declaration order),
    made consistent."""
    for j in fired:
        ye, ype = event_list[j].apply(te, ye, ype)
    try:
        return initialise(te, ye, ype, mode)
    except InitializationError as exc:
        names = ", ".join(repr(event_list[j].name) for j in fired)
        text = str(exc)
        index_two = "A DAE of index two starts only"
        if index_two in text:
            # inside a run the values are the action's, not y0 and yp0
            text = text[:text.index(index_two)] + (
                "A DAE of index two restarts only from values that satisfy it (hidden "
                "constraints included, y' too), which the state at an event is not: it is "
                "the steps' interpolant, and the index-two variables are not error-controlled "
                "there. Return such values from the action (y put back on the constraints, "
                "y' and the multipliers from the equations), as IDA needs them after "
                "IDAReInit; they are then kept.")
        raise InitializationError(f"after event {names} at t = {te:.9g}: {text}") from exc


def _rows_after_action(ts, ys, yps, te, ye, ype, steps):
    """The output after an action at ``te``: a row of its own after the state before
    (``steps``: the rows are the steps), or the rows at ``te`` (output times) take it."""
    if steps:
        ts.append(te)
        ys.append(ye.copy())
        yps.append(ype.copy())
        return
    for k in range(len(ts) - 1, -1, -1):
        if ts[k] < te:
            break
        ys[k], yps[k] = ye.copy(), ype.copy()


def _final_actions(fired, event_list, te, ye, ype, initialise, mode, ts, ys, yps, steps,
                   solver_name=SOLVER_NAME):
    """At a terminal event: the actions of the events ``fired`` with it still run (a mode
    switch, a reset at the instant the run stops, as Modelica's when-clauses run at a
    ``terminate()``), and the output ends with the state after them: a row of its own after
    the state before (``steps``: the rows are the steps), or the rows at ``te`` (output
    times) take it."""
    if all(event_list[j].action is None for j in fired):
        return
    y_act, yp_act = ye, ype
    for j in fired:
        y_act, yp_act = event_list[j].apply(te, y_act, yp_act)
    try:
        ye, ype = initialise(te, y_act, yp_act, mode)
    except InitializationError as exc:
        # nothing is integrated after the stop: the state the actions left is the last row
        # (an index-two DAE is not made consistent by a restart; values the actions did not
        # change stand as they were found)
        if not (np.array_equal(y_act, ye) and np.array_equal(yp_act, ype)):
            names = ", ".join(repr(event_list[j].name) for j in fired)
            warnings.warn(PlausibilityWarning(
                f"{solver_name}: the run stopped at the terminal event {names} at t = "
                f"{te:.9g}; the state its actions left could not be made consistent ({exc}); "
                f"the last output row is that state as the actions returned it."),
                stacklevel=outside_stacklevel())
        ye, ype = y_act, yp_act
    _rows_after_action(ts, ys, yps, te, ye, ype, steps)


def _nonnegative(nonnegative, n, y0, var_names):
    """The indices of the variables constrained to y >= 0 (checked at the start), or None."""
    if nonnegative is None or nonnegative is False:
        return None
    if nonnegative is True:
        idx = np.arange(n)
    else:
        idx = np.flatnonzero(_as_mask(nonnegative, n, "nonnegative"))
    bad = idx[y0[idx] < 0.0]
    if bad.size:
        names = [var_names[i] if var_names is not None else f"y[{i}]" for i in bad[:3]]
        raise InitializationError(f"y0 is negative in {', '.join(map(repr, names))}, declared "
                                  "non-negative")
    return idx if idx.size else None


def _of_a_system(residual) -> bool:
    """Whether ``residual`` is a compiled System's (its algebraic mask is the compiler's)."""
    from pvgraph.system import System
    return isinstance(getattr(residual, "__self__", None), System)


def _check_declared_algebraic(jacobian, t0, y0, yp0, r0, alg_mask, var_names):
    """Refuse an ``algebraic=`` that names a variable whose rate an equation reads at the start
    (a state declared algebraic is integrated wrongly without a word: with ``suppress_alg`` it
    leaves the error test, and the start computes its rate as if it had none)."""
    m = jacobian.mixed_matrix(t0, y0, yp0, r0, np.zeros(y0.size), np.ones(y0.size),
                              np.maximum(np.abs(yp0), 1.0))
    m = m.toarray() if hasattr(m, "toarray") else np.asarray(m)
    wrong = [j for j in np.flatnonzero(alg_mask)
             if np.all(np.isfinite(m[:, j])) and np.any(m[:, j] != 0.0)]
    if not wrong:
        return
    told = []
    for j in wrong[:4]:
        i = int(np.flatnonzero(m[:, j])[np.argmax(np.abs(m[np.flatnonzero(m[:, j]), j]))])
        name = f"y[{j}]" + (f" ({var_names[j]!r})" if var_names is not None else "")
        told.append(f"{name}: its rate appears in equation {i} (dF[{i}]/dy'[{j}] = "
                    f"{m[i, j]:.3g} at t0)")
    more = f" and {len(wrong) - 4} more" if len(wrong) > 4 else ""
    raise ValueError("algebraic= names variables whose rates the equations read, so they are "
                     "differential, not algebraic: " + "; ".join(told) + more + ". Leave them "
                     "out of algebraic= (an algebraic variable's rate appears in no equation).")


def _constraint_rows(jacobian, t0, y0, yp0, r0, alg_mask) -> list:
    """The equations that read no rate and no algebraic variable at the start (and do read a
    state): constraints on the states alone, a DAE of index two at least (three where the
    constraint's derivative does not read the algebraic variables either: a pendulum's
    position). A variable whose rate no equation reads counts as algebraic, declared or
    not. Empty where that cannot be told."""
    import scipy.sparse as sp
    try:
        n = y0.size
        scale = np.maximum(np.abs(y0), 1.0)
        dyp = jacobian.mixed_matrix(t0, y0, yp0, r0, np.zeros(n), np.ones(n), scale)
        dy = jacobian.mixed_matrix(t0, y0, yp0, r0, np.ones(n), np.zeros(n), scale)
        dyp, dy = sp.csr_matrix(dyp), sp.csr_matrix(dy)
    except Exception:       # noqa: BLE001  (only a hint for the messages)
        return []
    if not (np.all(np.isfinite(dyp.data)) and np.all(np.isfinite(dy.data))):
        return []
    dyp.eliminate_zeros()
    dy.eliminate_zeros()
    algebraic = np.asarray(alg_mask, dtype=bool) | (np.diff(dyp.tocsc().indptr) == 0)
    reads_rate = np.diff(dyp.indptr) > 0
    on_alg = dy[:, np.flatnonzero(algebraic)]
    on_states = dy[:, np.flatnonzero(~algebraic)]
    reads_alg = np.diff(on_alg.indptr) > 0
    reads_state = np.diff(on_states.indptr) > 0
    return [int(i) for i in np.flatnonzero(~reads_rate & ~reads_alg & reads_state)]


def _index_hint(rows) -> str:
    """The message's hint for equations that constrain the states alone (see
    :func:`_constraint_rows`)."""
    if not rows:
        return ""
    shown = ", ".join(map(str, rows[:4])) + (f" and {len(rows) - 4} more" if len(rows) > 4 else "")
    return (f"equation{'s' if len(rows) > 1 else ''} {shown} constrain{'' if len(rows) > 1 else 's'} "
            f"differential variables alone (no rate, no algebraic variable read), so the DAE's "
            f"index is two or more; solve_dae takes index one and Hessenberg index two, not a "
            f"mechanism's position constraints (index three: a pendulum in Cartesian "
            f"coordinates). Differentiate such a constraint to the velocity level (and "
            f"stabilise it), or write the model as a Component, whose compiler reduces the "
            f"index. ")


def _integrate(residual, t0, t_end, y0, yp0, rtol, atol, alg_mask, alg_given, suppress_alg, jac,
               jac_sparsity, event_list, t_eval, max_step, first_step, calc_initial,
               max_order, max_steps, var_names, dense_output, no_growth_after_failure=None,
               nonnegative=None, newton_iterate_retry=None, c_step=None, linear_solver=None):
    """The integration loop behind ``solve_dae`` (arguments already checked)."""
    n = y0.size
    r0 = residual(t0, y0, yp0)
    convert = not (isinstance(r0, np.ndarray) and r0.dtype == np.float64)
    r0 = np.asarray(r0, dtype=float)
    if r0.shape != (n,):
        raise ValueError(f"residual returned shape {r0.shape}, expected ({n},)")
    counted = _Counted(residual, convert)
    counted.calls = 1
    if convert:
        def fun(t, y, yp):
            return np.asarray(residual(t, y, yp), dtype=float)
    else:
        fun = residual
    jacobian = JacobianEvaluator(fun, n, jac, jac_sparsity, typical=atol / rtol)
    constraint_rows = None      # found when a message needs them (see _constraint_rows)
    if alg_given and alg_mask.any() and not _of_a_system(residual):
        _check_declared_algebraic(jacobian, t0, y0, yp0, r0, alg_mask, var_names)
        start = (t0, y0.copy(), yp0.copy(), r0.copy())
        constraint_rows = functools.cache(lambda: _constraint_rows(jacobian, *start, alg_mask))
    lu_kind = _lu_kind(linear_solver, residual, n)
    if lu_kind == "c":
        jacobian.dense_only = True      # the C LU takes dense matrices (n <= CLU_MAX_N)
        jacobian.sparse = False
    # the given pattern object itself: the C LU remembers its column order by object
    lu_pattern = jac_sparsity if jac_sparsity is not None else getattr(jacobian, "pattern",
                                                                       None)
    if lu_kind == "c" and lu_pattern is None:
        system = _c_system_of(residual)
        lu_pattern = system.jac_sparsity if system is not None else None
    lu = LUSolver(lu_kind, pattern=lu_pattern)
    ic_lu = LUSolver(lu_kind, pattern=lu_pattern)       # the (re)starts' Newton matrices
    # IDA's suppressalg (see the suppress_alg parameter)
    error_mask = ((~alg_mask).astype(float)
                  if suppress_alg and alg_given and alg_mask.any() else None)

    def initialise(t, y, yp, mode):
        ewt = 1.0 / (rtol * np.abs(y) + atol)
        span = max(t_end - t, 1e-3 * (t_end - t0))     # an action at t_end still needs one
        h0 = min(initial_step(yp, ewt if error_mask is None else ewt * error_mask,
                              span, max_step, first_step, t), span)
        return start_values(counted, t, y, yp, mode, alg_mask, alg_given, jacobian, rtol,
                            atol, span, h0, var_names, lu=ic_lu)

    y, yp = initialise(t0, y0, yp0, calc_initial)

    integ = make_integrator(c_step, fun, n, rtol, atol, error_mask, jacobian, lu, max_order,
                            max_step, var_names, no_growth_after_failure, nonnegative,
                            newton_iterate_retry)
    if constraint_rows is not None:
        integ.index_hint = lambda: _index_hint(constraint_rows())
    integ.reinit(t0, y, yp, t_end, first_step)
    solved = {"nre": 0, "nlu": 0}
    # output rows between steps are the step's interpolant (integ.interpolate), which keeps
    # every linear relation of the equations (a node's flows sum to zero on every row;
    # solving some of the algebraic variables and not others broke that by 44 tolerance
    # units). Event conditions between steps take the algebraic variables solved where the
    # equations determine them better than their interpolant (a threshold on a saturated
    # output fired 1.1 ms early), with a matrix of their own, so t_eval never changes the
    # run. The state an action restarts from is the step's interpolant, made consistent by
    # the restart.
    locate = integ.interpolate if error_mask is None else _consistent_interpolant(
        integ, fun, jacobian, LUSolver(lu_kind, pattern=lu_pattern), alg_mask, rtol, atol,
        solved)

    ts, ys, yps = [], [], []
    i_eval = 0
    if t_eval is None:
        ts.append(t0)
        ys.append(y.copy())
        yps.append(yp.copy())
    else:
        while i_eval < t_eval.size and t_eval[i_eval] <= t0:
            ts.append(t0)
            ys.append(y.copy())
            yps.append(yp.copy())
            i_eval += 1

    tracker = EventTracker(event_list) if event_list else None
    if tracker is not None:
        tracker.reset(t0, y, yp)
    # the C step evaluates compiled event functions after each step and reports when none
    # can have crossed zero (the tracker then holds the new values)
    c_events = tracker is not None and hasattr(integ, "watch_events") and \
        integ.watch_events(tracker)
    records = []
    chatter = None      # (first time, count, last time) of actions in a row at one instant
    dense = DenseOutput(n) if dense_output else None
    message = "The solver successfully reached the end of the integration interval."
    restart_mode = calc_initial if calc_initial is not None else "algebraic"
    steps_at_start = integ.nst
    end_state = None            # state after an action exactly at t_end
    rescue = {"count": 0, "delta": 0.0}     # restarts past a failed corrector (see _rescue)

    # the C step can run the loop itself between steps whose events need the Python code
    run = (_c_run(integ, n, t_end, t_eval, steps_at_start + max_steps)
           if dense is None and hasattr(integ, "advance") and integ.can_advance(tracker)
           else None)

    while True:
        if integ.nst - steps_at_start >= max_steps:
            raise SolverError(
                f"{SOLVER_NAME} reached max_steps = {max_steps} at t = {integ.tn:.9g} (h = "
                f"{integ.hh:.3g}) before t_end = {t_end:.9g}; raise max_steps or "
                f"{_why_many_steps(integ, var_names)}", t=integ.tn, h=integ.hh)
        if run is not None:
            i_from = run.i_eval = i_eval
            status = integ.advance(run)
            if t_eval is None:
                m = run.count
                if m:
                    ts.extend(run.t_rows[:m].tolist())
                    ys.extend(run.y_rows[:m].copy())
                    yps.extend(run.yp_rows[:m].copy())
                    run.count = 0
            else:
                i_eval = run.i_eval
                ts.extend(t_eval[i_from:i_eval])
                ys.extend(run.y_rows[i_from:i_eval])
                yps.extend(run.yp_rows[i_from:i_eval])
            if status == ADV_END:
                hit = None
                break
            if status == ADV_PAUSE:
                continue
            # ADV_EVENTS: a step was taken; its events, outputs and end test follow here
        else:
            try:
                integ.step()
            except SolverError as exc:
                # the corrector failed down to a vanishing step: an algebraic variable whose
                # equation turns from flat to steep (a valve opening from its leak, with no
                # volume on the node) sends Newton from one side far onto the other. Go on a
                # little beyond the last step with the states predicted and the algebraic
                # variables solved with a line search (as at a restart), then restart there
                got = _rescue(exc, integ, initialise, t_end, rescue, tracker)
                y_new, yp_new, t_new, _ = got
                if t_eval is not None:
                    while i_eval < t_eval.size and t_eval[i_eval] <= t_new:
                        yv, ypv = ((y_new, yp_new) if t_eval[i_eval] == t_new
                                   else integ.interpolate(t_eval[i_eval]))
                        ts.append(t_eval[i_eval])
                        ys.append(np.array(yv, dtype=float))
                        yps.append(np.array(ypv, dtype=float))
                        i_eval += 1
                else:
                    ts.append(t_new)
                    ys.append(y_new.copy())
                    yps.append(yp_new.copy())
                if tracker is not None:
                    tracker.reset(t_new, y_new, yp_new)
                if t_end - t_new <= END_FUZZ * UROUND * (abs(t_new) + abs(t_new - got[3])):
                    end_state = (y_new, yp_new)
                    break
                # the algebraic variables go into the error test from here: left out, the
                # steps after a rescue can settle on a branch of the node's equation far from
                # the solution (a node pressure of -1e7 bar, a load held by nothing)
                integ.error_mask = None
                integ.reinit(t_new, y_new, yp_new, t_end)
                continue
        t_old, tn = integ.t_old, integ.tn
        if dense is not None:
            dense.append(t_old, tn, integ.kused, integ.psi, integ.phi)
        hit = None
        if tracker is not None and not (c_events and integ.events_quiet()):
            g_new = tracker.evaluate(tn, integ.yy, integ.yp)
            hit = _first_hit(tracker.crossings(t_old, tn, g_new, locate),
                             event_list, integ.interpolate, records, t_old, tn)
            tracker.g = g_new
        if t_eval is not None:
            # an output time equal to the time of an action is reported after the action
            # (values are right-continuous: a step at t_step has its new value there)
            t_upto = tn if hit is None else hit[0]
            before_action = hit is not None and not hit[2].terminal
            while i_eval < t_eval.size and (t_eval[i_eval] < t_upto or (
                    t_eval[i_eval] == t_upto and not before_action)):
                yv, ypv = integ.interpolate(t_eval[i_eval])
                ts.append(t_eval[i_eval])
                ys.append(yv)
                yps.append(ypv)
                i_eval += 1
        elif hit is None:
            ts.append(tn)
            ys.append(integ.yy)
            yps.append(integ.yp)
        if hit is not None:
            te, fired, ev, ye, ype = hit
            if dense is not None:
                dense.truncate(te)    # the step's interpolant holds up to the event only
            if t_eval is None:
                ts.append(te)
                ys.append(ye)
                yps.append(ype)
            if ev.terminal:
                message = f"A terminal event ({ev.name!r}) occurred at t = {te:.9g}."
                _final_actions(fired, event_list, te, ye, ype, initialise, restart_mode,
                               ts, ys, yps, t_eval is None)
                break
            located = (ye, ype)
            ye, ype = _apply_actions(fired, event_list, te, ye, ype, initialise, restart_mode)
            if t_eval is None:
                ts.append(te)
                ys.append(ye.copy())
                yps.append(ype.copy())
            else:
                while i_eval < t_eval.size and t_eval[i_eval] <= te:
                    ts.append(t_eval[i_eval])
                    ys.append(ye.copy())
                    yps.append(ype.copy())
                    i_eval += 1
            if t_end - te <= END_FUZZ * UROUND * (abs(te) + abs(integ.hused)):
                # the action happened at the end of the interval (a ramp ending at t_end)
                end_state = (ye, ype)
                if t_eval is None:
                    ts[-1] = t_end
                break
            integ.reinit(te, ye, ype, t_end)
            crossed = {}
            for rec in reversed(records):
                if rec.t != te:
                    break
                if rec.index in fired:
                    crossed.setdefault(rec.index, rec.direction)   # the latest crossing
            tracker.reset(te, ye, ype, crossed=crossed, located=(te,) + located)
            chatter = _chattering(chatter, te, fired, event_list, integ.hused)
            continue
        if t_end - tn <= END_FUZZ * UROUND * (abs(tn) + abs(integ.hused)):
            break

    if t_eval is not None and (hit is None or not hit[2].terminal):
        while i_eval < t_eval.size:
            yv, ypv = (integ.interpolate(t_eval[i_eval]) if end_state is None
                       else (end_state[0].copy(), end_state[1].copy()))
            ts.append(t_eval[i_eval])
            ys.append(yv)
            yps.append(ypv)
            i_eval += 1
    elif t_eval is None and hit is None and end_state is None:
        ts[-1] = t_end
        ys[-1], yps[-1] = integ.interpolate(t_end)
    if tracker is not None and hit is None and end_state is None and integ.tn < t_end:
        # the last step ends within rounding of t_end: a zero exactly at t_end (a step at
        # t_step = t_end) lies beyond it, in (tn, t_end]
        ye, ype = locate(t_end)
        g_end = tracker.evaluate(t_end, ye, ype)
        end_hit = _first_hit(tracker.crossings(integ.tn, t_end, g_end, locate),
                             event_list, integ.interpolate, records, integ.tn, t_end)
        if end_hit is not None and end_hit[2].terminal:
            message = (f"A terminal event ({end_hit[2].name!r}) occurred at t = "
                       f"{end_hit[0]:.9g}.")
            _final_actions(end_hit[1], event_list, t_end, end_hit[3], end_hit[4], initialise,
                           restart_mode, ts, ys, yps, t_eval is None)
        elif end_hit is not None:
            ye, ype = _apply_actions(end_hit[1], event_list, t_end, end_hit[3], end_hit[4],
                                     initialise, restart_mode)
            # the state before and after, as at other actions
            _rows_after_action(ts, ys, yps, t_end, ye, ype, t_eval is None)

    nre = counted.calls + integ.nre + jacobian.nfev + solved["nre"]
    stats = {
        "nsteps": integ.nst,
        "nre": nre,
        "nje": jacobian.nje,
        "nlu": lu.nlu,
        "netf": integ.netf,
        "ncfn": integ.ncfn,
        "nconstr": integ.nconstr,
        "nni": integ.nni,
        "nroot": tracker.nroot if tracker is not None else 0,
    }
    if solved["nlu"]:
        # the event functions' algebraic variables solved (see _consistent_interpolant):
        # the matrices made for them
        stats["nlu_events"] = solved["nlu"]
    if integ.netf >= THRASH_MIN_FAILURES and integ.netf > THRASH_FRACTION * integ.nst:
        hint = ("an algebraic variable of a DAE of index above one (name the algebraic "
                "variables with algebraic=[...] and leave them out of the test with "
                "suppress_alg=True), " if error_mask is None else "")
        rows = constraint_rows() if constraint_rows is not None else []
        if rows:
            hint = _index_hint(rows) + "Otherwise: " + hint
        warnings.warn(PlausibilityWarning(
            f"{SOLVER_NAME}: {integ.netf} of {integ.nst} steps failed the local error test: "
            f"the step is held by something the error test cannot follow: {hint}a switch or "
            f"kink not declared as an event, or a tolerance below what the equations resolve. "
            f"The result may be far less accurate than the tolerance."),
            stacklevel=outside_stacklevel())
    if rescue["count"]:
        stats["nrescue"] = rescue["count"]
        t_first, names = rescue["first"]
        warnings.warn(PlausibilityWarning(
            f"{SOLVER_NAME}: the corrector failed down to a vanishing step {rescue['count']} "
            f"time{'s' if rescue['count'] > 1 else ''} (first at t = {t_first:.6g} s"
            f"{', on ' + ', '.join(map(repr, names)) if names else ''}); the run went on past "
            f"each with the algebraic variables solved a step further and every variable in "
            f"the error test from there. The run from there on may follow another solution "
            f"of the equations that failed (a node's pressure on a far branch), not only be "
            f"approximate near those times: check it. Where an algebraic pressure sits between "
            f"valves with no volume, a VolumeNode on that node makes the circuit "
            f"well-posed."), stacklevel=outside_stacklevel())
    return DAEResult(
        t=np.asarray(ts, dtype=float),
        y=np.array(ys, dtype=float) if ys else np.empty((0, n)),
        yp=np.array(yps, dtype=float) if yps else np.empty((0, n)),
        events=records,
        t_events=np.array([rec.t for rec in records], dtype=float),
        stats=stats,
        success=True,
        message=message,
        sol=dense,
    )
