/* FMI 2.0 status wrapper around a pythonfmu FMU binary.

   pythonfmu turns every Python exception of an FMU into fmi2Fatal, also when the FMU rejects a
   parameter in fmi2ExitInitializationMode -- a user error that FMI 2.0 reports as fmi2Error,
   after which the FMU may be reset or freed.  This library is the FMU's binary; it loads the
   pythonfmu binary renamed beside it (<identifier>.pythonfmu.so, RTLD_LOCAL) and forwards every
   FMI 2.0 co-simulation function to it unchanged, except that fmi2Fatal from the set-up calls
   (fmi2SetupExperiment, fmi2EnterInitializationMode, fmi2ExitInitializationMode) becomes
   fmi2Error.  The FMUs of this project keep their instances safe to reset and free after such
   an error (their Python side balances pythonfmu's reference counts).

   pythonfmu passes the FMU's messages to the host only when loggingOn is true, so a rejected
   parameter went unseen by a plain `fmpy simulate`.  This library instantiates the pythonfmu
   FMU with loggingOn = true and passes on to the host every message of status fmi2Warning or
   above, and the others only when the host asked for logging (loggingOn or
   fmi2SetDebugLogging), as Reference-FMUs do.  The messages themselves are unchanged.

   pythonfmu 0.7 also writes to freed memory when its library is unloaded (at the host's exit,
   or when the host unloads it): a static std::shared_ptr to its interpreter state is first
   destroyed by the C++ exit handler, then set to nullptr by the library's destructor function
   (finalizePythonInterpreter), which releases the stale pointer's control block a second time:
   it decrements a count inside a freed 128-byte block, which glibc may report at exit as
   "corrupted double-linked list" (valgrind: an invalid read in finalizePythonInterpreter
   under _dl_fini).  This library calls finalizePythonInterpreter itself first, from an exit
   handler registered after the pythonfmu binary is loaded (so it runs before that binary's
   own), while the pointer is still valid: the state is released once and the pointer is
   null, so both later releases do nothing. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

static void *real_library = NULL;
static void (*release_state)(void) = NULL;

/* The exit handler: pythonfmu's own release of its interpreter state, while it is valid (see
   the top of this file). */
static void release_python_state(void)
{
    void (*release)(void) = release_state;
    release_state = NULL;
    if (release != NULL)
        release();
}

/* Registers release_python_state once the pythonfmu binary is loaded: exit handlers run in the
   reverse order of their registration, so it runs before the pythonfmu binary's (at exit, or
   when the host unloads this library, which keeps the pythonfmu binary loaded).  A pythonfmu
   without finalizePythonInterpreter needs nothing. */
static void release_first(void)
{
    *(void **)(&release_state) = dlsym(real_library, "finalizePythonInterpreter");
    if (release_state != NULL && atexit(release_python_state) != 0)
        release_state = NULL;
}

/* The pythonfmu binary beside this library: same path, ".so" -> ".pythonfmu.so". */
static void *library(void)
{
    Dl_info self;
    char path[4096];
    size_t n;
    if (real_library != NULL)
        return real_library;
    if (dladdr((void *)&library, &self) == 0 || self.dli_fname == NULL)
        return NULL;
    n = strlen(self.dli_fname);
    if (n < 3 || n + 10 >= sizeof path || strcmp(self.dli_fname + n - 3, ".so") != 0)
        return NULL;
    memcpy(path, self.dli_fname, n - 3);
    strcpy(path + n - 3, ".pythonfmu.so");
    real_library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (real_library == NULL)
        fprintf(stderr, "%s: cannot load %s: %s\n", self.dli_fname, path, dlerror());
    else
        release_first();
    return real_library;
}

static void *resolve(const char *name)
{
    void *lib = library();
    return lib != NULL ? dlsym(lib, name) : NULL;
}

/* One instance: the pythonfmu instance and the host's logger with its logging flag. */
typedef struct {
    fmi2Component inner;
    fmi2CallbackFunctions host, own;
    int logging;
} Wrapped;

#define INNER(c) ((c) != NULL ? ((Wrapped *)(c))->inner : NULL)

/* The logger pythonfmu calls: the message formatted, passed on if the host is to see it (as
   the format itself, with no conversion left: hosts that ignore the variadic arguments, fmpy,
   show it as it is). */
static void filter_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                          fmi2String category, fmi2String message, ...)
{
    Wrapped *w = (Wrapped *)env;
    char text[2048];
    va_list ap;
    if (w == NULL || w->host.logger == NULL || (status < fmi2Warning && !w->logging))
        return;
    va_start(ap, message);
    vsnprintf(text, sizeof text, message != NULL ? message : "", ap);
    va_end(ap);
    for (char *p = text; *p; p++)
        if (*p == '%')
            *p = '?';
    w->host.logger(w->host.componentEnvironment, instance, status, category, text);
}

