/* plant_model.c -- a native plant as the model of a native FMU (native_model.h): written once
 * for every plant.
 *
 * The plant's C (<plant>_plant.c, generated from the pythonfmu class by
 * synthesis/fmi/native/tracer/plant_phases.py; model_config.h names its functions PLANT_*) has five
 * functions, the phases of the Python FMU:
 *
 *   PLANT_CHECK    check_parameters(): NULL or the ParameterError's message;
 *   PLANT_START    prepare(): the plant's slots S (state, time, status, bookkeeping, constants);
 *   PLANT_INPUTS   do_step(t, h) up to the integrator's advance(): its arguments;
 *   PLANT_ADVANCE  advance(...) on the slots (the stepping loop of plant_runtime.c inside);
 *   PLANT_OUTPUTS  the outputs from the slots.
 *
 * The slots live in the instance's memory (model_data_size); a phase that fails where Python
 * raises makes the FMI call fail with fmi2Error (model_failure).
 *
 * descent-fmus (MIT licence).
 */
#include <stdio.h>
#include <string.h>

#include "native_model.h"
#include "plant_runtime.h"
#include "model_config.h"

MODEL_TABLES(-1)

typedef struct {
    double S[PLANT_N_SLOTS];
    int failed;                 /* the last prepare/step failed: msg says why */
    char msg[PC_MSG];
} PlantData;

static char message[PC_MSG];

static const char *failed(int rc, const char *what, char *msg)
{
    if (rc == PC_RAISE)
        return msg;
    snprintf(msg, PC_MSG, "%s: an arithmetic error where the Python plant raises "
             "(ArithmeticError or ValueError)", what);
    return msg;
}

const char *model_check(const ModelState *s)
{
    int rc = PLANT_CHECK(s->r, s->i, message);
    return rc == PC_OK ? NULL : failed(rc, "parameter check", message);
}

void model_outputs(ModelState *s)
{
    (void)s;                    /* the outputs are written by every prepare and step */
}

size_t model_data_size(void)
{
    return sizeof(PlantData);
}

void model_prepare(ModelState *s)
{
    PlantData *d = (PlantData *)s->data;
    int rc = PLANT_START(s->r, s->i, d->S, d->msg);
    if (rc == PC_OK)
        rc = PLANT_OUTPUTS(s->r, s->i, d->S);
    d->failed = rc != PC_OK;
    if (d->failed)
        failed(rc, "prepare", d->msg);
}

void model_step(ModelState *s, double t, double h)
{
    PlantData *d = (PlantData *)s->data;
    double th[2], call[PLANT_N_CALL];
    int rc;
    if (d->failed)
        return;
    th[0] = t;
    th[1] = h;
    rc = PLANT_INPUTS(s->r, s->i, th, call);
    if (rc == PC_OK)
        rc = PLANT_ADVANCE(s->r, s->i, d->S, call);
    if (rc == PC_OK)
        rc = PLANT_OUTPUTS(s->r, s->i, d->S);
    if (rc != PC_OK) {
        d->failed = 1;
        failed(rc, "doStep", d->msg);
    }
}

const char *model_failure(const ModelState *s)
{
    const PlantData *d = (const PlantData *)s->data;
    return d != NULL && d->failed ? d->msg : NULL;
}
