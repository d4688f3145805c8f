"""``solve_dae_sundials``: the same problem, signature and result, solved by SUNDIALS IDA.

SUNDIALS IDA is reached through scikit-sundae (``pip install pvgraph[sundials]``), imported
only when this backend is called. It is the reference against which ``solve_dae`` is
checked for accuracy and speed.

How the backend drives IDA:

* Consistent initial values come from pvgraph's own calculation (``initial.start_values``,
  the same as ``solve_dae``) and IDA is started from them without IDACalcIC, whose fixed
  trial step (the whole interval by default) fails on stiff hydraulic circuits.
* The first step is IDA's estimate (0.001 of the interval, ||h y'|| <= 1/2) capped by the
  fastest time scale of the system, |dF_j/dy'_j| / |dF_j/dy_j| over the differential
  variables, so long runs from a steady state do not start with a step of hours.
* IDA is stepped one internal step at a time towards ``t_end`` (stop time ``t_end``);
  the backend counts the steps, so ``max_steps`` and ``max_wall_time`` stop a chattering
  run with a clear message, and ``stats["nsteps"]`` is known with or without ``t_eval``.
  Output times are interpolated by IDA within its last step (IDA_NORMAL with the output
  time already passed).
* Events are located by IDA's rootfinding. At an event with an action, IDA stops, the
  action is applied, pvgraph recomputes consistent values and IDA is re-initialised; an
  output time equal to the event time reports the value after the action. IDA masks a
  root function that starts at zero; so that a restart behaves as the built-in solver's
  (:meth:`pvgraph.solver.events.EventTracker.reset`), the backend checks the fired events
  over the first step after it: one left at its zero that steps back to where it came from
  has crossed back (a relay: fired again at the restart, and stopped as chattering after 50
  such actions); a directional one its action turned back that steps across its zero again
  stops the run as Zeno behaviour (:func:`~pvgraph.solver.events.zeno_error`); one the
  restart's consistent values put back before its zero (an event on an algebraic variable)
  does not fire again for the same crossing.
* With ``jac_sparsity`` and n >= ``SPARSE_MIN_N`` IDA uses its sparse direct solver
  (SuperLU_MT) with the user Jacobian's entries in the pattern's CSC order.
* SUNDIALS' own messages (printed by scikit-sundae) are captured and put into the
  ``SolverError`` raised on failure, not printed.
* When IDA fails a step (repeated Newton or error-test failures, typically on the kink of a
  friction or table law), the backend restarts it from the last accepted step at order 1,
  up to ``MAX_FAILURE_RESTARTS`` times and only after progress; then it raises.

Differences from ``solve_dae`` worth knowing: scikit-sundae does not switch on IDA's
suppressalg option, so algebraic variables stay in IDA's local error test; ``nlu``,
``netf``, ``ncfn`` and ``nni`` are not exposed and are None; dense output
(``dense_output=True``) is a cubic Hermite interpolant through the internal steps.
"""

from __future__ import annotations

import contextlib
import io
import time
import warnings

import numpy as np
import scipy.sparse as sp

from pvgraph.errors import InitializationError, SolverError
from pvgraph.solver.events import (SIGN_PROBE, UROUND, EventTracker, check_times,
                                   normalize_events, probe, stopping_event, turned_back,
                                   zeno_error)
from pvgraph.solver.ida import dominant_names, initial_step
from pvgraph.solver.initial import start_values
from pvgraph.solver.linalg import SPARSE_MIN_N, JacobianEvaluator
from pvgraph.solver.result import DAEResult, EventRecord

__all__ = ["solve_dae_sundials", "time_scale_step"]

SOLVER_NAME = "SUNDIALS IDA"
TIME_SCALE_FRACTION = 0.5   # first step at most this fraction of the fastest time scale
IDA_SUCCESS, IDA_TSTOP_RETURN, IDA_ROOT_RETURN = 0, 1, 2
SPARSE_WARNING = "Custom sparse Jacobian approximation will be ignored"
MAX_FAILURE_RESTARTS = 20   # restarts from the last step after an IDA step failure


def _import_sksundae():
    """Import scikit-sundae or explain how to install it."""
    try:
        import sksundae
    except ImportError as exc:
        raise ImportError(
            "solve_dae_sundials needs SUNDIALS through scikit-sundae, which is not installed; "
            "install the optional extra with `pip install pvgraph[sundials]` (or "
            "`pip install scikit-sundae`).") from exc
    return sksundae


