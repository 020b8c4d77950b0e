/* sensed_controller.h -- what the native twins of a network-operator law reading the drag
 * estimate share (sensed_model.c: SensedNetworkOperatorController, guided_model.c:
 * GuidedNetworkOperatorController): the checks and the preparation of
 * SensedNetworkOperatorController, in its order.  The including model's model_config.h gives
 * IX_ESTIMATE besides what no_controller.h and estimator.h read.
 *
 * descent-fmus (MIT licence).
 */
#ifndef DESCENT_SENSED_CONTROLLER_H
#define DESCENT_SENSED_CONTROLLER_H

#include <stdio.h>

#include "native_model.h"
#include "no_controller.h"
#include "estimator.h"

/* the generic controller's checks, then the estimator's parameters, then estimate_input (the
   order of SensedNetworkOperatorController.check_parameters): NULL, or the problem in msg */
static const char *sensed_controller_check(const ModelState *s, NOController *law, char *msg,
                                           size_t size)
{
    const int ei = s->i[IX_ESTIMATE];
    if (no_controller_check(s, law, msg, size) != NULL)
        return msg;
    if (est_check(s->r, s->i, msg) != NULL)
        return msg;
    if (ei < 0 || ei > NO_NX_MAX) {
        snprintf(msg, size, "estimate_input = %d outside 0..%d", ei, NO_NX_MAX);
        return msg;
    }
    return NULL;
}

/* prepare(): the law's input scaling, a new estimator */
static void sensed_controller_prepare(ModelState *s, NOController *law,
                                      EstimatorRun *est)
{
    no_controller_prepare(s, law);
    est_run_prepare(est, s->r, s->i);
}

#endif
