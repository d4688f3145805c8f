/* One step of pvgraph's BDF method (pvgraph/solver/ida.py, IDAIntegrator.step) in C.
 *
 * The same floating-point operations in the same order as the Python/numpy code, so the two
 * give the same numbers bit for bit:
 *   - elementwise array operations are loops (compiled without contraction into FMA);
 *   - np.add.reduce(v) of a 1-D array is numpy's pairwise summation (pv_sum);
 *   - np.add.reduce(phi[:k+1], axis=0) adds the rows one after the other, from 0.0;
 *   - np.dot(v, v) is 0.0 + cblas_ddot of numpy's own BLAS (its function pointer is given);
 *   - np.dot(gamma, phi[1:k+1]) is the BLAS call numpy makes for it: daxpy into zeros for
 *     k = 1, dgemv (row major, transposed) for k > 1;
 *   - the LU solve is scipy's LAPACK dgetrs (its pointer from scipy.linalg.cython_lapack);
 *   - x ** y of Python floats is the C library's pow, math.sqrt its sqrt.
 * A dense iteration matrix of a compiled Jacobian (System.jacobian_dense) is evaluated by the
 * compiled pv_jacobian, scattered into a zeroed column-major matrix as numpy's
 * J[rows, cols] = values and factorised by scipy's LAPACK dgetrf (the routine scipy's getrf
 * calls) or by the sparse LU of clu.c, as the Python code does (LUSolver's kind). Anything
 * else -- finite-difference or sparse matrices, and
 * any matrix with a non-finite entry or a zero pivot (to report it) -- is evaluated and
 * factorised by the Python code (a callback), which also raises every error from the codes
 * returned here.
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

typedef int64_t i64;

#define MAX_ORDER 5
#define EPCON 0.33
#define MAX_NEWTON_ITERS 4
#define MAX_CONV_FAILS 10
#define MAX_ERR_FAILS 10
#define RATE_MAX 0.9
#define XRATE 0.25
#define SS_FIRST_STEP 20.0
#define SS_CJ_CHANGED 100.0
#define ETA_MAX 2.0
#define ETA_MIN 0.5
#define ETA_LOW 0.9
#define ETA_MIN_EF 0.25
#define ETA_CF 0.25
#define UROUND 2.220446049250313e-16

/* statuses of the corrector, as in ida.py */
enum { OK, NEWTON_FAIL, RESIDUAL_FAIL, SETUP_FAIL, ERROR_FAIL, JACOBIAN_FAIL };
/* what pv_step returns */
enum { STEP_OK = 0, STEP_HMIN = 1, STEP_ERR_FAILS = 2, STEP_CONV_FAILS = 3, STEP_PYERR = 4 };
#define FAIL_BY_PYTHON (-1)
#define PYERR 99

typedef int (*res_fn)(double, const double *, const double *, const double *,
                      const double *, const void *, double *);
typedef double (*ddot64_fn)(i64, const double *, i64, const double *, i64);
typedef double (*ddot32_fn)(int, const double *, int, const double *, int);
typedef void (*daxpy64_fn)(i64, double, const double *, i64, double *, i64);
typedef void (*daxpy32_fn)(int, double, const double *, int, double *, int);
typedef void (*dgemv64_fn)(int, int, i64, i64, double, const double *, i64, const double *,
                           i64, double, double *, i64);
typedef void (*dgemv32_fn)(int, int, int, int, double, const double *, int, const double *,
                           int, double, double *, int);
typedef void (*dgetrs_fn)(char *, int *, int *, double *, int *, int *, double *, int *, int *);
typedef int (*setup_fn)(double, double, double);
typedef int (*solve_fn)(void);
typedef int (*jac_fn)(double, const double *, const double *, const double *,
                      const double *, const void *, double, double *);
typedef int (*ev_fn)(double, const double *, const double *, const double *, const double *,
                     const void *, double *);
typedef void (*dgetrf_fn)(int *, int *, double *, int *, int *, int *);
#define DOT_MAX_N 10000

