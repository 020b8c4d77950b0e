/* no_model.c -- the generic network-operator controller (NetworkOperatorController) as the
 * model of a native FMU (native_model.h): the twin of the pythonfmu class of
 * models/controllers/network_operator.py, with its variables (names, defaults, descriptions,
 * units; model_config.h gives their value references), its checks and messages, and its
 * outputs to the last bit.
 *
 * A candidate law is a set of start values: the matrix psi[i,j], nx, nq, nu, out[k], q[k], the
 * bounds and the input scaling.  The matrix is checked and compiled into an arc program
 * (no_interp.c) when the parameters are checked -- entering and leaving initialisation, as the
 * Python controller does -- and interpreted at every output: no compiler is involved per law.
 *
 * descent-fmus (MIT licence).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "native_model.h"
#include "model_config.h"
#include "no_interp.h"
#include "no_operations.h"
#include "py_repr.h"

const char MODEL_GUID[] = MODEL_CONFIG_GUID;
const int MODEL_SAMPLE_PERIOD = VR_SAMPLE;
const int MODEL_N_REAL = N_REAL, MODEL_N_INTEGER = N_INTEGER;
const double MODEL_REAL_START[N_REAL] = {MODEL_CONFIG_REAL_START};
const int MODEL_INTEGER_START[N_INTEGER] = {MODEL_CONFIG_INTEGER_START};
const unsigned char MODEL_REAL_KIND[N_REAL] = {MODEL_CONFIG_REAL_KIND};
const unsigned char MODEL_INTEGER_KIND[N_INTEGER] = {MODEL_CONFIG_INTEGER_KIND};

typedef struct {
    NOProgram program;              /* the checked matrix */
    int nx, nq;                     /* the source counts it was compiled with */
    int scaled;                     /* an input scale != 1 or offset != 0 */
} Data;

static char message[400];

/* the controller's checks, in the order of NetworkOperatorController.check_parameters; the
   matrix compiled into the model's data if every one passes */
const char *model_check(const ModelState *s)
{
    const double *r = s->r;
    const int *i = s->i, nx = i[IX_NX], nq = i[IX_NQ], nu = i[IX_NU];
    Data *d = (Data *)s->data;
    char a[40], b[40];
    int k;
    if (nx < 0 || nx > NO_NX_MAX)
        snprintf(message, sizeof message, "nx = %d outside 0..%d", nx, NO_NX_MAX);
    else if (nq < 0 || nq > NO_NQ_MAX)
        snprintf(message, sizeof message, "nq = %d outside 0..%d", nq, NO_NQ_MAX);
    else if (nu < 1 || nu > NO_NU_MAX)
        snprintf(message, sizeof message, "nu = %d outside 1..%d", nu, NO_NU_MAX);
    else
        message[0] = '\0';
    if (message[0])
        return message;
    for (k = 0; k < nu; k++) {
        const double lo = r[VR_UMIN + k], hi = r[VR_UMAX + k];
        if (!(isfinite(lo) && isfinite(hi) && lo <= hi)) {
            snprintf(message, sizeof message, "u_min[%d] = %s, u_max[%d] = %s: need finite "
                     "bounds with u_min <= u_max", k + 1, py_repr(lo, a), k + 1, py_repr(hi, b));
            return message;
        }
    }
    for (k = 0; k < nq; k++)
        if (!isfinite(r[VR_Q + k])) {
            snprintf(message, sizeof message, "parameter q[%d] must be finite, got %s", k + 1,
                     py_repr(r[VR_Q + k], a));
            return message;
        }
    for (k = 0; k < nx; k++)
        if (!(isfinite(r[VR_XSCALE + k]) && isfinite(r[VR_XOFFSET + k]))) {
            snprintf(message, sizeof message, "x_scale[%d] = %s, x_offset[%d] = %s: need finite "
                     "values", k + 1, py_repr(r[VR_XSCALE + k], a), k + 1,
                     py_repr(r[VR_XOFFSET + k], b));
            return message;
        }
    if (no_compile(&d->program, i + IX_PSI, nx, nq, i + IX_OUT, nu, message, sizeof message))
        return message;
    d->nx = nx;
    d->nq = nq;
    return NULL;
}

size_t model_data_size(void) { return sizeof(Data); }

void model_prepare(ModelState *s)
{
    Data *d = (Data *)s->data;
    int k;
    d->scaled = 0;
    for (k = 0; k < d->nx; k++)
        if (s->r[VR_XSCALE + k] != 1.0 || s->r[VR_XOFFSET + k] != 0.0)
            d->scaled = 1;
}

/* the start values are the basic law: checked and compiled as the Python controller's
   constructor does */
void model_reset(ModelState *s)
{
    if (model_check(s) == NULL)
        model_prepare(s);
}

void model_outputs(ModelState *s)
{
    const Data *d = (const Data *)s->data;
    double *r = s->r, sources[NO_NX_MAX + NO_NQ_MAX], z[NO_NU_MAX];
    int k;
    for (k = 0; k < d->nx; k++)
        sources[k] = d->scaled ? no_scale(r[VR_X + k], r[VR_XSCALE + k], r[VR_XOFFSET + k])
                               : r[VR_X + k];
    memcpy(sources + d->nx, r + VR_Q, sizeof(double) * (size_t)d->nq);
    no_evaluate(&d->program, sources, z);
    for (k = 0; k < d->program.nu; k++)
        r[VR_U + k] = no_clip(z[k], r[VR_UMIN + k], r[VR_UMAX + k]);
}
