/* loop.h -- the closed-loop engine's types, shared by closed_loop.c (set-up, life cycle,
 * doStep) and loop_values.c (get and set, the functions a closed loop does not support). */
#ifndef DESCENT_LOOP_H
#define DESCENT_LOOP_H

#include <stddef.h>

#include "fmi2Functions.h"

#define LOOP_GUID_MAX 200
#define LOOP_PATH_MAX 4096

typedef struct {
    char type;
    int comp;
    fmi2ValueReference vr, cvr;
    int settable, has_start;
    char start[64];
} LoopVar;

typedef struct {
    char type;
    int src, dst;
    fmi2ValueReference svr, dvr;
} LoopConn;

typedef struct {
    char role[32], path[256], ident[256], guid[LOOP_GUID_MAX];
    void *lib;
    fmi2Component c;
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetDebugLoggingTYPE *debug_logging;
    fmi2SetupExperimentTYPE *setup;
    fmi2EnterInitializationModeTYPE *enter;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2TerminateTYPE *terminate;
    fmi2ResetTYPE *reset;
    fmi2GetRealTYPE *get_real;
    fmi2GetIntegerTYPE *get_int;
    fmi2GetBooleanTYPE *get_bool;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_int;
    fmi2SetBooleanTYPE *set_bool;
    fmi2DoStepTYPE *step;
} Part;

typedef enum { M_INSTANTIATED, M_INIT, M_STEP, M_TERMINATED, M_ERROR } Mode;

typedef struct {
    Part part[2];
    LoopVar *vars;
    size_t nvars;
    LoopConn *conns;
    size_t nconns;
    long period_vr;            /* -1: none */
    double period_default, T;
    char *name, model[128];
    fmi2CallbackFunctions host, cb;
    Mode mode;
    double t0, t, s;           /* start time, current time, time of the last sample */
    long k;                    /* index of the last sample */
    int stop_defined;
    double stop;
} Loop;

/* closed_loop.c */
void loop_error(Loop *L, const char *fmt, ...);
/* loop_values.c */
fmi2Status set_one(Part *p, char type, fmi2ValueReference vr, const void *value);
fmi2Status get_one(Part *p, char type, fmi2ValueReference vr, void *value);

#endif