/* Keep in step with _State in cstep.py: 8-byte fields only. */
typedef struct {
    i64 n, maxord, has_mask, no_growth, iterate_retry, blas64;
    double rtol, hmax_inv, inv_n;
    double *phi, *ewt, *ewt_err, *mask, *atol, *harmonic;
    double *yy, *yp, *ee, *eew, *r, *delta, *dw, *work, *failvec, *sq;
    void *res;
    const double *d, *P;
    const void *T;
    void *ddot, *dgemv, *daxpy, *dgetrs, *setup, *solve;
    double *lu;
    int *piv;
    double t_bound, tn, hh, hused, cj, cjlast, cjold, ck, ss, t_old, ee_norm;
    double psi[8];
    double c_psi[8], c_sigma[8], c_beta[8], c_gamma[8], c_cj, c_ck;
    i64 has_coeffs;
    i64 kk, kused, phase, ns, nst_restart, force_setup;
    i64 nst, nre, nni, netf, ncfn, nsetups;
    i64 fail_kind, fail_serial;
    double err_t, err_h;
    i64 err_count, err_status;
    /* the dense setup in C (jac == NULL: by the Python callback) */
    void *jac, *dgetrf;
    const i64 *rows, *cols;
    double *jout, *c_lu;
    int *c_piv;
    i64 nnz, c_setups;
    /* the event functions after a step (ev == NULL or g_old == NULL: not evaluated) */
    void *ev;
    const i64 *ev_idx;
    double *ev_buf, *g_old, *g_new;
    i64 ev_m, ev_state;
    /* the sparse LU of clu.c (lu_ctx == NULL: LAPACK); lu_c: the factors to solve with are
       its last ones */
    void *lu_ctx, *lu_factor, *lu_solve;
    i64 lu_c;
} pv_state;

typedef i64 (*clu_factor_fn)(void *, const double *);
typedef void (*clu_solve_fn)(const void *, double *);

/* numpy's pairwise summation (loops_utils.h.src), 8 accumulators, blocks of 128 */
static double pairwise(const double *a, i64 n)
{
    if (n < 8) {
        double res = 0.;
        for (i64 i = 0; i < n; i++) res += a[i];
        return res;
    }
    else if (n <= 128) {
        double r[8], res;
        i64 i;
        for (int j = 0; j < 8; j++) r[j] = a[j];
        for (i = 8; i < n - (n % 8); i += 8)
            for (int j = 0; j < 8; j++) r[j] += a[i + j];
        res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
        for (; i < n; i++) res += a[i];
        return res;
    }
    else {
        i64 n2 = n / 2;
        n2 -= n2 % 8;
        return pairwise(a, n2) + pairwise(a + n2, n - n2);
    }
}

/* np.add.reduce of a 1-D array: the identity 0.0 plus the pairwise sum */
static double reduce_sum(const double *a, i64 n) { return 0.0 + pairwise(a, n); }

/* ida.sumsq: np.dot(v, v) (numpy's DOUBLE_dot: sum = 0.; sum += cblas_ddot), above
   DOT_MAX_N elements np.add.reduce(v * v) */
static double sumsq(const pv_state *s, const double *v)
{
    if (s->n > DOT_MAX_N) {
        for (i64 i = 0; i < s->n; i++) s->sq[i] = v[i] * v[i];
        return reduce_sum(s->sq, s->n);
    }
    double sum = 0.;
    if (s->blas64) sum += ((ddot64_fn) s->ddot)(s->n, v, 1, v, 1);
    else sum += ((ddot32_fn) s->ddot)((int) s->n, v, 1, v, 1);
    return sum;
}

static double py_max(double a, double b) { return b > a ? b : a; }
static double py_min(double a, double b) { return b < a ? b : a; }

static void set_fail(pv_state *s, int kind, const double *v)
{
    memcpy(s->failvec, v, (size_t) s->n * sizeof(double));
    s->fail_kind = kind;
    s->fail_serial++;
}

