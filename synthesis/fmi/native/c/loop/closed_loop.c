/* closed_loop.c -- the binary of a closed-loop FMU (FMI 2.0 co-simulation): a plant FMU and a
 * controller FMU, both FMI 2.0 co-simulation binaries extracted in the closed loop's resources/,
 * loaded (dlopen) and flown as one FMU that accepts any communication step.
 *
 * resources/loop.txt (written by synthesis/fmi/containers.py) says what to load and how:
 *   name NAME                 the closed loop's model name (the prefix of its messages)
 *   period T                  the controller's sample period [s] (the wiring's step)
 *   component ROLE PATH IDENT GUID    resources/PATH/binaries/linux64/IDENT.so, 0 = plant first
 *   var VR TYPE COMP CVR KIND [START] closed-loop variable VR = variable CVR of component COMP;
 *                                      KIND p: a parameter (settable), o: an output
 *   periodvar VR              the closed loop's parameter that sets T (sample_period)
 *   conn TYPE SRC SVR DST DVR          a connection, in the order they are copied
 * TYPE is R (Real), I (Integer) or B (Boolean); value reference 0 is the closed loop's time.
 *
 * The master algorithm is the package's (synthesis/fmi/closed_loop.py and master/master.c):
 * at a sample instant s_k = t0 + k T the connections are copied, plant -> controller first
 * (u_k = phi(y(s_k))), and u_k is held until the next sample (zero-order hold); the plant is
 * stepped to the next sample instant or the end of the host's step, whichever comes first; the
 * controller is stepped over its whole period [s_k, s_{k+1}] when the plant reaches s_{k+1}.
 * A whole period [s_k, s_{k+1}] is stepped with T itself, as the masters step it; another
 * piece that is the host's whole step with the host's (t, h), else with what is left.  So at
 * h = T the components see exactly the calls of the master and of fmpy's container FMU: the
 * same numbers bit for bit.  sample_period = 0
 * (the controller's "at every communication point") samples at the loop's own step, the
 * communication step of fmpy's container.
 *
 * Errors and warnings of the components are passed on to the host's logger whatever loggingOn
 * says (the components filter their own debug messages), prefixed with the component's role;
 * the closed loop logs its own errors always. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "loop.h"

/* -- logging ------------------------------------------------------------------------------ */

/* Pass one message to the host, as the format itself with no conversion left in it (hosts
 * that ignore the variadic arguments, fmpy, show it as it is). */
static void host_log(Loop *L, fmi2Status status, const char *category, char *msg)
{
    if (L == NULL || L->host.logger == NULL)
        return;
    for (char *p = msg; *p; p++)
        if (*p == '%')
            *p = '?';
    L->host.logger(L->host.componentEnvironment, L->name ? L->name : "", status, category,
                   msg);
}

void loop_error(Loop *L, const char *fmt, ...)
{
    char text[900], msg[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    snprintf(msg, sizeof msg, "%s: %s", L->model[0] ? L->model : "closed loop", text);
    host_log(L, fmi2Error, "logStatusError", msg);
}

/* The components' logger: every message they send, prefixed with the component's role and
 * model identifier ("plant (Reentry): ..."; a prefix "<instance>: " or "<identifier>: " of
 * their own is dropped). */
static void part_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                        fmi2String category, fmi2String message, ...)
{
    Loop *L = (Loop *)env;
    char text[900], msg[2048];
    const char *body = text, *ident = "?";
    va_list ap;
    va_start(ap, message);
    vsnprintf(text, sizeof text, message ? message : "", ap);
    va_end(ap);
    for (int i = 0; i < 2; i++)
        if (instance && strcmp(instance, L->part[i].role) == 0)
            ident = L->part[i].ident;
    for (int i = 0; i < 2; i++) {
        const char *prefix = i == 0 ? (instance ? instance : "") : ident;
        size_t n = strlen(prefix);
        if (n > 0 && strncmp(body, prefix, n) == 0 && body[n] == ':' && body[n + 1] == ' ')
            body += n + 2;
    }
    snprintf(msg, sizeof msg, "%s (%s): %s", instance ? instance : "?", ident, body);
    host_log(L, status, category ? category : "logAll", msg);
}

