/* master.c -- the closed-loop master of two FMI 2.0 co-simulation FMUs, in C, loaded once per
 * process and called once per flight (the evaluator's native path; also linked into the pure-C
 * benchmark).
 *
 * The master algorithm is the one of the Python master (ClosedLoop in synthesis/fmi/closed_loop.py),
 * call for call: each component is reset, its start values set (Reals then Integers), set up
 * (no tolerance, stop time defined), initialised; then on the grid t_k = k h, k = 0 .. n with
 * n = ceil(t_end / h - 1e-9): read the plant outputs y(t_k), set them as controller inputs,
 * read u_k = phi(y(t_k)), set it as plant input (at k = 0 then read the plant outputs asked
 * for at the start, DmOutputs.n0); read the stop output every check_every steps
 * (and at k = n) and end the flight when its condition holds; else doStep the plant, then the
 * controller, over [t_k, t_k + min(h, t_end - t_k)].  The same FMI calls in the same order give
 * the same numbers bit for bit.
 *
 * Every FMI status above fmi2Warning ends the flight with an error: the function returns a
 * non-zero code and dm_message() says which call failed and what the FMUs logged.
 */
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "master.h"

typedef struct {
    void *lib;
    fmi2Component c;
    const char *role;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup;
    fmi2EnterInitializationModeTYPE *enter;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2ResetTYPE *reset;
    fmi2GetRealTYPE *get_real;
    fmi2GetIntegerTYPE *get_int;
    fmi2GetBooleanTYPE *get_bool;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_int;
    fmi2DoStepTYPE *step;
} DmFmu;

struct DmMaster {
    DmFmu plant, ctrl;
    fmi2CallbackFunctions callbacks;
    char message[4096];
    size_t used;
    /* the wiring */
    size_t ny, nu;
    fmi2ValueReference *y_vr, *x_vr, *u_vr, *pu_vr;
    double *y, *u, h;
    int stop_type;                 /* 0: none, 1: Real, 2: Integer, 3: Boolean */
    int stop_op;                   /* 0: !=, 1: <=, 2: >= */
    fmi2ValueReference stop_vr;
    double stop_value;
    long check_every;
};

static void say(DmMaster *m, const char *fmt, ...)
{
    va_list ap;
    int n;
    if (m->used + 2 >= sizeof m->message)
        return;
    if (m->used > 0)
        m->message[m->used++] = ';', m->message[m->used++] = ' ', m->message[m->used] = 0;
    va_start(ap, fmt);
    n = vsnprintf(m->message + m->used, sizeof m->message - m->used, fmt, ap);
    va_end(ap);
    if (n > 0)
        m->used += (size_t)n < sizeof m->message - m->used ? (size_t)n
                                                            : sizeof m->message - m->used - 1;
}

/* The FMUs' logger: their messages are kept for the error of the flight they happen in. */
static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    DmMaster *m = (DmMaster *)env;
    char text[1024];
    va_list ap;
    (void)status;
    (void)category;
    va_start(ap, message);
    vsnprintf(text, sizeof text, message ? message : "", ap);
    va_end(ap);
    say(m, "%s: %s", instance ? instance : "?", text);
}

#define DM_SYM(f, field, name)                                                    \
    if ((*(void **)&(f)->field = dlsym((f)->lib, name)) == NULL) {              \
        say(m, "%s library has no %s", role, name);                             \
        return 1;                                                               \
    }

static int load(DmMaster *m, DmFmu *f, const char *role, const char *library,
                const char *guid, const char *resources)
{
    fmi2InstantiateTYPE *instantiate;
    f->role = role;
    if ((f->lib = dlopen(library, RTLD_NOW | RTLD_LOCAL)) == NULL) {
        say(m, "cannot load the %s library: %s", role, dlerror());
        return 1;
    }
    DM_SYM(f, free_instance, "fmi2FreeInstance")
    DM_SYM(f, setup, "fmi2SetupExperiment")
    DM_SYM(f, enter, "fmi2EnterInitializationMode")
    DM_SYM(f, exit_init, "fmi2ExitInitializationMode")
    DM_SYM(f, reset, "fmi2Reset")
    DM_SYM(f, get_real, "fmi2GetReal")
    DM_SYM(f, get_int, "fmi2GetInteger")
    DM_SYM(f, get_bool, "fmi2GetBoolean")
    DM_SYM(f, set_real, "fmi2SetReal")
    DM_SYM(f, set_int, "fmi2SetInteger")
    DM_SYM(f, step, "fmi2DoStep")
    if ((*(void **)&instantiate = dlsym(f->lib, "fmi2Instantiate")) == NULL) {
        say(m, "%s library has no fmi2Instantiate", role);
        return 1;
    }
    f->c = instantiate(role, fmi2CoSimulation, guid, resources, &m->callbacks, fmi2False,
                       fmi2False);
    if (f->c == NULL) {
        say(m, "fmi2Instantiate of the %s failed", role);
        return 1;
    }
    return 0;
}

