/* fmi2_host.c -- a minimal FMI 2.0 co-simulation host in C (no Python in the process).
 *
 * Loads an FMU's shared library with dlopen, resolves the FMI 2.0 functions, instantiates it,
 * initialises it with its default start values and then, for every line of stdin (the input
 * values, C99 hexadecimal floats or nan/inf), sets the inputs, reads the outputs (printed as
 * hexadecimal floats, one line per input line) and steps 1 s.
 *
 *   fmi2_host LIBRARY GUID "VR_IN,VR_IN,..." "VR_OUT,VR_OUT,..." [RESOURCE_URI] < inputs > outputs
 *
 * RESOURCE_URI (optional): the FMU's resources folder as a file URI, for FMUs that read it (a
 * closed-loop container FMU finds its components there); an empty VR_IN list steps an FMU
 * without inputs (a closed loop) once per input line.
 *
 * tests/fmi/native/test_native_law.py builds it with the system compiler and runs it with
 * LD_PRELOAD, PYTHONHOME and PYTHONPATH unset: a native law FMU needs nothing of Python.
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef void *Component;
typedef unsigned int VR;
typedef void (*Logger)(void *, const char *, int, const char *, const char *, ...);
typedef struct {
    Logger logger;
    void *(*allocate)(size_t, size_t);
    void (*free)(void *);
    void *step_finished;
    void *environment;
} Callbacks;

static void logger(void *env, const char *name, int status, const char *category,
                   const char *message, ...)
{
    (void)env;
    fprintf(stderr, "[%s %d %s] %s\n", name, status, category, message);
}

static int parse_vrs(const char *text, VR *out, int max)
{
    int n = 0;
    const char *p = text;
    while (*p && n < max) {
        char *end;
        out[n++] = (VR)strtoul(p, &end, 10);
        p = (*end == ',') ? end + 1 : end;
        if (end == p && *p == '\0')
            break;
    }
    return n;
}

typedef Component (*InstantiateF)(const char *, int, const char *, const char *,
                                  const Callbacks *, int, int);
typedef int (*SetupF)(Component, int, double, double, int, double);
typedef int (*ModeF)(Component);
typedef int (*SetRealF)(Component, const VR *, size_t, const double *);
typedef int (*GetRealF)(Component, const VR *, size_t, double *);
typedef int (*DoStepF)(Component, double, double, int);
typedef void (*FreeF)(Component);

#define SYM(type, name) type name = (type)dlsym(lib, #name); \
    if (name == NULL) { fprintf(stderr, "missing %s\n", #name); return 3; }

int main(int argc, char **argv)
{
    VR in[64], out[64];
    double x[64], u[64];
    int nx, nu, k, status = 0;
    double t = 0.0;
    char line[8192];
    void *lib;
    Component c;
    Callbacks cb = {logger, calloc, free, NULL, NULL};
    if (argc != 5 && argc != 6) {
        fprintf(stderr, "usage: fmi2_host LIBRARY GUID VR_IN,... VR_OUT,... [RESOURCE_URI]\n");
        return 2;
    }
    lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (lib == NULL) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 3;
    }
    SYM(InstantiateF, fmi2Instantiate)
    SYM(SetupF, fmi2SetupExperiment)
    SYM(ModeF, fmi2EnterInitializationMode)
    SYM(ModeF, fmi2ExitInitializationMode)
    SYM(SetRealF, fmi2SetReal)
    SYM(GetRealF, fmi2GetReal)
    SYM(DoStepF, fmi2DoStep)
    SYM(ModeF, fmi2Terminate)
    SYM(FreeF, fmi2FreeInstance)
    nx = parse_vrs(argv[3], in, 64);
    nu = parse_vrs(argv[4], out, 64);
    c = fmi2Instantiate("host", 1 /* fmi2CoSimulation */, argv[2], argc == 6 ? argv[5] : "",
                        &cb, 0, 0);
    if (c == NULL)
        return 4;
    if (fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) || fmi2EnterInitializationMode(c)
        || fmi2ExitInitializationMode(c))
        return 5;
    while (fgets(line, sizeof line, stdin)) {
        char *p = line, *end;
        for (k = 0; k < nx; k++) {
            x[k] = strtod(p, &end);
            p = end;
        }
        status |= fmi2SetReal(c, in, (size_t)nx, x);
        status |= fmi2GetReal(c, out, (size_t)nu, u);
        for (k = 0; k < nu; k++)
            printf(k ? " %a" : "%a", u[k]);
        printf("\n");
        status |= fmi2DoStep(c, t, 1.0, 1);
        t += 1.0;
    }
    fmi2Terminate(c);
    fmi2FreeInstance(c);
    dlclose(lib);
    return status ? 6 : 0;
}
