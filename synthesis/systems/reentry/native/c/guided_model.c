/* guided_model.c -- the network-operator law with an on-board predictor-corrector
 * (GuidedNetworkOperatorController) as the model of a native FMU: the twin of the pythonfmu
 * class of models/controllers/reentry_npc.py: the correction c one number per cycle (replan = 0),
 * or a plan over altitude re-solved every cycle (replan = 1, replan.h; its linear programmes
 * solved by lp.h where the Python calls SciPy's HiGHS).
 *
 * Everything of sensed_model.c (the generic controller, the estimator -- here the density-profile
 * fit) plus the guidance cycle: at the first output evaluation of a communication point at or
 * after the next correction time, above hf, the correction c in [-correction_max,
 * correction_max] whose predicted down-range is Lf is solved (brent.h: the predictor-corrector's
 * solve_control and SciPy's brentq), the prediction flying the nominal model with the fitted
 * profile and this guidance itself.  With replan = 1 the weights of the plan are re-solved
 * instead (replan.h), the predictions recording their loads, the floor of the plan's peak the
 * running peak of the load at the navigated states (_track_peak).  The arithmetic is generated from the Python functions
 * (<prefix>_sensing.c: GUIDE_GEOMETRY, GUIDE_CORRECTED, GUIDE_STEP, GUIDE_LOAD, GUIDE_PLAN,
 * SENSING_PROFILE); what is written here is their order, the loops and the state between calls,
 * in the order of the Python methods _outputs, _maybe_correct, _correct, _predictor,
 * _track_peak and predict_flight.
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
#include "replan.h"

MODEL_TABLES(VR_SAMPLE)

typedef struct {
    NOController law;
    EstimatorRun est;
    GuidanceCycle gc;
    double c, miss;                /* _c, _miss */
    int n_pred;                    /* _n_pred */
    double plan[PLAN_K], peak;     /* _plan, _peak (replan = 1) */
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
    const double *plan;            /* the correction: the plan's value at the predicted altitude,
                                      or (NULL) the constant c */
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
    if (s->i[IX_REPLAN] != 0 && !(GUIDE_HORIZON / s->r[VR_DTPRED] < RP_MAX_STEPS)) {
        snprintf(message, sizeof message, "replan = 1 with dt_pred = %g s: a prediction of %g "
                 "steps is more than the native re-planner records (dt_pred >= %g s)",
                 s->r[VR_DTPRED], GUIDE_HORIZON / s->r[VR_DTPRED], GUIDE_HORIZON / RP_MAX_STEPS);
        return message;
    }
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
    memset(d->plan, 0, sizeof d->plan);
    d->peak = 0.0;
}

void model_reset(ModelState *s)
{
    if (model_check(s) == NULL)
        model_prepare(s);
}

/* control(xp) of _predictor with the correction c (the plan's value at the altitude of xp, if
   the prediction flies a plan): the law on the predicted state plus the correction */
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
    if (p->plan != NULL) {
        double pin[PLAN_K + 1], pout[1];
        memcpy(pin, p->plan, sizeof(double) * PLAN_K);
        pin[PLAN_K] = out[3];
        if (GUIDE_PLAN(s->r, s->i, pin, pout) != PC_OK)
            return PC_ERROR;
        c = pout[0];
    }
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

/* predicted_load(x, u, kd, lam, model) appended to loads[*n], if loads is not NULL */
static int record(const Prediction *p, const double *x, double u, double *loads, int *n)
{
    double in[7], out[1];
    int k;
    if (loads == NULL)
        return PC_OK;
    for (k = 0; k < 4; k++)
        in[k] = x[k];
    in[4] = u;
    in[5] = p->kd;
    in[6] = p->lam;
    if (GUIDE_LOAD(p->s->r, p->s->i, in, out) != PC_OK)
        return PC_ERROR;
    loads[(*n)++] = out[0];
    return PC_OK;
}

/* predict_flight(x, control(c), kd, model, dt, lam, record) - Lf: the miss, and the loads
   (*n of them) if loads is not NULL */
static int fly(const Prediction *p, double c, double *miss, double *loads, int *n)
{
    double x[4], in[8], out[6], t = 0.0;
    int k;
    memcpy(x, p->x, sizeof x);
    if (n != NULL)
        *n = 0;
    while (t < GUIDE_HORIZON - 1e-9) {
        if (control(p, x, c, &in[4]) != PC_OK || record(p, x, in[4], loads, n) != PC_OK)
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
            if (record(p, x, in[4], loads, n) != PC_OK)
                return PC_ERROR;
            *miss = out[5] - GUIDE_LF;
            return PC_OK;
        }
        if (out[4] != 0.0)                          /* diverged */
            break;
        if (record(p, x, in[4], loads, n) != PC_OK)
            return PC_ERROR;
        t += p->s->r[VR_DTPRED];
    }
    *miss = GUIDE_NOT_REACHED - GUIDE_LF;
    return PC_OK;
}

