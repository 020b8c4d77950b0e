/* fmi3_cs.c -- the generic FMI 3.0 co-simulation wrapper of every descent-fmus native FMU and
 * closed-loop FMU.
 *
 * The same model (native_model.h) as the FMI 2.0 wrapper, and the same wrapper logic: this file
 * compiles fmi2_cs.c into itself under private names (descent_fmi2DoStep, ...; not exported)
 * and implements every FMI 3.0 function on top of those.  So the state machine, the sampling of
 * a sampled controller, the causality rules of get/set, the parameter checks and every message
 * exist once, in fmi2_cs.c; this file only translates the interface:
 *
 *   FMI 3.0                              FMI 2.0 wrapper
 *   fmi3InstantiateCoSimulation         fmi2Instantiate (the instantiation token is the GUID,
 *                                       the resource path turned into a file URI)
 *   fmi3InstantiateModelExchange, ...   fmi2Instantiate as model exchange (refused, with its
 *                                       message)
 *   fmi3EnterInitializationMode(t0, t1) fmi2SetupExperiment + fmi2EnterInitializationMode
 *   fmi3Get/SetFloat64, Get/SetInt32    fmi2Get/SetReal, Get/SetInteger (same value references)
 *   fmi3DoStep                          fmi2DoStep (never an event, never an early return)
 *   the log message callback            the FMI 2.0 logger, relayed (errors are logged whatever
 *                                       loggingOn says, as in fmi2_cs.c)
 *
 * Compiled with FMI3_OVER_LOOP defined (fmi3_loop.c), the FMI 2.0 implementation it wraps is
 * the closed-loop engine (../loop/closed_loop.c and loop_values.c) instead of fmi2_cs.c: the
 * FMI 3.0 face of a closed loop whose components stay FMI 2.0 FMUs in its resources/.  The
 * wrapped implementation provides, besides the FMI 2.0 functions, inner_error (an error
 * through the host's logger), unsupported (a function it does not support) and none_of (a
 * call about variables of a type it has none of), each with its own message.
 *
 * FMI 3.0 requires one independent variable, "time", read-only: for a native FMU value
 * reference MODEL_N_REAL + MODEL_N_INTEGER (after every model variable), for a closed loop 0
 * (its FMI 2.0 time).  Every function of
 * the standard's headers is defined; those of features this FMU does not declare (model
 * exchange, scheduled execution, event mode, clocks, FMU state, derivatives, variables of the
 * other types) return fmi3Error with a message, or fmi3OK when asked for nothing.
 *
 * descent-fmus (MIT licence).
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The FMI 2.0 wrapper's functions under private names: fmi2Functions.h maps every fmi2X to
   fmi2FullName(fmi2X) when it is used; once the header is in, fmi2FullName is redefined, so that
   fmi2_cs.c below defines (and this file calls) descent_fmi2X.  They are not exported: only the
   header's declarations carry the export attribute, and those keep the plain names. */
#include "fmi2Functions.h"
#undef fmi2FullName
#define fmi2FullName(name) descent_##name
#ifdef FMI3_OVER_LOOP
#include "closed_loop.c"
#include "loop_values.c"
#define inner_error(c, ...) loop_error((Loop *)(c), __VA_ARGS__)
#define VR_TIME ((fmi3ValueReference)0)
#else
#include "fmi2_cs.c"
#define inner_error(c, ...) log_error((Instance *)(c), __VA_ARGS__)
#define VR_TIME ((fmi3ValueReference)(MODEL_N_REAL + MODEL_N_INTEGER))
#endif

#include "fmi3Functions.h"

typedef char int32_is_int[(sizeof(fmi3Int32) == sizeof(fmi2Integer)) ? 1 : -1];

typedef struct {
    fmi2Component inner;            /* the FMI 2.0 wrapper's instance */
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Adapter;

#define INNER(instance) (((Adapter *)(instance))->inner)

/* the FMI 2.0 wrapper's logger: pass the message on to the FMI 3.0 callback (the statuses have
   the same numbers; the message already names the instance) */
static void relay(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                  fmi2String category, fmi2String message, ...)
{
    Adapter *a = (Adapter *)env;
    (void)name;
    if (a != NULL && a->log != NULL)
        a->log(a->env, (fmi3Status)status, category, message);
}

static fmi3Status status3(fmi2Status s) { return (fmi3Status)s; }

static fmi3Status unsupported3(fmi3Instance instance, const char *what)
{
    if (instance == NULL)
        return fmi3Error;
    return status3(unsupported(INNER(instance), what));
}

/* a call about variables of a type this FMU has none of: fine when it names none */
static fmi3Status none_of3(fmi3Instance instance, size_t n, const char *type)
{
    if (instance == NULL)
        return fmi3Error;
    return status3(none_of(INNER(instance), n, type));
}

/* scalar variables only: one value per value reference */
static int scalars(fmi3Instance instance, size_t nvr, size_t nvalues)
{
    if (nvr == nvalues)
        return 1;
    inner_error(INNER(instance), "%lu values for %lu value references: this FMU has "
              "scalar variables only", (unsigned long)nvalues, (unsigned long)nvr);
    return 0;
}

/* -- inquire version numbers, logging ------------------------------------------------------ */
const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    if (instance == NULL)
        return fmi3Error;
    return status3(fmi2SetDebugLogging(INNER(instance), loggingOn, nCategories, categories));
}

