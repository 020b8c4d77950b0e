/* fmi2_cs.c -- the generic FMI 2.0 co-simulation wrapper of every descent-fmus native FMU.
 *
 * Written once; a native FMU is this file + its model (model.c, see native_model.h), compiled
 * into one shared library.  Everything the model does not decide lives here: instances, the
 * FMI 2.0 state machine (instantiated -> initialisation -> stepping -> terminated), get/set by
 * value reference with the causality rules, doStep, reset and logging.
 *
 * Outputs are computed lazily: any set or step marks them stale, and the next read of an output
 * recomputes them from the current inputs, parameters and time (a static law has direct
 * feed-through, so a master reading u right after setting x gets phi(x)).
 *
 * Errors (an unknown value reference, setting an output, a fixed parameter set while stepping,
 * an invalid parameter at exitInitializationMode) return fmi2Error and are logged through the
 * host's logger with category logStatusError; the instance stays usable after fmi2Reset.
 *
 * Start values: those compiled into the model (MODEL_*_START), unless the FMU's resources hold
 * start_values.txt -- lines "<value reference> <value> [name]", every other line ignored --
 * whose values replace them for every instance (instantiation and fmi2Reset).  So one compiled
 * model (the network-operator interpreter) ships as many FMUs as there are laws, each with its
 * law's start values in modelDescription.xml and in that file (synthesis/fmi/native/builders/
 * law_fmu.py writes both); a malformed file fails the instantiation with a logged message.
 *
 * A stateful model (native_model.h, optional hooks) gets its own zeroed memory per instance and
 * is told when its start values are set (instantiation, reset), when its parameters passed the
 * check (entering and leaving initialisation, as the pythonfmu slaves prepare) and when it
 * steps, and may report that preparing or stepping failed (fmi2Error); the defaults below do
 * nothing.
 *
 * descent-fmus (MIT licence).
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "native_model.h"
#include "py_repr.h"

/* -- default hooks: a model without a state of its own defines none of them ---------------- */
#if defined(_MSC_VER)
#define DEFAULT_HOOK(name) descent_default_##name
#pragma comment(linker, "/alternatename:model_data_size=descent_default_model_data_size")
#pragma comment(linker, "/alternatename:model_reset=descent_default_model_reset")
#pragma comment(linker, "/alternatename:model_prepare=descent_default_model_prepare")
#pragma comment(linker, "/alternatename:model_step=descent_default_model_step")
#pragma comment(linker, "/alternatename:model_failure=descent_default_model_failure")
#else
#define DEFAULT_HOOK(name) __attribute__((weak)) name
#endif

size_t DEFAULT_HOOK(model_data_size)(void) { return 0; }

void DEFAULT_HOOK(model_reset)(ModelState *s) { (void)s; }

void DEFAULT_HOOK(model_prepare)(ModelState *s) { (void)s; }

void DEFAULT_HOOK(model_step)(ModelState *s, double t, double h)
{
    (void)s;
    (void)t;
    (void)h;
}

const char *DEFAULT_HOOK(model_failure)(const ModelState *s)
{
    (void)s;
    return NULL;
}

typedef enum { ST_INSTANTIATED, ST_INIT, ST_STEP, ST_TERMINATED, ST_ERROR } Mode;

typedef struct {
    ModelState s;
    Mode mode;
    int stale;                      /* outputs must be recomputed */
    int sampling;                   /* sample_period > 0 */
    int holding;                    /* between two samples: outputs held, inputs ignored */
    int sampled_once;               /* sample_t is set */
    double sample_t;                /* time of the last sample [s] */
    int logging;
    char *name;
    double *r_start;                /* the start values (compiled, or from the resources) */
    int *i_start;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
} Instance;

/* log an error through the host's logger: "<instance>: <message>" */
static void log_error(Instance *c, const char *fmt, ...)
{
    char msg[600], text[512];
    va_list args;
    if (c == NULL || c->logger == NULL)
        return;
    va_start(args, fmt);
    vsnprintf(text, sizeof text, fmt, args);
    va_end(args);
    snprintf(msg, sizeof msg, "%s: %s", c->name, text);
    /* the message is passed as the format itself: hosts that ignore the variadic arguments
       (fmpy) show it as it is; so it must not contain a conversion */
    for (char *p = msg; *p; p++)
        if (*p == '%')
            *p = '?';
    c->logger(c->env, c->name, fmi2Error, "logStatusError", msg);
}