static int residual(pv_state *s, double t, double *out)
{
    s->nre++;
    return ((res_fn) s->res)(t, s->yy, s->yp, s->d, s->P, s->T, out);
}

/* y = sum of phi[0..k], y' = np.dot(gamma, phi[1..k]) */
static void predict(pv_state *s, i64 kk, const double *gamma)
{
    i64 n = s->n;
    const double *phi = s->phi;
    double *yy = s->yy, *yp = s->yp;
    for (i64 i = 0; i < n; i++) yy[i] = 0.0 + phi[i];
    for (i64 j = 1; j <= kk; j++)
        for (i64 i = 0; i < n; i++) yy[i] += phi[j * n + i];
    memset(yp, 0, (size_t) n * sizeof(double));
    if (kk == 1) {
        if (s->blas64) ((daxpy64_fn) s->daxpy)(n, gamma[0], phi + n, 1, yp, 1);
        else ((daxpy32_fn) s->daxpy)((int) n, gamma[0], phi + n, 1, yp, 1);
    }
    else {
        /* CblasRowMajor = 101, CblasTrans = 112 */
        if (s->blas64)
            ((dgemv64_fn) s->dgemv)(101, 112, kk, n, 1., phi + n, n, gamma, 1, 0., yp, 1);
        else
            ((dgemv32_fn) s->dgemv)(101, 112, (int) kk, (int) n, 1., phi + n, (int) n, gamma, 1,
                                    0., yp, 1);
    }
}

/* LUSolver.solve: dense by dgetrs here, sparse (SuperLU) by the Python code */
static int lu_solve(pv_state *s, double *x)
{
    if (s->lu_c) {
        memcpy(x, s->r, (size_t) s->n * sizeof(double));
        ((clu_solve_fn) s->lu_solve)(s->lu_ctx, x);
        return 0;
    }
    if (s->lu == NULL) return ((solve_fn) s->solve)();
    int n = (int) s->n, one = 1, info = 0;
    char trans = 'N';
    memcpy(x, s->r, (size_t) n * sizeof(double));
    ((dgetrs_fn) s->dgetrs)(&trans, &n, &one, s->lu, &n, s->piv, x, &n, &info);
    return 0;
}

/* JacobianEvaluator.iteration_matrix (System.jacobian_dense) and LUSolver.factor for a
   compiled Jacobian: 0, or -1 where the Python code must do it (a non-finite value, a zero
   pivot: it evaluates the same matrix again and reports the failure) */
static int dense_setup(pv_state *s, double tn, double cj)
{
    const i64 n = s->n, nnz = s->nnz;
    double *a = s->c_lu, *v = s->jout;
    ((jac_fn) s->jac)(tn, s->yy, s->yp, s->d, s->P, s->T, cj, v);
    for (i64 k = 0; k < nnz; k++)
        if (!isfinite(v[k])) return -1;
    memset(a, 0, (size_t) (n * n) * sizeof(double));
    for (i64 k = 0; k < nnz; k++) a[s->cols[k] * n + s->rows[k]] = v[k];
    if (s->lu_ctx != NULL) {
        if (((clu_factor_fn) s->lu_factor)(s->lu_ctx, a) != 0) return -1;
        s->lu = NULL;
        s->lu_c = 1;
        s->c_setups++;
        return 0;
    }
    int ni = (int) n, info = 0;
    ((dgetrf_fn) s->dgetrf)(&ni, &ni, a, &ni, s->c_piv, &info);
    if (info != 0) return -1;
    s->lu = a;
    s->piv = s->c_piv;
    s->lu_c = 0;
    s->c_setups++;
    return 0;
}

