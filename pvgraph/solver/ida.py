"""Variable-order, variable-step BDF for F(t, y, y') = 0, following SUNDIALS IDA.

The method is IDA's: backward differentiation formulas of order 1 to 5 in fixed-leading-
coefficient form, with the solution history held as modified divided differences
``phi[0..k]`` and the step-ratio coefficients psi, alpha, beta, sigma, gamma. Each step

1. rescales the history for the new step size and predicts y and y' from it,
2. solves the corrector F(t_n, y, y_pred' + cj (y - y_pred)) = 0 by modified Newton with
   the iteration matrix J = dF/dy + cj dF/dy'; J and its LU factors are reused while
   cj / cj_at_last_setup stays in [3/5, 5/3], and old factors are compensated by the
   factor 2 / (1 + cj ratio),
3. accepts the Newton iterate when ``ss * ||delta|| <= 0.33`` with the convergence-rate
   estimate ss, fails on rate > 0.9 or after 4 iterations (retrying once with a fresh J at
   the predictor, then once with J refreshed at the last iterate),
4. tests the local error ``ck * ||y - y_pred||`` in the weighted RMS norm with weights
   1 / (rtol |y| + atol), algebraic components optionally suppressed,
5. after success chooses order k-1, k or k+1 from the error estimates at those orders
   and the step ratio in [1/2, 9/10] or 2; after failure cuts the step (0.25 for Newton
   failures, 0.25..0.9 then 0.25 for error-test failures, order 1 after the third).

During the first steps (phase 0) the order is raised and the step doubled until the
order reaches its maximum, a step fails, or the error estimates call for a lower order.

After a step that needed a retry (error-test or Newton failure) the step may grow at once,
as in IDA. CVODE's rule of no growth right after a failure (``NO_GROWTH_AFTER_FAILURE``)
was measured across the IVP Test Set (``benchmarks/bench_testset.py``): it saves steps on
none of the problems and costs many on the Transistor Amplifier (86 150 against 40 801 steps
at rtol 1e-8) and digits on OREGO (6.55 against 7.45 at 1e-8), so it is off by default. Circuits with dry friction are the exception: there Newton sits on
the friction kink after a failure and a doubled step fails again (the PVE closed-loop example
stops at t = 0.038 s without the rule), so ``simulate`` switches it on.

References
----------
.. [1] A. C. Hindmarsh, R. Serban, C. J. Balos, D. J. Gardner, D. R. Reynolds,
   C. S. Woodward, "User Documentation for IDA", SUNDIALS, chapter "Mathematical
   considerations".
.. [2] K. E. Brenan, S. L. Campbell, L. R. Petzold, "Numerical Solution of Initial-Value
   Problems in Differential-Algebraic Equations", SIAM, 1996 (DASSL, ch. 5).
"""

from __future__ import annotations

import math

import numpy as np

from pvgraph.errors import SolverError
from pvgraph.solver.result import interpolate

__all__ = ["IDAIntegrator", "initial_step", "wrms_norm", "error_weights",
           "bdf_coefficients", "dominant_names"]

MAX_ORDER = 5
EPCON = 0.33                # Newton convergence test constant
TOLDEL = 1e-8 * EPCON       # a first correction this small is converged outright
MAX_NEWTON_ITERS = 4
MAX_CONV_FAILS = 10         # Newton failures allowed within one step
MAX_ERR_FAILS = 10          # error-test failures allowed within one step
RATE_MAX = 0.9              # Newton diverges above this contraction rate
# After a fresh J at the predictor fails to contract, refresh J once at the last iterate and
# go on from there. Where the iteration matrix changes between the predictor and the
# solution (a torque law tanh(w / w_eps) whose slope changes 18 % over the predictor's speed
# error, at rtol 1e-9), the first correction overshoots and the second, the same size,
# lands on the solution: the rate test reads that as divergence at every step size.
NEWTON_ITERATE_RETRY = False      # IDA's behaviour by default; simulate() switches it on
# Up to this many unknowns the history update is one np.add.accumulate (fewer calls); above
# it, row by row (measured: 3.8 against 4.9 us at n = 50, 6.3 against 3.1 us at n = 200)
ACCUMULATE_MAX_N = 64
XRATE = 0.25
CJ_RATIO_LOW = (1.0 - XRATE) / (1.0 + XRATE)    # 3/5: outside [3/5, 5/3] refactorise
CJ_RATIO_HIGH = 1.0 / CJ_RATIO_LOW
SS_FIRST_STEP = 20.0        # rate-constant guess on the first step and after a new J
SS_CJ_CHANGED = 100.0       # ... and after cj changed
ETA_MAX = 2.0               # step growth after success
ETA_MIN = 0.5               # smallest step reduction after success
ETA_LOW = 0.9               # largest step reduction after success
ETA_MIN_EF = 0.25           # smallest reduction after an error-test failure
ETA_CF = 0.25               # reduction after a Newton failure
H0_FRACTION = 1e-3          # first step as a fraction of the interval
H0_YP_NORM = 0.5            # ... and such that ||h0 y'0|| <= 1/2
UROUND = np.finfo(float).eps
H0_MIN_REL = 256 * np.finfo(float).eps    # ... and at least this fraction of |t| (see initial_step)
NO_GROWTH_AFTER_FAILURE = False     # CVODE's rule; off by default (module docstring)
N_CULPRITS = 3              # variable names quoted in failure messages

