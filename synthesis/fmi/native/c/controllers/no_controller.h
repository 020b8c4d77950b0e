/* no_controller.h -- the generic network-operator controller's parameters, checks and outputs,
 * shared by the native twins that carry one (no_model.c: NetworkOperatorController;
 * sensed_model.c: SensedNetworkOperatorController).  The including model's model_config.h
 * gives the value references (VR_X, VR_U, VR_Q, VR_UMIN, VR_UMAX, VR_XSCALE, VR_XOFFSET, IX_NX,
 * IX_NQ, IX_NU, IX_OUT, IX_PSI) and the capacity (NO_NX_MAX, NO_NQ_MAX, NO_NU_MAX, NO_L_MAX).
 *
 * The checks are NetworkOperatorController.check_parameters in its order and words; the matrix
 * is compiled into an arc program when they pass (no_interp.c), and the outputs are the Python
 * controller's law(): bitwise the same doubles.
 *
 * descent-fmus (MIT licence).
 */
#ifndef DESCENT_NO_CONTROLLER_H
#define DESCENT_NO_CONTROLLER_H

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "native_model.h"
#include "no_interp.h"
#include "no_operations.h"
#include "py_repr.h"

typedef struct {
    NOProgram program;              /* the checked matrix */
    int nx, nq;                     /* the source counts it was compiled with */
    int scaled;                     /* an input scale != 1 or offset != 0 */
} NOController;

/* NULL, or the first problem (in msg, size bytes); the matrix compiled into *d if none */
static const char *no_controller_check(const ModelState *s, NOController *d, char *msg,
                                       size_t size)
{
    const double *r = s->r;
    const int *i = s->i, nx = i[IX_NX], nq = i[IX_NQ], nu = i[IX_NU];
    char a[40], b[40];
    int k;
    if (nx < 0 || nx > NO_NX_MAX) {
        snprintf(msg, size, "nx = %d outside 0..%d", nx, NO_NX_MAX);
        return msg;
    }
    if (nq < 0 || nq > NO_NQ_MAX) {
        snprintf(msg, size, "nq = %d outside 0..%d", nq, NO_NQ_MAX);
        return msg;
    }
    if (nu < 1 || nu > NO_NU_MAX) {
        snprintf(msg, size, "nu = %d outside 1..%d", nu, NO_NU_MAX);
        return msg;
    }
    for (k = 0; k < nu; k++) {
        const double lo = r[VR_UMIN + k], hi = r[VR_UMAX + k];
        if (!(isfinite(lo) && isfinite(hi) && lo <= hi)) {
            snprintf(msg, size, "u_min[%d] = %s, u_max[%d] = %s: need finite bounds with "
                     "u_min <= u_max", k + 1, py_repr(lo, a), k + 1, py_repr(hi, b));
            return msg;
        }
    }
    for (k = 0; k < nq; k++)
        if (!isfinite(r[VR_Q + k])) {
            snprintf(msg, size, "parameter q[%d] must be finite, got %s", k + 1,
                     py_repr(r[VR_Q + k], a));
            return msg;
        }
    for (k = 0; k < nx; k++)
        if (!(isfinite(r[VR_XSCALE + k]) && isfinite(r[VR_XOFFSET + k]))) {
            snprintf(msg, size, "x_scale[%d] = %s, x_offset[%d] = %s: need finite values",
                     k + 1, py_repr(r[VR_XSCALE + k], a), k + 1, py_repr(r[VR_XOFFSET + k], b));
            return msg;
        }
    if (no_compile(&d->program, i + IX_PSI, nx, nq, i + IX_OUT, nu, msg, size))
        return msg;
    d->nx = nx;
    d->nq = nq;
    return NULL;
}

/* prepare(): the input scaling in use or not */
static void no_controller_prepare(const ModelState *s, NOController *d)
{
    int k;
    d->scaled = 0;
    for (k = 0; k < d->nx; k++)
        if (s->r[VR_XSCALE + k] != 1.0 || s->r[VR_XOFFSET + k] != 0.0)
            d->scaled = 1;
}

/* law(x): the clipped outputs u[k] of the law for the inputs x (nx values, unscaled) */
static void no_controller_law(const ModelState *s, const NOController *d, const double *x,
                              double *u)
{
    const double *r = s->r;
    double sources[NO_NX_MAX + NO_NQ_MAX], z[NO_NU_MAX];
    int k;
    for (k = 0; k < d->nx; k++)
        sources[k] = d->scaled ? no_scale(x[k], r[VR_XSCALE + k], r[VR_XOFFSET + k]) : x[k];
    memcpy(sources + d->nx, r + VR_Q, sizeof(double) * (size_t)d->nq);
    no_evaluate(&d->program, sources, z);
    for (k = 0; k < d->program.nu; k++)
        u[k] = no_clip(z[k], r[VR_UMIN + k], r[VR_UMAX + k]);
}

/* the outputs u[k] of the law for the current inputs x */
static void no_controller_outputs(ModelState *s, const NOController *d)
{
    no_controller_law(s, d, s->r + VR_X, s->r + VR_U);
}

#endif
