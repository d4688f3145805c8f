/* LU factorisation with partial pivoting of a sparse matrix held dense (pvgraph/solver/clu.py).
 *
 * For a column order q fixed once per sparsity pattern (a fill-reducing ordering), the kernel
 * computes P A Q = L U with LAPACK's row partial pivoting: at elimination step k the pivot is
 * the entry of largest magnitude in the eliminated column k (column q[k] of A) among the rows
 * not yet pivoted, the first in LAPACK's current row order on ties -- the pivot sequence
 * dgetrf takes on A[:, q]. The elimination is left-looking (Gilbert and Peierls): column k is
 * the sparse triangular solve L x = A[:, q[k]] over the rows reached in the graph of L (a
 * depth-first search gives them in topological order), then the pivot search over the
 * unpivoted rows of x. Work is proportional to the floating-point operations, plus one pass
 * over the n x n input.
 *
 * The kernel depends on no pattern: the structure is read from the nonzero entries of the
 * matrix at each factorisation, so any matrix factors correctly; the column order only
 * decides the fill. A factorisation starts on the structure of the last successful one
 * (reuse = 1, the default): while a column has the same nonzero rows and takes the same
 * pivot, it is eliminated without a search; at the first column that differs, the searches
 * take over. Either way the factors are those of a factorisation from scratch, bit for bit.
 *
 * API (the signatures other C code calls through function pointers):
 *   void   *pv_lu_new(int64_t n, const int64_t *perm_c)   a context, or NULL (bad arguments,
 *                                                         no memory); perm_c[k] = column of A
 *                                                         eliminated at step k (NULL: natural)
 *   void    pv_lu_free(void *ctx)
 *   int64_t pv_lu_factor(void *ctx, const double *a)      a[j*n + i] = A[i, j] (column major),
 *                                                         not modified. Returns 0; j + 1 when
 *                                                         column j of A (j = perm_c[k]) has an
 *                                                         exactly zero pivot at step k (LAPACK's
 *                                                         info for the natural order); -1 when
 *                                                         an entry is not finite; -2 when memory
 *                                                         for the factors cannot be allocated.
 *   void    pv_lu_solve(const void *ctx, double *b)      A x = b in place with the last
 *                                                         successful factorisation. It uses the
 *                                                         context's scratch vector: one solve at
 *                                                         a time per context.
 *
 * Context layout (pv_lu below, fields in this order; clu.py mirrors the leading ones):
 *   int64_t n, status (last factor's return), step (its zero-pivot step, else -1),
 *           lnz, unz, anz (entries of L below and U above the diagonal, entries of A),
 *           lcap, ucap, acap (capacities), reuse (1: start on the last structure),
 *           nreused (factorisations done without a search), restart (step where the last
 *           factorisation searched from: 0 from scratch, -1 none);
 *   int32_t *q (n) column order, *p (n) p[k] = row of A pivoted at step k, *pinv (n)
 *           pinv[p[k]] = k, *ipiv (n) LAPACK's ipiv, 0-based (row k was swapped with row
 *           ipiv[k] at step k),
 *           *Lp (n+1), *Li (lcap)  L by columns, strictly lower, row indices as steps,
 *           *Up (n+1), *Ui (ucap)  U by columns, strictly upper, row indices as steps,
 *           *Ap (n+1), *Ai (acap)  the nonzero rows of A[:, q[k]] (the last structure);
 *   double  *Lx (lcap), *Ux (ucap), *Ud (n) (U's diagonal), *x (n) (scratch, zero between
 *           calls), *w (n) (the solve's scratch);
 *   int32_t *pos, *row_at (n)  LAPACK's current row order, *xi (2n), *mark (n)  search scratch.
 *
 * References
 *   J. R. Gilbert, T. Peierls, "Sparse partial pivoting in time proportional to arithmetic
 *   operations", SIAM J. Sci. Stat. Comput. 9 (1988) 862-874.
 *   T. A. Davis, "Direct Methods for Sparse Linear Systems", SIAM 2006, ch. 6 (cs_lu, cs_dfs).
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

typedef int32_t idx;

typedef struct {
    int64_t n, status, step, lnz, unz, anz, lcap, ucap, acap, reuse, nreused, restart;
    idx *q, *p, *pinv, *ipiv;
    idx *Lp, *Li, *Up, *Ui, *Ap, *Ai;
    double *Lx, *Ux, *Ud, *x, *w;
    idx *pos, *row_at, *xi, *mark;
    double *Uinv;       /* 1 / Ud where that is finite, else 0: the solve multiplies (the
                           latency of a division would chain from row to row) */
} pv_lu;