static void set_starts(Instance *c)
{
    memcpy(c->s.r, c->r_start, sizeof(double) * (size_t)MODEL_N_REAL);
    if (MODEL_N_INTEGER > 0)
        memcpy(c->s.i, c->i_start, sizeof(int) * (size_t)MODEL_N_INTEGER);
    if (c->s.data != NULL)
        memset(c->s.data, 0, model_data_size());
    c->s.time = 0.0;
    c->s.last_step = 0.0;
    c->stale = 1;
    c->sampling = c->holding = c->sampled_once = 0;
    c->sample_t = 0.0;
    model_reset(&c->s);
}

/* the file <resources>/<name> of the resource location (a file URI: file:///dir, file:/dir,
   %XX escapes) in path (size bytes); 0 if the location is no usable file URI */
static int resource_path(const char *location, const char *name, char *path, size_t size)
{
    const char *p;
    size_t n = 0;
    if (location == NULL || strncmp(location, "file:", 5) != 0)
        return 0;
    p = location + 5;
    if (strncmp(p, "///", 3) == 0)
        p += 2;
    else if (strncmp(p, "//localhost/", 12) == 0)
        p += 11;
#if defined(_WIN32)
    if (p[0] == '/' && p[1] != '\0' && p[2] == ':')
        p++;                                    /* /C:/dir -> C:/dir */
#endif
    for (; *p && n + 1 < size; p++) {
        unsigned int byte;
        if (p[0] == '%' && p[1] && p[2] && sscanf(p + 1, "%2x", &byte) == 1) {
            path[n++] = (char)byte;
            p += 2;
        } else
            path[n++] = *p;
    }
    if (n > 0 && path[n - 1] != '/')
        path[n++] = '/';
    if (n + strlen(name) + 1 > size)
        return 0;
    strcpy(path + n, name);
    return 1;
}

/* the start values of c: the compiled ones, replaced by those of <resources>/start_values.txt
   if the FMU has that file; 0 and a logged message if the file is malformed */
static int load_starts(Instance *c, const char *location)
{
    char path[4096], line[512];
    FILE *f;
    int row = 0, ok = 1;
    memcpy(c->r_start, MODEL_REAL_START, sizeof(double) * (size_t)MODEL_N_REAL);
    if (MODEL_N_INTEGER > 0)
        memcpy(c->i_start, MODEL_INTEGER_START, sizeof(int) * (size_t)MODEL_N_INTEGER);
    if (!resource_path(location, "start_values.txt", path, sizeof path)
        || (f = fopen(path, "r")) == NULL)
        return 1;
    while (ok && fgets(line, sizeof line, f) != NULL) {
        char *end, *p = line;
        unsigned long vr;
        row++;
        while (*p == ' ' || *p == '\t')
            p++;
        if (*p < '0' || *p > '9')
            continue;                           /* a comment or an empty line */
        vr = strtoul(p, &end, 10);
        if (vr < (unsigned long)MODEL_N_REAL) {
            double v = strtod(end, &p);
            ok = p != end;
            c->r_start[vr] = v;
        } else if (vr < (unsigned long)(MODEL_N_REAL + MODEL_N_INTEGER)) {
            long v = strtol(end, &p, 10);
            ok = p != end;
            c->i_start[vr - (unsigned long)MODEL_N_REAL] = (int)v;
        } else
            ok = 0;
        if (ok && vr < (unsigned long)MODEL_N_REAL && MODEL_REAL_KIND[vr] == KIND_OUTPUT)
            ok = 0;                             /* outputs have no start value */
    }
    fclose(f);
    if (!ok)
        log_error(c, "resources/start_values.txt line %d: need \"<value reference> <value>\" "
                  "of a parameter or input", row);
    return ok;
}

