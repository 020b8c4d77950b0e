/* table_model.c -- a program table played back as the model of a native FMU (native_model.h).
 *
 * Hand-written once for every table; model_config.h (generated) gives the kind, the capacity
 * TABLE_NODES x TABLE_CHANNELS, the GUID and the start values (the table itself).
 *
 * TABLE_KIND 0, piecewise linear on a uniform grid (as the pythonfmu ProgramController):
 *   Reals: u[1..C] (outputs: the value at the current time t), du[1..C] (outputs: the slope of
 *   the segment that starts at t, 0 after t_end), t_end, table[i,j] (node i at
 *   t = (i-1) t_end / (n_nodes-1)), sample_period; Integer: n_nodes.
 * TABLE_KIND 1, piecewise constant between breakpoints, averaged over the coming step (as the
 *   pythonfmu LandingProgram): Reals: u[1..C] (outputs: the mean of the program over
 *   [t, t + h], h the last step size, before the first step the parameter step), t[1..N]
 *   (breakpoints: row i holds from t[i] to t[i+1], the last row for ever), table[i,j], step,
 *   sample_period; Integer: n_nodes.
 *
 * descent-fmus (MIT licence).
 */
#include <math.h>
#include <stdio.h>

#include "native_model.h"
#include "model_config.h"

#define N TABLE_NODES
#define C TABLE_CHANNELS

#if TABLE_KIND == 0
#define VR_U 0
#define VR_DU (VR_U + C)
#define VR_TEND (VR_DU + C)
#define VR_TABLE (VR_TEND + 1)
#define VR_SAMPLE (VR_TABLE + N * C)
#else
#define VR_U 0
#define VR_T (VR_U + C)
#define VR_TABLE (VR_T + N)
#define VR_STEP (VR_TABLE + N * C)
#define VR_SAMPLE (VR_STEP + 1)
#endif
#define N_REAL (VR_SAMPLE + 1)

const char MODEL_GUID[] = MODEL_CONFIG_GUID;
const int MODEL_SAMPLE_PERIOD = VR_SAMPLE;
const int MODEL_N_REAL = N_REAL, MODEL_N_INTEGER = 1;
const double MODEL_REAL_START[N_REAL] = {MODEL_CONFIG_REAL_START};
const int MODEL_INTEGER_START[1] = {MODEL_CONFIG_INTEGER_START};
const unsigned char MODEL_REAL_KIND[N_REAL] = {MODEL_CONFIG_REAL_KIND};
const unsigned char MODEL_INTEGER_KIND[1] = {MODEL_CONFIG_INTEGER_KIND};

static char message[200];

#define AT(r, i, j) ((r)[VR_TABLE + (i) * C + (j)])

const char *model_check(const ModelState *s)
{
    const double *r = s->r;
    int n = s->i[0], i, j;
    if (n < (TABLE_KIND == 0 ? 2 : 1) || n > N) {
        snprintf(message, sizeof message, "n_nodes must be in %d..%d, got %d",
                 TABLE_KIND == 0 ? 2 : 1, N, n);
        return message;
    }
#if TABLE_KIND == 0
    if (!(isfinite(r[VR_TEND]) && r[VR_TEND] > 0.0)) {
        snprintf(message, sizeof message, "parameter t_end must be > 0 s, got %g", r[VR_TEND]);
        return message;
    }
#else
    if (!(isfinite(r[VR_STEP]) && r[VR_STEP] > 0.0)) {
        snprintf(message, sizeof message, "parameter step must be > 0 s, got %g", r[VR_STEP]);
        return message;
    }
    for (i = 0; i < n; i++)
        if (!isfinite(r[VR_T + i]) || (i > 0 && r[VR_T + i] < r[VR_T + i - 1])) {
            snprintf(message, sizeof message, "t[%d] = %g: breakpoints must be finite and "
                     "non-decreasing", i + 1, r[VR_T + i]);
            return message;
        }
#endif
    for (i = 0; i < n; i++)
        for (j = 0; j < C; j++)
            if (!isfinite(AT(r, i, j))) {
                snprintf(message, sizeof message, "table[%d,%d] must be finite", i + 1, j + 1);
                return message;
            }
    return NULL;
}

void model_outputs(ModelState *s)
{
    double *r = s->r;
    const double t = s->time;
    int n = s->i[0], i, j;
    if (n < 1 || n > N)
        return;                                 /* rejected at initialisation */
#if TABLE_KIND == 0
    {
        const int n_int = n - 1;
        const double t_end = r[VR_TEND], dt = t_end / n_int;
        if (n < 2 || !(t_end > 0.0))
            return;
        if (t >= t_end - 1e-9 * dt) {
            for (j = 0; j < C; j++) {
                r[VR_U + j] = AT(r, n - 1, j);
                r[VR_DU + j] = 0.0;
            }
            return;
        }
        i = (int)floor(t / dt + 1e-9);
        i = i < n_int - 1 ? i : n_int - 1;
        i = i > 0 ? i : 0;
        for (j = 0; j < C; j++) {
            const double a = AT(r, i, j), b = AT(r, i + 1, j);
            const double du = (b - a) / dt;
            r[VR_DU + j] = du;
            r[VR_U + j] = a + du * (t - i * dt);
        }
    }
#else
    {
        const double h = s->last_step > 0.0 ? s->last_step : r[VR_STEP];
        const double t1 = t + h;
        for (j = 0; j < C; j++) {
            double mean = 0.0;
            for (i = 0; i < n; i++) {
                const double a = r[VR_T + i], b = i + 1 < n ? r[VR_T + i + 1] : INFINITY;
                const double overlap = (b < t1 ? b : t1) - (a > t ? a : t);
                if (overlap > 0.0)
                    mean += AT(r, i, j) * overlap / h;
            }
            r[VR_U + j] = mean;
        }
    }
#endif
}