/* -- creation and destruction ------------------------------------------------------------- */

/* The FMI 2.0 resource location of an FMI 3.0 resource path (a folder): a file URI, every byte
   but the unreserved ones, '/' and ':' percent-encoded, '\' read as '/'; NULL for NULL. */
static char *resource_uri(const char *path)
{
    char *uri, *q;
    if (path == NULL || (uri = (char *)malloc(3 * strlen(path) + 9)) == NULL)
        return NULL;
    q = uri + sprintf(uri, "file://%s", path[0] == '/' ? "" : "/");
    for (; *path; path++) {
        unsigned char c = (unsigned char)*path;
        if (c == '\\')
            *q++ = '/';
        else if ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9')
                 || strchr("-._~/:", c) != NULL)
            *q++ = (char)c;
        else
            q += sprintf(q, "%%%02X", c);
    }
    *q = 0;
    return uri;
}

/* fmi2Instantiate of the wrapped implementation as `type`, its messages relayed to a->log */
static fmi2Component instantiate2(Adapter *a, fmi3String name, fmi2Type type, fmi3String token,
                                  fmi3String resourcePath, fmi3Boolean visible,
                                  fmi3Boolean loggingOn)
{
    fmi2CallbackFunctions callbacks = {relay, calloc, free, NULL, NULL};
    char *uri = resource_uri(resourcePath);
    fmi2Component c;
    callbacks.componentEnvironment = a;
    c = fmi2Instantiate(name, type, token, uri, &callbacks, visible, loggingOn);
    free(uri);
    return c;
}

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    Adapter *a = (Adapter *)calloc(1, sizeof(Adapter));
    (void)earlyReturnAllowed;       /* a step always ends where it was asked to */
    (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    if (a == NULL)
        return NULL;
    a->env = instanceEnvironment;
    a->log = logMessage;
    a->inner = instantiate2(a, instanceName, fmi2CoSimulation, instantiationToken, resourcePath,
                            visible, loggingOn);
    if (a->inner != NULL && eventModeUsed) {
        inner_error(a->inner, "event mode is not supported by this FMU "
                    "(hasEventMode=\"false\")");
        fmi2FreeInstance(a->inner);
        a->inner = NULL;
    }
    if (a->inner == NULL) {
        free(a);
        return NULL;
    }
    return a;
}

/* the other interface types: refused by the wrapped fmi2Instantiate, with its message, through
   the caller's logger */
static fmi3Instance cs_only(fmi3String name, fmi3String token, fmi3InstanceEnvironment env,
                            fmi3LogMessageCallback log)
{
    Adapter a;
    fmi2Component c;
    a.inner = NULL;
    a.env = env;
    a.log = log;
    if ((c = instantiate2(&a, name, fmi2ModelExchange, token, NULL, fmi3False, fmi3False))
        != NULL)
        fmi2FreeInstance(c);        /* not reached: a co-simulation FMU refuses */
    return NULL;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    (void)resourcePath; (void)visible; (void)loggingOn;
    return cs_only(instanceName, instantiationToken, instanceEnvironment, logMessage);
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)resourcePath; (void)visible; (void)loggingOn;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    return cs_only(instanceName, instantiationToken, instanceEnvironment, logMessage);
}

void fmi3FreeInstance(fmi3Instance instance)
{
    if (instance == NULL)
        return;
    fmi2FreeInstance(INNER(instance));
    free(instance);
}

/* -- initialisation, termination, reset --------------------------------------------------- */
fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    fmi2Status s;
    if (instance == NULL)
        return fmi3Error;
    s = fmi2SetupExperiment(INNER(instance), toleranceDefined, tolerance, startTime,
                            stopTimeDefined, stopTime);
    if (s != fmi2OK)
        return status3(s);
    return status3(fmi2EnterInitializationMode(INNER(instance)));
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    return instance == NULL ? fmi3Error : status3(fmi2ExitInitializationMode(INNER(instance)));
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    return instance == NULL ? fmi3Error : status3(fmi2Terminate(INNER(instance)));
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    return instance == NULL ? fmi3Error : status3(fmi2Reset(INNER(instance)));
}