def time_scale_step(jacobian, t, y, yp, r, differential):
    """Fastest time scale |dF_j/dy'_j| / |dF_j/dy_j| over the differential variables.

    Returns inf when no differential variable has both diagonal entries.
    """
    n = y.size
    scale = np.maximum(np.abs(y), 1.0)
    dfdy = jacobian.mixed_matrix(t, y, yp, r, np.ones(n), np.zeros(n), scale)
    dfdyp = jacobian.mixed_matrix(t, y, yp, r, np.zeros(n), np.ones(n), scale)
    a = np.abs(dfdy.diagonal() if sp.issparse(dfdy) else np.diag(dfdy))
    m = np.abs(dfdyp.diagonal() if sp.issparse(dfdyp) else np.diag(dfdyp))
    ok = differential & (a > 0.0) & (m > 0.0) & np.isfinite(a) & np.isfinite(m)
    return float(np.min(m[ok] / a[ok])) if ok.any() else np.inf


class _NonFinite(Exception):
    """Raised inside the residual callback to stop IDA at a NaN or inf residual."""


class _Residual:
    """scikit-sundae residual callback: counts calls, stops IDA at a non-finite residual.

    scikit-sundae ignores return values, and IDA accepts NaN residuals without failing its
    tests (it then shrinks the step for ever); an exception makes IDASolve return at once.
    """

    def __init__(self, residual):
        self.residual = residual
        self.calls = 0
        self.bad = None         # (t, rows) of the last non-finite residual

    def __call__(self, t, y, yp, res):
        self.calls += 1
        res[:] = self.residual(t, y, yp)
        if not np.isfinite(np.add.reduce(res)):
            self.bad = (t, np.flatnonzero(~np.isfinite(res)))
            raise _NonFinite()


#: successful IDA steps in a row that leave t unchanged before the run is stopped (SUNDIALS'
#: own limit of steps per call, mxstep, is 500)
MAX_STALLED_STEPS = 500


def _at_zero(g, t, y, yp, dt) -> bool:
    """True if the event function ``g`` is at its zero at ``(t, y, y')`` within what IDA's
    location of a root leaves (its time tolerance, 100 ulps of t and the step, times the
    function's rate, from a first-order probe along y')."""
    delta = SIGN_PROBE * dt if dt > 0.0 else 1e-9 * max(abs(t), 1.0)
    g0, rise = probe(g, t, y, yp, delta)
    return g0 == 0.0 or abs(g0) <= 200.0 * UROUND * (abs(t) + abs(dt)) * abs(rise) / delta


def _stall(stalled, tn, t_end):
    """One more step that did not advance t; a SolverError after MAX_STALLED_STEPS."""
    stalled += 1
    if stalled >= MAX_STALLED_STEPS:
        raise SolverError(
            f"{SOLVER_NAME}'s step fell below the rounding of t at t = {tn:.12g}: "
            f"{stalled} steps in a row left t unchanged, before t_end = {t_end:.9g}. The "
            f"model changes faster there than IDA can follow (an impact on a stop, a "
            f"discontinuity without an event); the built-in solver (solver='pvgraph') "
            f"handles such kinks with its own step rules, or give max_step.", t=tn)
    return stalled


class _PiecewiseHermite:
    """Cubic Hermite interpolation of the output rows, split at repeated times (an event's
    row before its action and the one after): each side of an event interpolates its own
    branch, the value at the event time is the one after the action."""

    def __init__(self, t, y, yp):
        from scipy.interpolate import CubicHermiteSpline
        cuts = np.flatnonzero(np.diff(t) <= 0.0) + 1      # the first row after each repeat
        bounds = [0, *cuts.tolist(), len(t)]
        self._pieces = []
        for a, b in zip(bounds[:-1], bounds[1:]):
            if b - a >= 2:
                self._pieces.append((t[a], CubicHermiteSpline(t[a:b], y[a:b], yp[a:b], axis=0)))
            else:       # a lone row (an event at the end): constant there
                row = y[a]
                self._pieces.append((t[a], lambda tq, row=row: np.broadcast_to(
                    row, np.shape(tq) + row.shape).copy()))
        self._starts = np.array([p[0] for p in self._pieces])

    def _evaluate(self, tq, nu):
        tq_arr = np.asarray(tq, dtype=float)
        k = np.clip(np.searchsorted(self._starts, tq_arr, side="right") - 1, 0,
                    len(self._pieces) - 1)

        def at(piece, tv):
            f = piece[1]
            if nu == 0:
                return np.asarray(f(tv))
            if hasattr(f, "derivative"):
                return np.asarray(f(tv, nu))
            return np.zeros_like(np.asarray(f(tv)))     # a lone row: constant
        if tq_arr.ndim == 0:
            return at(self._pieces[int(k)], tq_arr)
        out = np.empty((tq_arr.size,) + np.shape(at(self._pieces[0], tq_arr.flat[0])))
        for i, (tv, kv) in enumerate(zip(tq_arr.ravel(), np.atleast_1d(k).ravel())):
            out[i] = at(self._pieces[int(kv)], tv)
        return out

    def __call__(self, tq):
        return self._evaluate(tq, 0)

    def derivative(self, tq):
        """Interpolated y'(t), as :class:`~pvgraph.solver.result.DenseOutput` gives it."""
        return self._evaluate(tq, 1)


