/* native_model.h -- what a model of a descent-fmus native FMU gives the generic FMI 2.0
 * co-simulation wrapper (fmi2_cs.c).
 *
 * A model is a set of Real and Integer variables (value references 0..N_REAL-1 for the Reals,
 * N_REAL..N_REAL+N_INTEGER-1 for the Integers, in the order of modelDescription.xml), their
 * start values and kinds, and two functions: a parameter check and the computation of the
 * outputs from the inputs, the parameters and the time.  The wrapper does everything else
 * (instances, modes, get/set, steps, logging), once for every native export.
 *
 * A model with a state of its own (an estimator's sums, a compiled matrix) also defines some of
 * the optional hooks at the end: fmi2_cs.c holds default definitions of them that do nothing
 * (weak symbols), so a model that is a plain function of its inputs (law_model.c) defines none.
 *
 * descent-fmus (MIT licence).
 */
#ifndef DESCENT_NATIVE_MODEL_H
#define DESCENT_NATIVE_MODEL_H

#include <stddef.h>

/* kinds of variables (causality and variability) */
#define KIND_INPUT 0         /* causality input, continuous */
#define KIND_OUTPUT 1        /* causality output */
#define KIND_FIXED 2         /* parameter, fixed: set before/while initialising only */
#define KIND_TUNABLE 3       /* parameter, tunable: also between steps */

typedef struct {
    double *r;               /* Real values, by value reference */
    int *i;                  /* Integer values, by value reference - N_REAL */
    double time;             /* current communication point [s] */
    double last_step;        /* size of the last doStep > 0 [s]; 0 before the first */
    void *data;              /* the model's own memory per instance (model_data_size() bytes,
                                zeroed at instantiation and reset), or NULL */
} ModelState;

extern const char MODEL_GUID[];
/* A model file defines the tables below from its model_config.h (MODEL_CONFIG_GUID, N_REAL,
   N_INTEGER, MODEL_CONFIG_{REAL,INTEGER}_{START,KIND}) with one line after including it:
   MODEL_TABLES(value reference of its sample_period, or -1) */
#define MODEL_TABLES(sample_period)                                                         \
    const char MODEL_GUID[] = MODEL_CONFIG_GUID;                                            \
    const int MODEL_SAMPLE_PERIOD = (sample_period);                                        \
    const int MODEL_N_REAL = N_REAL, MODEL_N_INTEGER = N_INTEGER;                           \
    const double MODEL_REAL_START[N_REAL] = {MODEL_CONFIG_REAL_START};                      \
    const int MODEL_INTEGER_START[N_INTEGER] = {MODEL_CONFIG_INTEGER_START};                \
    const unsigned char MODEL_REAL_KIND[N_REAL] = {MODEL_CONFIG_REAL_KIND};                 \
    const unsigned char MODEL_INTEGER_KIND[N_INTEGER] = {MODEL_CONFIG_INTEGER_KIND};
/* value reference of the Real parameter sample_period of a sampled controller, or -1: with a
   period Ts > 0 the wrapper holds the outputs and ignores the inputs between samples (a
   communication step that ends Ts or more after the last sample is the model's next step) */
extern const int MODEL_SAMPLE_PERIOD;
extern const int MODEL_N_REAL, MODEL_N_INTEGER;
extern const double MODEL_REAL_START[];
extern const int MODEL_INTEGER_START[];
extern const unsigned char MODEL_REAL_KIND[], MODEL_INTEGER_KIND[];

/* NULL if the parameters are valid, else a message naming the offending one (the model's own
 * static buffer) */
const char *model_check(const ModelState *s);

/* the outputs (Reals of KIND_OUTPUT) from the inputs, the parameters and the time; never NaN or
 * inf */
void model_outputs(ModelState *s);

/* -- optional hooks (default: nothing) ------------------------------------------------------ */
/* bytes of per-instance memory the model needs in s->data */
size_t model_data_size(void);
/* the start values have just been set (instantiation, fmi2Reset): derive what depends on them */
void model_reset(ModelState *s);
/* the parameters passed model_check (entering and leaving initialisation mode): derive the run
   constants from them */
void model_prepare(ModelState *s);
/* the model's own step over [t, t + h] (a sampled controller: the whole interval since its last
   sample), after the outputs were brought up to date and before s->time moves to t + h */
void model_step(ModelState *s, double t, double h);
/* NULL, or why the last model_prepare or model_step failed (a native plant where Python would
   raise): the wrapper then logs it and returns fmi2Error from fmi2ExitInitializationMode or
   fmi2DoStep */
const char *model_failure(const ModelState *s);

#endif