/* -- common functions ------------------------------------------------------------------- */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t n,
                               const fmi2String categories[])
{
    (void)n;
    (void)categories;
    if (comp == NULL)
        return fmi2Error;
    ((Instance *)comp)->logging = loggingOn;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String guid,
                              fmi2String resourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    Instance tmp, *c;
    (void)visible;
    memset(&tmp, 0, sizeof tmp);
    tmp.name = (char *)(instanceName ? instanceName : "");
    if (functions != NULL) {
        tmp.logger = functions->logger;
        tmp.env = functions->componentEnvironment;
    }
    if (fmuType != fmi2CoSimulation) {
        log_error(&tmp, "this FMU supports co-simulation only");
        return NULL;
    }
    if (guid == NULL || strcmp(guid, MODEL_GUID) != 0) {
        log_error(&tmp, "wrong GUID %s, expected %s (the modelDescription.xml of another FMU?)",
                  guid ? guid : "(null)", MODEL_GUID);
        return NULL;
    }
    c = (Instance *)calloc(1, sizeof(Instance));
    if (c == NULL)
        return NULL;
    *c = tmp;
    c->name = (char *)malloc(strlen(tmp.name) + 1);
    c->s.r = (double *)calloc((size_t)MODEL_N_REAL + 1, sizeof(double));
    c->s.i = (int *)calloc((size_t)MODEL_N_INTEGER + 1, sizeof(int));
    c->s.data = model_data_size() > 0 ? calloc(1, model_data_size()) : NULL;
    c->r_start = (double *)calloc((size_t)MODEL_N_REAL + 1, sizeof(double));
    c->i_start = (int *)calloc((size_t)MODEL_N_INTEGER + 1, sizeof(int));
    if (c->name != NULL)
        strcpy(c->name, tmp.name);
    if (c->name == NULL || c->s.r == NULL || c->s.i == NULL || c->r_start == NULL
        || c->i_start == NULL || (model_data_size() > 0 && c->s.data == NULL)
        || !load_starts(c, resourceLocation)) {
        fmi2FreeInstance(c);
        return NULL;
    }
    c->logging = loggingOn;
    c->mode = ST_INSTANTIATED;
    set_starts(c);
    return c;
}

