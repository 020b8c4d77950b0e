/* law_model.c -- a network-operator law as the model of a native FMU (see native_model.h).
 *
 * Hand-written once for every law: the law itself is law.c (law.h), generated from the law's
 * matrix; model_config.h, generated with it, gives the sizes, the GUID and the start values.
 * Variables (value references in this order, as the generic NetworkOperatorController names
 * them): inputs x[1..NX]; outputs u[1..NU]; tunable parameters q[1..NQ]; fixed parameters
 * u_min[1..NU], u_max[1..NU], x_scale[1..NX], x_offset[1..NX], sample_period (a sampled
 * controller: fmi2_cs.c holds the outputs between samples).
 *
 * descent-fmus (MIT licence).
 */
#include <math.h>
#include <stdio.h>

#include "native_model.h"
#include "model_config.h"

#define VR_X 0
#define VR_U (VR_X + NATIVE_LAW_NX)
#define VR_Q (VR_U + NATIVE_LAW_NU)
#define VR_UMIN (VR_Q + NATIVE_LAW_NQ)
#define VR_UMAX (VR_UMIN + NATIVE_LAW_NU)
#define VR_XSCALE (VR_UMAX + NATIVE_LAW_NU)
#define VR_XOFFSET (VR_XSCALE + NATIVE_LAW_NX)
#define VR_SAMPLE (VR_XOFFSET + NATIVE_LAW_NX)
#define N_REAL (VR_SAMPLE + 1)

const char MODEL_GUID[] = MODEL_CONFIG_GUID;
const int MODEL_SAMPLE_PERIOD = VR_SAMPLE;
const int MODEL_N_REAL = N_REAL, MODEL_N_INTEGER = 0;
const double MODEL_REAL_START[N_REAL] = {MODEL_CONFIG_REAL_START};
const int MODEL_INTEGER_START[1] = {0};
const unsigned char MODEL_REAL_KIND[N_REAL] = {MODEL_CONFIG_REAL_KIND};
const unsigned char MODEL_INTEGER_KIND[1] = {KIND_FIXED};

static char message[200];

const char *model_check(const ModelState *s)
{
    const double *r = s->r;
    int k;
    for (k = 0; k < NATIVE_LAW_NQ; k++)
        if (!isfinite(r[VR_Q + k])) {
            snprintf(message, sizeof message, "parameter q[%d] must be finite, got %g", k + 1,
                     r[VR_Q + k]);
            return message;
        }
    for (k = 0; k < NATIVE_LAW_NU; k++) {
        double lo = r[VR_UMIN + k], hi = r[VR_UMAX + k];
        if (!(isfinite(lo) && isfinite(hi) && lo <= hi)) {
            snprintf(message, sizeof message, "u_min[%d] = %g, u_max[%d] = %g: need finite "
                     "bounds with u_min <= u_max", k + 1, lo, k + 1, hi);
            return message;
        }
    }
    for (k = 0; k < NATIVE_LAW_NX; k++)
        if (!(isfinite(r[VR_XSCALE + k]) && isfinite(r[VR_XOFFSET + k]))) {
            snprintf(message, sizeof message, "x_scale[%d] = %g, x_offset[%d] = %g: need "
                     "finite values", k + 1, r[VR_XSCALE + k], k + 1, r[VR_XOFFSET + k]);
            return message;
        }
    return NULL;
}

void model_outputs(ModelState *s)
{
    double *r = s->r;
    NATIVE_LAW_EVAL(r + VR_X, r + VR_Q, r + VR_XSCALE, r + VR_XOFFSET, r + VR_UMIN, r + VR_UMAX,
             r + VR_U);
}
