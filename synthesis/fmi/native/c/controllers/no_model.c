/* no_model.c -- the generic network-operator controller (NetworkOperatorController) as the
 * model of a native FMU (native_model.h): the twin of the pythonfmu class of
 * models/controllers/network_operator.py, with its variables (names, defaults, descriptions,
 * units; model_config.h gives their value references), its checks and messages, and its
 * outputs to the last bit (no_controller.h).
 *
 * A candidate law is a set of start values: the matrix psi[i,j], nx, nq, nu, out[k], q[k], the
 * bounds and the input scaling.  The matrix is checked and compiled into an arc program
 * (no_interp.c) when the parameters are checked -- entering and leaving initialisation, as the
 * Python controller does -- and interpreted at every output: no compiler is involved per law.
 *
 * descent-fmus (MIT licence).
 */
#include "native_model.h"
#include "model_config.h"
#include "no_controller.h"

MODEL_TABLES(VR_SAMPLE)

static char message[400];

const char *model_check(const ModelState *s)
{
    return no_controller_check(s, (NOController *)s->data, message, sizeof message);
}

size_t model_data_size(void) { return sizeof(NOController); }

void model_prepare(ModelState *s)
{
    no_controller_prepare(s, (NOController *)s->data);
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
    no_controller_outputs(s, (const NOController *)s->data);
}
