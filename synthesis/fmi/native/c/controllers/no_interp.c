/* no_interp.c -- the network operator's matrix interpreter (see no_interp.h).
 *
 * descent-fmus (MIT licence).
 */
#include <stdio.h>
#include <string.h>

#include "no_interp.h"
#include "no_operations.h"

/* index of psi[i,j] (0-based, i <= j) in the upper triangle row by row */
#define PSI_AT(i, j) ((i) * NO_L_MAX - (i) * ((i) - 1) / 2 + ((j) - (i)))

/* compile_law's checks of one entry, in its order (the diagonal: binary operation, not on a
   source node; above it: unary operation, not into a source node) */
static const char *check_entry(int i, int j, int v, int ns, char *msg, size_t size)
{
    if (i == j) {
        if (v < 0 || v > NO_N_BINARY) {
            snprintf(msg, size, "unknown binary operation %d at node %d (psi[%d,%d]); valid: "
                     "1..%d", v, i + 1, i + 1, i + 1, NO_N_BINARY);
            return msg;
        }
        if (i < ns && v != 0) {
            snprintf(msg, size, "node %d is a source node (input or parameter) and cannot "
                     "carry binary operation %d", i + 1, v);
            return msg;
        }
    } else if (v != 0) {
        if (v < 1 || v > NO_N_UNARY) {
            snprintf(msg, size, "unknown unary operation %d on arc %d->%d (psi[%d,%d]); valid: "
                     "1..%d", v, i + 1, j + 1, i + 1, j + 1, NO_N_UNARY);
            return msg;
        }
        if (j < ns) {
            snprintf(msg, size, "arc %d->%d ends in source node %d", i + 1, j + 1, j + 1);
            return msg;
        }
    }
    return NULL;
}

const char *no_compile(NOProgram *p, const int *psi, int nx, int nq, const int *out, int nu,
                       char *msg, size_t size)
{
    NOProgram next;                     /* filled, then copied: *p changes only if valid */
    const int ns = nx + nq;
    int i, j, k;
    const char *bad;
    if (nx < 0 || nq < 0 || ns > NO_L_MAX) {
        snprintf(msg, size, "%d inputs + %d parameters do not fit in a %d-node matrix", nx, nq,
                 NO_L_MAX);
        return msg;
    }
    for (i = 0; i < NO_L_MAX; i++)
        for (j = i; j < NO_L_MAX; j++)
            if ((bad = check_entry(i, j, psi[PSI_AT(i, j)], ns, msg, size)) != NULL)
                return bad;
    next.ns = ns;
    next.nu = nu;
    next.n_arcs = 0;
    /* a node starts at finite(unit) (atan2: 0), the unit itself once an arc reaches it
       (atan2: NaN, which its first arc replaces) */
    for (j = 0; j < NO_L_MAX; j++) {
        const int b = psi[PSI_AT(j, j)];
        next.init[j] = (j >= ns && b) ? no_finite(NO_UNIT[b]) : 0.0;
    }
    for (i = 0; i < NO_L_MAX; i++)
        for (j = i + 1; j < NO_L_MAX; j++) {
            const int r = psi[PSI_AT(i, j)], b = psi[PSI_AT(j, j)];
            if (r && b) {
                NOArc *a = &next.arcs[next.n_arcs++];
                next.init[j] = NO_UNIT[b];
                a->i = (unsigned char)i;
                a->j = (unsigned char)j;
                a->code = (short)NO_ARC_CODE(r, b);
            }
        }
    for (k = 0; k < nu; k++) {
        if (out[k] < 1 || out[k] > NO_L_MAX) {
            snprintf(msg, size, "output %d names node %d, outside 1..%d", k + 1, out[k],
                     NO_L_MAX);
            return msg;
        }
        next.outs[k] = out[k] - 1;
    }
    /* the arcs in use only: the rest of the table is not copied */
    memcpy(p, &next, offsetof(NOProgram, arcs) + sizeof(NOArc) * (size_t)next.n_arcs);
    memcpy(p->init, next.init, sizeof next.init);
    memcpy(p->outs, next.outs, sizeof next.outs);
    return NULL;
}

void no_evaluate(const NOProgram *p, const double *sources, double *z_out)
{
    double z[NO_L_MAX];
    const NOArc *a = p->arcs, *end = p->arcs + p->n_arcs;
    int k;
    memcpy(z, p->init, sizeof z);
    for (k = 0; k < p->ns; k++)
        z[k] = no_finite(sources[k]);
    for (; a < end; a++)
        z[a->j] = no_arc(a->code, z[a->j], z[a->i]);      /* finite(chi(z_j, rho(z_i))) */
    for (k = 0; k < p->nu; k++)
        z_out[k] = z[p->outs[k]];
}