/* the miss of the constant correction c (predict_range) */
static int predicted_miss(double c, void *ctx, double *miss)
{
    return fly((const Prediction *)ctx, c, miss, NULL, NULL);
}

/* evaluate(c) of _correct with replan = 1: the prediction under the plan's weights c */
static int predicted_plan(const double *c, void *ctx, double *miss, double *loads, int *n)
{
    Prediction *p = (Prediction *)ctx;
    int rc;
    p->plan = c;
    rc = fly(p, 0.0, miss, loads, n);
    p->plan = NULL;
    return rc;
}

/* the most samples one prediction records: two a step and one at hf */
static int load_capacity(double dt)
{
    return 2 * (int)(GUIDE_HORIZON / dt + 2.0) + 1;
}

/* the estimator's profile(a_drag, nav): kd, lam, log factor */
static int profile(ModelState *s, Data *d, double *prof)
{
    double in[3] = {0.0, 0.0, 0.0};
    est_nominal(&d->est.e, s->r, in);
    return SENSING_PROFILE(s->r, s->i, d->est.e.st, in, prof);
}

/* the re-planner's problem of this cycle (the parameters, the flown peak as the floor) */
static int replan_problem(const ModelState *s, const Data *d, RpProblem *pb)
{
    const double steps = GUIDE_HORIZON / s->r[VR_DTPRED];
    if (!(steps < RP_MAX_STEPS))    /* model_check refused it */
        return PC_ERROR;
    pb->k = PLAN_K;
    pb->cap = 2 * (int)(steps + 2.0) + 1;     /* two samples a step, one at hf */
    pb->c_max = s->r[VR_CMAX];
    pb->trust = s->r[VR_TRUST];
    pb->effort = s->r[VR_EFFORT];
    pb->floor = d->peak;
    pb->iterations = s->i[IX_RITER];
    pb->tol = s->r[VR_TOL];
    pb->max_iter = s->i[IX_MAXITER];
    pb->fd_step = PLAN_FD_STEP;
    pb->miss_scale = PLAN_MISS_SCALE;
    return PC_OK;
}

/* _correct(x): the profile, then the correction whose predicted miss is zero -- or, with
   replan = 1, the plan (h_now: the altitude of x) */
static int correct(void *ctx, double h_now)
{
    Now *now = (Now *)ctx;
    ModelState *s = now->s;
    Data *d = (Data *)s->data;
    const double *x = now->x;
    Prediction p;
    double prof[3], bound = s->r[VR_CMAX];
    const int nx = d->law.nx, ei = s->i[IX_ESTIMATE], ci = s->i[IX_CORRECTION];
    int k;
    if (profile(s, d, prof) != PC_OK)
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
    p.plan = NULL;
    if (s->i[IX_REPLAN]) {
        RpProblem pb;
        if (replan_problem(s, d, &pb) != PC_OK)
            return PC_ERROR;
        return rp_replan(&pb, predicted_plan, &p, d->plan, &d->miss, &d->n_pred);
    }
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

/* _correction_at(x) with replan = 1: the plan's value at the altitude of the navigated state */
static int plan_now(Now *now, const Data *d, double *c)
{
    double in[PLAN_K + 1], out[1];
    if (altitude(now, &in[PLAN_K]) != PC_OK)
        return PC_ERROR;
    memcpy(in, d->plan, sizeof d->plan);
    if (GUIDE_PLAN(now->s->r, now->s->i, in, out) != PC_OK)
        return PC_ERROR;
    *c = out[0];
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
        if (s->i[IX_REPLAN] && !d->gc.failed && plan_now(&now, d, &d->c) != PC_OK)
            gc_fail(&d->gc, "the plan's correction");
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

/* _track_peak(u): the running peak of the model's load at the navigated states (the plan's
   floor); an arithmetic error leaves it as it is */
static void track_peak(ModelState *s, Data *d, double u)
{
    double prof[3], in[7], out[1];
    int k;
    if (profile(s, d, prof) != PC_OK)
        return;
    for (k = 0; k < 4; k++)
        in[k] = s->r[VR_NAV + k];
    in[4] = u;
    in[5] = prof[0];
    in[6] = prof[1];
    if (GUIDE_LOAD(s->r, s->i, in, out) == PC_OK && out[0] > d->peak)
        d->peak = out[0];
}

/* do_step: with replan = 1 the peak so far; commit the sample with the law's output u[1]; the
   time of the next evaluation */
void model_step(ModelState *s, double t, double h)
{
    Data *d = (Data *)s->data;
    if (s->i[IX_REPLAN])
        track_peak(s, d, s->r[VR_U]);
    est_run_step(&d->est, s->r, s->i, s->r[VR_U]);
    d->gc.t = t + h;
}

const char *model_failure(const ModelState *s)
{
    const Data *d = (const Data *)s->data;
    return d == NULL ? NULL : gc_failure(&d->gc, est_run_failure(&d->est));
}
