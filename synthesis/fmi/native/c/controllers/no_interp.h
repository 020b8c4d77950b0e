/* no_interp.h -- the network operator's matrix interpreter: a matrix psi given as numbers
 * (the Integer parameters psi[i,j] of a generic controller FMU) checked and compiled into an
 * arc program, then evaluated with the operations of no_operations.h (generated from the one
 * operation table), in the order and with the guards of
 * models/controllers/law_interpreter.py (compile_law, evaluate): bitwise the same values.
 *
 * Sizes (model_config.h, generated from the Python controller's capacity): NO_L_MAX nodes,
 * NO_NU_MAX outputs.
 *
 * descent-fmus (MIT licence).
 */
#ifndef DESCENT_NO_INTERP_H
#define DESCENT_NO_INTERP_H

#include <stddef.h>

#include "model_config.h"

typedef struct {
    unsigned char i, j;             /* arc i -> j (0-based) */
    short code;                     /* NO_ARC_CODE(unary rho, binary chi of node j) */
} NOArc;

typedef struct {
    int n_arcs, ns, nu;
    NOArc arcs[NO_L_MAX * (NO_L_MAX - 1) / 2];
    double init[NO_L_MAX];          /* node values before the arcs (units of the operations) */
    int outs[NO_NU_MAX];            /* 0-based output nodes */
} NOProgram;

/* Check the matrix (psi: the upper triangle row by row, psi[i,j] for i <= j, as the
 * controller's variables are ordered) with nx inputs, nq parameters and the nu output nodes
 * out[k] (1-based), as compile_law does, and compile it into *p.  Returns NULL, or the message
 * of the first problem (compile_law's text, in msg) -- *p is then left as it was. */
const char *no_compile(NOProgram *p, const int *psi, int nx, int nq, const int *out, int nu,
                       char *msg, size_t size);

/* the output node values for the source values (nx inputs then nq parameters, ns in all) */
void no_evaluate(const NOProgram *p, const double *sources, double *z_out);

#endif