/* IDAIntegrator._newton */
static int newton(pv_state *s, double tn, i64 kk, double hh, double cj, const double *gamma)
{
    const i64 n = s->n;
    double *yy = s->yy, *yp = s->yp, *r = s->r, *delta = s->delta, *dw = s->dw, *ee = s->eew;
    const double *ewt = s->ewt;
    const double inv_n = s->inv_n;
    const double cj_low = (1.0 - XRATE) / (1.0 + XRATE), cj_high = 1.0 / cj_low;
    const double toldel = 1e-8 * EPCON;
    int call_setup = s->force_setup || s->nst_restart == 0;
    double cjratio = cj / s->cjold;
    if (cjratio < cj_low || cjratio > cj_high) call_setup = 1;
    if (cj != s->cjlast) s->ss = SS_CJ_CHANGED;
    int jcur = 0, at_iterate = 0;
    for (;;) {
        if (!at_iterate) {
            predict(s, kk, gamma);
            residual(s, tn, r);
        }
        if (call_setup) {
            if (!isfinite(reduce_sum(r, n))) {
                set_fail(s, RESIDUAL_FAIL, r);
                return RESIDUAL_FAIL;
            }
            s->nsetups++;
            s->cjold = cj;
            s->ss = SS_FIRST_STEP;
            s->force_setup = 0;
            int info = s->jac != NULL ? dense_setup(s, tn, cj) : -1;
            if (info != 0) info = ((setup_fn) s->setup)(tn, cj, hh);
            jcur = 1;
            cjratio = 1.0;
            if (info != 0) {
                if (info == 3) return PYERR;
                s->force_setup = 1;
                s->fail_kind = FAIL_BY_PYTHON;
                s->fail_serial++;
                return info == 1 ? JACOBIAN_FAIL : SETUP_FAIL;
            }
        }
        i64 m = 0;
        double oldnrm = 0.0, delnrm;
        double scale = cjratio != 1.0 ? 2.0 / (1.0 + cjratio) : 0.0;
        for (;;) {
            if (lu_solve(s, delta) != 0) return PYERR;
            if (scale != 0.0)
                for (i64 i = 0; i < n; i++) delta[i] *= scale;
            s->nni++;
            for (i64 i = 0; i < n; i++) dw[i] = delta[i] * ewt[i];
            delnrm = sqrt(sumsq(s, dw) * inv_n);
            if (!(delnrm <= 1e300)) {
                set_fail(s, RESIDUAL_FAIL, r);
                return RESIDUAL_FAIL;
            }
            for (i64 i = 0; i < n; i++) yy[i] -= delta[i];
            for (i64 i = 0; i < n; i++) yp[i] -= cj * delta[i];
            if (m == 0 && !at_iterate)
                for (i64 i = 0; i < n; i++) ee[i] = -delta[i];
            else
                for (i64 i = 0; i < n; i++) ee[i] -= delta[i];
            if (m == 0) {
                oldnrm = delnrm;
                if (delnrm <= toldel) break;
            }
            else {
                double rate = pow(delnrm / oldnrm, 1.0 / (double) m);
                if (rate > RATE_MAX) {
                    m = -1;
                    break;
                }
                s->ss = rate / (1.0 - rate);
            }
            if (s->ss * delnrm <= EPCON) break;
            m += 1;
            if (m >= MAX_NEWTON_ITERS) {
                m = -1;
                break;
            }
            residual(s, tn, r);
        }
        if (m >= 0) {
            memcpy(s->ee, ee, (size_t) n * sizeof(double));
            s->ee_norm = (m == 0 && !at_iterate) ? delnrm : -1.0;
            return OK;
        }
        set_fail(s, NEWTON_FAIL, dw);
        if (jcur && (at_iterate || !s->iterate_retry)) return NEWTON_FAIL;
        if (jcur) {
            at_iterate = 1;
            residual(s, tn, r);
            if (!isfinite(reduce_sum(r, n))) return NEWTON_FAIL;
        }
        call_setup = 1;
    }
}