/* -- Float64 and Int32: the Reals and Integers of the model; the time ------------------------ */
fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues)
{
    size_t k;
    fmi2Status s = fmi2OK;
    if (instance == NULL || !scalars(instance, nValueReferences, nValues))
        return fmi3Error;
    for (k = 0; k < nValueReferences; k++)
        if (valueReferences[k] == VR_TIME)
            break;
    if (k == nValueReferences)      /* no time: the whole array in one call */
        return status3(fmi2GetReal(INNER(instance), valueReferences, nValueReferences, values));
    for (k = 0; k < nValueReferences && s <= fmi2Warning; k++)
        s = valueReferences[k] == VR_TIME
            ? fmi2GetRealStatus(INNER(instance), fmi2LastSuccessfulTime, &values[k])
            : fmi2GetReal(INNER(instance), &valueReferences[k], 1, &values[k]);
    return status3(s);
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues)
{
    size_t k;
    if (instance == NULL || !scalars(instance, nValueReferences, nValues))
        return fmi3Error;
    for (k = 0; k < nValueReferences; k++)
        if (valueReferences[k] == VR_TIME) {
            inner_error(INNER(instance), "value reference %lu is the independent "
                      "variable time and cannot be set", (unsigned long)VR_TIME);
            return fmi3Error;
        }
    return status3(fmi2SetReal(INNER(instance), valueReferences, nValueReferences, values));
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Int32 values[], size_t nValues)
{
    if (instance == NULL || !scalars(instance, nValueReferences, nValues))
        return fmi3Error;
    return status3(fmi2GetInteger(INNER(instance), valueReferences, nValueReferences,
                                  (fmi2Integer *)values));
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Int32 values[], size_t nValues)
{
    if (instance == NULL || !scalars(instance, nValueReferences, nValues))
        return fmi3Error;
    return status3(fmi2SetInteger(INNER(instance), valueReferences, nValueReferences,
                                  (const fmi2Integer *)values));
}

/* -- the other types: this FMU has no variables of them ----------------------------------- */
#define NO_VARIABLES(type, ctype)                                                            \
    fmi3Status fmi3Get##type(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,  \
                             ctype values[], size_t nValues)                                \
    {                                                                                        \
        (void)vr; (void)values; (void)nValues;                                               \
        return none_of3(instance, n, #type);                                                 \
    }                                                                                        \
    fmi3Status fmi3Set##type(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,  \
                             const ctype values[], size_t nValues)                          \
    {                                                                                        \
        (void)vr; (void)values; (void)nValues;                                               \
        return none_of3(instance, n, #type);                                                 \
    }
NO_VARIABLES(Float32, fmi3Float32)
NO_VARIABLES(Int8, fmi3Int8)
NO_VARIABLES(UInt8, fmi3UInt8)
NO_VARIABLES(Int16, fmi3Int16)
NO_VARIABLES(UInt16, fmi3UInt16)
NO_VARIABLES(UInt32, fmi3UInt32)
NO_VARIABLES(Int64, fmi3Int64)
NO_VARIABLES(UInt64, fmi3UInt64)
NO_VARIABLES(Boolean, fmi3Boolean)
NO_VARIABLES(String, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues)
{
    (void)vr; (void)valueSizes; (void)values; (void)nValues;
    return none_of3(instance, n, "Binary");
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues)
{
    (void)vr; (void)valueSizes; (void)values; (void)nValues;
    return none_of3(instance, n, "Binary");
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                        fmi3Clock values[])
{
    (void)vr; (void)values;
    return none_of3(instance, n, "Clock");
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                        const fmi3Clock values[])
{
    (void)vr; (void)values;
    return none_of3(instance, n, "Clock");
}

/* -- co-simulation ------------------------------------------------------------------------ */
fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    fmi2Status s;
    fmi2Real t;
    if (instance == NULL)
        return fmi3Error;
    s = fmi2DoStep(INNER(instance), currentCommunicationPoint, communicationStepSize,
                   noSetFMUStatePriorToCurrentPoint);
    if (eventHandlingNeeded != NULL)
        *eventHandlingNeeded = fmi3False;
    if (terminateSimulation != NULL)
        *terminateSimulation = fmi3False;
    if (earlyReturn != NULL)
        *earlyReturn = fmi3False;
    if (lastSuccessfulTime != NULL && fmi2GetRealStatus(INNER(instance), fmi2LastSuccessfulTime,
                                                        &t) == fmi2OK)
        *lastSuccessfulTime = t;
    return status3(s);
}