void fmi2FreeInstance(fmi2Component comp)
{
    Instance *c = (Instance *)comp;
    if (c == NULL)
        return;
    free(c->s.r);
    free(c->s.i);
    free(c->s.data);
    free(c->r_start);
    free(c->i_start);
    free(c->name);
    free(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    Instance *c = (Instance *)comp;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (c == NULL)
        return fmi2Error;
    if (c->mode != ST_INSTANTIATED) {
        log_error(c, "fmi2SetupExperiment is allowed only after instantiation or reset");
        return fmi2Error;
    }
    c->s.time = startTime;
    c->stale = 1;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp)
{
    Instance *c = (Instance *)comp;
    if (c == NULL)
        return fmi2Error;
    if (c->mode != ST_INSTANTIATED) {
        log_error(c, "fmi2EnterInitializationMode is allowed only after instantiation or "
                  "reset");
        return fmi2Error;
    }
    c->mode = ST_INIT;
    c->stale = 1;
    /* the start values are set by now: prepare with them (a container reads outputs during
       initialisation); invalid values are reported at fmi2ExitInitializationMode */
    if (model_check(&c->s) == NULL)
        model_prepare(&c->s);
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp)
{
    Instance *c = (Instance *)comp;
    const char *bad;
    if (c == NULL)
        return fmi2Error;
    if (c->mode != ST_INIT) {
        log_error(c, "fmi2ExitInitializationMode outside initialisation mode");
        return fmi2Error;
    }
    bad = model_check(&c->s);
    if (bad == NULL && MODEL_SAMPLE_PERIOD >= 0) {
        double period = c->s.r[MODEL_SAMPLE_PERIOD];
        static char msg[120];
        char value[40];
        if (!isfinite(period) || period < 0.0) {       /* the pythonfmu controllers' words */
            snprintf(msg, sizeof msg, "parameter sample_period must be %s, got %s",
                     isfinite(period) ? ">= 0" : "finite", py_repr(period, value));
            bad = msg;
        }
        c->sampling = period > 0.0;
    }
    if (bad != NULL) {
        log_error(c, "%s", bad);
        c->mode = ST_ERROR;
        return fmi2Error;
    }
    c->holding = c->sampled_once = 0;
    c->mode = ST_STEP;
    c->stale = 1;
    model_prepare(&c->s);
    bad = model_failure(&c->s);
    if (bad != NULL) {
        log_error(c, "%s", bad);
        c->mode = ST_ERROR;
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component comp)
{
    Instance *c = (Instance *)comp;
    if (c == NULL)
        return fmi2Error;
    c->mode = ST_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp)
{
    Instance *c = (Instance *)comp;
    if (c == NULL)
        return fmi2Error;
    set_starts(c);
    c->mode = ST_INSTANTIATED;
    return fmi2OK;
}

/* -- get / set --------------------------------------------------------------------------- */
static int real_index(Instance *c, fmi2ValueReference vr)
{
    if (vr >= (fmi2ValueReference)MODEL_N_REAL) {
        log_error(c, "no Real variable has value reference %lu", (unsigned long)vr);
        return -1;
    }
    return (int)vr;
}

static int integer_index(Instance *c, fmi2ValueReference vr)
{
    if (vr < (fmi2ValueReference)MODEL_N_REAL
        || vr >= (fmi2ValueReference)(MODEL_N_REAL + MODEL_N_INTEGER)) {
        log_error(c, "no Integer variable has value reference %lu", (unsigned long)vr);
        return -1;
    }
    return (int)vr - MODEL_N_REAL;
}

/* may a variable of this kind be set now? */
static int settable(Instance *c, unsigned char kind, fmi2ValueReference vr)
{
    if (kind == KIND_OUTPUT) {
        log_error(c, "value reference %lu is an output and cannot be set",
                  (unsigned long)vr);
        return 0;
    }
    if (kind == KIND_FIXED && c->mode != ST_INSTANTIATED && c->mode != ST_INIT) {
        log_error(c, "value reference %lu is a fixed parameter: set it before the end of "
                  "initialisation (or after fmi2Reset)", (unsigned long)vr);
        return 0;
    }
    return 1;
}

static void refresh(Instance *c)
{
    if (c->stale && !c->holding) {
        model_outputs(&c->s);
        c->stale = 0;
    }
}

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                       fmi2Real value[])
{
    Instance *c = (Instance *)comp;
    size_t k;
    if (c == NULL || (n > 0 && (vr == NULL || value == NULL)))
        return fmi2Error;
    refresh(c);
    for (k = 0; k < n; k++) {
        int j = real_index(c, vr[k]);
        if (j < 0)
            return fmi2Error;
        value[k] = c->s.r[j];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                          fmi2Integer value[])
{
    Instance *c = (Instance *)comp;
    size_t k;
    if (c == NULL || (n > 0 && (vr == NULL || value == NULL)))
        return fmi2Error;
    refresh(c);
    for (k = 0; k < n; k++) {
        int j = integer_index(c, vr[k]);
        if (j < 0)
            return fmi2Error;
        value[k] = c->s.i[j];
    }
    return fmi2OK;
}

/* Boolean and String variables: a native model has none */
static fmi2Status none_of(fmi2Component comp, size_t n, const char *type)
{
    if (n == 0)
        return fmi2OK;
    log_error((Instance *)comp, "this FMU has no %s variables", type);
    return fmi2Error;
}

fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                          fmi2Boolean value[])
{
    (void)vr;
    (void)value;
    return none_of(comp, n, "Boolean");
}

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                         fmi2String value[])
{
    (void)vr;
    (void)value;
    return none_of(comp, n, "String");
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real value[])
{
    Instance *c = (Instance *)comp;
    size_t k;
    if (c == NULL || (n > 0 && (vr == NULL || value == NULL)))
        return fmi2Error;
    for (k = 0; k < n; k++) {
        int j = real_index(c, vr[k]);
        if (j < 0 || !settable(c, MODEL_REAL_KIND[j], vr[k]))
            return fmi2Error;
        if (c->holding && MODEL_REAL_KIND[j] == KIND_INPUT)
            continue;                       /* between samples the inputs are not read */
        c->s.r[j] = value[k];
    }
    c->stale = 1;
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                          const fmi2Integer value[])
{
    Instance *c = (Instance *)comp;
    size_t k;
    if (c == NULL || (n > 0 && (vr == NULL || value == NULL)))
        return fmi2Error;
    for (k = 0; k < n; k++) {
        int j = integer_index(c, vr[k]);
        if (j < 0 || !settable(c, MODEL_INTEGER_KIND[j], vr[k]))
            return fmi2Error;
        c->s.i[j] = value[k];
    }
    c->stale = 1;
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                          const fmi2Boolean value[])
{
    (void)vr;
    (void)value;
    return none_of(comp, n, "Boolean");
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                         const fmi2String value[])
{
    (void)vr;
    (void)value;
    return none_of(comp, n, "String");
}

