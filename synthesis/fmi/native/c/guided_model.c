/* guided_model.c -- the network-operator law with an on-board predictor-corrector
 * (GuidedNetworkOperatorController) as the model of a native FMU: the twin of the pythonfmu
 * class of models/controllers/reentry_npc.py, with the correction c one number per cycle
 * (replan = 0; the re-planner's linear programmes stay in the pythonfmu FMU).
 *
 * Everything of sensed_model.c (the generic controller, the estimator -- here the density-profile
 * fit) plus the guidance cycle: at the first output evaluation of a communication point at or
 * after the next correction time, above hf, the correction c in [-correction_max,
 * correction_max] whose predicted down-range is Lf is solved (brent.h: the predictor-corrector's
 * solve_control and SciPy's brentq), the prediction flying the nominal model with the fitted
 * profile and this guidance itself.  The arithmetic is generated from the Python functions
 * (<prefix>_sensing.c: GUIDE_GEOMETRY, GUIDE_CORRECTED, GUIDE_STEP, SENSING_PROFILE); what is
 * written here is their order, the loops and the state between calls, in the order of the
 * Python methods _outputs, _maybe_correct, _correct, _predictor and predict_flight.
 *
 * descent-fmus (MIT licence).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "native_model.h"
#include "model_config.h"
#include "sensed_controller.h"
#include "brent.h"
#include "guidance_cycle.h"

MODEL_TABLES(VR_SAMPLE)

typedef struct {
    NOController law;
    EstimatorRun est;
    GuidanceCycle gc;
    double c, miss;                /* _c, _miss */
    int n_pred;                    /* _n_pred */
} Data;

/* the cycle's callbacks' context: the model and the navigated state */
typedef struct {
    ModelState *s;
    double x[4];
} Now;

/* what one prediction needs (the closure of GuidedNetworkOperatorController._predictor) */
typedef struct {
    const ModelState *s;
    const Data *d;
    double x[4];                   /* the navigated state the prediction starts from */
    double inputs[NO_NX_MAX];      /* the law's inputs, as self.x[:nx] when the cycle began */
    double kd, lam, log_factor;    /* the fitted profile */
    double dlam, h_now;
    int k_e, k_c, reads;
} Prediction;

static char message[PC_MSG];

/* the generic controller's checks, the estimator's parameters (GuidedParams), estimate_input,
   correction_input (the order of GuidedNetworkOperatorController.check_parameters), then what
   this twin does not have */
const char *model_check(const ModelState *s)
{
    const int ei = s->i[IX_ESTIMATE], ci = s->i[IX_CORRECTION];
    if (sensed_controller_check(s, &((Data *)s->data)->law, message, sizeof message) != NULL)
        return message;
    if (ci < 0 || ci > NO_NX_MAX) {
        snprintf(message, sizeof message, "correction_input = %d outside 0..%d", ci, NO_NX_MAX);
        return message;
    }
    if (ci != 0 && ci == ei)
        return "correction_input and estimate_input must differ";
    if (s->i[IX_REPLAN] != 0)
        return "replan = 1: the native GuidedNetworkOperatorController has no re-planner (fly "
               "the pythonfmu GuidedNetworkOperatorController.fmu for it)";
    return NULL;
}

size_t model_data_size(void) { return sizeof(Data); }

void model_prepare(ModelState *s)
{
    Data *d = (Data *)s->data;
    sensed_controller_prepare(s, &d->law, &d->est);
    gc_prepare(&d->gc);
    d->c = d->miss = 0.0;
    d->n_pred = 0;
}

void model_reset(ModelState *s)
{
    if (model_check(s) == NULL)
        model_prepare(s);
}

/* control(xp) of _predictor with the constant correction c: the law on the predicted state
   plus the correction */
static int control(const Prediction *p, const double *xp, double c, double *u)
{
    const ModelState *s = p->s;
    double in[7], out[4], inputs[NO_NX_MAX], z[NO_NU_MAX];
    int k;
    if (p->d->law.nx < 2)            /* inputs[0], inputs[1] = ...: IndexError */
        return PC_ERROR;
    for (k = 0; k < 4; k++)
        in[k] = xp[k];
    in[4] = p->log_factor;
    in[5] = p->dlam;
    in[6] = p->h_now;
    if (GUIDE_GEOMETRY(s->r, s->i, in, out) != PC_OK)
        return PC_ERROR;
    memcpy(inputs, p->inputs, sizeof inputs);
    inputs[0] = out[0];
    inputs[1] = out[1];
    if (p->k_e >= 0)
        inputs[p->k_e] = out[2];
    if (p->reads)
        inputs[p->k_c] = c;
    no_controller_law(s, &p->d->law, inputs, z);
    if (s->r[VR_GAIN] == 0.0) {
        *u = z[0];
        return PC_OK;
    }
    {
        double cin[8], cout[1];
        cin[0] = z[0];
        cin[1] = c;
        for (k = 0; k < 4; k++)
            cin[2 + k] = xp[k];
        cin[6] = p->kd;
        cin[7] = p->lam;
        if (GUIDE_CORRECTED(s->r, s->i, cin, cout) != PC_OK)
            return PC_ERROR;
        *u = cout[0];
    }
    return PC_OK;
}