/* -- set-up --------------------------------------------------------------------------------- */

/* The folder of a file URI ("file:///a/b", "file:/a/b", "file://localhost/a/b"), decoded. */
static int uri_path(const char *uri, char *out, size_t size)
{
    size_t n = 0;
    if (uri == NULL)
        return 1;
    if (strncmp(uri, "file://localhost/", 17) == 0)
        uri += 16;
    else if (strncmp(uri, "file:///", 8) == 0)
        uri += 7;
    else if (strncmp(uri, "file:/", 6) == 0)
        uri += 5;
    for (; *uri && n + 1 < size; uri++) {
        unsigned int c;
        if (uri[0] == '%' && uri[1] && uri[2] && sscanf(uri + 1, "%2x", &c) == 1)
            out[n++] = (char)c, uri += 2;
        else
            out[n++] = *uri;
    }
    out[n] = 0;
    while (n > 1 && out[n - 1] == '/')
        out[--n] = 0;
    return 0;
}

static int parse_line(Loop *L, char *line, int *nparts)
{
    char word[32], type[4];
    if (sscanf(line, "%31s", word) != 1 || word[0] == '#')
        return 0;
    if (strcmp(word, "name") == 0)
        return sscanf(line, "%*s %127s", L->model) != 1;
    if (strcmp(word, "period") == 0)
        return sscanf(line, "%*s %lf", &L->period_default) != 1;
    if (strcmp(word, "periodvar") == 0)
        return sscanf(line, "%*s %ld", &L->period_vr) != 1;
    if (strcmp(word, "component") == 0) {
        Part *p;
        if (*nparts >= 2)
            return 1;
        p = &L->part[(*nparts)++];
        return sscanf(line, "%*s %31s %255s %255s %199s", p->role, p->path, p->ident,
                      p->guid) != 4;
    }
    if (strcmp(word, "var") == 0) {
        LoopVar *v = &L->vars[L->nvars++];
        char kind[4];
        int n = sscanf(line, "%*s %u %3s %d %u %3s %63s", &v->vr, type, &v->comp, &v->cvr,
                       kind, v->start);
        v->type = type[0], v->settable = kind[0] == 'p', v->has_start = n == 6;
        return n < 5 || v->comp < 0 || v->comp > 1;
    }
    if (strcmp(word, "conn") == 0) {
        LoopConn *c = &L->conns[L->nconns++];
        int n = sscanf(line, "%*s %3s %d %u %d %u", type, &c->src, &c->svr, &c->dst, &c->dvr);
        c->type = type[0];
        return n != 5 || c->src < 0 || c->src > 1 || c->dst < 0 || c->dst > 1;
    }
    return 1;
}

static int read_config(Loop *L, const char *folder)
{
    char path[LOOP_PATH_MAX + 16], line[1024];
    size_t lines = 0;
    int nparts = 0, bad = 0;
    FILE *f;
    snprintf(path, sizeof path, "%s/loop.txt", folder);
    if ((f = fopen(path, "r")) == NULL) {
        loop_error(L, "cannot read %s", path);
        return 1;
    }
    while (fgets(line, sizeof line, f) != NULL)
        lines++;
    rewind(f);
    L->vars = calloc(lines + 1, sizeof *L->vars);
    L->conns = calloc(lines + 1, sizeof *L->conns);
    L->period_vr = -1;
    if (L->vars == NULL || L->conns == NULL) {
        fclose(f);
        loop_error(L, "out of memory");
        return 1;
    }
    for (size_t i = 1; fgets(line, sizeof line, f) != NULL; i++)
        if (!bad && parse_line(L, line, &nparts)) {
            loop_error(L, "%s line %lu cannot be read: %s", path, (unsigned long)i, line);
            bad = 1;
        }
    fclose(f);
    if (!bad && nparts != 2) {
        loop_error(L, "%s names %d components, not 2", path, nparts);
        bad = 1;
    }
    return bad;
}

