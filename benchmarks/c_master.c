/* c_master.c -- a closed loop of two FMI 2.0 co-simulation FMUs in plain C (no Python in the
 * process): the pure-C reference of benchmarks/native_paths.py.
 *
 * The master algorithm of synthesis/fmi/closed_loop.py and of fmpy's container FMU (Gauss-Seidel
 * on the grid t_k = k h): read the plant outputs y(t_k), set them as controller inputs, read
 * u_k = phi(y(t_k)), set it as plant input, doStep both over [t_k, t_k + h].  A flight resets
 * both FMUs, sets the start values, initialises and steps to the stop time (the plants freeze
 * once their status is non-zero, as in the container path).
 *
 *   c_master PLANT.so PLANT_GUID CTRL.so CTRL_GUID SPEC FLIGHTS
 *
 * SPEC is a text file of lines "<p|c> <R|I> <vr> <value>" (start values of the plant or the
 * controller, values as C99 hexadecimal floats or integers), "y <plant vr> <controller vr>"
 * (a plant output to a controller input), "u <controller vr> <plant vr>", "o <plant vr>" (a
 * Real output printed at the end), "h <step>" and "t <stop time>".  Prints the outputs of the
 * last flight (hexadecimal floats, one line) and "seconds_per_flight <s>" on stderr.
 *
 * Build: cc -std=c99 -O2 -o c_master c_master.c -ldl
 */
#define _POSIX_C_SOURCE 199309L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef void *Component;
typedef unsigned int VR;
typedef struct {
    void (*logger)(void *, const char *, int, const char *, const char *, ...);
    void *(*allocate)(size_t, size_t);
    void (*free)(void *);
    void *step_finished;
    void *environment;
} Callbacks;

typedef struct {
    void *lib;
    Component c;
    Component (*instantiate)(const char *, int, const char *, const char *, const Callbacks *,
                             int, int);
    int (*setup)(Component, int, double, double, int, double);
    int (*enter)(Component), (*exit_init)(Component), (*reset)(Component);
    int (*set_real)(Component, const VR *, size_t, const double *);
    int (*get_real)(Component, const VR *, size_t, double *);
    int (*set_int)(Component, const VR *, size_t, const int *);
    int (*step)(Component, double, double, int);
    VR rvr[4096], ivr[4096];
    double rval[4096];
    int ival[4096], nr, ni;
} Fmu;

static void logger(void *env, const char *name, int status, const char *category,
                   const char *message, ...)
{
    (void)env;
    fprintf(stderr, "[%s %d %s] %s\n", name, status, category, message);
}

#define SYM(f, field, name) \
    if ((*(void **)&(f)->field = dlsym((f)->lib, name)) == NULL) { \
        fprintf(stderr, "missing %s\n", name); exit(3); }

static void load(Fmu *f, const char *path, const char *guid, const char *name)
{
    static Callbacks cb = {logger, calloc, free, NULL, NULL};
    if ((f->lib = dlopen(path, RTLD_NOW | RTLD_LOCAL)) == NULL) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        exit(3);
    }
    SYM(f, instantiate, "fmi2Instantiate")
    SYM(f, setup, "fmi2SetupExperiment")
    SYM(f, enter, "fmi2EnterInitializationMode")
    SYM(f, exit_init, "fmi2ExitInitializationMode")
    SYM(f, reset, "fmi2Reset")
    SYM(f, set_real, "fmi2SetReal")
    SYM(f, get_real, "fmi2GetReal")
    SYM(f, set_int, "fmi2SetInteger")
    SYM(f, step, "fmi2DoStep")
    if ((f->c = f->instantiate(name, 1, guid, "", &cb, 0, 0)) == NULL)
        exit(4);
}

static int start(Fmu *f, double t_end)
{
    return f->reset(f->c) | f->set_real(f->c, f->rvr, (size_t)f->nr, f->rval)
           | f->set_int(f->c, f->ivr, (size_t)f->ni, f->ival)
           | f->setup(f->c, 0, 0.0, 0.0, 1, t_end) | f->enter(f->c) | f->exit_init(f->c);
}

int main(int argc, char **argv)
{
    static Fmu plant, ctrl;
    VR y_p[64], y_c[64], u_c[64], u_p[64], out[64];
    double y[64], u[64], o[64], h = 1.0, t_end = 300.0;
    int ny = 0, nu = 0, no = 0, flights, n, k, status = 0;
    char kind, type, line[256];
    struct timespec t0, t1;
    FILE *spec;
    if (argc != 7) {
        fprintf(stderr, "usage: c_master PLANT.so GUID CTRL.so GUID SPEC FLIGHTS\n");
        return 2;
    }
    load(&plant, argv[1], argv[2], "plant");
    load(&ctrl, argv[3], argv[4], "controller");
    if ((spec = fopen(argv[5], "r")) == NULL)
        return 2;
    while (fgets(line, sizeof line, spec)) {
        unsigned a, b;
        char value[128];
        Fmu *f;
        if (sscanf(line, "%c %c %u %127s", &kind, &type, &a, value) == 4 && (kind == 'p' || kind == 'c')) {
            f = kind == 'p' ? &plant : &ctrl;
            if (type == 'R') {
                f->rvr[f->nr] = a;
                f->rval[f->nr++] = strtod(value, NULL);
            } else {
                f->ivr[f->ni] = a;
                f->ival[f->ni++] = atoi(value);
            }
        } else if (sscanf(line, "y %u %u", &a, &b) == 2) {
            y_p[ny] = a;
            y_c[ny++] = b;
        } else if (sscanf(line, "u %u %u", &a, &b) == 2) {
            u_c[nu] = a;
            u_p[nu++] = b;
        } else if (sscanf(line, "o %u", &a) == 1) {
            out[no++] = a;
        } else if (line[0] == 'h') {
            h = strtod(line + 1, NULL);
        } else if (line[0] == 't') {
            t_end = strtod(line + 1, NULL);
        }
    }
    fclose(spec);
    flights = atoi(argv[6]);
    n = (int)(t_end / h + 0.5);
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (int flight = 0; flight < flights; flight++) {
        status |= start(&plant, t_end) | start(&ctrl, t_end);
        for (k = 0; k <= n; k++) {
            const double t = k * h;
            status |= plant.get_real(plant.c, y_p, (size_t)ny, y)
                      | ctrl.set_real(ctrl.c, y_c, (size_t)ny, y)
                      | ctrl.get_real(ctrl.c, u_c, (size_t)nu, u)
                      | plant.set_real(plant.c, u_p, (size_t)nu, u);
            if (k == n)
                break;
            status |= plant.step(plant.c, t, h, 1) | ctrl.step(ctrl.c, t, h, 1);
        }
        if (status > 1) {
            fprintf(stderr, "an FMU call failed in flight %d\n", flight);
            return 5;
        }
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    plant.get_real(plant.c, out, (size_t)no, o);
    for (k = 0; k < no; k++)
        printf(k ? " %a" : "%a", o[k]);
    printf("\n");
    fprintf(stderr, "seconds_per_flight %.9g\n",
            ((t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec)) / flights);
    return 0;
}
