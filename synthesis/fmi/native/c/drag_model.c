/* drag_model.c -- S1's drag-factor estimator alone (DragEstimator) as the model of a native
 * FMU: the twin of the pythonfmu class of models/controllers/drag_estimator.py.  Inputs a_drag,
 * nav_x1..nav_x4 and u (the control of the coming step); outputs drag_factor_log (y3) and
 * drag_factor; parameters threshold, noise, bias, noise_seed, sample_period.  The estimator's
 * arithmetic is generated from the Python estimator (estimator.h, <prefix>_sensing.c).
 *
 * descent-fmus (MIT licence).
 */
#include <stdio.h>

#include "native_model.h"
#include "model_config.h"
#include "estimator.h"

const char MODEL_GUID[] = MODEL_CONFIG_GUID;
const int MODEL_SAMPLE_PERIOD = VR_SAMPLE;
const int MODEL_N_REAL = N_REAL, MODEL_N_INTEGER = N_INTEGER;
const double MODEL_REAL_START[N_REAL] = {MODEL_CONFIG_REAL_START};
const int MODEL_INTEGER_START[N_INTEGER] = {MODEL_CONFIG_INTEGER_START};
const unsigned char MODEL_REAL_KIND[N_REAL] = {MODEL_CONFIG_REAL_KIND};
const unsigned char MODEL_INTEGER_KIND[N_INTEGER] = {MODEL_CONFIG_INTEGER_KIND};

typedef struct {
    Estimator e;
    int failed;                   /* the last step failed where Python raises: msg says why */
    char msg[PC_MSG];
} Data;

static char message[PC_MSG];

/* where the Python estimator raises (an arithmetic error outside its own try) */
static const char *arithmetic(char *msg, const char *what)
{
    snprintf(msg, PC_MSG, "%s: an arithmetic error where the Python estimator raises "
             "(ArithmeticError or ValueError)", what);
    return msg;
}

const char *model_check(const ModelState *s)
{
    int rc = SENSING_CHECK(s->r, s->i, message);
    if (rc == PC_OK)
        return NULL;
    return rc == PC_RAISE ? message : arithmetic(message, "parameter check");
}

size_t model_data_size(void) { return sizeof(Data); }

/* prepare(): a new estimator */
void model_prepare(ModelState *s)
{
    Data *d = (Data *)s->data;
    d->failed = est_start(&d->e, s->r, s->i) != PC_OK;
    if (d->failed)
        arithmetic(d->msg, "prepare");
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
    Data *d = (Data *)s->data;
    (void)t;
    (void)h;
    if (!d->failed && est_commit(&d->e, s->r, s->i, s->r[VR_UIN]) != PC_OK) {
        d->failed = 1;
        arithmetic(d->msg, "doStep");
    }
}

const char *model_failure(const ModelState *s)
{
    const Data *d = (const Data *)s->data;
    return d != NULL && d->failed ? d->msg : NULL;
}
