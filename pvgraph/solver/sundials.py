"""``solve_dae_sundials``: the same problem, signature and result, solved by SUNDIALS IDA.

SUNDIALS IDA is reached through scikit-sundae (``pip install pvgraph[sundials]``), imported
only when this backend is called. It is the reference against which ``solve_dae`` is
checked for accuracy and speed.

Differences from ``solve_dae`` worth knowing:

* scikit-sundae does not switch on IDA's suppressalg option, so algebraic variables stay in
  IDA's local error test (``solve_dae`` leaves them out).
* Events with an ``action`` stop IDA; the action is applied and IDA is restarted from the
  event time with consistent initialisation (IDACalcIC), as ``solve_dae`` does.
* ``stats`` has ``nsteps`` only when output is at every internal step (``t_eval=None``);
  ``nlu``, ``netf``, ``ncfn``, ``nni`` and ``nroot`` are not exposed by scikit-sundae and
  are None. ``nre`` counts every residual call, including IDA's difference-quotient ones.
* Dense output (``dense_output=True``) is a cubic Hermite interpolant through the internal
  steps, not IDA's own polynomial.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from pvgraph.errors import InitializationError, SolverError
from pvgraph.solver.events import normalize_events
from pvgraph.solver.linalg import SPARSE_MIN_N
from pvgraph.solver.result import DAEResult, EventRecord

__all__ = ["solve_dae_sundials"]


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


def solve_dae_sundials(residual, t_span, y0, yp0, *, rtol=1e-6, atol=1e-8, algebraic=None,
                       jac=None, jac_sparsity=None, events=None, t_eval=None, max_step=None,
                       first_step=None, calc_initial="algebraic", max_order=5,
                       max_steps=100_000, var_names=None, dense_output=False):
    """Solve F(t, y, y') = 0 with SUNDIALS IDA; arguments and result as ``solve_dae``.

    References
    ----------
    .. [1] A. C. Hindmarsh et al., "SUNDIALS: Suite of nonlinear and differential/algebraic
       equation solvers", ACM TOMS 31 (2005) 363-396.
    .. [2] scikit-sundae, https://github.com/NatLabRockies/scikit-sundae
    """
    sksundae = _import_sksundae()
    t0, t_end = float(t_span[0]), float(t_span[1])
    if not t_end > t0:
        raise ValueError(f"t_span must be increasing, got {t_span!r}")
    y = np.array(y0, dtype=float).ravel()
    yp = np.array(yp0, dtype=float).ravel()
    n = y.size
    atol_arr = np.broadcast_to(np.asarray(atol, dtype=float), (n,)).copy()
    if algebraic is None:
        alg_idx = None
    else:
        a = np.asarray(algebraic)
        alg_idx = np.flatnonzero(a).tolist() if a.dtype == bool else a.astype(int).tolist()
    event_list = normalize_events(events)
    calls = [0]

    def resfn(t, yy, ypp, res):
        calls[0] += 1
        res[:] = residual(t, yy, ypp)

    options = dict(rtol=float(rtol), atol=atol_arr, algebraic_idx=alg_idx,
                   max_order=int(max_order), max_num_steps=int(max_steps),
                   first_step=0.0 if first_step is None else float(first_step),
                   max_step=0.0 if max_step is None else float(max_step))
    use_sparse = jac_sparsity is not None and n >= SPARSE_MIN_N
    if use_sparse:
        pattern = sp.csc_matrix(jac_sparsity, dtype=float)
        pattern.data[:] = 1.0
        pattern.eliminate_zeros()
        pattern.sort_indices()
        options.update(linsolver="sparse", sparsity=pattern)
        rows = pattern.indices
        cols = np.repeat(np.arange(n), np.diff(pattern.indptr))
    if jac is not None:
        if use_sparse:
            def jacfn(t, yy, ypp, res, cj, JJ):
                m = jac(t, yy, ypp, cj)
                JJ[:] = np.asarray(sp.csr_matrix(m)[rows, cols]).ravel() if sp.issparse(m) \
                    else np.asarray(m)[rows, cols]
        else:
            def jacfn(t, yy, ypp, res, cj, JJ):
                m = jac(t, yy, ypp, cj)
                JJ[:, :] = m.toarray() if sp.issparse(m) else m
        options["jacfn"] = jacfn
    if event_list:
        def eventsfn(t, yy, ypp, out):
            for i, ev in enumerate(event_list):
                out[i] = ev.fun(t, yy, ypp)
        eventsfn.terminal = [bool(ev.terminal or ev.action is not None) for ev in event_list]
        eventsfn.direction = [int(ev.direction) for ev in event_list]
        options.update(eventsfn=eventsfn, num_events=len(event_list))

    ts, ys, yps, records = [], [], [], []
    nsteps, nje = 0, 0
    t_start = t0
    mode = calc_initial
    message = "The solver successfully reached the end of the integration interval."
    while True:
        ic = {"algebraic": "yp0", "all": "y0", None: None}[mode]
        opts = dict(options, calc_initcond=ic)
        if ic is not None:
            opts["calc_init_dt"] = t_end - t_start
        solver = sksundae.ida.IDA(resfn, **opts)
        if t_eval is None:
            tspan = np.array([t_start, t_end])
            wanted = None
        else:
            t_eval = np.asarray(t_eval, dtype=float)
            wanted = t_eval[(t_eval >= t_start) & (t_eval <= t_end)]
            if t_start > t0:
                wanted = wanted[wanted > t_start]
            inner = wanted[wanted > t_start]
            tspan = np.concatenate([[t_start], inner])
            if tspan.size == 1:
                break
            if tspan.size == 2:     # two points would select one-step output
                tspan = np.array([t_start, 0.5 * (t_start + tspan[1]), tspan[1]])
        try:
            soln = solver.solve(tspan, y, yp)
        except RuntimeError as exc:
            if "IDACalcIC" in str(exc):
                raise InitializationError(f"SUNDIALS IDA at t = {t_start:.9g}: {exc}") from exc
            raise SolverError(f"SUNDIALS IDA failed after t = {t_start:.9g}: {exc}",
                              t=t_start) from exc
        if not soln.success:
            raise SolverError(f"SUNDIALS IDA failed at t = {soln.t[-1]:.9g}: {soln.message}",
                              t=float(soln.t[-1]))
        nje += int(soln.njev)
        st, sy, syp = np.atleast_1d(soln.t), np.atleast_2d(soln.y), np.atleast_2d(soln.yp)
        stop_event = None
        if soln.t_events is not None:
            for k, te in enumerate(soln.t_events):
                for i in np.flatnonzero(soln.i_events[k]):
                    ev = event_list[i]
                    records.append(EventRecord(float(te), int(i), ev.name,
                                               soln.y_events[k].copy(),
                                               soln.yp_events[k].copy(),
                                               int(np.sign(soln.i_events[k][i]))))
                    if stop_event is None and (ev.terminal or ev.action is not None):
                        stop_event = (float(te), int(i), ev, soln.y_events[k].copy(),
                                      soln.yp_events[k].copy())
        if wanted is None:
            nsteps += st.size - 1 - (1 if stop_event is not None else 0)
            ts.extend(st)
            ys.extend(sy)
            yps.extend(syp)
        else:
            keep = np.isin(st, wanted)
            if stop_event is not None:
                keep[-1] = st[-1] in wanted and st[-1] != stop_event[0]
            ts.extend(st[keep])
            ys.extend(sy[keep])
            yps.extend(syp[keep])
        if stop_event is None:
            break
        te, i, ev, ye, ype = stop_event
        if ev.terminal:
            message = f"A terminal event ({ev.name!r}) occurred at t = {te:.9g}."
            break
        ye, ype = ev.apply(te, ye, ype)
        t_start, y, yp = te, ye, ype
        mode = calc_initial if calc_initial is not None else "algebraic"
        if t_end - t_start <= 1e-12 * max(1.0, abs(t_end)):
            break

    t_out = np.asarray(ts, dtype=float)
    y_out = np.vstack(ys) if ys else np.empty((0, n))
    yp_out = np.vstack(yps) if yps else np.empty((0, n))
    sol = None
    if dense_output and t_out.size > 1:
        from scipy.interpolate import CubicHermiteSpline
        # later rows win at repeated times (the state after an event reset)
        last = np.r_[np.diff(t_out) > 0.0, True]
        sol = CubicHermiteSpline(t_out[last], y_out[last], yp_out[last], axis=0)
    stats = {"nsteps": nsteps if t_eval is None else None, "nre": calls[0], "nje": nje,
             "nlu": None, "netf": None, "ncfn": None, "nni": None, "nroot": None}
    return DAEResult(t=t_out, y=y_out, yp=yp_out, events=records,
                     t_events=np.array([r.t for r in records], dtype=float), stats=stats,
                     success=True, message=message, sol=sol)