#define PV_LU_NMAX 46340      /* n * n fits a 32-bit index */

void pv_lu_free(void *vctx)
{
    pv_lu *c = (pv_lu *) vctx;
    if (c == NULL) return;
    void *arrays[] = {c->q, c->p, c->pinv, c->ipiv, c->Lp, c->Li, c->Up, c->Ui, c->Ap, c->Ai,
                      c->Lx, c->Ux, c->Ud, c->x, c->w, c->pos, c->row_at, c->xi, c->mark,
                      c->Uinv};
    for (size_t k = 0; k < sizeof arrays / sizeof arrays[0]; k++) free(arrays[k]);
    free(c);
}

void *pv_lu_new(int64_t n, const int64_t *perm_c)
{
    if (n < 1 || n > PV_LU_NMAX) return NULL;
    pv_lu *c = (pv_lu *) calloc(1, sizeof(pv_lu));
    if (c == NULL) return NULL;
    size_t un = (size_t) n;
    c->n = n;
    c->status = 1;                      /* nothing factorised yet */
    c->step = c->restart = -1;
    c->reuse = 1;
    c->lcap = c->ucap = c->acap = 4 * n + 16;     /* grow as needed */
    c->q = malloc(un * sizeof(idx));
    c->p = malloc(un * sizeof(idx));
    c->pinv = malloc(un * sizeof(idx));
    c->ipiv = malloc(un * sizeof(idx));
    c->Lp = calloc(un + 1, sizeof(idx));
    c->Up = calloc(un + 1, sizeof(idx));
    c->Ap = calloc(un + 1, sizeof(idx));
    c->Li = malloc((size_t) c->lcap * sizeof(idx));
    c->Ui = malloc((size_t) c->ucap * sizeof(idx));
    c->Ai = malloc((size_t) c->acap * sizeof(idx));
    c->Lx = malloc((size_t) c->lcap * sizeof(double));
    c->Ux = malloc((size_t) c->ucap * sizeof(double));
    c->Ud = calloc(un, sizeof(double));
    c->Uinv = calloc(un, sizeof(double));
    c->x = calloc(un, sizeof(double));
    c->w = calloc(un, sizeof(double));
    c->pos = malloc(un * sizeof(idx));
    c->row_at = malloc(un * sizeof(idx));
    c->xi = malloc(2 * un * sizeof(idx));
    c->mark = malloc(un * sizeof(idx));
    if (!c->q || !c->p || !c->pinv || !c->ipiv || !c->Lp || !c->Up || !c->Ap || !c->Li
        || !c->Ui || !c->Ai || !c->Lx || !c->Ux || !c->Ud || !c->Uinv || !c->x || !c->w || !c->pos
        || !c->row_at || !c->xi || !c->mark) {
        pv_lu_free(c);
        return NULL;
    }
    /* the column order must be a permutation of 0..n-1 */
    for (int64_t k = 0; k < n; k++) c->mark[k] = 0;
    for (int64_t k = 0; k < n; k++) {
        int64_t j = perm_c == NULL ? k : perm_c[k];
        if (j < 0 || j >= n || c->mark[j]) {
            pv_lu_free(c);
            return NULL;
        }
        c->mark[j] = 1;
        c->q[k] = (idx) j;
    }
    return c;
}

/* room for `need` entries in the index array *pi (and the value array *px if given);
   0, or -1 (no memory) */
static int grow(idx **pi, double **px, int64_t *cap, int64_t need)
{
    if (need <= *cap) return 0;
    int64_t ncap = 2 * *cap;
    if (ncap < need) ncap = need;
    idx *ni = realloc(*pi, (size_t) ncap * sizeof(idx));
    if (ni == NULL) return -1;
    *pi = ni;
    if (px != NULL) {
        double *nx = realloc(*px, (size_t) ncap * sizeof(double));
        if (nx == NULL) return -1;
        *px = nx;
    }
    *cap = ncap;
    return 0;
}

/* Depth-first search from row j in the graph of L (row i leads to the rows of L's column
   pinv[i] when row i is pivoted); the rows finished are pushed on xi[top..) in reverse
   post-order (cs_dfs). Returns the new top. */