/* -- what this FMU does not declare: an error with a message ------------------------------- */
#define UNSUPPORTED(fn, ...)                                                                 \
    fmi3Status fn(fmi3Instance instance, __VA_ARGS__) { return unsupported3(instance, #fn); }
#define UNSUPPORTED0(fn)                                                                     \
    fmi3Status fn(fmi3Instance instance) { return unsupported3(instance, #fn); }

UNSUPPORTED0(fmi3EnterEventMode)
UNSUPPORTED0(fmi3EnterStepMode)
UNSUPPORTED0(fmi3EnterConfigurationMode)
UNSUPPORTED0(fmi3ExitConfigurationMode)
UNSUPPORTED0(fmi3EvaluateDiscreteStates)
UNSUPPORTED0(fmi3EnterContinuousTimeMode)
UNSUPPORTED(fmi3GetNumberOfVariableDependencies, fmi3ValueReference vr, size_t *n)
UNSUPPORTED(fmi3GetVariableDependencies, fmi3ValueReference dependent, size_t e1[],
            fmi3ValueReference independents[], size_t e2[], fmi3DependencyKind kinds[], size_t n)
UNSUPPORTED(fmi3GetFMUState, fmi3FMUState *state)
UNSUPPORTED(fmi3SetFMUState, fmi3FMUState state)
UNSUPPORTED(fmi3FreeFMUState, fmi3FMUState *state)
UNSUPPORTED(fmi3SerializedFMUStateSize, fmi3FMUState state, size_t *size)
UNSUPPORTED(fmi3SerializeFMUState, fmi3FMUState state, fmi3Byte bytes[], size_t size)
UNSUPPORTED(fmi3DeserializeFMUState, const fmi3Byte bytes[], size_t size, fmi3FMUState *state)
UNSUPPORTED(fmi3GetDirectionalDerivative, const fmi3ValueReference unknowns[], size_t nu,
            const fmi3ValueReference knowns[], size_t nk, const fmi3Float64 seed[], size_t ns,
            fmi3Float64 sensitivity[], size_t nsens)
UNSUPPORTED(fmi3GetAdjointDerivative, const fmi3ValueReference unknowns[], size_t nu,
            const fmi3ValueReference knowns[], size_t nk, const fmi3Float64 seed[], size_t ns,
            fmi3Float64 sensitivity[], size_t nsens)
UNSUPPORTED(fmi3GetIntervalDecimal, const fmi3ValueReference vr[], size_t n,
            fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
UNSUPPORTED(fmi3GetIntervalFraction, const fmi3ValueReference vr[], size_t n,
            fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
UNSUPPORTED(fmi3GetShiftDecimal, const fmi3ValueReference vr[], size_t n, fmi3Float64 shifts[])
UNSUPPORTED(fmi3GetShiftFraction, const fmi3ValueReference vr[], size_t n,
            fmi3UInt64 counters[], fmi3UInt64 resolutions[])
UNSUPPORTED(fmi3SetIntervalDecimal, const fmi3ValueReference vr[], size_t n,
            const fmi3Float64 intervals[])
UNSUPPORTED(fmi3SetIntervalFraction, const fmi3ValueReference vr[], size_t n,
            const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
UNSUPPORTED(fmi3SetShiftDecimal, const fmi3ValueReference vr[], size_t n,
            const fmi3Float64 shifts[])
UNSUPPORTED(fmi3SetShiftFraction, const fmi3ValueReference vr[], size_t n,
            const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
UNSUPPORTED(fmi3UpdateDiscreteStates, fmi3Boolean *needUpdate, fmi3Boolean *terminate,
            fmi3Boolean *nominalsChanged, fmi3Boolean *valuesChanged,
            fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime)
UNSUPPORTED(fmi3CompletedIntegratorStep, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
            fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
UNSUPPORTED(fmi3SetTime, fmi3Float64 time)
UNSUPPORTED(fmi3SetContinuousStates, const fmi3Float64 x[], size_t n)
UNSUPPORTED(fmi3GetContinuousStateDerivatives, fmi3Float64 dx[], size_t n)
UNSUPPORTED(fmi3GetEventIndicators, fmi3Float64 z[], size_t n)
UNSUPPORTED(fmi3GetContinuousStates, fmi3Float64 x[], size_t n)
UNSUPPORTED(fmi3GetNominalsOfContinuousStates, fmi3Float64 nominals[], size_t n)
UNSUPPORTED(fmi3GetNumberOfEventIndicators, size_t *n)
UNSUPPORTED(fmi3GetNumberOfContinuousStates, size_t *n)
UNSUPPORTED(fmi3GetOutputDerivatives, const fmi3ValueReference vr[], size_t n,
            const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues)
UNSUPPORTED(fmi3ActivateModelPartition, fmi3ValueReference clock, fmi3Float64 activationTime)