SOLVER_NAME = "pvgraph BDF"   # named in every failure message (not SUNDIALS IDA)

OK, NEWTON_FAIL, RESIDUAL_FAIL, SETUP_FAIL, ERROR_FAIL, JACOBIAN_FAIL, CONSTRAINT_FAIL = range(7)
HARMONIC = [sum(1.0 / j for j in range(1, k + 1)) for k in range(MAX_ORDER + 2)]


#: Longer vectors take their sums of squares with numpy's pairwise sum, not BLAS ``ddot``:
#: OpenBLAS splits dot products above 10 000 elements over threads, which on a busy machine
#: costs milliseconds a call (3.7 ms against 13 us at n = 12 000 on 2 shared cores) and makes
#: the last bit depend on the thread count. Up to this length both are single-threaded and
#: ``ddot`` is the faster.
DOT_MAX_N = 10_000


def sumsq(v) -> float:
    """The sum of squares of ``v`` (a dot product up to ``DOT_MAX_N`` elements)."""
    return np.dot(v, v) if v.size <= DOT_MAX_N else float(np.add.reduce(v * v))


def wrms_norm(v, w):
    """Weighted root-mean-square norm sqrt(mean((v w)^2))."""
    vw = v * w
    return math.sqrt(sumsq(vw) / vw.size)


def error_weights(y, rtol, atol):
    """IDA's error weights 1 / (rtol |y| + atol)."""
    return 1.0 / (rtol * np.abs(y) + atol)


def min_step_reason(t) -> str:
    """Why a step below ``16 eps |t|`` is refused, with the way out where ``t`` is large."""
    text = (f"the step size fell below the minimum 16 eps |t| = {16.0 * UROUND * abs(t):.3g} "
            f"s (the resolution of the time t)")
    if abs(t) > 1e4:
        text += ("; far from t = 0 the time cannot resolve shorter steps: start the run "
                 "nearer t = 0 (times are relative: shift t_start and the inputs' times)")
    return text


def initial_step(yp, ewt_mask, t_span_length, max_step=None, first_step=None, t=0.0):
    """IDA's first step: 0.001 of the interval, reduced so that ||h y'|| <= 1/2.

    Not below ``H0_MIN_REL * |t|`` (nor above the interval): a step that cannot change the
    time ``t`` in floating point is no step (far from t = 0, at t = 1e9, 5e-9 s is not), and
    the minimum-step test would stop the run before its first step.
    """
    if first_step is not None:
        h = float(first_step)
    else:
        h = H0_FRACTION * t_span_length
        ypnorm = wrms_norm(yp, ewt_mask)
        if ypnorm > H0_YP_NORM / h:
            h = H0_YP_NORM / ypnorm
    if max_step is not None and h > max_step:
        h = max_step
    floor = min(H0_MIN_REL * abs(t), t_span_length)
    return max(h, floor) if floor > 0.0 else h