#define LOOP_SYM(field, name)                                                       \
    if ((*(void **)&p->field = dlsym(p->lib, name)) == NULL) {                       \
        loop_error(L, "the %s library %s has no %s", p->role, file, name);            \
        return 1;                                                                     \
    }

static int load_part(Loop *L, Part *p, const char *folder, fmi2Boolean logging)
{
    char file[LOOP_PATH_MAX * 2], res[LOOP_PATH_MAX * 2];
    snprintf(file, sizeof file, "%s/%s/binaries/linux64/%s.so", folder, p->path, p->ident);
    if ((p->lib = dlopen(file, RTLD_NOW | RTLD_LOCAL)) == NULL) {
        loop_error(L, "cannot load the %s: %s", p->role, dlerror());
        return 1;
    }
    LOOP_SYM(instantiate, "fmi2Instantiate") LOOP_SYM(free_instance, "fmi2FreeInstance")
    LOOP_SYM(debug_logging, "fmi2SetDebugLogging") LOOP_SYM(setup, "fmi2SetupExperiment")
    LOOP_SYM(enter, "fmi2EnterInitializationMode")
    LOOP_SYM(exit_init, "fmi2ExitInitializationMode") LOOP_SYM(terminate, "fmi2Terminate")
    LOOP_SYM(reset, "fmi2Reset") LOOP_SYM(get_real, "fmi2GetReal")
    LOOP_SYM(get_int, "fmi2GetInteger") LOOP_SYM(get_bool, "fmi2GetBoolean")
    LOOP_SYM(set_real, "fmi2SetReal") LOOP_SYM(set_int, "fmi2SetInteger")
    LOOP_SYM(set_bool, "fmi2SetBoolean") LOOP_SYM(step, "fmi2DoStep")
    snprintf(res, sizeof res, "file://%s/%s/resources", folder, p->path);
    p->c = p->instantiate(p->role, fmi2CoSimulation, p->guid, res, &L->cb, fmi2False, logging);
    if (p->c == NULL) {
        loop_error(L, "fmi2Instantiate of the %s (%s) failed", p->role, p->ident);
        return 1;
    }
    return 0;
}

/* -- values --------------------------------------------------------------------------------- */

/* The start values of the closed loop's variables, set into the components (as fmpy's
 * container does after instantiation and reset); the sample period back to its start. */
static fmi2Status apply_starts(Loop *L)
{
    fmi2Status worst = fmi2OK;
    L->T = L->period_default;
    for (size_t i = 0; i < L->nvars; i++) {
        LoopVar *v = &L->vars[i];
        fmi2Real r;
        fmi2Integer n;
        fmi2Status st;
        if (!v->has_start)
            continue;
        if (v->type == 'R')
            r = strtod(v->start, NULL), st = set_one(&L->part[v->comp], 'R', v->cvr, &r);
        else
            n = (fmi2Integer)(v->type == 'B' ? strcmp(v->start, "true") == 0
                                             : strtol(v->start, NULL, 10)),
            st = set_one(&L->part[v->comp], v->type, v->cvr, &n);
        if ((long)v->vr == L->period_vr)
            L->T = v->type == 'R' ? r : (double)n;
        worst = st > worst ? st : worst;
    }
    return worst;
}

/* Copy the connections (in their order: plant -> controller, then controller -> plant). */
static fmi2Status exchange(Loop *L)
{
    for (size_t i = 0; i < L->nconns; i++) {
        LoopConn *c = &L->conns[i];
        union { fmi2Real r; fmi2Integer i; fmi2Boolean b; } value;
        if (get_one(&L->part[c->src], c->type, c->svr, &value) > fmi2Warning
            || set_one(&L->part[c->dst], c->type, c->dvr, &value) > fmi2Warning) {
            loop_error(L, "copying %s value reference %u to the %s at t = %.17g s failed",
                       L->part[c->src].role, c->svr, L->part[c->dst].role, L->t);
            return fmi2Error;
        }
    }
    return fmi2OK;
}
/* -- the FMI functions ------------------------------------------------------------------------ */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

