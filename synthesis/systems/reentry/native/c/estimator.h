/* estimator.h -- S1's drag-factor estimator in a native controller (DragEstimator,
 * SensedNetworkOperatorController): the life of models.controllers.drag_estimator.
 * DragFactorEstimator around its generated C (<prefix>_sensing.c, traced from the Python
 * estimator by synthesis/systems/reentry/native/sensing.py; model_config.h names it SENSING_*).
 *
 * What is written here is the plumbing the tracer cannot see: the state between calls, the
 * constructor's start (sums 0, no sample yet, the generator seeded with noise_seed as
 * random.Random(noise_seed) is, the first draw), the nominal drag computed before the sample
 * that needs it, and the Gaussian draw of each sample where Python draws it (noise > 0).
 * model_config.h gives VR_NOISE, VR_NAV (nav_x1..nav_x4) and IX_SEED.
 *
 * descent-fmus (MIT licence).
 */
#ifndef DESCENT_ESTIMATOR_H
#define DESCENT_ESTIMATOR_H

#include <math.h>
#include <stdio.h>

#include "plant_runtime.h"
#include "py_random.h"

/* the state st of <prefix>_sensing.h: sw, swz, u_prev, err, last_x1..4 */
#define EST_U_PREV 2
#define EST_ERR 3
#define EST_LAST 4

typedef struct {
    double st[SENSING_N_ST];
    PyRandom rng;
} Estimator;

/* _draw(): the error of the next sample (a Gaussian draw only where Python draws one) */
static int est_draw(Estimator *e, const double *r, const int *iv)
{
    double in[1] = {0.0}, out[1];
    int rc;
    if (r[VR_NOISE] > 0.0)
        in[0] = py_random_gauss(&e->rng, 0.0, r[VR_NOISE]);
    rc = SENSING_DRAW(r, iv, in, out);
    if (rc == PC_OK)
        e->st[EST_ERR] = out[0];
    return rc;
}

/* DragFactorEstimator(params): no sample yet, the generator seeded, the first draw */
static int est_start(Estimator *e, const double *r, const int *iv)
{
    int k;
    for (k = 0; k < SENSING_N_ST; k++)
        e->st[k] = 0.0;
    for (k = 0; k < 4; k++)
        e->st[EST_LAST + k] = NAN;        /* _last_x = None: equal to no state */
    py_random_seed(&e->rng, iv[IX_SEED]);
    return est_draw(e, r, iv);
}

/* in[0], in[1]: the nominal drag of the current sample failed (1) or not, and its value */
static void est_nominal(const Estimator *e, const double *r, double *in)
{
    double x[5], out[1] = {0.0};
    int k;
    for (k = 0; k < 4; k++)
        x[k] = r[VR_NAV + k];
    x[4] = e->st[EST_U_PREV];
    in[0] = SENSING_NOMINAL(x, out) != PC_OK;
    in[1] = in[0] != 0.0 ? 0.0 : out[0];
}

/* drag_factor_log and drag_factor now (with the current sample) */
static int est_estimate(const Estimator *e, const double *r, const int *iv, double *out)
{
    double in[3] = {0.0, 0.0, 0.0};
    est_nominal(e, r, in);
    return SENSING_ESTIMATE(r, iv, e->st, in, out);
}

/* commit(a_drag, x, u_next), then the next draw */
static int est_commit(Estimator *e, const double *r, const int *iv, double u_next)
{
    double in[3] = {0.0, 0.0, 0.0};
    int rc;
    est_nominal(e, r, in);
    in[2] = u_next;
    rc = SENSING_COMMIT(r, iv, e->st, in);
    return rc == PC_OK ? est_draw(e, r, iv) : rc;
}

/* -- an estimator inside a model: failures where the Python estimator raises --------------- */
typedef struct {
    Estimator e;
    int failed;                   /* the last prepare/step failed where Python raises */
    char msg[PC_MSG];             /* ... and why */
} EstimatorRun;

/* msg: an arithmetic error in `what` where the Python estimator raises */
static const char *est_arithmetic(char *msg, const char *what)
{
    snprintf(msg, PC_MSG, "%s: an arithmetic error where the Python estimator raises "
             "(ArithmeticError or ValueError)", what);
    return msg;
}

/* SENSING_CHECK's verdict as a model_check message (NULL: valid), in `message` */
static const char *est_check(const double *r, const int *iv, char *message)
{
    int rc = SENSING_CHECK(r, iv, message);
    if (rc == PC_OK)
        return NULL;
    return rc == PC_RAISE ? message : est_arithmetic(message, "parameter check");
}

/* prepare(): a new estimator */
static void est_run_prepare(EstimatorRun *x, const double *r, const int *iv)
{
    x->failed = est_start(&x->e, r, iv) != PC_OK;
    if (x->failed)
        est_arithmetic(x->msg, "prepare");
}

/* do_step: commit the sample with the control u of the coming step */
static void est_run_step(EstimatorRun *x, const double *r, const int *iv, double u)
{
    if (!x->failed && est_commit(&x->e, r, iv, u) != PC_OK) {
        x->failed = 1;
        est_arithmetic(x->msg, "doStep");
    }
}

static const char *est_run_failure(const EstimatorRun *x)
{
    return x != NULL && x->failed ? x->msg : NULL;
}

#endif