def bdf_coefficients(h, k, psi):
    """Return IDA's step coefficients for step h at order k: (psi, sigma, beta, gamma, cj, ck).

    ``beta`` (a list) scales the history rows to phi*, ``gamma`` holds gamma[1..k] for the
    y' predictor (an array), cj is the leading coefficient and ck the variable-step error
    constant.
    """
    psi = list(psi)
    beta = [1.0] * (k + 1)
    sigma = [1.0] * (k + 1)
    gamma = [0.0] * (k + 1)
    alpha_prev = 1.0
    alpha_sum = 0.0 + 1.0       # sum(alpha[:k]), summed in index order
    temp1 = h
    for i in range(1, k + 1):
        temp2 = psi[i - 1]
        psi[i - 1] = temp1
        beta[i] = beta[i - 1] * temp1 / temp2
        temp1 = temp2 + h
        alpha = h / temp1
        sigma[i] = i * sigma[i - 1] * alpha
        gamma[i] = gamma[i - 1] + alpha_prev / h
        if i < k:
            alpha_sum += alpha
        alpha_prev = alpha
    psi[k] = temp1
    alphas = -HARMONIC[k]
    ck = max(abs(alpha_prev + alphas + alpha_sum), alpha_prev)
    return (psi, sigma, beta, np.array(gamma[1:]), -alphas / h, ck)


def dominant_names(weighted, var_names, count=N_CULPRITS):
    """Names of the entries with the largest |weighted| values (non-finite ones first)."""
    weighted = np.asarray(weighted, dtype=float)
    key = np.where(np.isfinite(weighted), np.abs(weighted), np.inf)
    order = np.argsort(-key, kind="stable")[:count]
    names = []
    for i in order:
        names.append(var_names[i] if var_names is not None else f"y[{i}]")
    return names


def _nonfinite_entries(m):
    """(rows, columns) of the non-finite entries of a dense or sparse matrix, or None."""
    if hasattr(m, "tocoo"):
        if np.isfinite(m.data).all():
            return None
        c = m.tocoo()
        bad = ~np.isfinite(c.data)
        return sorted(set(c.row[bad].tolist())), sorted(set(c.col[bad].tolist()))
    if np.isfinite(np.add.reduce(m, axis=None)):
        return None
    rows, cols = np.nonzero(~np.isfinite(m))
    if rows.size == 0:
        return None
    return sorted(set(rows.tolist())), sorted(set(cols.tolist()))