/* ida.bdf_coefficients into the c_* fields */
static void coefficients(pv_state *s, double h, i64 k, const double *psi_in)
{
    double *psi = s->c_psi, *beta = s->c_beta, *sigma = s->c_sigma, gamma[8];
    memcpy(psi, psi_in, 8 * sizeof(double));
    for (int i = 0; i <= k; i++) {
        beta[i] = 1.0;
        sigma[i] = 1.0;
        gamma[i] = 0.0;
    }
    double alpha_prev = 1.0, alpha_sum = 0.0 + 1.0, temp1 = h;
    for (i64 i = 1; i <= k; i++) {
        double temp2 = psi[i - 1];
        psi[i - 1] = temp1;
        beta[i] = beta[i - 1] * temp1 / temp2;
        temp1 = temp2 + h;
        double alpha = h / temp1;
        sigma[i] = (double) i * sigma[i - 1] * alpha;
        gamma[i] = gamma[i - 1] + alpha_prev / h;
        if (i < k) alpha_sum += alpha;
        alpha_prev = alpha;
    }
    psi[k] = temp1;
    double alphas = -s->harmonic[k];
    s->c_ck = py_max(fabs(alpha_prev + alphas + alpha_sum), alpha_prev);
    s->c_cj = -alphas / h;
    for (i64 i = 0; i < k; i++) s->c_gamma[i] = gamma[i + 1];
    s->has_coeffs = 1;
}

static void set_weights(pv_state *s, const double *y)
{
    const i64 n = s->n;
    double *w = s->ewt;
    for (i64 i = 0; i < n; i++) {
        double v = fabs(y[i]);
        v *= s->rtol;
        v += s->atol[i];
        w[i] = 1.0 / v;
    }
    if (s->has_mask)
        for (i64 i = 0; i < n; i++) s->ewt_err[i] = w[i] * s->mask[i];
}

/* IDAIntegrator._complete_step */
static void complete_step(pv_state *s, i64 kk, double hh, i64 knew, double err_k,
                          double err_km1, int failed)
{
    const i64 n = s->n, maxord = s->maxord;
    double *phi = s->phi, *ee = s->ee, *v = s->work;
    s->nst++;
    s->nst_restart++;
    i64 kdiff = kk - s->kused;
    s->kused = kk;
    s->hused = hh;
    if (knew == kk - 1 || kk == maxord) s->phase = 1;
    if (s->phase == 0) {
        if (s->nst_restart > 1) {
            kk += 1;
            double hnew = ETA_MAX * hh;
            double tmp = fabs(hnew) * s->hmax_inv;
            if (tmp > 1.0) hnew /= tmp;
            hh = hnew;
        }
    }
    else {
        int action;
        double err_kp1 = 0.0, err_knew;
        if (knew == kk - 1) action = -1;
        else if (kk == maxord || kk + 1 >= s->ns || kdiff == 1) action = 0;
        else {
            const double *ew = s->ewt_err, *p = phi + (kk + 1) * n;
            for (i64 i = 0; i < n; i++) v[i] = (ee[i] - p[i]) * ew[i];
            err_kp1 = sqrt(sumsq(s, v) / (double) n) / (double) (kk + 2);
            double terr_k = (double) (kk + 1) * err_k;
            double terr_kp1 = (double) (kk + 2) * err_kp1;
            if (kk == 1) action = terr_kp1 >= 0.5 * terr_k ? 0 : 1;
            else {
                double terr_km1 = (double) kk * err_km1;
                if (terr_km1 <= py_min(terr_k, terr_kp1)) action = -1;
                else if (terr_kp1 >= terr_k) action = 0;
                else action = 1;
            }
        }
        if (action == 1) {
            kk += 1;
            err_knew = err_kp1;
        }
        else if (action == -1) {
            kk -= 1;
            err_knew = err_km1;
        }
        else err_knew = err_k;
        double rr = pow(2.0 * err_knew + 1e-4, -1.0 / (double) (kk + 1));
        if (rr >= ETA_MAX && !(failed && s->no_growth)) {
            double hnew = ETA_MAX * hh;
            double tmp = fabs(hnew) * s->hmax_inv;
            if (tmp > 1.0) hnew /= tmp;
            hh = hnew;
        }
        else if (rr <= 1.0) hh *= py_max(ETA_MIN, py_min(ETA_LOW, rr));
    }
    s->kk = kk;
    s->hh = hh;
    i64 kused = s->kused;
    if (kused < maxord) memcpy(phi + (kused + 1) * n, ee, (size_t) n * sizeof(double));
    for (i64 i = 0; i < n; i++) phi[kused * n + i] += ee[i];
    for (i64 j = kused - 1; j >= 0; j--)
        for (i64 i = 0; i < n; i++) phi[j * n + i] += phi[(j + 1) * n + i];
    set_weights(s, phi);
}

