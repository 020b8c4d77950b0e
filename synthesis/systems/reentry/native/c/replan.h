/* replan.h -- the on-board re-planner of the native GuidedNetworkOperatorController: the loop of
 * models.controllers.reentry_replan (_columns, lp_step, replan) in C, step for step.
 *
 * Every guidance cycle the weights c_1..c_K of the plan (a bank of hat functions of the altitude,
 * added to the law's output) are re-solved from the navigated state:
 *
 * 1. ``iterations`` sequential linear-programming steps: the prediction at c and one per weight
 *    moved by RP_FD_STEP give the miss and the predicted loads and their finite-difference
 *    derivatives; the linearised minimax problem (minimise s + effort sum |c_j + Delta_j|
 *    subject to every predicted load <= s, s >= the peak already flown, predicted miss = 0,
 *    |c_j + Delta_j| <= c_max, |Delta_j| <= trust) is solved by lp.h; where the miss cannot be
 *    nulled, the least |miss| instead; where that fails too, no step;
 * 2. a uniform offset of all weights nulls the predicted miss (brent.h's br_solve_control from
 *    0 in [-c_max, c_max]).
 *
 * The predictions and Brent's search are the Python's operation for operation; the linear
 * programmes are lp.h where Python calls SciPy's HiGHS, so a re-planned flight equals the
 * pythonfmu FMU's to the rounding of the LP solutions, not bit for bit.
 *
 * descent-fmus (MIT licence).
 */
#ifndef DESCENT_REPLAN_H
#define DESCENT_REPLAN_H

#include <stdlib.h>

#include "brent.h"
#include "lp.h"
#include "plant_runtime.h"

/* the most steps of one prediction whose loads the re-planner records (memory: 2 K doubles a
   step) */
#define RP_MAX_STEPS 1e5
/* the most weights of a plan (the buffers of one cycle live on the stack) */
#define RP_K_MAX 32

/* evaluate(c, ctx, &miss, loads, &n): the prediction under the weights c -- its miss and its n
   load samples in loads[0..n-1] (room for RpProblem.cap); PC_OK or PC_ERROR (Python raised) */
typedef int (*rp_eval)(const double *c, void *ctx, double *miss, double *loads, int *n);

typedef struct {
    int k;                         /* weights */
    int cap;                       /* most load samples of one prediction */
    double c_max, trust, effort, floor;
    int iterations;
    double tol;                    /* Brent's tolerance on the miss [m], and its iterations */
    int max_iter;
    double fd_step, miss_scale;    /* reentry_replan.FD_STEP, MISS_SCALE */
} RpProblem;

/* Python's min(max(v, -c_max), c_max) */
static double rp_clip(double v, double c_max)
{
    const double lo = -c_max > v ? -c_max : v;
    return c_max < lo ? c_max : lo;
}

/* lp_step(m0, l0, dm, G, c, ...): the step delta[0..k-1] (G: n x k, row-major); PC_ERROR only
   when out of memory */
static int rp_lp_step(const RpProblem *pb, int n, double m0, const double *l0, const double *dm,
                      const double *g, const double *c, double *delta)
{
    const int k = pb->k, nv = 2 * k + 1, rows = n + 1 + 2 * k;
    double *a = (double *)calloc((size_t)rows * nv, sizeof(double));
    double *b = (double *)malloc(sizeof(double) * (size_t)rows);
    double cost[2 * RP_K_MAX + 1], lo[2 * RP_K_MAX + 1], hi[2 * RP_K_MAX + 1],
        aeq[2 * RP_K_MAX + 1], x[2 * RP_K_MAX + 1];
    double beq, value;
    int i, j, rc = PC_OK;
    if (a == NULL || b == NULL || k > RP_K_MAX) {
        rc = PC_ERROR;
        goto done;
    }
    for (j = 0; j < nv; j++) {     /* variables Delta_1..k, s, t_1..k */
        cost[j] = j < k ? 0.0 : (j == k ? 1.0 : pb->effort);
        aeq[j] = j < k ? dm[j] / pb->miss_scale : 0.0;
        lo[j] = j < k ? (-pb->trust > -pb->c_max - c[j] ? -pb->trust : -pb->c_max - c[j])
                      : (j == k ? -INFINITY : 0.0);
        hi[j] = j < k ? (pb->trust < pb->c_max - c[j] ? pb->trust : pb->c_max - c[j])
                      : INFINITY;
    }
    for (i = 0; i < n; i++) {      /* G Delta - s <= -l0 */
        for (j = 0; j < k; j++)
            a[(size_t)i * nv + j] = g[(size_t)i * k + j];
        a[(size_t)i * nv + k] = -1.0;
        b[i] = -l0[i];
    }
    a[(size_t)n * nv + k] = -1.0;  /* -s <= -floor */
    b[n] = -pb->floor;
    for (j = 0; j < k; j++) {      /* +-(c + Delta) <= t */
        a[(size_t)(n + 1 + j) * nv + j] = 1.0;
        a[(size_t)(n + 1 + j) * nv + k + 1 + j] = -1.0;
        b[n + 1 + j] = -c[j];
        a[(size_t)(n + 1 + k + j) * nv + j] = -1.0;
        a[(size_t)(n + 1 + k + j) * nv + k + 1 + j] = -1.0;
        b[n + 1 + k + j] = c[j];
    }
    beq = -m0 / pb->miss_scale;
    i = lp_solve(nv, cost, rows, a, b, 1, aeq, &beq, lo, hi, x, &value);
    if (i == LP_NOMEMORY) {
        rc = PC_ERROR;
        goto done;
    }
    if (i == LP_OPTIMAL) {
        for (j = 0; j < k; j++)
            delta[j] = x[j];
        goto done;
    }
    /* the miss cannot be nulled within the step: the least |miss| (variables Delta, e) */
    for (j = 0; j <= k; j++) {
        cost[j] = j < k ? 0.0 : 1.0;
        a[j] = j < k ? dm[j] / pb->miss_scale : -1.0;
        a[(k + 1) + j] = j < k ? -dm[j] / pb->miss_scale : -1.0;
    }
    lo[k] = 0.0;
    hi[k] = INFINITY;
    b[0] = -m0 / pb->miss_scale;
    b[1] = m0 / pb->miss_scale;
    i = lp_solve(k + 1, cost, 2, a, b, 0, NULL, NULL, lo, hi, x, &value);
    if (i == LP_NOMEMORY)
        rc = PC_ERROR;
    for (j = 0; j < k; j++)
        delta[j] = i == LP_OPTIMAL ? x[j] : 0.0;
done:
    free(a);
    free(b);
    return rc;
}