class IDAIntegrator:
    """State of one IDA integration: history array, coefficients, weights and counters.

    Parameters
    ----------
    fun : callable
        Residual ``fun(t, y, yp) -> ndarray (n,)``.
    n : int
        Number of unknowns.
    rtol : float
        Relative tolerance.
    atol : ndarray (n,)
        Absolute tolerances.
    error_mask : ndarray (n,) or None
        1.0 for components in the local error test, 0.0 for suppressed (algebraic) ones.
    jacobian : linalg.JacobianEvaluator
        Source of the iteration matrix.
    lu : linalg.LUSolver
        Factorisation of the iteration matrix.
    max_order : int
        Highest BDF order, 1 to 5.
    max_step : float or None
        Largest step size.
    var_names : list of str or None
        Variable names for error messages.
    no_growth_after_failure : bool or None
        No step increase right after a failed attempt; None takes
        ``NO_GROWTH_AFTER_FAILURE``.
    newton_iterate_retry : bool or None
        Refresh J once at the last iterate when a fresh J at the predictor fails to contract;
        None takes ``NEWTON_ITERATE_RETRY``.
    nonnegative : ndarray of int or None
        Components that must stay >= 0 (IDA's constraints, value 1): a corrected step that
        makes one negative is retried with a step shrunk to 0.9 of the way to the zero
        crossing (at least 0.1 of it), as IDA does.
    """

    def __init__(self, fun, n, rtol, atol, error_mask, jacobian, lu, max_order=MAX_ORDER,
                 max_step=None, var_names=None, no_growth_after_failure=None,
                 nonnegative=None, newton_iterate_retry=None):
        if not 1 <= max_order <= MAX_ORDER:
            raise ValueError(f"max_order must be in 1..{MAX_ORDER}, got {max_order}")
        self.fun = fun
        self.n = n
        self.rtol = rtol
        self.atol = atol
        self.error_mask = error_mask
        self.jacobian = jacobian
        self.lu = lu
        self.maxord = max_order
        self.max_step = max_step
        self.hmax_inv = 1.0 / max_step if max_step else 0.0
        self.var_names = var_names
        self.no_growth = (NO_GROWTH_AFTER_FAILURE if no_growth_after_failure is None
                          else bool(no_growth_after_failure))
        self.iterate_retry = (NEWTON_ITERATE_RETRY if newton_iterate_retry is None
                              else bool(newton_iterate_retry))
        self.inv_n = 1.0 / n
        self.n_small = n <= ACCUMULATE_MAX_N
        self.phi = np.zeros((max_order + 2, n))
        self.ee = np.zeros(n)
        self._ee_norm = -1.0        # ||ee|| in the weighted norm when Newton took it, else -1
        self._err_rows = np.empty((2, n))     # scratch for the order k-1, k-2 estimates
        # counters over the whole integration
        self.nst = 0
        self.nre = 0
        self.nni = 0
        self.netf = 0
        self.ncfn = 0
        self.nsetups = 0
        self.nconstr = 0
        self._fail = None
        self.nonnegative = (None if nonnegative is None or len(nonnegative) == 0
                            else np.asarray(nonnegative, dtype=np.int64))
        self._rr_constr = ETA_CF

    # ------------------------------------------------------------------ set-up
    def reinit(self, t, y, yp, t_bound, first_step=None):
        """Start (or restart after an event) from a consistent (t, y, yp) at order 1."""
        self.tn = float(t)
        self.t_bound = float(t_bound)
        self.yy = np.array(y, dtype=float)
        self.yp = np.array(yp, dtype=float)
        self.phi[:] = 0.0
        self.phi[0] = self.yy
        self.phi[1] = self.yp
        self._set_weights(self.yy)
        h = initial_step(self.yp, self.ewt_err, t_bound - t, self.max_step, first_step, t)
        if (self.tn + h - t_bound) * h > 0.0:
            h = (t_bound - self.tn) * (1.0 - 4.0 * UROUND)
        if h <= 0.0:
            raise SolverError(f"no room to step at t = {t:.9g} (end {t_bound:.9g})", t=t, h=h)
        self.phi[1] *= h
        self.hh = h
        self.kk = 1
        self.kused = 0
        self.hused = 0.0
        self.psi = [h] + [0.0] * (MAX_ORDER + 1)
        self._coeffs = None
        self.cj = 1.0 / h
        self.cjlast = self.cj
        self.cjold = self.cj
        self.ck = 1.0
        self.phase = 0
        self.ns = 0
        self.nst_restart = 0
        self.ss = SS_FIRST_STEP
        self.force_setup = True
        self.t_old = self.tn

    def _set_weights(self, y):
        """Error weights for Newton (all components) and for the error test (masked)."""
        w = np.abs(y)
        w *= self.rtol
        w += self.atol
        self.ewt = np.divide(1.0, w, out=w)
        if self.error_mask is None:
            self.ewt_err = w
        else:
            self.ewt_err = np.multiply(w, self.error_mask)

    # -------------------------------------------------------------------- step
    def step(self):
        """Take one successful step towards ``t_bound``; raise SolverError on failure."""
        phi = self.phi
        saved_t = self.tn
        hh = self.hh
        if (saved_t + hh - self.t_bound) * hh > 0.0:
            hh_new = (self.t_bound - saved_t) * (1.0 - 4.0 * UROUND)
            if self.nst_restart == 0:
                phi[1] *= hh_new / hh
                self.psi[0] = hh_new
            hh = hh_new
        kk = self.kk
        ncf = nef = 0
        psi_old = self.psi
        while True:
            if abs(hh) < 16.0 * UROUND * abs(saved_t):
                self._raise(min_step_reason(saved_t), saved_t, hh)
            # --- coefficients (IDASetCoeffs)
            if hh != self.hused or kk != self.kused:
                self.ns = 0
            ns = self.ns = min(self.ns + 1, self.kused + 2)
            if kk + 1 >= ns:
                coeffs = self._coeffs = bdf_coefficients(hh, kk, psi_old)
            else:
                coeffs = self._coeffs
            psi, sigma, beta, gamma, cj, ck = coeffs
            self.cjlast = self.cj
            self.cj = cj
            for i in range(ns, kk + 1):
                phi[i] *= beta[i]
            tn = saved_t + hh
            # --- corrector and error test
            status = self._newton(tn, kk, hh, cj, gamma)
            if status == OK and self.nonnegative is not None:
                status = self._check_constraints()
            if status == OK:
                ew = self.ewt_err
                ee = self.ee
                if self._ee_norm >= 0.0 and ew is self.ewt:
                    # one Newton iteration: ee = -delta, whose norm Newton just took
                    enorm_k = self._ee_norm
                else:
                    v = ee * ew
                    enorm_k = math.sqrt(sumsq(v) * self.inv_n)
                err_k = sigma[kk] * enorm_k
                terr_k = (kk + 1) * err_k
                knew = kk
                err_km1 = 0.0
                if kk > 2:
                    # estimates at orders k-1 and k-2 in one pass: ee + phi[k] (+ phi[k-1])
                    d = np.add.accumulate(phi[kk:kk - 2:-1], axis=0, out=self._err_rows)
                    d += ee
                    d *= ew
                    d *= d
                    sq = np.add.reduce(d, axis=1)
                    err_km1 = sigma[kk - 1] * math.sqrt(sq[0] * self.inv_n)
                    terr_km1 = kk * err_km1
                    terr_km2 = (kk - 1) * sigma[kk - 2] * math.sqrt(sq[1] * self.inv_n)
                    if max(terr_km1, terr_km2) <= terr_k:
                        knew = kk - 1
                elif kk == 2:
                    err_km1 = sigma[1] * wrms_norm(phi[2] + ee, ew)
                    if 2.0 * err_km1 <= 0.5 * terr_k:
                        knew = 1
                if ck * enorm_k <= 1.0:
                    break
                status = ERROR_FAIL
            # --- failure: restore the history and choose a smaller step (IDAHandleNFlag)
            self.phase = 1
            for i in range(ns, kk + 1):
                phi[i] /= beta[i]
            if status == ERROR_FAIL:
                self._fail = (ERROR_FAIL, ee * ew)
                nef += 1
                self.netf += 1
                if nef >= MAX_ERR_FAILS:
                    self._raise(f"the local error test failed {nef} times in one step",
                                saved_t, hh, ee * ew, "the weighted error estimate is dominated by")
                if nef == 1:
                    err_knew = err_km1 if knew == kk - 1 else err_k
                    kk = knew
                    rr = 0.9 * (2.0 * err_knew + 1e-4) ** (-1.0 / (kk + 1))
                    rr = max(ETA_MIN_EF, min(ETA_LOW, rr))
                elif nef == 2:
                    kk = knew
                    rr = ETA_MIN_EF
                else:
                    kk = 1
                    rr = ETA_MIN_EF
            else:
                ncf += 1
                self.ncfn += 1
                if ncf >= MAX_CONV_FAILS:
                    self._raise_newton(status, ncf, saved_t, hh)
                rr = self._rr_constr if status == CONSTRAINT_FAIL else ETA_CF
            hh *= rr
            if self.nst_restart == 0:
                psi_old = list(psi_old)
                psi_old[0] = hh
                phi[1] *= rr
            self.kk = kk
            self.hh = hh
        # --- success (IDACompleteStep)
        self.psi = psi
        self.t_old = saved_t
        self.tn = tn
        self._complete_step(kk, hh, knew, err_k, err_km1, nef + ncf > 0)

    def _check_constraints(self):
        """OK, or CONSTRAINT_FAIL with the step ratio that stops short of the crossing.

        As IDA's IDANls: the ratio is 0.9 min(y_pred / (y_pred - y)) over the violated
        components, at least 0.1.
        """
        idx = self.nonnegative
        y = self.yy[idx]
        bad = y < 0.0
        if not bad.any():
            return OK
        self.nconstr += 1
        y_new = y[bad]
        y_pred = y_new - self.ee[idx][bad]
        with np.errstate(divide="ignore", invalid="ignore"):
            q = np.where(y_pred > 0.0, y_pred / (y_pred - y_new), 0.0)
        self._rr_constr = max(0.9 * float(np.min(q)), 0.1)
        weighted = np.zeros(self.n)
        weighted[idx[bad]] = -y_new * self.ewt[idx[bad]]
        self._fail = (CONSTRAINT_FAIL, weighted)
        return CONSTRAINT_FAIL

    def _newton(self, tn, kk, hh, cj, gamma):
        """Modified Newton on the corrector; leaves y, y' and the correction ee in self."""
        phi = self.phi
        fun = self.fun
        ewt = self.ewt
        inv_n = self.inv_n
        k1 = kk + 1
        call_setup = self.force_setup or self.nst_restart == 0
        cjratio = cj / self.cjold
        if cjratio < CJ_RATIO_LOW or cjratio > CJ_RATIO_HIGH:
            call_setup = True
        if cj != self.cjlast:
            self.ss = SS_CJ_CHANGED
        jcur = False
        at_iterate = False      # J refreshed at the last iterate (not the predictor)
        lu_solve = self.lu.solve
        while True:
            if not at_iterate:
                yy = np.add.reduce(phi[:k1], axis=0)
                yp = np.dot(gamma, phi[1:k1])
                r = fun(tn, yy, yp)
                self.nre += 1
            if call_setup:
                if not math.isfinite(np.add.reduce(r)):
                    self._fail = (RESIDUAL_FAIL, r)
                    return RESIDUAL_FAIL
                info = self._setup(tn, yy, yp, r, cj, hh)
                jcur = True
                cjratio = 1.0
                if info != 0:
                    return JACOBIAN_FAIL if self._fail[0] == JACOBIAN_FAIL else SETUP_FAIL
            m = 0
            oldnrm = 0.0
            scale = 2.0 / (1.0 + cjratio) if cjratio != 1.0 else 0.0
            while True:
                delta = lu_solve(r)
                if scale:
                    delta *= scale
                self.nni += 1
                dw = delta * ewt
                delnrm = math.sqrt(sumsq(dw) * inv_n)
                if not delnrm <= 1e300:
                    self._fail = (RESIDUAL_FAIL, r)
                    return RESIDUAL_FAIL
                yy -= delta
                yp -= cj * delta
                if m == 0 and not at_iterate:
                    ee = -delta
                else:
                    ee -= delta
                if m == 0:
                    oldnrm = delnrm
                    if delnrm <= TOLDEL:
                        break
                else:
                    rate = (delnrm / oldnrm) ** (1.0 / m)
                    if rate > RATE_MAX:
                        m = -1
                        break
                    self.ss = rate / (1.0 - rate)
                if self.ss * delnrm <= EPCON:
                    break
                m += 1
                if m >= MAX_NEWTON_ITERS:
                    m = -1
                    break
                r = fun(tn, yy, yp)
                self.nre += 1
            if m >= 0:
                self.yy = yy
                self.yp = yp
                self.ee = ee
                self._ee_norm = delnrm if m == 0 and not at_iterate else -1.0
                return OK
            self._fail = (NEWTON_FAIL, dw)
            if jcur and (at_iterate or not self.iterate_retry):
                return NEWTON_FAIL
            if jcur:
                # a fresh J at the predictor did not contract: once per attempt, refresh it
                # at the last iterate and go on from there (newton_iterate_retry)
                at_iterate = True
                r = fun(tn, yy, yp)
                self.nre += 1
                if not math.isfinite(np.add.reduce(r)):
                    return NEWTON_FAIL
            call_setup = True

    def _setup(self, tn, yy, yp, r, cj, hh):
        """Evaluate and factorise J = dF/dy + cj dF/dy'; return 0 or the singular column+1."""
        self.nsetups += 1
        self.cjold = cj
        self.ss = SS_FIRST_STEP
        self.force_setup = False
        m = self.jacobian.iteration_matrix(tn, yy, yp, r, cj, self.ewt, hh)
        bad = _nonfinite_entries(m)
        if bad is not None:
            # a NaN or inf in dF/dy: recoverable like a failed residual (a smaller step
            # may stay inside the model's domain), reported as such if it persists
            self.force_setup = True
            self._fail = (JACOBIAN_FAIL, bad)
            return -1
        info = self.lu.factor(m)
        if info != 0:
            self.force_setup = True
            self._fail = (SETUP_FAIL, info)
        return info

    def _complete_step(self, kk, hh, knew, err_k, err_km1, failed=False):
        """Order and step selection after a successful step, then update the history."""
        phi = self.phi
        ee = self.ee
        self.nst += 1
        self.nst_restart += 1
        kdiff = kk - self.kused
        self.kused = kk
        self.hused = hh
        maxord = self.maxord
        if knew == kk - 1 or kk == maxord:
            self.phase = 1
        if self.phase == 0:
            if self.nst_restart > 1:
                kk += 1
                hnew = ETA_MAX * hh
                tmp = abs(hnew) * self.hmax_inv
                if tmp > 1.0:
                    hnew /= tmp
                hh = hnew
        else:
            # choose among orders k-1, k, k+1
            if knew == kk - 1:
                action = -1
            elif kk == maxord or kk + 1 >= self.ns or kdiff == 1:
                action = 0
            else:
                err_kp1 = wrms_norm(ee - phi[kk + 1], self.ewt_err) / (kk + 2)
                terr_k = (kk + 1) * err_k
                terr_kp1 = (kk + 2) * err_kp1
                if kk == 1:
                    action = 0 if terr_kp1 >= 0.5 * terr_k else 1
                else:
                    terr_km1 = kk * err_km1
                    if terr_km1 <= min(terr_k, terr_kp1):
                        action = -1
                    elif terr_kp1 >= terr_k:
                        action = 0
                    else:
                        action = 1
            if action == 1:
                kk += 1
                err_knew = err_kp1
            elif action == -1:
                kk -= 1
                err_knew = err_km1
            else:
                err_knew = err_k
            rr = (2.0 * err_knew + 1e-4) ** (-1.0 / (kk + 1))
            if rr >= ETA_MAX and not (failed and self.no_growth):
                hnew = ETA_MAX * hh
                tmp = abs(hnew) * self.hmax_inv
                if tmp > 1.0:
                    hnew /= tmp
                hh = hnew
            elif rr <= 1.0:
                hh *= max(ETA_MIN, min(ETA_LOW, rr))
        self.kk = kk
        self.hh = hh
        kused = self.kused
        if kused < maxord:
            phi[kused + 1] = ee
        phi[kused] += ee
        if 1 < kused and self.n_small:
            # phi[j] += phi[j + 1] for j = kused - 1 .. 0 in one sequential pass (the same
            # sums in the same order: IEEE addition is commutative); for small n only: the
            # overlapping reversed view costs a copy and a strided pass, 25x the loop at n = 20 000
            rows = phi[kused::-1]
            np.add.accumulate(rows, axis=0, out=rows)
        else:
            for j in range(kused - 1, -1, -1):
                phi[j] += phi[j + 1]
        self._set_weights(phi[0])

    # ------------------------------------------------------------ dense output
    def interpolate(self, t):
        """(y, y') at t in the last step, from the BDF interpolating polynomial."""
        return interpolate(t, self.tn, self.kused, self.psi, self.phi)

    # ------------------------------------------------------------------ errors
    def _raise(self, what, t, h, weighted=None, lead="culprits:"):
        culprits = []
        text = f"{SOLVER_NAME} failed at t = {t:.9g} trying step h = {h:.3g}: {what}"
        if weighted is not None:
            culprits = dominant_names(weighted, self.var_names)
            text += f"; {lead} {', '.join(repr(c) for c in culprits)}"
            if "error test" in what and self._reads_no_rate(int(np.nanargmax(np.where(
                    np.isfinite(weighted), np.abs(weighted), np.inf)))):
                text += (f". {culprits[0]!r} is algebraic (no equation reads its rate): it "
                         f"jumps here (an input that switches at this time, a step or the "
                         f"corner of a table), or the DAE's index is above one. Make the "
                         f"switch an event, or leave the algebraic variables out of the error "
                         f"test (suppress_alg=True with algebraic=[...])")
        elif self._fail is not None:
            return self._raise_newton(self._fail[0], 0, t, h, what)
        else:
            culprits = dominant_names(self.ee * self.ewt_err, self.var_names)
            text += ("; the step size is controlled by the local error of "
                     + ", ".join(map(repr, culprits)))
        raise SolverError(self._hinted(text) + ".", t=t, h=h, culprits=culprits)

    def _hinted(self, text) -> str:
        """``text`` with the hint of equations that constrain the states alone, where the
        caller found some (see solve._constraint_rows)."""
        hint = getattr(self, "index_hint", None)
        hint = hint() if callable(hint) else hint
        return text + ". " + hint.rstrip(". ") if hint else text

    def _reads_no_rate(self, j) -> bool:
        """True if the residual does not change with y'[j] at the last accepted point (an
        algebraic variable), by one difference; False where that cannot be told."""
        try:
            y = np.array(self.yy, dtype=float)
            yp = np.array(self.yp, dtype=float)
            r0 = np.asarray(self.fun(self.tn, y, yp), dtype=float)
            yp[j] += 1e-3 * max(abs(yp[j]), 1.0)
            r1 = np.asarray(self.fun(self.tn, y, yp), dtype=float)
        except Exception:       # noqa: BLE001  (only a hint: the failure is reported anyway)
            return False
        return bool(np.all(np.isfinite(r0)) and np.array_equal(r0, r1))

    def _raise_newton(self, status, ncf, t, h, what=None):
        kind, data = self._fail if self._fail is not None else (status, None)
        head = f"{SOLVER_NAME} failed at t = {t:.9g} trying step h = {h:.3g}: "
        if what is None:
            what = f"{ncf} corrector failures in one step"
        if kind == SETUP_FAIL:
            col = int(data) - 1
            if col >= 0:
                name = self.var_names[col] if self.var_names is not None else f"y[{col}]"
                culprits = [name]
                msg = (f"{what}; the iteration matrix dF/dy + cj dF/dy' is singular in the "
                       f"column of {name!r} (no equation determines it, or the DAE has "
                       "index > 1)")
            else:
                culprits = []
                msg = f"{what}; the iteration matrix dF/dy + cj dF/dy' is singular"
        elif kind == JACOBIAN_FAIL:
            rows, cols = data
            culprits = [self.var_names[c] if self.var_names is not None else f"y[{c}]"
                        for c in cols[:N_CULPRITS]]
            msg = (f"{what}; the Jacobian dF/dy + cj dF/dy' is not finite (NaN or inf) in "
                   f"equation(s) {rows[:N_CULPRITS]}, column(s) of "
                   f"{', '.join(map(repr, culprits))}: a derivative is undefined at this "
                   "point (e.g. a square root or power of a value that reached zero or "
                   "went negative)")
        elif kind == RESIDUAL_FAIL:
            r = np.asarray(data)
            bad = np.flatnonzero(~np.isfinite(r))
            culprits = dominant_names(np.where(np.isfinite(r), 0.0, np.inf), self.var_names,
                                      count=max(1, min(N_CULPRITS, bad.size)))
            nonfinite_y = np.flatnonzero(~np.isfinite(self.yy))
            msg = (f"{what}; the residual is not finite (NaN or inf) in equation(s) "
                   f"{bad[:N_CULPRITS].tolist()} (rows of {', '.join(map(repr, culprits))})")
            if nonfinite_y.size:
                msg += "; non-finite variables: " + ", ".join(
                    repr(n) for n in dominant_names(np.where(np.isfinite(self.yy), 0, np.inf),
                                                    self.var_names, min(3, nonfinite_y.size)))
        elif kind == CONSTRAINT_FAIL:
            culprits = dominant_names(data, self.var_names,
                                      count=max(1, min(N_CULPRITS, np.count_nonzero(data))))
            msg = (f"{what}; the corrected solution makes a variable declared non-negative "
                   f"negative ({', '.join(map(repr, culprits))}) however short the step: the "
                   "problem leaves y >= 0 there, or its tolerances are too loose for it")
        elif kind == ERROR_FAIL:
            culprits = dominant_names(data, self.var_names)
            msg = (f"{what}; the weighted local error estimate is dominated by "
                   f"{', '.join(map(repr, culprits))}")
        else:
            culprits = dominant_names(data, self.var_names)
            msg = (f"{what}; the Newton iteration did not converge, its correction is "
                   f"dominated by {', '.join(map(repr, culprits))}")
            d = np.asarray(data, dtype=float)
            j = int(np.nanargmax(np.where(np.isfinite(d), np.abs(d), np.inf))) if d.size else -1
            if j >= 0 and abs(h) <= 1e-9 * max(abs(t), 1e-3) and self._reads_no_rate(j):
                msg += (f". {culprits[0]!r} is algebraic (no equation reads its rate) and the "
                        f"step has shrunk to nothing: where the equations constrain states "
                        f"directly (a pendulum's length on its positions), the DAE's index is "
                        f"above one; reduce it (differentiate the constraint), or run it with "
                        f"its algebraic variables named and out of the error test "
                        f"(suppress_alg=True with algebraic=[...])")
        raise SolverError(self._hinted(head + msg) + ".", t=t, h=h, culprits=culprits)