/* predict_range(x, control(c), kd, model, dt, lam) - Lf: predict_flight without the loads */
static int predicted_miss(double c, void *ctx, double *miss)
{
    const Prediction *p = (const Prediction *)ctx;
    double x[4], in[8], out[6], t = 0.0;
    int k;
    memcpy(x, p->x, sizeof x);
    while (t < GUIDE_HORIZON - 1e-9) {
        if (control(p, x, c, &in[4]) != PC_OK)
            return PC_ERROR;
        for (k = 0; k < 4; k++)
            in[k] = x[k];
        in[5] = p->kd;
        in[6] = p->lam;
        in[7] = p->s->r[VR_DTPRED];
        if (GUIDE_STEP(p->s->r, p->s->i, in, out) != PC_OK)
            return PC_ERROR;
        for (k = 0; k < 4; k++)
            x[k] = out[k];
        if (out[4] == 1.0) {                        /* EVENT: h = hf reached */
            *miss = out[5] - GUIDE_LF;
            return PC_OK;
        }
        if (out[4] != 0.0)                          /* diverged */
            break;
        t += p->s->r[VR_DTPRED];
    }
    *miss = GUIDE_NOT_REACHED - GUIDE_LF;
    return PC_OK;
}

/* _correct(x): the profile, then the correction whose predicted miss is zero (h_now: the
   altitude of x) */
static int correct(void *ctx, double h_now)
{
    Now *now = (Now *)ctx;
    ModelState *s = now->s;
    Data *d = (Data *)s->data;
    const double *x = now->x;
    Prediction p;
    double in[3] = {0.0, 0.0, 0.0}, prof[3], bound = s->r[VR_CMAX];
    const int nx = d->law.nx, ei = s->i[IX_ESTIMATE], ci = s->i[IX_CORRECTION];
    int k;
    est_nominal(&d->est.e, s->r, in);
    if (SENSING_PROFILE(s->r, s->i, d->est.e.st, in, prof) != PC_OK)
        return PC_ERROR;
    p.s = s;
    p.d = d;
    for (k = 0; k < 4; k++)
        p.x[k] = x[k];
    memset(p.inputs, 0, sizeof p.inputs);
    for (k = 0; k < nx; k++)
        p.inputs[k] = s->r[VR_X + k];
    p.kd = prof[0];
    p.lam = prof[1];
    p.log_factor = prof[2];
    p.dlam = prof[1] - GUIDE_LAM;
    p.h_now = h_now;
    p.k_e = ei > 0 && ei <= nx ? ei - 1 : -1;
    p.k_c = ci - 1;
    p.reads = ci > 0 && ci <= nx;
    return gc_solve(predicted_miss, &p, s->r[VR_TOL], s->i[IX_MAXITER], -bound, bound, &d->c,
                    &d->miss, &d->n_pred);
}

/* altitude(x, Rz) of the navigated state (the geometry's out[3]) */
static int altitude(void *ctx, double *h)
{
    Now *now = (Now *)ctx;
    double in[7] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0}, out[4];
    int k;
    for (k = 0; k < 4; k++)
        in[k] = now->x[k];
    if (GUIDE_GEOMETRY(now->s->r, now->s->i, in, out) != PC_OK)
        return PC_ERROR;
    *h = out[3];
    return PC_OK;
}

void model_outputs(ModelState *s)
{
    Data *d = (Data *)s->data;
    double *r = s->r, out[4];
    const int ei = s->i[IX_ESTIMATE], ci = s->i[IX_CORRECTION], nx = d->law.nx;
    const int reads = ci > 0 && ci <= nx, active = reads || r[VR_GAIN] != 0.0;
    const double *x;
    Now now;
    int k;
    now.s = s;
    for (k = 0; k < 4; k++)
        now.x[k] = r[VR_NAV + k];
    x = now.x;
    if (active && !d->gc.failed) {
        if (gc_maybe_correct(&d->gc, s->r[VR_CYCLE], altitude, correct, &now) != PC_OK)
            gc_fail(&d->gc, "the guidance cycle");
        if (reads)
            r[VR_X + ci - 1] = d->c;
    }
    if (est_estimate(&d->est.e, r, s->i, out) == PC_OK) {
        r[VR_Y3] = out[0];
        r[VR_FACTOR] = out[1];
        r[VR_SHE] = out[2];
        r[VR_FACTOR_SD] = out[3];
        if (ei > 0 && ei <= NO_NX_MAX)
            r[VR_X + ei - 1] = out[0];
    }
    no_controller_outputs(s, &d->law);
    if (active && r[VR_GAIN] != 0.0 && !d->gc.failed) {
        double cin[8], cout[1];
        const double c = d->c;
        cin[0] = r[VR_U];
        cin[1] = c;
        for (k = 0; k < 4; k++)
            cin[2 + k] = x[k];
        cin[6] = 0.0;
        cin[7] = GUIDE_LAM;
        if (r[VR_GATE] != 0.0 && c > 0.0) {       /* the gate needs the estimated drag */
            int err = 0;
            cin[6] = GUIDE_KD * py_exp(r[VR_Y3], &err);
            if (err)
                gc_fail(&d->gc, "the gated correction");
        }
        if (!d->gc.failed && GUIDE_CORRECTED(r, s->i, cin, cout) == PC_OK)
            r[VR_U] = cout[0];
        else
            gc_fail(&d->gc, "the correction");
    }
    r[VR_CORR] = d->c;
    r[VR_MISS] = d->miss;
    s->i[IX_NPRED] = d->n_pred;
}

/* do_step: commit the sample with the law's output u[1]; the time of the next evaluation */
void model_step(ModelState *s, double t, double h)
{
    Data *d = (Data *)s->data;
    est_run_step(&d->est, s->r, s->i, s->r[VR_U]);
    d->gc.t = t + h;
}

const char *model_failure(const ModelState *s)
{
    const Data *d = (const Data *)s->data;
    return d == NULL ? NULL : gc_failure(&d->gc, est_run_failure(&d->est));
}
