/* drag_model.c -- S1's drag-factor estimator alone (DragEstimator) as the model of a native
 * FMU: the twin of the pythonfmu class of models/controllers/drag_estimator.py.  Inputs a_drag,
 * nav_x1..nav_x4 and u (the control of the coming step); outputs drag_factor_log (y3) and
 * drag_factor; parameters threshold, noise, bias, noise_seed, sample_period.  The estimator's
 * arithmetic is generated from the Python estimator (estimator.h, <prefix>_sensing.c).
 *
 * descent-fmus (MIT licence).
 */
#include "native_model.h"
#include "model_config.h"
#include "estimator.h"

MODEL_TABLES(VR_SAMPLE)

typedef EstimatorRun Data;

static char message[PC_MSG];

const char *model_check(const ModelState *s)
{
    return est_check(s->r, s->i, message);
}

size_t model_data_size(void) { return sizeof(Data); }

/* prepare(): a new estimator */
void model_prepare(ModelState *s)
{
    est_run_prepare((Data *)s->data, s->r, s->i);
}

/* the Python FMU builds its estimator when first used: the defaults' */
void model_reset(ModelState *s)
{
    model_prepare(s);
}

void model_outputs(ModelState *s)
{
    const Data *d = (const Data *)s->data;
    double out[2];
    if (est_estimate(&d->e, s->r, s->i, out) == PC_OK) {
        s->r[VR_Y3] = out[0];
        s->r[VR_FACTOR] = out[1];
    }
}

/* do_step: commit the sample with the control u of the coming step */
void model_step(ModelState *s, double t, double h)
{
    (void)t;
    (void)h;
    est_run_step((Data *)s->data, s->r, s->i, s->r[VR_UIN]);
}

const char *model_failure(const ModelState *s)
{
    return est_run_failure((const Data *)s->data);
}