/* The function `name` of the pythonfmu binary, looked up once. */
#define REAL(name) \
    static name##TYPE *p_##name = NULL; \
    if (p_##name == NULL) \
        *(void **)(&p_##name) = resolve(#name)

#define FORWARD_STATUS(name, params, args) \
    fmi2Status name params \
    { \
        REAL(name); \
        return p_##name != NULL && c != NULL ? p_##name args : fmi2Fatal; \
    }

/* set-up calls: a rejected value is fmi2Error, not fmi2Fatal */
#define SETUP_STATUS(name, params, args) \
    fmi2Status name params \
    { \
        fmi2Status s; \
        REAL(name); \
        if (p_##name == NULL || c == NULL) \
            return fmi2Fatal; \
        s = p_##name args; \
        return s == fmi2Fatal ? fmi2Error : s; \
    }

const char *fmi2GetTypesPlatform(void)
{
    return fmi2TypesPlatform;
}

const char *fmi2GetVersion(void)
{
    return fmi2Version;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String guid,
                              fmi2String resourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    Wrapped *w;
    REAL(fmi2Instantiate);
    if (p_fmi2Instantiate == NULL || (w = calloc(1, sizeof *w)) == NULL)
        return NULL;
    if (functions != NULL)
        w->host = w->own = *functions;
    w->own.logger = filter_logger;
    w->own.componentEnvironment = w;
    w->logging = loggingOn;
    w->inner = p_fmi2Instantiate(instanceName, fmuType, guid, resourceLocation, &w->own,
                                 visible, fmi2True);
    if (w->inner == NULL) {
        free(w);
        return NULL;
    }
    return w;
}

void fmi2FreeInstance(fmi2Component c)
{
    REAL(fmi2FreeInstance);
    if (p_fmi2FreeInstance != NULL && c != NULL)
        p_fmi2FreeInstance(INNER(c));
    free(c);
}

/* the host's flag decides what passes the filter; pythonfmu itself keeps logging everything */
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                               const fmi2String categories[])
{
    (void)n;
    (void)categories;
    if (c == NULL)
        return fmi2Error;
    ((Wrapped *)c)->logging = on;
    return fmi2OK;
}
SETUP_STATUS(fmi2SetupExperiment,
             (fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
              fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime),
             (INNER(c), toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime))
SETUP_STATUS(fmi2EnterInitializationMode, (fmi2Component c), (INNER(c)))
SETUP_STATUS(fmi2ExitInitializationMode, (fmi2Component c), (INNER(c)))
FORWARD_STATUS(fmi2Terminate, (fmi2Component c), (INNER(c)))
FORWARD_STATUS(fmi2Reset, (fmi2Component c), (INNER(c)))

FORWARD_STATUS(fmi2GetReal,
               (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]),
               (INNER(c), vr, n, v))
FORWARD_STATUS(fmi2GetInteger,
               (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]),
               (INNER(c), vr, n, v))
FORWARD_STATUS(fmi2GetBoolean,
               (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]),
               (INNER(c), vr, n, v))
FORWARD_STATUS(fmi2GetString,
               (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]),
               (INNER(c), vr, n, v))
FORWARD_STATUS(fmi2SetReal,
               (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]),
               (INNER(c), vr, n, v))
FORWARD_STATUS(fmi2SetInteger,
               (fmi2Component c, const fmi2ValueReference vr[], size_t n,
                const fmi2Integer v[]),
               (INNER(c), vr, n, v))
FORWARD_STATUS(fmi2SetBoolean,
               (fmi2Component c, const fmi2ValueReference vr[], size_t n,
                const fmi2Boolean v[]),
               (INNER(c), vr, n, v))
FORWARD_STATUS(fmi2SetString,
               (fmi2Component c, const fmi2ValueReference vr[], size_t n,
                const fmi2String v[]),
               (INNER(c), vr, n, v))

FORWARD_STATUS(fmi2GetFMUstate, (fmi2Component c, fmi2FMUstate *s), (INNER(c), s))
FORWARD_STATUS(fmi2SetFMUstate, (fmi2Component c, fmi2FMUstate s), (INNER(c), s))
FORWARD_STATUS(fmi2FreeFMUstate, (fmi2Component c, fmi2FMUstate *s), (INNER(c), s))
FORWARD_STATUS(fmi2SerializedFMUstateSize, (fmi2Component c, fmi2FMUstate s, size_t *n),
               (INNER(c), s, n))
FORWARD_STATUS(fmi2SerializeFMUstate,
               (fmi2Component c, fmi2FMUstate s, fmi2Byte bytes[], size_t n),
               (INNER(c), s, bytes, n))
FORWARD_STATUS(fmi2DeSerializeFMUstate,
               (fmi2Component c, const fmi2Byte bytes[], size_t n, fmi2FMUstate *s),
               (INNER(c), bytes, n, s))
FORWARD_STATUS(fmi2GetDirectionalDerivative,
               (fmi2Component c, const fmi2ValueReference vUnknown[], size_t nUnknown,
                const fmi2ValueReference vKnown[], size_t nKnown, const fmi2Real dvKnown[],
                fmi2Real dvUnknown[]),
               (INNER(c), vUnknown, nUnknown, vKnown, nKnown, dvKnown, dvUnknown))

FORWARD_STATUS(fmi2SetRealInputDerivatives,
               (fmi2Component c, const fmi2ValueReference vr[], size_t n,
                const fmi2Integer order[], const fmi2Real value[]),
               (INNER(c), vr, n, order, value))
FORWARD_STATUS(fmi2GetRealOutputDerivatives,
               (fmi2Component c, const fmi2ValueReference vr[], size_t n,
                const fmi2Integer order[], fmi2Real value[]),
               (INNER(c), vr, n, order, value))
FORWARD_STATUS(fmi2DoStep,
               (fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior),
               (INNER(c), t, h, noSetPrior))
FORWARD_STATUS(fmi2CancelStep, (fmi2Component c), (INNER(c)))
FORWARD_STATUS(fmi2GetStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Status *v),
               (INNER(c), s, v))
FORWARD_STATUS(fmi2GetRealStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Real *v),
               (INNER(c), s, v))
FORWARD_STATUS(fmi2GetIntegerStatus,
               (fmi2Component c, const fmi2StatusKind s, fmi2Integer *v), (INNER(c), s, v))
FORWARD_STATUS(fmi2GetBooleanStatus,
               (fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v), (INNER(c), s, v))
FORWARD_STATUS(fmi2GetStringStatus, (fmi2Component c, const fmi2StatusKind s, fmi2String *v),
               (INNER(c), s, v))
