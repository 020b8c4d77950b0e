/* guidance_cycle.h -- the guidance cycle of S1's native guidance controllers (npc_model.c:
 * ReentryNPC, guided_model.c: GuidedNetworkOperatorController), as
 * models.controllers.reentry_npc._GuidanceCycle runs it: at a communication point at or after
 * the next correction time, above hf, the model's correction runs and the next time moves on by
 * whole cycles.  model_config.h gives GUIDE_HF; the including model gives its altitude and its
 * correction as callbacks.
 *
 * descent-fmus (MIT licence).
 */
#ifndef DESCENT_GUIDANCE_CYCLE_H
#define DESCENT_GUIDANCE_CYCLE_H

#include <stdio.h>

#include "brent.h"
#include "plant_runtime.h"

typedef struct {
    double t, next;                /* _t (end of the last step), _next (next correction) */
    int failed;                    /* a correction failed where Python raises */
    char msg[PC_MSG];              /* ... and where */
} GuidanceCycle;

/* prepare(): no step yet, a correction due at once */
static void gc_prepare(GuidanceCycle *g)
{
    g->t = g->next = 0.0;
    g->failed = 0;
}

/* _maybe_correct(x, cycle): altitude(ctx, &h) of the navigated state, asked only when a
   correction is due; correct(ctx, h) when it is above hf.  PC_OK or PC_ERROR (Python raised) */
static int gc_maybe_correct(GuidanceCycle *g, double cycle, int (*altitude)(void *, double *),
                            int (*correct)(void *, double), void *ctx)
{
    double h, m;
    int err = 0;
    if (!(g->t >= g->next - 1e-9))
        return PC_OK;
    if (altitude(ctx, &h) != PC_OK)
        return PC_ERROR;
    if (!(h > GUIDE_HF))
        return PC_OK;
    if (correct(ctx, h) != PC_OK)
        return PC_ERROR;
    m = py_ceil((g->t - g->next) / cycle + 1e-9, &err);
    if (err)
        return PC_ERROR;
    g->next += cycle * (m > 1.0 ? m : 1.0);
    return PC_OK;
}

/* the correction's root search: solve_control(miss, *value, tol, max_iter, (lo, hi)) (brent.h)
   from the last value; the value, its predicted miss, and the predictions counted in *n_pred */
static int gc_solve(br_fn miss, void *ctx, double tol, int max_iter, double lo, double hi,
                    double *value, double *predicted, int *n_pred)
{
    double v, m;
    int n;
    if (br_solve_control(miss, ctx, *value, tol, max_iter, lo, hi, &v, &m, &n) != 0)
        return PC_ERROR;
    *value = v;
    *predicted = m;
    *n_pred += n;
    return PC_OK;
}

/* the failure of the cycle (what), once: the wrapper reports it at the next doStep */
static void gc_fail(GuidanceCycle *g, const char *what)
{
    if (!g->failed) {
        g->failed = 1;
        snprintf(g->msg, PC_MSG, "%s: an arithmetic error where the Python guidance raises "
                 "(ArithmeticError, ValueError or IndexError)", what);
    }
}

/* model_failure: the cycle's failure, else ``other`` (the estimator's, or NULL) */
static const char *gc_failure(const GuidanceCycle *g, const char *other)
{
    return g->failed ? g->msg : other;
}

#endif