void fmi2FreeInstance(fmi2Component comp)
{
    Loop *L = (Loop *)comp;
    if (L == NULL)
        return;
    for (int i = 0; i < 2; i++) {
        if (L->part[i].c != NULL)
            L->part[i].free_instance(L->part[i].c);
        if (L->part[i].lib != NULL)
            dlclose(L->part[i].lib);
    }
    free(L->vars), free(L->conns), free(L->name), free(L);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String guid,
                              fmi2String resourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    char folder[LOOP_PATH_MAX];
    Loop *L = calloc(1, sizeof *L);
    (void)guid;
    (void)visible;
    if (L == NULL)
        return NULL;
    if (functions != NULL)
        L->host = *functions;
    L->name = strdup(instanceName ? instanceName : "closed loop");
    L->cb.logger = part_logger;
    L->cb.allocateMemory = calloc;
    L->cb.freeMemory = free;
    L->cb.componentEnvironment = L;
    if (fmuType != fmi2CoSimulation)
        loop_error(L, "this FMU supports co-simulation only");
    else if (uri_path(resourceLocation, folder, sizeof folder))
        loop_error(L, "no resource location given (the folder of resources/loop.txt)");
    else if (read_config(L, folder) == 0 && load_part(L, &L->part[0], folder, loggingOn) == 0
             && load_part(L, &L->part[1], folder, loggingOn) == 0
             && apply_starts(L) <= fmi2Warning) {
        L->mode = M_INSTANTIATED;
        return L;
    }
    fmi2FreeInstance(L);
    return NULL;
}

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t n,
                               const fmi2String categories[])
{
    Loop *L = (Loop *)comp;
    fmi2Status a, b;
    if (L == NULL)
        return fmi2Error;
    a = L->part[0].debug_logging(L->part[0].c, loggingOn, n, categories);
    b = L->part[1].debug_logging(L->part[1].c, loggingOn, n, categories);
    return a > b ? a : b;
}

/* Both components' function `f`, plant first; an error is logged and ends in M_ERROR. */
#define BOTH(L, f, what, ...)                                                            \
    do {                                                                                 \
        for (int i_ = 0; i_ < 2; i_++) {                                                 \
            fmi2Status st_ = (L)->part[i_].f((L)->part[i_].c, ##__VA_ARGS__);            \
            if (st_ > fmi2Warning) {                                                     \
                loop_error(L, "%s %s failed", (L)->part[i_].role, what);                 \
                (L)->mode = M_ERROR;                                                     \
                return st_;                                                              \
            }                                                                            \
        }                                                                                \
    } while (0)

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    Loop *L = (Loop *)comp;
    if (L == NULL)
        return fmi2Error;
    L->t0 = L->t = L->s = startTime;
    L->stop_defined = stopTimeDefined, L->stop = stopTime;
    BOTH(L, setup, "fmi2SetupExperiment", toleranceDefined, tolerance, startTime,
         stopTimeDefined, stopTime);
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp)
{
    Loop *L = (Loop *)comp;
    if (L == NULL)
        return fmi2Error;
    BOTH(L, enter, "fmi2EnterInitializationMode");
    L->mode = M_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp)
{
    Loop *L = (Loop *)comp;
    if (L == NULL)
        return fmi2Error;
    if (!(L->T >= 0.0 && L->T < INFINITY)) {
        loop_error(L, "sample_period must be finite and >= 0 (0: at the loop's step), got %g s",
                   L->T);
        L->mode = M_ERROR;
        return fmi2Error;
    }
    BOTH(L, exit_init, "fmi2ExitInitializationMode");
    L->t = L->s = L->t0, L->k = 0;
    if (exchange(L) > fmi2Warning) {
        L->mode = M_ERROR;
        return fmi2Error;
    }
    L->mode = M_STEP;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component comp)
{
    Loop *L = (Loop *)comp;
    if (L == NULL)
        return fmi2Error;
    BOTH(L, terminate, "fmi2Terminate");
    L->mode = M_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp)
{
    Loop *L = (Loop *)comp;
    if (L == NULL)
        return fmi2Error;
    BOTH(L, reset, "fmi2Reset");
    L->mode = M_INSTANTIATED;
    L->t0 = L->t = L->s = 0.0, L->k = 0;
    return apply_starts(L);
}