/* -- unsupported optional features (capability flags false in modelDescription.xml) ------- */
static fmi2Status unsupported(fmi2Component comp, const char *what)
{
    log_error((Instance *)comp, "%s is not supported by this FMU", what);
    return fmi2Error;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s)
{
    (void)s;
    return unsupported(c, "fmi2GetFMUstate");
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s)
{
    (void)s;
    return unsupported(c, "fmi2SetFMUstate");
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s)
{
    (void)s;
    return unsupported(c, "fmi2FreeFMUstate");
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n)
{
    (void)s;
    (void)n;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n)
{
    (void)s;
    (void)b;
    (void)n;
    return unsupported(c, "fmi2SerializeFMUstate");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n,
                                   fmi2FMUstate *s)
{
    (void)s;
    (void)b;
    (void)n;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz,
                                        const fmi2Real du[], fmi2Real dz[])
{
    (void)u; (void)nu; (void)z; (void)nz; (void)du; (void)dz;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr; (void)n; (void)order; (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t n, const fmi2Integer order[], fmi2Real value[])
{
    (void)vr; (void)n; (void)order; (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}

fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep"); }

/* -- stepping ---------------------------------------------------------------------------- */
fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real t, fmi2Real h,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *c = (Instance *)comp;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (c == NULL)
        return fmi2Error;
    if (c->mode != ST_STEP) {
        log_error(c, "fmi2DoStep before fmi2ExitInitializationMode (or after an error)");
        return fmi2Error;
    }
    if (!(h >= 0.0)) {
        log_error(c, "negative communication step size %g", h);
        return fmi2Error;
    }
    if (c->sampling) {
        /* sampled: hold the outputs of the last sample until a step ends sample_period or more
           after it; that step is the model's step over the whole interval since the sample */
        double t1 = t + h, elapsed;
        if (!c->sampled_once) {
            c->sample_t = t;
            c->sampled_once = 1;
        }
        if (!c->holding) {
            refresh(c);
            c->holding = 1;
        }
        elapsed = t1 - c->sample_t;
        if (elapsed < c->s.r[MODEL_SAMPLE_PERIOD] * (1.0 - 1e-9))
            return fmi2OK;
        if (c->sample_t != t) {      /* one communication step since the sample: as given */
            t = c->sample_t;
            h = elapsed;
        }
        c->sample_t = t1;
        c->holding = 0;
    }
    refresh(c);
    model_step(&c->s, t, h);
    if (model_failure(&c->s) != NULL) {
        log_error(c, "%s", model_failure(&c->s));
        c->mode = ST_ERROR;
        return fmi2Error;
    }
    c->s.time = t + h;
    if (h > 0.0)
        c->s.last_step = h;
    c->stale = 1;
    return fmi2OK;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v)
{
    (void)k;
    (void)v;
    return unsupported(c, "fmi2GetStatus");
}

fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind k, fmi2Real *v)
{
    Instance *c = (Instance *)comp;
    if (c != NULL && v != NULL && k == fmi2LastSuccessfulTime) {
        *v = c->s.time;
        return fmi2OK;
    }
    return unsupported(comp, "fmi2GetRealStatus");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v)
{
    (void)k;
    (void)v;
    return unsupported(c, "fmi2GetIntegerStatus");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v)
{
    (void)k;
    (void)v;
    return unsupported(c, "fmi2GetBooleanStatus");
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v)
{
    (void)k;
    (void)v;
    return unsupported(c, "fmi2GetStringStatus");
}