/* the miss of the plan shifted by an offset (the uniform offset's root search) */
typedef struct {
    rp_eval evaluate;
    void *ctx;
    const RpProblem *pb;
    const double *c;
    double *shifted, *loads;
} RpOffset;

static void rp_shift(const RpProblem *pb, const double *c, double offset, double *out)
{
    int j;
    for (j = 0; j < pb->k; j++)
        out[j] = rp_clip(c[j] + offset, pb->c_max);
}

static int rp_offset_miss(double offset, void *ctx, double *miss)
{
    RpOffset *o = (RpOffset *)ctx;
    int n;
    rp_shift(o->pb, o->c, offset, o->shifted);
    return o->evaluate(o->shifted, o->ctx, miss, o->loads, &n) == PC_OK ? 0 : PC_ERROR;
}

/* replan(evaluate, c, ...): the cycle's plan in plan[0..k-1] (in: the last plan), its predicted
   miss in *miss, the predictions made added to *n_pred; PC_OK, or PC_ERROR with plan, *miss and
   *n_pred untouched (Python raised) */
static int rp_replan(const RpProblem *pb, rp_eval evaluate, void *ctx, double *plan,
                     double *miss, int *n_pred)
{
    const int k = pb->k, cap = pb->cap;
    double *loads = (double *)malloc(sizeof(double) * (size_t)(k + 1) * cap);
    double *g = (double *)malloc(sizeof(double) * (size_t)cap * (k > 0 ? k : 1));
    double c[RP_K_MAX], dm[RP_K_MAX], step[RP_K_MAX], cj[RP_K_MAX], delta[RP_K_MAX];
    double m0, mj, offset, m;
    int counts[RP_K_MAX + 1], it, i, j, n, evals, made = 0, rc = PC_ERROR;
    RpOffset o;
    if (loads == NULL || g == NULL || k > RP_K_MAX)
        goto done;
    for (j = 0; j < k; j++)
        c[j] = rp_clip(plan[j], pb->c_max);
    for (it = 0; it < pb->iterations; it++) {
        if (evaluate(c, ctx, &m0, loads, &counts[0]) != PC_OK)   /* _columns */
            goto done;
        n = counts[0];
        for (j = 0; j < k; j++) {
            step[j] = c[j] + pb->fd_step <= pb->c_max ? pb->fd_step : -pb->fd_step;
            memcpy(cj, c, sizeof(double) * k);
            cj[j] += step[j];
            if (evaluate(cj, ctx, &mj, &loads[(size_t)(j + 1) * cap], &counts[j + 1]) != PC_OK)
                goto done;
            dm[j] = (mj - m0) / step[j];
            n = counts[j + 1] < n ? counts[j + 1] : n;
        }
        for (i = 0; i < n; i++)
            for (j = 0; j < k; j++)
                g[(size_t)i * k + j] = (loads[(size_t)(j + 1) * cap + i] - loads[i]) / step[j];
        made += k + 1;
        if (rp_lp_step(pb, n, m0, loads, dm, g, c, delta) != PC_OK)
            goto done;
        for (j = 0; j < k; j++)
            c[j] = rp_clip(c[j] + delta[j], pb->c_max);
    }
    o.evaluate = evaluate;
    o.ctx = ctx;
    o.pb = pb;
    o.c = c;
    o.shifted = cj;
    o.loads = loads;
    if (br_solve_control(rp_offset_miss, &o, 0.0, pb->tol, pb->max_iter, -pb->c_max, pb->c_max,
                         &offset, &m, &evals) != 0)
        goto done;
    rp_shift(pb, c, offset, plan);
    *miss = m;
    *n_pred += made + evals;
    rc = PC_OK;
done:
    free(loads);
    free(g);
    return rc;
}

#endif
