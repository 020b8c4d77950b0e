/* master.h -- the C master of two FMI 2.0 co-simulation FMUs (master.c): a closed loop loaded
 * once, one call per flight.  What each function does is said in master.c. */
#ifndef DESCENT_MASTER_H
#define DESCENT_MASTER_H

#include <stddef.h>

#include "fmi2FunctionTypes.h"

typedef struct DmMaster DmMaster;

/* Start values of one component for one flight: only those that differ from its defaults. */
typedef struct {
    size_t nr;
    const fmi2ValueReference *rvr;
    const fmi2Real *rval;
    size_t ni;
    const fmi2ValueReference *ivr;
    const fmi2Integer *ival;
} DmValues;

/* What a flight reads at its end: plant outputs of each type, written to caller's buffers;
 * and n0 plant Reals read at t = 0 after the first exchange of values (where a recording takes
 * its first sample), written to val0 (n0 = 0: none). */
typedef struct {
    size_t nr, ni, nb;
    const fmi2ValueReference *rvr, *ivr, *bvr;
    fmi2Real *rval;
    fmi2Integer *ival;
    fmi2Boolean *bval;
    size_t n0;
    const fmi2ValueReference *vr0;
    fmi2Real *val0;
} DmOutputs;

/* Start values of a batch of flights (dm_fly_many): flight k sets nr[k] Reals and ni[k]
 * Integers, its value references and values following those of flights 0 .. k-1 in the four
 * concatenated arrays. */
typedef struct {
    const long *nr;
    const fmi2ValueReference *rvr;
    const fmi2Real *rval;
    const long *ni;
    const fmi2ValueReference *ivr;
    const fmi2Integer *ival;
} DmBatchValues;

#define DM_EXPORT __attribute__((visibility("default")))

DM_EXPORT DmMaster *dm_open(const char *plant_library, const char *plant_guid,
                            const char *plant_resources, const char *ctrl_library,
                            const char *ctrl_guid, const char *ctrl_resources);
DM_EXPORT const char *dm_message(const DmMaster *m);
DM_EXPORT int dm_wire(DmMaster *m, size_t ny, const fmi2ValueReference *y_vr,
                      const fmi2ValueReference *x_vr, size_t nu, const fmi2ValueReference *u_vr,
                      const fmi2ValueReference *pu_vr, double h, int stop_type,
                      fmi2ValueReference stop_vr, int stop_op, double stop_value,
                      long check_every);
DM_EXPORT int dm_fly(DmMaster *m, double t_end, const DmValues *plant, const DmValues *ctrl,
                     const DmOutputs *out, long *steps, int *stopped);
DM_EXPORT long dm_fly_many(DmMaster *m, long first, long n, double t_end,
                           const DmBatchValues *plant, const DmBatchValues *ctrl,
                           const DmOutputs *out, long *steps, int *stopped);
DM_EXPORT void dm_close(DmMaster *m);

#endif