static idx dfs(pv_lu *c, idx j, idx top, idx stamp)
{
    idx *xi = c->xi, *pstack = c->xi + c->n, *mark = c->mark, *pinv = c->pinv;
    const idx *Lp = c->Lp, *Li = c->Li;
    idx head = 0;
    xi[0] = j;
    while (head >= 0) {
        j = xi[head];
        idx jnew = pinv[j];
        if (mark[j] != stamp) {
            mark[j] = stamp;
            pstack[head] = jnew < 0 ? 0 : Lp[jnew];
        }
        idx end = jnew < 0 ? 0 : Lp[jnew + 1];
        int done = 1;
        for (idx p = pstack[head]; p < end; p++) {
            idx i = Li[p];
            if (mark[i] == stamp) continue;
            pstack[head] = p + 1;
            xi[++head] = i;
            done = 0;
            break;
        }
        if (done) {
            head--;
            xi[--top] = j;
        }
    }
    return top;
}

/* whether the 8 doubles at v are all +0.0 or -0.0: the OR of their bits, sign bits aside,
   is zero (integer operations: a subnormal counts, whatever the floating-point mode) */
static int all_zero8(const double *v)
{
#ifdef __SSE2__
    __m128i o = _mm_or_si128(_mm_or_si128(_mm_loadu_si128((const __m128i *) v),
                                          _mm_loadu_si128((const __m128i *) (v + 2))),
                             _mm_or_si128(_mm_loadu_si128((const __m128i *) (v + 4)),
                                          _mm_loadu_si128((const __m128i *) (v + 6))));
    o = _mm_and_si128(o, _mm_set1_epi64x(INT64_MAX));
    return _mm_movemask_epi8(_mm_cmpeq_epi32(o, _mm_setzero_si128())) == 0xFFFF;
#else
    uint64_t u[8];
    memcpy(u, v, sizeof u);
    return ((u[0] | u[1] | u[2] | u[3] | u[4] | u[5] | u[6] | u[7]) << 1) == 0;
#endif
}

/* any non-finite entry in columns q[k..n) of a */
static int nonfinite_from(const pv_lu *c, const double *a, int64_t k)
{
    const int64_t n = c->n;
    for (; k < n; k++) {
        const double *col = a + (int64_t) c->q[k] * n;
        for (int64_t i = 0; i < n; i++)
            if (!isfinite(col[i])) return 1;
    }
    return 0;
}

/* The elimination with searches from step k0 on. Expects the state of steps < k0: pinv
   (-1 for unpivoted rows), pos / row_at, L's columns with rows of A, lnz = Lp[k0],
   unz = Up[k0], anz = Ap[k0], x zero, mark below k0. Records each column's nonzero rows
   (Ap / Ai) for the next factorisation. */
/* LAPACK's interchange of rows k and pos[piv] (its row order decides ties); ipiv[k] */
static void interchange(pv_lu *c, idx k, idx piv)
{
    idx *pos = c->pos, *row_at = c->row_at;
    idx at = pos[piv], other = row_at[k];
    c->ipiv[k] = at;
    row_at[at] = other;
    pos[other] = at;
    row_at[k] = piv;
    pos[piv] = k;
}

