/* sensed_model.c -- the network-operator law reading the drag-factor estimate
 * (SensedNetworkOperatorController) as the model of a native FMU: the twin of the pythonfmu
 * class of models/controllers/drag_estimator.py.  Everything of the generic controller
 * (no_controller.h) plus the estimator (estimator.h): before the law is evaluated its input
 * x[estimate_input] (default 3; 0 = none) is set to the estimate y3, and every step commits the
 * sample with the law's output u[1].
 *
 * descent-fmus (MIT licence).
 */
#include <stdio.h>

#include "native_model.h"
#include "model_config.h"
#include "sensed_controller.h"

MODEL_TABLES(VR_SAMPLE)

typedef struct {
    NOController law;
    EstimatorRun est;
} Data;

static char message[PC_MSG];

/* SensedNetworkOperatorController.check_parameters */
const char *model_check(const ModelState *s)
{
    return sensed_controller_check(s, &((Data *)s->data)->law, message, sizeof message);
}

size_t model_data_size(void) { return sizeof(Data); }

void model_prepare(ModelState *s)
{
    Data *d = (Data *)s->data;
    sensed_controller_prepare(s, &d->law, &d->est);
}

void model_reset(ModelState *s)
{
    if (model_check(s) == NULL)
        model_prepare(s);
}

void model_outputs(ModelState *s)
{
    Data *d = (Data *)s->data;
    double out[2];
    const int ei = s->i[IX_ESTIMATE];
    if (est_estimate(&d->est.e, s->r, s->i, out) == PC_OK) {
        s->r[VR_Y3] = out[0];
        s->r[VR_FACTOR] = out[1];
        if (ei > 0 && ei <= NO_NX_MAX)
            s->r[VR_X + ei - 1] = out[0];
    }
    no_controller_outputs(s, &d->law);
}

/* do_step: commit the sample with the law's output u[1] */
void model_step(ModelState *s, double t, double h)
{
    (void)t;
    (void)h;
    est_run_step(&((Data *)s->data)->est, s->r, s->i, s->r[VR_U]);
}

const char *model_failure(const ModelState *s)
{
    const Data *d = (const Data *)s->data;
    return d != NULL ? est_run_failure(&d->est) : NULL;
}