DM_EXPORT void dm_close(DmMaster *m)
{
    DmFmu *fs[2];
    if (m == NULL)
        return;
    fs[0] = &m->plant, fs[1] = &m->ctrl;
    for (int i = 0; i < 2; i++) {
        if (fs[i]->c != NULL && fs[i]->free_instance != NULL)
            fs[i]->free_instance(fs[i]->c);
        if (fs[i]->lib != NULL)
            dlclose(fs[i]->lib);
    }
    free(m->y_vr), free(m->x_vr), free(m->u_vr), free(m->pu_vr), free(m->y), free(m->u);
    free(m);
}

/* The message of the last failure ("" if none). */
DM_EXPORT const char *dm_message(const DmMaster *m)
{
    return m->message;
}

/* Load both FMUs' libraries and instantiate them (fmi2CoSimulation, no logging).  Returns NULL
 * only if memory runs out; else check dm_message(m)[0] (a failure leaves a message). */
DM_EXPORT DmMaster *dm_open(const char *plant_library, const char *plant_guid,
                            const char *plant_resources, const char *ctrl_library,
                            const char *ctrl_guid, const char *ctrl_resources)
{
    DmMaster *m = calloc(1, sizeof *m);
    if (m == NULL)
        return NULL;
    m->callbacks.logger = logger;
    m->callbacks.allocateMemory = calloc;
    m->callbacks.freeMemory = free;
    m->callbacks.componentEnvironment = m;
    if (load(m, &m->plant, "plant", plant_library, plant_guid, plant_resources) == 0)
        load(m, &m->ctrl, "controller", ctrl_library, ctrl_guid, ctrl_resources);
    return m;
}

static fmi2ValueReference *copy_vr(const fmi2ValueReference *v, size_t n)
{
    fmi2ValueReference *out = malloc((n ? n : 1) * sizeof *out);
    if (out != NULL && n)
        memcpy(out, v, n * sizeof *out);
    return out;
}

/* The connections (plant output y_vr[i] -> controller input x_vr[i]; controller output
 * u_vr[i] -> plant input pu_vr[i]), the communication step and the stop condition. */
DM_EXPORT int dm_wire(DmMaster *m, size_t ny, const fmi2ValueReference *y_vr,
                      const fmi2ValueReference *x_vr, size_t nu, const fmi2ValueReference *u_vr,
                      const fmi2ValueReference *pu_vr, double h, int stop_type,
                      fmi2ValueReference stop_vr, int stop_op, double stop_value,
                      long check_every)
{
    m->ny = ny, m->nu = nu, m->h = h;
    m->y_vr = copy_vr(y_vr, ny), m->x_vr = copy_vr(x_vr, ny);
    m->u_vr = copy_vr(u_vr, nu), m->pu_vr = copy_vr(pu_vr, nu);
    m->y = calloc(ny ? ny : 1, sizeof(double)), m->u = calloc(nu ? nu : 1, sizeof(double));
    m->stop_type = stop_type, m->stop_vr = stop_vr, m->stop_op = stop_op;
    m->stop_value = stop_value, m->check_every = check_every < 1 ? 1 : check_every;
    if (!m->y_vr || !m->x_vr || !m->u_vr || !m->pu_vr || !m->y || !m->u) {
        say(m, "out of memory");
        return 1;
    }
    return 0;
}

#define DM_CALL(what, call)                                                       \
    if ((call) > fmi2Warning) {                                                 \
        say(m, "%s failed", what);                                              \
        return 1;                                                               \
    }

static int start(DmMaster *m, DmFmu *f, const DmValues *v, double t_end)
{
    DM_CALL(f == &m->plant ? "plant fmi2Reset" : "controller fmi2Reset", f->reset(f->c))
    if (v->nr)
        DM_CALL(f == &m->plant ? "setting the plant's Reals" : "setting the controller's Reals",
                f->set_real(f->c, v->rvr, v->nr, v->rval))
    if (v->ni)
        DM_CALL(f == &m->plant ? "setting the plant's Integers"
                               : "setting the controller's Integers",
                f->set_int(f->c, v->ivr, v->ni, v->ival))
    DM_CALL(f == &m->plant ? "plant fmi2SetupExperiment" : "controller fmi2SetupExperiment",
            f->setup(f->c, fmi2False, 0.0, 0.0, fmi2True, t_end))
    DM_CALL(f == &m->plant ? "plant fmi2EnterInitializationMode"
                           : "controller fmi2EnterInitializationMode", f->enter(f->c))
    DM_CALL(f == &m->plant ? "plant fmi2ExitInitializationMode"
                           : "controller fmi2ExitInitializationMode", f->exit_init(f->c))
    return 0;
}

static int stop_holds(DmMaster *m, int *holds)
{
    fmi2Real r = 0.0;
    fmi2Integer i = 0;
    fmi2Boolean b = 0;
    double v;
    fmi2Status st;
    if (m->stop_type == 1)
        st = m->plant.get_real(m->plant.c, &m->stop_vr, 1, &r), v = r;
    else if (m->stop_type == 2)
        st = m->plant.get_int(m->plant.c, &m->stop_vr, 1, &i), v = (double)i;
    else
        st = m->plant.get_bool(m->plant.c, &m->stop_vr, 1, &b), v = (double)b;
    *holds = m->stop_op == 0 ? v != m->stop_value
             : m->stop_op == 1 ? v <= m->stop_value : v >= m->stop_value;
    return st > fmi2Warning;
}