def solve_dae_sundials(residual, t_span, y0, yp0, *, rtol=1e-6, atol=1e-8, algebraic=None,
                       jac=None, jac_sparsity=None, events=None, t_eval=None, max_step=None,
                       first_step=None, calc_initial="algebraic", max_order=5,
                       max_steps=100_000, var_names=None, dense_output=False,
                       max_wall_time=None):
    """Solve F(t, y, y') = 0 with SUNDIALS IDA; arguments and result as ``solve_dae``.

    ``max_steps`` counts IDA's internal steps over the whole run; ``max_wall_time`` [s], if
    given, stops a run that takes longer. Both raise SolverError naming the time reached.

    References
    ----------
    .. [1] A. C. Hindmarsh et al., "SUNDIALS: Suite of nonlinear and differential/algebraic
       equation solvers", ACM TOMS 31 (2005) 363-396.
    .. [2] scikit-sundae, https://github.com/NatLabRockies/scikit-sundae
    """
    sksundae = _import_sksundae()
    from .solve import (_as_mask, _chattering, _check_declared_algebraic, _final_actions,
                        _of_a_system, check_arguments)
    t0, t_end, y, yp, rtol, atol_arr, var_names = check_arguments(
        t_span, y0, yp0, rtol, atol, max_steps, var_names)
    n = y.size
    r0 = np.asarray(residual(t0, y, yp), dtype=float)
    if r0.shape != (n,):
        raise ValueError(f"residual returned shape {r0.shape}, expected ({n},)")
    if calc_initial not in ("algebraic", "all", None):
        raise ValueError(f"calc_initial must be 'algebraic', 'all' or None, got {calc_initial!r}")
    alg_mask = _as_mask(algebraic, n)
    event_list = normalize_events(events)
    t_eval = check_times(t0, t_end, t_eval, max_step, first_step)

    res_cb = _Residual(residual)

    def fun(t, yy, ypp):
        res_cb.calls += 1
        return np.asarray(residual(t, yy, ypp), dtype=float)

    jacobian = JacobianEvaluator(fun, n, jac, jac_sparsity, typical=atol_arr / rtol)
    if algebraic is not None and alg_mask.any() and not _of_a_system(residual):
        _check_declared_algebraic(jacobian, t0, y, yp, r0, alg_mask, var_names)
    differential = ~alg_mask
    if jac is None:
        # the built-in solver's differences (increments from each variable's typical size
        # atol / rtol and the step), not IDA's difference quotients: with increments of the
        # order of atol, a variable far below its atol (Robertson's y2 ~ 1e-13 at atol 1e-6)
        # gets a column wrong by orders of magnitude, and the run drifts with success
        def jac(t, yy, ypp, cj):
            counted = jacobian.nje        # IDA's own count (njev) has this evaluation
            m = jacobian.iteration_matrix(t, yy, ypp, fun(t, yy, ypp), cj,
                                          1.0 / (rtol * np.abs(yy) + atol_arr), 1.0 / cj)
            jacobian.nje = counted
            return m

    def initialise(t, yy, ypp, mode):
        """pvgraph's consistent values and the first step from the system's time scales."""
        ewt = 1.0 / (rtol * np.abs(yy) + atol_arr)
        span = max(t_end - t, 1e-3 * (t_end - t0))     # an action at t_end still needs one
        h0 = min(initial_step(ypp, ewt, span, max_step, first_step), span)
        with np.errstate(all="ignore"):
            yy, ypp = start_values(fun, t, yy, ypp, mode, alg_mask, algebraic is not None,
                                   jacobian, rtol, atol_arr, span, h0, var_names)
            if first_step is None:
                ewt = 1.0 / (rtol * np.abs(yy) + atol_arr)
                h0 = min(initial_step(ypp, ewt, span, max_step), span)
                tau = time_scale_step(jacobian, t, yy, ypp, fun(t, yy, ypp), differential)
                h0 = min(h0, TIME_SCALE_FRACTION * tau)
        return yy, ypp, h0

    options = dict(rtol=rtol, atol=atol_arr,
                   algebraic_idx=np.flatnonzero(alg_mask).tolist() or None,
                   max_order=int(max_order), max_num_steps=int(max_steps),
                   max_step=0.0 if max_step is None else float(max_step))
    if jac_sparsity is not None and n >= SPARSE_MIN_N:
        pattern = sp.csc_matrix(jac_sparsity, dtype=float)
        pattern.data[:] = 1.0
        pattern.eliminate_zeros()
        pattern.sort_indices()
        options.update(linsolver="sparse", sparsity=pattern)
        if jac is not None:
            rows = pattern.indices
            cols = np.repeat(np.arange(n), np.diff(pattern.indptr))

            def jacfn(t, yy, ypp, res, cj, JJ):
                m = jac(t, yy, ypp, cj)
                JJ[:] = (np.asarray(sp.csr_matrix(m)[rows, cols]).ravel() if sp.issparse(m)
                         else np.asarray(m)[rows, cols])
            options["jacfn"] = jacfn
    elif jac is not None:
        def jacfn(t, yy, ypp, res, cj, JJ):
            m = jac(t, yy, ypp, cj)
            JJ[:, :] = m.toarray() if sp.issparse(m) else m
        options["jacfn"] = jacfn
    if event_list:
        tracker = EventTracker(event_list)   # one call for all events of one system

        def eventsfn(t, yy, ypp, out):
            out[:] = tracker.evaluate(t, yy, ypp)
        eventsfn.terminal = [False] * len(event_list)
        eventsfn.direction = [int(ev.direction) for ev in event_list]
        options.update(eventsfn=eventsfn, num_events=len(event_list))

    captured = io.StringIO()

    def failure(what, t, h=None):
        """SolverError for a failed IDA call, with SUNDIALS' message and non-finite rows."""
        text = f"{SOLVER_NAME} failed at t = {t:.9g}: {what}"
        sundials_msg = " ".join(captured.getvalue().split())
        if sundials_msg:
            text += f" (SUNDIALS: {sundials_msg})"
        culprits = []
        if res_cb.bad is not None:
            tb, rows = res_cb.bad
            weighted = np.zeros(n)
            weighted[rows] = np.inf
            culprits = dominant_names(weighted, var_names, count=max(1, min(3, rows.size)))
            text += (f"; NaN or inf at t = {tb:.9g} in "
                     f"equation(s) {rows[:3].tolist()} (rows of "
                     f"{', '.join(map(repr, culprits))})")
        return SolverError(text + ".", t=t, h=h, culprits=culprits)

    ts, ys, yps, records = [], [], [], []
    stopped = False     # by a terminal event
    i_eval = 0
    nsteps = nje = 0
    started = time.perf_counter()
    message = "The solver successfully reached the end of the integration interval."
    mode = calc_initial
    t_start = t0
    solver = None
    restarted = False
    n_restarts, t_failed = 0, -np.inf
    chatter = None      # (first time, count, last time) of actions in a row at one instant
    pending, dt_hit = None, 0.0     # the events an action fired, the step they were found in
    located = None                  # (t, y, y') where they were found, before the actions
    with contextlib.redirect_stdout(captured), warnings.catch_warnings(), \
            np.errstate(all="ignore"):
        warnings.filterwarnings("ignore", message=SPARSE_WARNING)
        while True:
            try:
                y, yp, h0 = initialise(t_start, y, yp, mode)
            except InitializationError as exc:
                where = "" if t_start == t0 else (
                    f"restarting after a step failure at t = {t_start:.9g}: "
                    if t_start == t_failed else f"after the event at t = {t_start:.9g}: ")
                raise InitializationError(f"{SOLVER_NAME} backend: {where}{exc}") from exc
            solver = sksundae.ida.IDA(res_cb, calc_initcond=None, first_step=h0, **options)
            try:
                solver.init_step(t_start, y, yp)
            except _NonFinite:
                raise failure("the residual is not finite", t_start) from None
            except RuntimeError as exc:
                raise failure(str(exc), t_start) from exc
            if t_eval is None and not restarted:
                ts.append(t_start)
                ys.append(y.copy())
                yps.append(yp.copy())
            elif t_eval is not None:
                while i_eval < t_eval.size and t_eval[i_eval] <= t_start:
                    ts.append(t_eval[i_eval])
                    ys.append(y.copy())
                    yps.append(yp.copy())
                    i_eval += 1
            t_last = t_start
            last_y, last_yp = y.copy(), yp.copy()
            # the directional events the actions just turned back from their zeros: the
            # first step ending across a zero again stops the run (see zeno_error)
            turned = [(j, d) for j, d in (pending or ()) if event_list[j].direction and
                      turned_back(event_list[j].fun, d, t_start, y, yp, dt_hit)]
            # the events the actions left at their zeros that also fire crossing back (a
            # relay): IDA masks a root function that starts at zero, so a first step back to
            # the side it came from is a crossing back at the restart, as the built-in
            # solver sees it (see EventTracker.reset)
            back = [(j, d) for j, d in (pending or ()) if event_list[j].direction != d and
                    _at_zero(event_list[j].fun, t_start, y, yp, dt_hit)]
            y_start, yp_start = y.copy(), yp.copy()
            # the events the restart put back on the side they came from, while the actions
            # left them at their zeros (the restart re-solved an algebraic variable the
            # crossing was found on): IDA would find the same crossing again. Its next root
            # in that direction is left out, unless the function moved away first (beyond
            # twice the restart's offset)
            again = {}
            for j, d in (pending or ()):
                g = event_list[j].fun
                if event_list[j].direction in (0, d):
                    offset = float(g(t_start, y, yp)) * d
                    if offset < 0.0 and _at_zero(g, *located, dt_hit):
                        again[j] = (d, -offset)
            pending = None
            hit = None
            restarted = False
            stalled = 0     # successful steps in a row that left t where it was
            while True:
                if nsteps >= max_steps:
                    raise SolverError(
                        f"{SOLVER_NAME} reached max_steps = {max_steps} at t = {t_last:.9g} "
                        f"before t_end = {t_end:.9g}; raise max_steps or check the model for "
                        "fast oscillations or chattering events.", t=t_last)
                if max_wall_time is not None and time.perf_counter() - started > max_wall_time:
                    raise SolverError(
                        f"{SOLVER_NAME} exceeded max_wall_time = {max_wall_time:g} s at t = "
                        f"{t_last:.9g} after {nsteps} steps, before t_end = {t_end:.9g}.",
                        t=t_last)
                try:
                    out = solver.step(t_end, "onestep", t_end)
                except _NonFinite:
                    raise failure("the residual is not finite", res_cb.bad[0]) from None
                if out.status < 0:
                    if n_restarts >= MAX_FAILURE_RESTARTS or t_last <= t_failed:
                        raise failure(out.message, float(t_last))
                    # restart from the last step at order 1 (a kink of a friction or table
                    # law defeats the history; pvgraph's solver does not grow the step there)
                    n_restarts += 1
                    t_failed = t_last
                    restarted = True
                    break
                tn = float(out.t)
                if out.status == IDA_ROOT_RETURN:
                    info = np.asarray(out.i_events[-1])
                    fired = []      # every root IDA returns here is at this instant
                    for j, d in turned:
                        if np.sign(info[j]) == d:
                            raise zeno_error(event_list[j], t_start, tn)
                    back = ()
                    for i in np.flatnonzero(info):
                        if i in again and np.sign(info[i]) == again[i][0]:
                            del again[i]    # the crossing the last action was for
                            continue
                        ev = event_list[i]
                        records.append(EventRecord(tn, int(i), ev.name, out.y.copy(),
                                                   out.yp.copy(), int(np.sign(info[i]))))
                        if ev.terminal or ev.action is not None:
                            fired.append(int(i))
                    if fired:
                        hit = (tn, fired, stopping_event(fired, event_list), out.y.copy(),
                               out.yp.copy())
                    if hit is None:
                        if tn <= t_last:
                            stalled = _stall(stalled, tn, t_end)
                        continue
                    nsteps += 1     # the step that found the event is left behind
                    dt_hit, turned = tn - t_last, ()
                elif tn > t_last:
                    nsteps += 1
                    stalled = 0
                    for j, d in turned:
                        if float(event_list[j].fun(tn, out.y, out.yp)) * d > 0.0:
                            raise zeno_error(event_list[j], t_start, tn)
                    turned = ()
                    for j, d in back:
                        if float(event_list[j].fun(tn, out.y, out.yp)) * d < 0.0:
                            ev = event_list[j]
                            records.append(EventRecord(t_start, j, ev.name, y_start.copy(),
                                                       yp_start.copy(), -d))
                            if ev.terminal or ev.action is not None:
                                hit = (t_start, [j], ev, y_start.copy(), yp_start.copy())
                                break
                    back = ()
                    if hit is not None:     # the step is left behind: the action comes first
                        break
                    for j, (d, offset) in list(again.items()):
                        if -float(event_list[j].fun(tn, out.y, out.yp)) * d > 2.0 * offset:
                            del again[j]
                else:
                    # no progress: the call after an output time IDA interpolated to, or a
                    # step below the rounding of t (SUNDIALS' "t + h = t" warning), which
                    # IDA returns as a success at the same t again and again
                    stalled = _stall(stalled, tn, t_end)
                    continue
                # outputs up to tn (before an action at tn: strictly before it)
                upto, inclusive = tn, hit is None or hit[2].terminal
                while i_eval < t_eval.size if t_eval is not None else False:
                    te_i = t_eval[i_eval]
                    if te_i > upto or (te_i == upto and not inclusive):
                        break
                    if te_i == tn:
                        yv, ypv = out.y.copy(), out.yp.copy()
                    else:
                        got = solver.step(te_i, "normal", t_end)
                        yv, ypv = got.y.copy(), got.yp.copy()
                    ts.append(te_i)
                    ys.append(yv)
                    yps.append(ypv)
                    i_eval += 1
                if t_eval is None:
                    ts.append(tn)
                    ys.append(out.y.copy())
                    yps.append(out.yp.copy())
                t_last = tn
                last_y, last_yp = out.y.copy(), out.yp.copy()
                if hit is not None or out.status == IDA_TSTOP_RETURN or tn >= t_end:
                    break
            nje += int(out.njev or 0)
            if restarted:
                t_start, y, yp = t_last, last_y, last_yp
                mode = "algebraic"
                continue
            if hit is None:
                break
            te, fired, ev, ye, ype = hit
            if ev.terminal:
                message = f"A terminal event ({ev.name!r}) occurred at t = {te:.9g}."
                stopped = True      # the output times after it are not reached
                # the actions at the instant still run
                _final_actions(fired, event_list, te, ye, ype,
                               lambda t, y_, yp_, m: initialise(t, y_, yp_, m)[:2],
                               calc_initial if calc_initial is not None else "algebraic",
                               ts, ys, yps, t_eval is None, SOLVER_NAME)
                break
            # actions in a row at one instant (a sliding mode): stopped as the built-in solver
            # stops them, instead of running to max_steps
            chatter = _chattering(chatter, te, fired, event_list, dt_hit, SOLVER_NAME,
                                  ulps=400.0)
            located = (te, ye.copy(), ype.copy())
            for j in fired:
                ye, ype = event_list[j].apply(te, ye, ype)
            pending = {}
            for rec in reversed(records):
                if rec.t != te:
                    break
                if rec.index in fired and rec.direction:
                    pending.setdefault(rec.index, rec.direction)
            pending = list(pending.items())
            t_start, y, yp = te, ye, ype
            mode = calc_initial if calc_initial is not None else "algebraic"
            if t_end - t_start <= 1e-12 * max(1.0, abs(t_end)):
                y, yp, _ = initialise(t_start, y, yp, mode)
                if t_eval is None:
                    ts.append(t_end)
                    ys.append(y.copy())
                    yps.append(yp.copy())
                break
        if t_eval is not None and not stopped:
            while i_eval < t_eval.size:     # output times at an action exactly at t_end
                ts.append(t_eval[i_eval])
                ys.append(y.copy())
                yps.append(yp.copy())
                i_eval += 1

    t_out = np.asarray(ts, dtype=float)
    y_out = np.vstack(ys) if ys else np.empty((0, n))
    yp_out = np.vstack(yps) if yps else np.empty((0, n))
    sol = None
    if dense_output and t_out.size > 1:
        sol = _PiecewiseHermite(t_out, y_out, yp_out)
    stats = {"nsteps": nsteps, "nre": res_cb.calls, "nje": nje + jacobian.nje,
             "nlu": None, "netf": None, "ncfn": None, "nni": None, "nroot": None}
    return DAEResult(t=t_out, y=y_out, yp=yp_out, events=records,
                     t_events=np.array([r.t for r in records], dtype=float), stats=stats,
                     success=True, message=message, sol=sol)