/* -- doStep ------------------------------------------------------------------------------------ */

static double tolerance(double T, double t)
{
    return 1e-9 * fmax(fmax(T, fabs(t)), 1e-3);
}

/* One piece: the plant from L->t to the next sample instant or to t + h, whichever comes first;
 * at a sample instant the controller's period, then the connections.  Returns 1 when the host's
 * step is done, 0 when another piece follows, -1 on an error. */
static int piece(Loop *L, double t, double h, fmi2Status *status)
{
    const double T = L->T > 0.0 ? L->T : L->period_default;
    const double target = t + h, start = L->t;
    const double next = T > 0.0 ? L->t0 + (double)(L->k + 1) * T : target;
    const double tol = tolerance(T, next);
    double end, dt;
    int sample;
    if (next < target - tol)
        end = next, sample = 1;
    else
        end = target, sample = fabs(next - target) <= tol
                               || (L->stop_defined && fabs(L->stop - target) <= tol);
    /* a whole period: T, as the masters step (fmpy simulate's h = (n + 1) dt - n dt is not
       exactly T); else the host's own step, or what is left of it */
    dt = start == L->s && T > 0.0 && fabs(next - end) <= tol ? T
         : start == t && end == target ? h : end - start;
    if ((*status = L->part[0].step(L->part[0].c, start, dt, fmi2True)) > fmi2Warning) {
        loop_error(L, "plant fmi2DoStep at t = %.17g s (step %.17g s) failed", start, dt);
        return -1;
    }
    L->t = end;
    if (sample) {
        const double dc = start == L->s ? dt : fabs(end - L->s - T) <= tol ? T : end - L->s;
        if ((*status = L->part[1].step(L->part[1].c, L->s, dc, fmi2True)) > fmi2Warning) {
            loop_error(L, "controller fmi2DoStep at t = %.17g s (step %.17g s) failed", L->s,
                       dc);
            return -1;
        }
        L->k++, L->s = end;
        if ((*status = exchange(L)) > fmi2Warning)
            return -1;
    }
    return end == target;
}

fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior)
{
    Loop *L = (Loop *)comp;
    fmi2Status status = fmi2OK;
    int done = 0;
    (void)noSetPrior;
    if (L == NULL)
        return fmi2Error;
    if (L->mode != M_STEP) {
        loop_error(L, "fmi2DoStep before fmi2ExitInitializationMode (or after an error)");
        return fmi2Error;
    }
    if (!(h > 0.0 && h < INFINITY)) {
        loop_error(L, "the communication step must be finite and > 0, got %g s", h);
        return fmi2Error;
    }
    if (fabs(t - L->t) > tolerance(L->T > 0.0 ? L->T : L->period_default, t)) {
        loop_error(L, "fmi2DoStep from t = %.17g s, but the closed loop is at t = %.17g s", t,
                   L->t);
        return fmi2Error;
    }
    if (L->s == L->t)
        L->s = t;            /* the host's own value of the same instant */
    L->t = t;
    while (!done) {
        if ((done = piece(L, t, h, &status)) < 0) {
            L->mode = M_ERROR;
            return status > fmi2Error ? status : fmi2Error;
        }
    }
    return fmi2OK;
}