static int64_t factor_from(pv_lu *c, const double *a, idx k0)
{
    const idx n = (idx) c->n;
    idx *pinv = c->pinv, *pos = c->pos, *mark = c->mark, *xi = c->xi;
    double *x = c->x;
    int64_t status = 0;
    c->step = -1;
    for (idx k = k0; k < n; k++) {
        if (grow(&c->Li, &c->Lx, &c->lcap, c->lnz + n) || grow(&c->Ui, &c->Ux, &c->ucap,
                                                                 c->unz + n)
            || grow(&c->Ai, NULL, &c->acap, c->anz + n)) {
            status = -2;
            break;
        }
        idx *Ai = c->Ai;
        int64_t anz = c->anz;
        const double *col = a + (int64_t) c->q[k] * n;
        idx top = n;
        /* the column's entries into x, and the rows they reach; blocks of 8 zeros skipped */
        for (idx i0 = 0; i0 < n; i0 += 8) {
            idx i1 = i0 + 8 < n ? i0 + 8 : n;
            if (i1 - i0 == 8 && all_zero8(col + i0)) continue;
            for (idx i = i0; i < i1; i++) {
                double v = col[i];
                if (v != 0.0) {
                    if (!isfinite(v)) {
                        status = -1;
                        break;
                    }
                    x[i] = v;
                    Ai[anz++] = i;
                    if (mark[i] != k) top = dfs(c, i, top, k);
                }
            }
            if (status) break;
        }
        if (status) {
            for (idx px = top; px < n; px++) x[xi[px]] = 0.0;
            break;
        }
        c->anz = anz;
        c->Ap[k + 1] = (idx) anz;
        /* x -= L[:, j] x_j for the pivoted rows, in topological order */
        const idx *Lp = c->Lp, *Li = c->Li;
        const double *Lx = c->Lx;
        for (idx px = top; px < n; px++) {
            idx j = pinv[xi[px]];
            if (j < 0) continue;
            double xj = x[xi[px]];
            for (idx p = Lp[j]; p < Lp[j + 1]; p++) x[Li[p]] -= Lx[p] * xj;
        }
        /* U's column; the pivot: largest |x| among unpivoted rows, first in row order */
        idx *Ui = c->Ui;
        double *Ux = c->Ux;
        int64_t unz = c->unz;
        idx piv = -1;
        double amax = -1.0;
        for (idx px = top; px < n; px++) {
            idx i = xi[px];
            if (pinv[i] >= 0) {
                Ui[unz] = pinv[i];
                Ux[unz++] = x[i];
                x[i] = 0.0;
            } else {
                double t = fabs(x[i]);
                if (t > amax || (t == amax && pos[i] < pos[piv])) {
                    amax = t;
                    piv = i;
                }
            }
        }
        c->unz = unz;
        c->Up[k + 1] = (idx) unz;
        if (amax <= 0.0) {          /* no candidate, or all exactly zero */
            for (idx px = top; px < n; px++) x[xi[px]] = 0.0;
            c->step = k;
            status = nonfinite_from(c, a, k + 1) ? -1 : (int64_t) c->q[k] + 1;
            break;
        }
        double pivot = x[piv];
        c->Ud[k] = pivot;
        pinv[piv] = k;
        c->p[k] = piv;
        interchange(c, k, piv);
        x[piv] = 0.0;
        idx *Lio = c->Li;
        double *Lxo = c->Lx;
        int64_t lnz = c->lnz;
        for (idx px = top; px < n; px++) {
            idx i = xi[px];
            if (pinv[i] < 0) {
                Lio[lnz] = i;
                Lxo[lnz++] = x[i] / pivot;
                x[i] = 0.0;
            }
        }
        c->lnz = lnz;
        c->Lp[k + 1] = (idx) lnz;
    }
    if (status == 0) {
        /* L's row indices become elimination steps, for the solve */
        idx *Li = c->Li;
        for (int64_t p = 0; p < c->lnz; p++) Li[p] = pinv[Li[p]];
    }
    return status;
}

/* Leave the previous structure at step k: the state factor_from expects */
static int64_t restart_at(pv_lu *c, const double *a, idx k)
{
    const idx n = (idx) c->n;
    idx *Li = c->Li, *p = c->p, *pinv = c->pinv, *mark = c->mark;
    for (int64_t s = 0; s < c->Lp[k]; s++) Li[s] = p[Li[s]];
    for (idx i = 0; i < n; i++) {
        pinv[i] = -1;
        mark[i] = -1;
    }
    for (idx j = 0; j < k; j++) pinv[p[j]] = j;
    c->lnz = c->Lp[k];
    c->unz = c->Up[k];
    c->anz = c->Ap[k];
    c->restart = k;
    return factor_from(c, a, k);
}

/* The elimination on the structure of the last factorisation: while each column's nonzero
   rows are the ones it had and the pivot is the row it was, the reach, its topological order
   and the candidates are the ones the searches would find, and so are the numbers; at the
   first column where either differs, the searches take over (restart_at). */