/* EventTracker.evaluate at the step's end (the compiled pv_events, entries ev_idx) into
   g_new, and the test of EventTracker.crossings: ev_state 1 when no event function was zero
   before the step and none has g_old * g_new <= 0 (no candidate), else 2 */
static void events_after(pv_state *s)
{
    ((ev_fn) s->ev)(s->tn, s->yy, s->yp, s->d, s->P, s->T, s->ev_buf);
    int quiet = 1;
    for (i64 j = 0; j < s->ev_m; j++) {
        double g = s->ev_buf[s->ev_idx[j]], o = s->g_old[j];
        s->g_new[j] = g;
        if (o == 0.0 || o * g <= 0.0) quiet = 0;
    }
    s->ev_state = quiet ? 1 : 2;
}

/* IDAIntegrator.step */
int pv_step(pv_state *s)
{
    const i64 n = s->n;
    double *phi = s->phi;
    const double saved_t = s->tn;
    double hh = s->hh;
    s->ev_state = 0;
    if ((saved_t + hh - s->t_bound) * hh > 0.0) {
        double hh_new = (s->t_bound - saved_t) * (1.0 - 4.0 * UROUND);
        if (s->nst_restart == 0) {
            double f = hh_new / hh;
            for (i64 i = 0; i < n; i++) phi[n + i] *= f;
            s->psi[0] = hh_new;
        }
        hh = hh_new;
    }
    i64 kk = s->kk, knew = kk;
    int ncf = 0, nef = 0;
    double psi_old[8], tn = 0.0, err_k = 0.0, err_km1 = 0.0;
    memcpy(psi_old, s->psi, sizeof psi_old);
    for (;;) {
        if (fabs(hh) < 16.0 * UROUND * fabs(saved_t)) {
            s->err_t = saved_t;
            s->err_h = hh;
            return STEP_HMIN;
        }
        if (hh != s->hused || kk != s->kused) s->ns = 0;
        i64 ns = s->ns + 1 < s->kused + 2 ? s->ns + 1 : s->kused + 2;
        s->ns = ns;
        if (kk + 1 >= ns) coefficients(s, hh, kk, psi_old);
        const double *sigma = s->c_sigma, *beta = s->c_beta;
        const double cj = s->c_cj, ck = s->c_ck;
        s->cjlast = s->cj;
        s->cj = cj;
        for (i64 i = ns; i <= kk; i++)
            for (i64 e = 0; e < n; e++) phi[i * n + e] *= beta[i];
        tn = saved_t + hh;
        int status = newton(s, tn, kk, hh, cj, s->c_gamma);
        if (status == PYERR) return STEP_PYERR;
        if (status == OK) {
            const double *ew = s->ewt_err, *ee = s->ee;
            double *v = s->work, enorm_k;
            if (s->ee_norm >= 0.0 && !s->has_mask) enorm_k = s->ee_norm;
            else {
                for (i64 i = 0; i < n; i++) v[i] = ee[i] * ew[i];
                enorm_k = sqrt(sumsq(s, v) * s->inv_n);
            }
            err_k = sigma[kk] * enorm_k;
            double terr_k = (double) (kk + 1) * err_k;
            knew = kk;
            err_km1 = 0.0;
            if (kk > 2) {
                double *d0 = s->work, *d1 = s->work + n;
                const double *pk = phi + kk * n, *pk1 = phi + (kk - 1) * n;
                for (i64 i = 0; i < n; i++) {
                    d0[i] = pk[i];
                    d1[i] = d0[i] + pk1[i];
                }
                for (i64 i = 0; i < n; i++) {
                    d0[i] += ee[i];
                    d1[i] += ee[i];
                }
                for (i64 i = 0; i < n; i++) {
                    d0[i] *= ew[i];
                    d1[i] *= ew[i];
                }
                for (i64 i = 0; i < n; i++) {
                    d0[i] *= d0[i];
                    d1[i] *= d1[i];
                }
                double sq0 = reduce_sum(d0, n), sq1 = reduce_sum(d1, n);
                err_km1 = sigma[kk - 1] * sqrt(sq0 * s->inv_n);
                double terr_km1 = (double) kk * err_km1;
                double terr_km2 = (double) (kk - 1) * sigma[kk - 2] * sqrt(sq1 * s->inv_n);
                if (py_max(terr_km1, terr_km2) <= terr_k) knew = kk - 1;
            }
            else if (kk == 2) {
                const double *p2 = phi + 2 * n;
                for (i64 i = 0; i < n; i++) v[i] = (p2[i] + ee[i]) * ew[i];
                err_km1 = sigma[1] * sqrt(sumsq(s, v) / (double) n);
                if (2.0 * err_km1 <= 0.5 * terr_k) knew = 1;
            }
            if (ck * enorm_k <= 1.0) break;
            status = ERROR_FAIL;
        }
        /* failure: restore the history and choose a smaller step */
        s->phase = 1;
        for (i64 i = ns; i <= kk; i++)
            for (i64 e = 0; e < n; e++) phi[i * n + e] /= beta[i];
        double rr;
        if (status == ERROR_FAIL) {
            double *v = s->work;
            for (i64 i = 0; i < n; i++) v[i] = s->ee[i] * s->ewt_err[i];
            set_fail(s, ERROR_FAIL, v);
            nef += 1;
            s->netf++;
            if (nef >= MAX_ERR_FAILS) {
                s->err_t = saved_t;
                s->err_h = hh;
                s->err_count = nef;
                return STEP_ERR_FAILS;
            }
            if (nef == 1) {
                double err_knew = knew == kk - 1 ? err_km1 : err_k;
                kk = knew;
                rr = 0.9 * pow(2.0 * err_knew + 1e-4, -1.0 / (double) (kk + 1));
                rr = py_max(ETA_MIN_EF, py_min(ETA_LOW, rr));
            }
            else if (nef == 2) {
                kk = knew;
                rr = ETA_MIN_EF;
            }
            else {
                kk = 1;
                rr = ETA_MIN_EF;
            }
        }
        else {
            ncf += 1;
            s->ncfn++;
            if (ncf >= MAX_CONV_FAILS) {
                s->err_t = saved_t;
                s->err_h = hh;
                s->err_count = ncf;
                s->err_status = status;
                return STEP_CONV_FAILS;
            }
            rr = ETA_CF;
        }
        hh *= rr;
        if (s->nst_restart == 0) {
            psi_old[0] = hh;
            for (i64 i = 0; i < n; i++) phi[n + i] *= rr;
        }
        s->kk = kk;
        s->hh = hh;
    }
    memcpy(s->psi, s->c_psi, sizeof s->psi);
    s->t_old = saved_t;
    s->tn = tn;
    complete_step(s, kk, hh, knew, err_k, err_km1, nef + ncf > 0);
    if (s->ev != NULL && s->g_old != NULL) events_after(s);
    return STEP_OK;
}

