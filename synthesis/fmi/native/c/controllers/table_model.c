/* table_model.c -- a program table played back as the model of a native FMU (native_model.h).
 *
 * Hand-written once for every table; model_config.h (generated) gives the kind, the capacity
 * TABLE_NODES x TABLE_CHANNELS, the GUID and the start values (the table itself).
 *
 * TABLE_KIND 0, piecewise linear (the native twin of the pythonfmu ProgramController,
 *   models/controllers/program_table.py: evaluate_program, its checks and messages): Reals
 *   u[1..C] (outputs: the value at the current time t), du[1..C] (outputs: the slope of the
 *   segment that starts at t, 0 after the last node), t_end, table[i,j], sample_period and, with
 *   TABLE_GRID, t_node[1..N]; Integers n_nodes and, with TABLE_GRID, grid (0: node i at
 *   t = (i-1) t_end / (n_nodes-1); 1: at t_node[i]).  Value references: model_config.h
 *   (VR_U, VR_DU, VR_TEND, VR_TABLE, VR_SAMPLE, IX_N, VR_TNODE, IX_GRID), generated from the
 *   variables.
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
#include "py_repr.h"

#define N TABLE_NODES
#define C TABLE_CHANNELS

#if TABLE_KIND == 0
#if !TABLE_GRID
#define IX_GRID IX_N                /* no grid variable: never read */
#endif
#else
#define VR_U 0
#define VR_T (VR_U + C)
#define VR_TABLE (VR_T + N)
#define VR_STEP (VR_TABLE + N * C)
#define VR_SAMPLE (VR_STEP + 1)
#define N_REAL (VR_SAMPLE + 1)
#define N_INTEGER 1
#define IX_N 0
#endif

MODEL_TABLES(VR_SAMPLE)

static char message[200];

#define AT(r, i, j) ((r)[VR_TABLE + (i) * C + (j)])

#if TABLE_KIND == 0
/* ProgramController.check_parameters, in its order and words */
static const char *check_program(const ModelState *s)
{
    const double *r = s->r;
    const int n = s->i[IX_N], grid = TABLE_GRID ? s->i[IX_GRID] : 0;
    char value[40];
    int i;
    if (n < 2 || n > N) {
        snprintf(message, sizeof message, "n_nodes must be in 2..%d, got %d", N, n);
        return message;
    }
    if (grid != 0 && grid != 1) {
        snprintf(message, sizeof message, "grid must be 0 (uniform) or 1 (t_node), got %d", grid);
        return message;
    }
    if (grid == 0 && !(isfinite(r[VR_TEND]) && r[VR_TEND] > 0.0)) {
        snprintf(message, sizeof message, "parameter t_end must be %s, got %s",
                 isfinite(r[VR_TEND]) ? "> 0" : "finite", py_repr(r[VR_TEND], value));
        return message;
    }
#if TABLE_GRID
    for (i = 0; grid == 1 && i < n; i++)
        if (!isfinite(r[VR_TNODE + i]) || (i > 0 && !(r[VR_TNODE + i] > r[VR_TNODE + i - 1]))) {
            snprintf(message, sizeof message, "t_node[1..n_nodes] must be finite and "
                     "increasing");
            return message;
        }
#else
    (void)i;
#endif
    return NULL;
}
#else
static const char *check_program(const ModelState *s)
{
    const double *r = s->r;
    const int n = s->i[IX_N];
    int i;
    if (n < 1 || n > N) {
        snprintf(message, sizeof message, "n_nodes must be in 1..%d, got %d", N, n);
        return message;
    }
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
    return NULL;
}
#endif

const char *model_check(const ModelState *s)
{
    const double *r = s->r;
    const int n = s->i[IX_N];
    const char *bad = check_program(s);
    int i, j;
    if (bad != NULL)
        return bad;
    for (i = 0; i < n; i++)
        for (j = 0; j < C; j++)
            if (!isfinite(AT(r, i, j))) {
                snprintf(message, sizeof message, "table[%d,%d] must be finite", i + 1, j + 1);
                return message;
            }
    return NULL;
}

#if TABLE_KIND == 0
/* the last node's values held (du = 0), or the first's before the first node */
static void hold_row(double *r, int i)
{
    int j;
    for (j = 0; j < C; j++) {
        r[VR_U + j] = AT(r, i, j);
        r[VR_DU + j] = 0.0;
    }
}

/* evaluate_program of program_table.py at time t on segment i, from a = t_i by dt */
static void on_segment(double *r, int i, double dt, double s)
{
    int j;
    for (j = 0; j < C; j++) {
        const double a = AT(r, i, j), b = AT(r, i + 1, j);
        const double du = (b - a) / dt;
        r[VR_DU + j] = du;
        r[VR_U + j] = a + du * s;
    }
}

#if TABLE_GRID
/* grid = 1: the node times t_node[i] (bisect_right on t + tol) */
static void at_nodes(double *r, int n, double t)
{
    const double *times = r + VR_TNODE;
    const int n_int = n - 1;
    const double tol = 1e-9 * (times[n_int] - times[0]) / n_int;
    int lo = 0, hi = n, i;
    if (t >= times[n_int] - tol) {
        hold_row(r, n - 1);
        return;
    }
    if (t < times[0] - tol) {
        hold_row(r, 0);
        return;
    }
    while (lo < hi) {                           /* the first node later than t + tol */
        const int mid = (lo + hi) / 2;
        if (t + tol < times[mid])
            hi = mid;
        else
            lo = mid + 1;
    }
    i = lo - 1;
    i = i < n_int - 1 ? i : n_int - 1;
    i = i > 0 ? i : 0;
    on_segment(r, i, times[i + 1] - times[i], t - times[i]);
}
#endif

void model_outputs(ModelState *s)
{
    double *r = s->r;
    const double t = s->time;
    const int n = s->i[IX_N];
    if (n < 2 || n > N)
        return;                                 /* rejected at initialisation */
#if TABLE_GRID
    if (s->i[IX_GRID] == 1) {
        at_nodes(r, n, t);
        return;
    }
#endif
    {
        const int n_int = n - 1;
        const double t_end = r[VR_TEND], dt = t_end / n_int;
        double i;
        if (!(t_end > 0.0))
            return;
        if (t >= t_end - 1e-9 * dt) {
            hold_row(r, n - 1);
            return;
        }
        i = floor(t / dt + 1e-9);
        i = i < n_int - 1 ? i : n_int - 1;
        i = i > 0 ? i : 0;
        on_segment(r, (int)i, dt, t - (int)i * dt);
    }
}
#else
void model_outputs(ModelState *s)
{
    double *r = s->r;
    const double t = s->time;
    const int n = s->i[IX_N];
    int i, j;
    if (n < 1 || n > N)
        return;                                 /* rejected at initialisation */
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
}
#endif
