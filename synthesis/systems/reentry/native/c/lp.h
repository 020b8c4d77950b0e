/* lp.h -- a small dense linear programme, solved on board by the native re-planner:
 *
 *     minimise c^T x  subject to  A_ub x <= b_ub,  A_eq x = b_eq,  lo <= x <= hi
 *
 * (n variables, few: the re-planner has 2K + 1; many inequality rows: the predicted loads;
 * lo/hi may be -INFINITY/INFINITY).  The primal has few columns and many rows, so the simplex
 * method runs on its dual, whose tableau has one row per primal variable:
 *
 *     maximise beta^T y  subject to  sum_i y_i a_i = c,  y_i >= 0 (inequalities), y_e free
 *
 * where a_i^T x >= beta_i are the primal's rows (each A_ub row negated, each finite bound a row
 * of its own) and the equality rows enter twice (y_e = y_e+ - y_e-).  Phase one drives the
 * artificial variables of the dual's n equations out; phase two optimises; the primal solution
 * x is read from the reduced costs of the artificial columns (x = -pi, pi the dual's simplex
 * multipliers).  Dantzig's rule, switching to Bland's rule (which cannot cycle) after a run of
 * degenerate pivots.
 *
 * The same problems are solved in Python by SciPy's HiGHS (models.controllers.reentry_replan.
 * lp_step): this is a second implementation, equal to it in the optimal value to rounding and
 * in the solution wherever the optimum is unique (tests/systems/reentry/test_native_replan.py).
 *
 * descent-fmus (MIT licence).
 */
#ifndef DESCENT_LP_H
#define DESCENT_LP_H

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define LP_OPTIMAL 0
#define LP_ITERATIONS 1    /* the iteration limit was reached */
#define LP_INFEASIBLE 2    /* the primal is infeasible (or unbounded: its dual is infeasible) */
#define LP_NOMEMORY 4

#define LP_TOL 1e-9        /* reduced costs and phase one's residual (the data are scaled to O(1)) */
#define LP_PIVOT 1e-11     /* smallest pivot */

typedef struct {
    int rows, cols, width;         /* n, structural + artificial columns, cols + 1 (rhs) */
    int m;                         /* structural columns */
    double *t;                     /* (rows + 1) x width; the last row: reduced costs, -z */
    int *basis;
    int bland;                     /* Bland's rule from now on */
} LpTableau;

#define LP_AT(tb, i, j) ((tb)->t[(size_t)(i) * (tb)->width + (j)])

static void lp_pivot(LpTableau *tb, int r, int q)
{
    const int w = tb->width;
    double *pr = &LP_AT(tb, r, 0);
    const double p = pr[q];
    int i, j;
    for (j = 0; j < w; j++)
        pr[j] /= p;
    pr[q] = 1.0;
    for (i = 0; i <= tb->rows; i++) {
        double *row = &LP_AT(tb, i, 0);
        const double f = row[q];
        if (i == r || f == 0.0)
            continue;
        for (j = 0; j < w; j++)
            row[j] -= f * pr[j];
        row[q] = 0.0;
    }
    tb->basis[r] = q;
}

/* the simplex iterations over the columns below ``allowed``: 0 optimal, 1 unbounded, 2 limit */
static int lp_iterate(LpTableau *tb, int allowed, int max_iter)
{
    const int n = tb->rows, rhs = tb->width - 1;
    const double *d = &LP_AT(tb, n, 0);
    int it, degenerate = 0;
    for (it = 0; it < max_iter; it++) {
        int q = -1, r = -1, i, j;
        double best = -LP_TOL, ratio = INFINITY;
        for (j = 0; j < allowed; j++)
            if (d[j] < best) {
                q = j;
                if (tb->bland)
                    break;
                best = d[j];
            }
        if (q < 0)
            return 0;
        for (i = 0; i < n; i++) {
            const double a = LP_AT(tb, i, q);
            if (a > LP_PIVOT) {
                const double v = LP_AT(tb, i, rhs) / a;
                if (r < 0 || v < ratio - 1e-12 ||
                    (v <= ratio + 1e-12 && (tb->bland ? tb->basis[i] < tb->basis[r]
                                                      : a > LP_AT(tb, r, q)))) {
                    if (r < 0 || v < ratio)
                        ratio = v;
                    r = i;
                }
            }
        }
        if (r < 0)
            return 1;
        degenerate = ratio <= 1e-12 ? degenerate + 1 : 0;
        if (degenerate > 2 * n + 10)
            tb->bland = 1;
        lp_pivot(tb, r, q);
    }
    return 2;
}

/* the reduced-cost row of the costs ``cost`` (one per column) for the current basis */
static void lp_costs(LpTableau *tb, const double *cost)
{
    const int n = tb->rows, w = tb->width;
    double *d = &LP_AT(tb, n, 0);
    int i, j;
    for (j = 0; j < w; j++)
        d[j] = j < tb->cols ? cost[j] : 0.0;
    for (i = 0; i < n; i++) {
        const double cb = cost[tb->basis[i]];
        if (cb != 0.0)
            for (j = 0; j < w; j++)
                d[j] -= cb * LP_AT(tb, i, j);
    }
}

/* the primal's rows a^T x >= beta as the dual's columns (module comment): the column count, and
   if ``col`` is not NULL, column k written to col[k * n ..] with cost -beta in cost[k] */