/* One flight from t = 0 to t_end (see the file's comment); *steps: the steps taken, *stopped:
 * whether the stop condition ended it; the plant's outputs in *out. */
DM_EXPORT int dm_fly(DmMaster *m, double t_end, const DmValues *plant, const DmValues *ctrl,
                     const DmOutputs *out, long *steps, int *stopped)
{
    DmFmu *p = &m->plant, *c = &m->ctrl;
    const double h = m->h;
    const long n = (long)ceil(t_end / h - 1e-9);
    long k;
    int holds = 0;
    m->used = 0, m->message[0] = 0;
    *stopped = 0;
    if (start(m, p, plant, t_end) || start(m, c, ctrl, t_end))
        return 1;
    for (k = 0; k <= n; k++) {
        const double t = k * h;
        /* one call after the other (the operands of | are not sequenced in C) */
        int st = p->get_real(p->c, m->y_vr, m->ny, m->y);
        st |= c->set_real(c->c, m->x_vr, m->ny, m->y);
        st |= c->get_real(c->c, m->u_vr, m->nu, m->u);
        st |= p->set_real(p->c, m->pu_vr, m->nu, m->u);
        if (st > fmi2Warning) {
            say(m, "exchanging values at t = %.17g s failed", t);
            return 1;
        }
        if (k == 0 && out->n0 && p->get_real(p->c, out->vr0, out->n0, out->val0) > fmi2Warning) {
            say(m, "reading the plant's outputs at t = 0 failed");
            return 1;
        }
        if (m->stop_type && (k % m->check_every == 0 || k == n)) {
            if (stop_holds(m, &holds)) {
                say(m, "reading the stop output at t = %.17g s failed", t);
                return 1;
            }
            if (holds) {
                *stopped = 1;
                break;
            }
        }
        if (k == n)
            break;
        {
            const double dt = h < t_end - t ? h : t_end - t;
            if (p->step(p->c, t, dt, fmi2True) > fmi2Warning
                || c->step(c->c, t, dt, fmi2True) > fmi2Warning) {
                say(m, "doStep at t = %.17g s failed", t);
                return 1;
            }
        }
    }
    *steps = k;
    if ((out->nr && p->get_real(p->c, out->rvr, out->nr, out->rval) > fmi2Warning)
        || (out->ni && p->get_int(p->c, out->ivr, out->ni, out->ival) > fmi2Warning)
        || (out->nb && p->get_bool(p->c, out->bvr, out->nb, out->bval) > fmi2Warning)) {
        say(m, "reading the plant's outputs failed");
        return 1;
    }
    return 0;
}

/* The values of flight k of a batch (the offsets: the counts of the flights before it). */
static void batch_values(const DmBatchValues *b, long k, long r0, long i0, DmValues *v)
{
    v->nr = (size_t)b->nr[k], v->rvr = b->rvr + r0, v->rval = b->rval + r0;
    v->ni = (size_t)b->ni[k], v->ivr = b->ivr + i0, v->ival = b->ival + i0;
}

/* Flights first .. n-1 of a batch, one dm_fly each on the same instances (reset by each
 * flight, as between two dm_fly calls): flight k's start values from *plant and *ctrl (see
 * DmBatchValues), its outputs at row k of out's arrays (out->nr Reals a row, and so on; the
 * n0 Reals at t = 0 at row k of val0), its
 * steps and stop flag at steps[k], stopped[k].  Returns n when every flight succeeded; else
 * the index of the failed flight, dm_message() saying why (the caller goes on from the next). */
DM_EXPORT long dm_fly_many(DmMaster *m, long first, long n, double t_end,
                           const DmBatchValues *plant, const DmBatchValues *ctrl,
                           const DmOutputs *out, long *steps, int *stopped)
{
    long pr = 0, pi = 0, cr = 0, ci = 0, k;
    for (k = 0; k < first; k++)
        pr += plant->nr[k], pi += plant->ni[k], cr += ctrl->nr[k], ci += ctrl->ni[k];
    for (k = first; k < n; k++) {
        DmValues pv, cv;
        DmOutputs o = *out;
        o.rval = out->rval + (size_t)k * out->nr;
        o.ival = out->ival + (size_t)k * out->ni;
        o.bval = out->bval + (size_t)k * out->nb;
        o.val0 = out->val0 + (size_t)k * out->n0;
        batch_values(plant, k, pr, pi, &pv);
        batch_values(ctrl, k, cr, ci, &cv);
        pr += plant->nr[k], pi += plant->ni[k], cr += ctrl->nr[k], ci += ctrl->ni[k];
        if (dm_fly(m, t_end, &pv, &cv, &o, &steps[k], &stopped[k]))
            return k;
    }
    return n;
}