/* result.interpolate: the interpolating polynomial of the last step and its derivative at t,
   np.dot(cy, phi[:kord+1]) and np.dot(cyp, phi[:kord+1]) (dgemv: kord + 1 >= 2 rows) */
void pv_interpolate(const pv_state *s, double t, double *y, double *yp)
{
    const i64 n = s->n;
    const double *psi = s->psi;
    double delt = t - s->tn, cy[8], cyp[8], c = 1.0, d = 0.0, gam = delt / psi[0];
    i64 kord = s->kused > 0 ? s->kused : 1;
    cy[0] = 1.0;
    cyp[0] = 0.0;
    for (i64 j = 1; j <= kord; j++) {
        d = d * gam + c / psi[j - 1];
        c = c * gam;
        cy[j] = c;
        cyp[j] = d;
        if (j < kord) gam = (delt + psi[j - 1]) / psi[j];
    }
    if (s->blas64) {
        ((dgemv64_fn) s->dgemv)(101, 112, kord + 1, n, 1., s->phi, n, cy, 1, 0., y, 1);
        ((dgemv64_fn) s->dgemv)(101, 112, kord + 1, n, 1., s->phi, n, cyp, 1, 0., yp, 1);
    }
    else {
        ((dgemv32_fn) s->dgemv)(101, 112, (int) (kord + 1), (int) n, 1., s->phi, (int) n, cy, 1,
                                0., y, 1);
        ((dgemv32_fn) s->dgemv)(101, 112, (int) (kord + 1), (int) n, 1., s->phi, (int) n, cyp,
                                1, 0., yp, 1);
    }
}