static int lp_columns(int n, int m_ub, int m_eq, const double *a_ub, const double *b_ub,
                      const double *a_eq, const double *b_eq, const double *lo,
                      const double *hi, double *col, double *cost)
{
    int k = 0, i, j, s;
    for (i = 0; i < m_ub; i++, k++)
        if (col) {
            for (j = 0; j < n; j++)
                col[(size_t)k * n + j] = -a_ub[(size_t)i * n + j];
            cost[k] = b_ub[i];
        }
    for (j = 0; j < n; j++) {
        if (isfinite(lo[j])) {
            if (col) {
                memset(&col[(size_t)k * n], 0, sizeof(double) * n);
                col[(size_t)k * n + j] = 1.0;
                cost[k] = -lo[j];
            }
            k++;
        }
        if (isfinite(hi[j])) {
            if (col) {
                memset(&col[(size_t)k * n], 0, sizeof(double) * n);
                col[(size_t)k * n + j] = -1.0;
                cost[k] = hi[j];
            }
            k++;
        }
    }
    for (i = 0; i < m_eq; i++)
        for (s = 1; s >= -1; s -= 2, k++)
            if (col) {
                for (j = 0; j < n; j++)
                    col[(size_t)k * n + j] = s * a_eq[(size_t)i * n + j];
                cost[k] = -s * b_eq[i];
            }
    return k;
}

/* the problem of the module comment (matrices row-major, n columns): LP_OPTIMAL with the
   solution in x[0..n-1] and its value in *value, else the status (x untouched) */
static int lp_solve(int n, const double *c, int m_ub, const double *a_ub, const double *b_ub,
                    int m_eq, const double *a_eq, const double *b_eq, const double *lo,
                    const double *hi, double *x, double *value)
{
    const int m = lp_columns(n, m_ub, m_eq, a_ub, b_ub, a_eq, b_eq, lo, hi, NULL, NULL);
    LpTableau tb;
    double *col, *cost, *sign;
    int i, j, status, rc = LP_OPTIMAL;
    const int max_iter = 50 * (n + m) + 100;
    tb.rows = n;
    tb.m = m;
    tb.cols = m + n;
    tb.width = m + n + 1;
    tb.bland = 0;
    tb.t = (double *)calloc((size_t)(n + 1) * tb.width, sizeof(double));
    tb.basis = (int *)malloc(sizeof(int) * (size_t)n);
    col = (double *)malloc(sizeof(double) * ((size_t)m * n + 1));
    cost = (double *)calloc((size_t)(m + n), sizeof(double));
    sign = (double *)malloc(sizeof(double) * (size_t)n);
    if (!tb.t || !tb.basis || !col || !cost || !sign) {
        rc = LP_NOMEMORY;
        goto done;
    }
    lp_columns(n, m_ub, m_eq, a_ub, b_ub, a_eq, b_eq, lo, hi, col, cost);
    for (i = 0; i < n; i++) {      /* the dual's equations, right-hand sides c_i >= 0 */
        sign[i] = c[i] < 0.0 ? -1.0 : 1.0;
        for (j = 0; j < m; j++)
            LP_AT(&tb, i, j) = sign[i] * col[(size_t)j * n + i];
        LP_AT(&tb, i, m + i) = 1.0;
        LP_AT(&tb, i, tb.width - 1) = sign[i] * c[i];
        tb.basis[i] = m + i;
    }
    {                              /* phase one: minimise the sum of the artificials */
        double *one = (double *)calloc((size_t)(m + n), sizeof(double));
        if (!one) {
            rc = LP_NOMEMORY;
            goto done;
        }
        for (j = m; j < m + n; j++)
            one[j] = 1.0;
        lp_costs(&tb, one);
        free(one);
    }
    status = lp_iterate(&tb, tb.cols, max_iter);
    if (status == 2) {
        rc = LP_ITERATIONS;
        goto done;
    }
    {
        double scale = 1.0;
        for (i = 0; i < n; i++)
            scale = fabs(c[i]) > scale ? fabs(c[i]) : scale;
        if (-LP_AT(&tb, n, tb.width - 1) > LP_TOL * scale) {
            rc = LP_INFEASIBLE;
            goto done;
        }
    }
    for (i = 0; i < n; i++)        /* artificials left in the basis at zero: pivot them out */
        if (tb.basis[i] >= m) {
            int q = -1;
            double big = LP_PIVOT;
            for (j = 0; j < m; j++)
                if (fabs(LP_AT(&tb, i, j)) > big) {
                    big = fabs(LP_AT(&tb, i, j));
                    q = j;
                }
            if (q >= 0)
                lp_pivot(&tb, i, q);
        }
    tb.bland = 0;
    lp_costs(&tb, cost);           /* phase two: minimise -beta^T y over the structurals */
    status = lp_iterate(&tb, m, max_iter);
    if (status != 0) {
        rc = status == 1 ? LP_INFEASIBLE : LP_ITERATIONS;
        goto done;
    }
    for (i = 0; i < n; i++)        /* x = -pi; pi_i = -(reduced cost of artificial i) * sign */
        x[i] = sign[i] * LP_AT(&tb, n, m + i);
    *value = 0.0;
    for (i = 0; i < n; i++)
        *value += c[i] * x[i];
done:
    free(tb.t);
    free(tb.basis);
    free(col);
    free(cost);
    free(sign);
    return rc;
}

#endif
