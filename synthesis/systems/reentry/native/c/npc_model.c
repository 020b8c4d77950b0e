/* npc_model.c -- S1's numerical predictor-corrector guidance (ReentryNPC) as the model of a
 * native FMU: the twin of the pythonfmu class of models/controllers/reentry_npc.py.
 *
 * The estimator (estimator.h: the density-profile fit) and the guidance cycle: at the first
 * output evaluation of a communication point at or after the next correction time, above hf,
 * the constant control u in [-0.2, 0.2] whose predicted down-range is Lf is solved (brent.h:
 * solve_control and SciPy's brentq), each prediction one integration of the nominal model with
 * the fitted profile to hf.  The arithmetic is generated from the Python functions
 * (<prefix>_sensing.c: GUIDE_ALTITUDE, GUIDE_RANGE, SENSING_PROFILE); what is written here is
 * their order and the state between calls, in the order of the Python methods _command,
 * _maybe_correct, _correct and do_step.
 *
 * descent-fmus (MIT licence).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "native_model.h"
#include "model_config.h"
#include "estimator.h"
#include "brent.h"
#include "guidance_cycle.h"

MODEL_TABLES(VR_SAMPLE)

typedef struct {
    EstimatorRun est;
    GuidanceCycle gc;
    double u, miss;                /* _u, _miss */
    double cycle;                  /* _cycle: the cycle as prepared */
    int n_pred;                    /* _n_pred */
} Data;

/* what one prediction needs: the start state and the fitted profile */
typedef struct {
    const ModelState *s;
    double x[4], kd, lam;
} Prediction;

/* the cycle's callbacks' context: the model and the navigated state */
typedef struct {
    ModelState *s;
    double x[4];
} Now;

static char message[PC_MSG];

const char *model_check(const ModelState *s)
{
    return est_check(s->r, s->i, message);
}

size_t model_data_size(void) { return sizeof(Data); }

void model_prepare(ModelState *s)
{
    Data *d = (Data *)s->data;
    est_run_prepare(&d->est, s->r, s->i);
    gc_prepare(&d->gc);
    d->u = d->miss = 0.0;
    d->cycle = s->r[VR_CYCLE];
    d->n_pred = 0;
}

void model_reset(ModelState *s)
{
    if (model_check(s) == NULL)
        model_prepare(s);
}

/* predict_range(x, u, kd, model, dt_pred, lam) - Lf */
static int predicted_miss(double u, void *ctx, double *miss)
{
    const Prediction *p = (const Prediction *)ctx;
    double in[8], out[1];
    int k;
    for (k = 0; k < 4; k++)
        in[k] = p->x[k];
    in[4] = u;
    in[5] = p->kd;
    in[6] = p->lam;
    in[7] = p->s->r[VR_DTPRED];
    if (GUIDE_RANGE(p->s->r, p->s->i, in, out) != PC_OK)
        return PC_ERROR;
    *miss = out[0] - GUIDE_LF;
    return PC_OK;
}

/* _correct(x): the profile, then the constant u whose predicted miss is zero */
static int correct(void *ctx, double h)
{
    Now *now = (Now *)ctx;
    ModelState *s = now->s;
    Data *d = (Data *)s->data;
    Prediction p;
    double in[3] = {0.0, 0.0, 0.0}, prof[3];
    int k;
    (void)h;
    est_nominal(&d->est.e, s->r, in);
    if (SENSING_PROFILE(s->r, s->i, d->est.e.st, in, prof) != PC_OK)
        return PC_ERROR;
    p.s = s;
    for (k = 0; k < 4; k++)
        p.x[k] = now->x[k];
    p.kd = prof[0];
    p.lam = prof[1];
    return gc_solve(predicted_miss, &p, s->r[VR_TOL], s->i[IX_MAXITER], GUIDE_U_MIN,
                    GUIDE_U_MAX, &d->u, &d->miss, &d->n_pred);
}

/* altitude(x, Rz) of the navigated state */
static int altitude(void *ctx, double *h)
{
    Now *now = (Now *)ctx;
    return GUIDE_ALTITUDE(now->s->r, now->s->i, now->x, h);
}

/* the command of this communication point (_command) and the estimator's outputs */
void model_outputs(ModelState *s)
{
    Data *d = (Data *)s->data;
    double *r = s->r, out[4];
    Now now;
    int k;
    now.s = s;
    for (k = 0; k < 4; k++)
        now.x[k] = r[VR_NAV + k];
    if (!d->gc.failed
            && gc_maybe_correct(&d->gc, d->cycle, altitude, correct, &now) != PC_OK)
        gc_fail(&d->gc, "the guidance cycle");
    if (est_estimate(&d->est.e, r, s->i, out) == PC_OK) {
        r[VR_Y3] = out[0];
        r[VR_FACTOR] = out[1];
        r[VR_SHE] = out[2];
        r[VR_FACTOR_SD] = out[3];
    }
    r[VR_UOUT] = d->u;
    r[VR_MISS] = d->miss;
    s->i[IX_NPRED] = d->n_pred;
}

/* do_step: commit the sample with the command u; the time of the next evaluation */
void model_step(ModelState *s, double t, double h)
{
    Data *d = (Data *)s->data;
    est_run_step(&d->est, s->r, s->i, d->u);
    d->gc.t = t + h;
}

const char *model_failure(const ModelState *s)
{
    const Data *d = (const Data *)s->data;
    return d == NULL ? NULL : gc_failure(&d->gc, est_run_failure(&d->est));
}