/* The integration loop of solve_dae around uneventful steps (keep in step with _Run in
   cstep.py). Steps are taken while no event function can have crossed zero: after each,
   the outputs of the step are written -- with t_eval, y and y' interpolated at every
   t_eval[i] <= tn into row i of out_y, out_yp; without, (tn, y, y') into row `count` of
   out_t, out_y, out_yp -- and the end of the interval is tested as the Python loop does.
   Returns ADV_END (the end was reached, outputs written), ADV_PAUSE (before a step: the step
   limit nst_limit is reached or the output rows are full), ADV_EVENTS (a step was taken whose
   events the Python code must evaluate or locate; its outputs are not written) or ADV_FAIL
   (the step failed; step_code is pv_step's code). */
enum { ADV_END = 0, ADV_PAUSE = 1, ADV_EVENTS = 2, ADV_FAIL = 3 };

typedef struct {
    i64 nst_limit;
    double t_end, end_tol;
    const double *t_eval;
    i64 n_eval, i_eval;
    double *out_t, *out_y, *out_yp;
    i64 cap, count, quiet, step_code;
    double *g_pair0, *g_pair1;
} pv_run;

int pv_advance(pv_state *s, pv_run *r)
{
    const i64 n = s->n;
    const size_t row = (size_t) n * sizeof(double);
    for (;;) {
        if (s->nst >= r->nst_limit) return ADV_PAUSE;
        if (r->t_eval == NULL && r->count >= r->cap) return ADV_PAUSE;
        int code = pv_step(s);
        if (code != STEP_OK) {
            r->step_code = code;
            return ADV_FAIL;
        }
        if (s->ev != NULL) {
            if (s->ev_state != 1) return ADV_EVENTS;
            /* CStepIntegrator.events_quiet: the values just written are the next step's
               old values, the other array of the pair takes the new ones */
            double *w = s->g_new;
            s->g_old = w;
            s->g_new = w == r->g_pair1 ? r->g_pair0 : r->g_pair1;
            r->quiet++;
        }
        const double tn = s->tn;
        if (r->t_eval != NULL) {
            while (r->i_eval < r->n_eval && r->t_eval[r->i_eval] <= tn) {
                const i64 i = r->i_eval;
                pv_interpolate(s, r->t_eval[i], r->out_y + i * n, r->out_yp + i * n);
                r->i_eval = i + 1;
            }
        }
        else {
            const i64 c = r->count;
            r->out_t[c] = tn;
            memcpy(r->out_y + c * n, s->yy, row);
            memcpy(r->out_yp + c * n, s->yp, row);
            r->count = c + 1;
        }
        if (r->t_end - tn <= r->end_tol * (fabs(tn) + fabs(s->hused))) return ADV_END;
    }
}