static int64_t refactor(pv_lu *c, const double *a)
{
    const idx n = (idx) c->n;
    const idx *p = c->p, *Ap = c->Ap, *Ai = c->Ai, *Lp = c->Lp, *Li = c->Li, *Up = c->Up,
              *Ui = c->Ui;
    idx *pos = c->pos, *row_at = c->row_at;
    double *Lx = c->Lx, *Ux = c->Ux, *x = c->x;
    for (idx i = 0; i < n; i++) pos[i] = row_at[i] = i;
    for (idx k = 0; k < n; k++) {
        const double *col = a + (int64_t) c->q[k] * n;
        idx t = Ap[k];
        const idx tend = Ap[k + 1];
        int same = 1, bad = 0;
        for (idx i0 = 0; i0 < n && same && !bad; i0 += 8) {
            idx i1 = i0 + 8 < n ? i0 + 8 : n;
            if (i1 - i0 == 8 && all_zero8(col + i0)) continue;
            for (idx i = i0; i < i1; i++) {
                double v = col[i];
                if (v != 0.0) {
                    if (!isfinite(v)) {
                        bad = 1;
                        break;
                    }
                    if (t == tend || Ai[t] != i) {
                        same = 0;
                        break;
                    }
                    x[i] = v;
                    t++;
                }
            }
        }
        if (bad || !same || t != tend) {
            for (idx s = Ap[k]; s < t; s++) x[Ai[s]] = 0.0;
            if (bad) {
                c->step = -1;
                return -1;
            }
            return restart_at(c, a, k);
        }
        /* x -= L[:, j] x_j in the order of U's column (topological), U's values */
        for (idx u = Up[k]; u < Up[k + 1]; u++) {
            idx j = Ui[u], r = p[j];
            double xj = x[r];
            x[r] = 0.0;
            Ux[u] = xj;
            for (idx s = Lp[j]; s < Lp[j + 1]; s++) x[p[Li[s]]] -= Lx[s] * xj;
        }
        /* the pivot among the candidates, as factor_from chooses it */
        idx piv = p[k];
        double amax = fabs(x[piv]);
        for (idx s = Lp[k]; s < Lp[k + 1]; s++) {
            idx i = p[Li[s]];
            double tv = fabs(x[i]);
            if (tv > amax || (tv == amax && pos[i] < pos[piv])) {
                amax = tv;
                piv = i;
            }
        }
        if (piv != p[k] || amax <= 0.0) {
            x[p[k]] = 0.0;
            for (idx s = Lp[k]; s < Lp[k + 1]; s++) x[p[Li[s]]] = 0.0;
            return restart_at(c, a, k);
        }
        double pivot = x[piv];
        c->Ud[k] = pivot;
        interchange(c, k, piv);
        x[piv] = 0.0;
        for (idx s = Lp[k]; s < Lp[k + 1]; s++) {
            idx r = p[Li[s]];
            Lx[s] = x[r] / pivot;
            x[r] = 0.0;
        }
    }
    c->nreused++;
    c->restart = -1;
    c->step = -1;
    return 0;
}

int64_t pv_lu_factor(void *vctx, const double *a)
{
    pv_lu *c = (pv_lu *) vctx;
    int64_t status;
    if (c->reuse && c->status == 0) {
        status = refactor(c, a);
    } else {
        const idx n = (idx) c->n;
        for (idx i = 0; i < n; i++) {
            c->pinv[i] = -1;
            c->pos[i] = c->row_at[i] = i;
            c->mark[i] = -1;
        }
        c->lnz = c->unz = c->anz = 0;
        c->restart = 0;
        status = factor_from(c, a, 0);
    }
    c->status = status;
    if (status == 0)
        for (int64_t k = 0; k < c->n; k++)       /* as LAPACK: no reciprocal below sfmin */
            c->Uinv[k] = fabs(c->Ud[k]) >= DBL_MIN ? 1.0 / c->Ud[k] : 0.0;
    return status;
}



void pv_lu_solve(const void *vctx, double *b)
{
    const pv_lu *c = (const pv_lu *) vctx;
    const idx n = (idx) c->n;
    const idx *p = c->p, *q = c->q, *Lp = c->Lp, *Li = c->Li, *Up = c->Up, *Ui = c->Ui;
    const double *Lx = c->Lx, *Ux = c->Ux, *Ud = c->Ud, *Uinv = c->Uinv;
    double *w = c->w;
    for (idx k = 0; k < n; k++) w[k] = b[p[k]];
    for (idx k = 0; k < n; k++) {
        double wk = w[k];
        if (wk != 0.0)
            for (idx t = Lp[k]; t < Lp[k + 1]; t++) w[Li[t]] -= Lx[t] * wk;
    }
    for (idx k = n - 1; k >= 0; k--) {
        double wk = w[k];
        if (wk != 0.0) {
            if (Uinv[k] != 0.0) wk *= Uinv[k]; else wk /= Ud[k];
            w[k] = wk;
            for (idx t = Up[k]; t < Up[k + 1]; t++) w[Ui[t]] -= Ux[t] * wk;
        }
    }
    for (idx k = 0; k < n; k++) b[q[k]] = w[k];
}
