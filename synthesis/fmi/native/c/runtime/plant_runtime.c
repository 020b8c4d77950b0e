/* plant_runtime.c -- the stepping loops and the Python-exact helpers of the native plants
 * (see plant_runtime.h).  Each function mirrors its Python original line for line:
 * rk4_step_with_k1, locate_crossing and advance_to of models/integrators.py;
 * rk4_linear_input_step and propagate_linear_input of models/rk4_input.py; math.hypot and
 * float formatting of CPython.
 *
 * descent-fmus (MIT licence).
 */
#include <float.h>
#include <stdlib.h>
#include <string.h>

#include "plant_runtime.h"
#include "py_repr.h"

/* -- models/integrators.py --------------------------------------------------------------- */

/* rk4_step_with_k1(f, x, k1, h, args) */
static int rk4_step_with_k1(const pc_system *p, const double *x, const double *k1, double h,
                            double *out)
{
    double y[PC_NMAX], k2[PC_NMAX], k3[PC_NMAX], k4[PC_NMAX];
    const int n = p->n;
    const double h2 = 0.5 * h;
    double h6;
    int j, err = 0;
    if (n < 1 || n > PC_NMAX)
        return 1;
    for (j = 0; j < n; j++)
        y[j] = x[j] + h2 * k1[j];
    err |= p->f(y, p->args, p->f_ctx, k2);
    for (j = 0; j < n; j++)
        y[j] = x[j] + h2 * k2[j];
    err |= p->f(y, p->args, p->f_ctx, k3);
    for (j = 0; j < n; j++)
        y[j] = x[j] + h * k3[j];
    err |= p->f(y, p->args, p->f_ctx, k4);
    h6 = h / 6.0;
    for (j = 0; j < n; j++)
        out[j] = x[j] + h6 * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j]);
    return err;
}

/* locate_crossing(f, x0, k0, h, args, g, g0, g1, tol, max_iter=30): the fraction s of the step
   in *s, the state there in xs; PC_OUT_ERROR where Python raises */
static int locate_crossing(const pc_system *p, const double *x0, const double *k0, double h,
                           double g0, double g1, double *s_out, double *xs)
{
    double a = 0.0, ga = g0, b = 1.0, gb = g1, s = 0.0, gs;
    int side = 0, it;
    for (it = 0; it < 30; it++) {
        if (gb - ga == 0.0)
            return PC_OUT_ERROR;                    /* ZeroDivisionError */
        s = (a * gb - b * ga) / (gb - ga);
        if (rk4_step_with_k1(p, x0, k0, s * h, xs) || p->event(xs, p->event_ctx, &gs))
            return PC_OUT_ERROR;
        if (fabs(gs) <= p->tol || (b - a) < 1e-15)
            break;
        if (gs > 0.0) {
            a = s;
            ga = gs;
            if (side == 1)
                gb *= 0.5;
            side = 1;
        } else {
            b = s;
            gb = gs;
            if (side == -1)
                ga *= 0.5;
            side = -1;
        }
    }
    *s_out = s;
    return 0;
}

/* the event check of one sub-step: PC_OUT_EVENT (x, *t set), 0 (no event) or PC_OUT_ERROR */
static int event_in_step(const pc_system *p, double *x, const double *k1, const double *xn,
                         double t0, double i, double h, double *t)
{
    double g0, g1, s, xs[PC_NMAX];
    int j;
    if (p->event(xn, p->event_ctx, &g1))
        return PC_OUT_ERROR;
    if (!(g1 <= 0.0))
        return 0;
    if (p->event(x, p->event_ctx, &g0) || locate_crossing(p, x, k1, h, g0, g1, &s, xs))
        return PC_OUT_ERROR;
    for (j = 0; j < p->n; j++)
        x[j] = xs[j];
    *t = t0 + (i + s) * h;
    return PC_OUT_EVENT;
}

int pc_advance_to(const pc_system *p, double *x, double t0, double t_end, double dt, double *t)
{
    const double span = t_end - t0;
    double steps, h, i, k1[PC_NMAX], xn[PC_NMAX];
    int j;
    if (span <= 0.0) {
        *t = t0;
        return PC_OUT_OK;
    }
    steps = span / dt - 1e-9;
    if (!isfinite(steps) || p->n > PC_NMAX)
        return PC_OUT_ERROR;                        /* math.ceil raises */
    steps = ceil(steps);
    if (steps < 1.0)
        steps = 1.0;                                /* max(1, ...) */
    h = span / steps;
    for (i = 0.0; i < steps; i += 1.0) {
        int err = p->f(x, p->args, p->f_ctx, k1);
        if (!err && p->on_step != NULL)
            err = p->on_step(x, k1, p->on_step_ctx, p->S);
        if (!err)
            err = rk4_step_with_k1(p, x, k1, h, xn);
        for (j = 0; j < p->n && !err; j++)
            err = !isfinite(xn[j]);
        if (err) {
            *t = t0 + i * h;
            return PC_OUT_DIVERGED;
        }
        if (p->event != NULL) {
            int e = event_in_step(p, x, k1, xn, t0, i, h, t);
            if (e)
                return e;
        }
        for (j = 0; j < p->n; j++)
            x[j] = xn[j];
    }
    *t = t_end;
    return PC_OUT_OK;
}

/* -- models/rk4_input.py ----------------------------------------------------------------- */

/* rk4_linear_input_step(f, x, h, u0, u1) */
static int rk4_linear_input_step(pc_rhs f, const double *ctx, int n, double *x, double h,
                                 const double *u0, const double *u1, int m)
{
    double um[PC_NMAX], y[PC_NMAX], k1[PC_NMAX], k2[PC_NMAX], k3[PC_NMAX], k4[PC_NMAX];
    const double h2 = 0.5 * h;
    double h6;
    int j, err = 0;
    for (j = 0; j < m; j++)
        um[j] = 0.5 * (u0[j] + u1[j]);
    err |= f(x, u0, ctx, k1);
    for (j = 0; j < n; j++)
        y[j] = x[j] + h2 * k1[j];
    err |= f(y, um, ctx, k2);
    for (j = 0; j < n; j++)
        y[j] = x[j] + h2 * k2[j];
    err |= f(y, um, ctx, k3);
    for (j = 0; j < n; j++)
        y[j] = x[j] + h * k3[j];
    err |= f(y, u1, ctx, k4);
    h6 = h / 6.0;
    for (j = 0; j < n; j++)
        x[j] = x[j] + h6 * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j]);
    return err;
}

int pc_propagate_linear(pc_rhs f, const double *f_ctx, int n, double *x, double span,
                        const double *u0, const double *du, int m, double steps)
{
    double ua[PC_NMAX], ub[PC_NMAX], h, i;
    int j;
    if (n > PC_NMAX || m > PC_NMAX || steps == 0.0)
        return PC_ERROR;                            /* span / 0: ZeroDivisionError */
    h = span / steps;
    for (j = 0; j < m; j++)
        ua[j] = u0[j];
    for (i = 1.0; i <= steps; i += 1.0) {
        const double s = i * h;
        for (j = 0; j < m; j++)
            ub[j] = u0[j] + du[j] * s;
        if (rk4_linear_input_step(f, f_ctx, n, x, h, ua, ub, m))
            return PC_ERROR;
        for (j = 0; j < m; j++)
            ua[j] = ub[j];
    }
    return PC_OK;
}

/* -- numpy.linalg of 3x3 matrices --------------------------------------------------------- */

/* LU with partial pivoting in place (LAPACK's getrf for n = 3): perm[i] is the original row of
   row i, *sign the permutation's sign; 0 on a zero pivot (the factorization goes on, as getrf's
   does) */
static int lu3(double m[3][3], int perm[3], int *sign)
{
    int k, i, j, regular = 1;
    *sign = 1;
    for (i = 0; i < 3; i++)
        perm[i] = i;
    for (k = 0; k < 3; k++) {
        int p = k;
        for (i = k + 1; i < 3; i++)
            if (fabs(m[i][k]) > fabs(m[p][k]))
                p = i;
        if (p != k) {
            const int t = perm[k];
            perm[k] = perm[p];
            perm[p] = t;
            for (j = 0; j < 3; j++) {
                const double v = m[k][j];
                m[k][j] = m[p][j];
                m[p][j] = v;
            }
            *sign = -*sign;
        }
        if (m[k][k] == 0.0) {
            regular = 0;
            continue;
        }
        for (i = k + 1; i < 3; i++) {
            m[i][k] /= m[k][k];
            for (j = k + 1; j < 3; j++)
                m[i][j] -= m[i][k] * m[k][j];
        }
    }
    return regular;
}

static int finite9(const double *a)
{
    int k;
    for (k = 0; k < 9; k++)
        if (!isfinite(a[k]))
            return 0;
    return 1;
}

int pc_det3(const double *a, double *out)
{
    double m[3][3];
    int perm[3], sign, k;
    for (k = 0; k < 9; k++)
        m[k / 3][k % 3] = a[k];
    lu3(m, perm, &sign);
    *out = m[0][0] * m[1][1] * m[2][2] * sign;      /* the diagonal's product, then the sign */
    return !finite9(a);
}

int pc_inv3(const double *a, double *out)
{
    double m[3][3], x[3][3];
    int perm[3], sign, k, i, j, c;
    for (k = 0; k < 9; k++)
        m[k / 3][k % 3] = a[k];
    if (!lu3(m, perm, &sign) || !finite9(a))
        return 1;                                   /* "Singular matrix" */
    for (c = 0; c < 3; c++) {                       /* L U x = P e_c, column by column */
        for (i = 0; i < 3; i++) {
            double s = perm[i] == c ? 1.0 : 0.0;
            for (j = 0; j < i; j++)
                s -= m[i][j] * x[j][c];
            x[i][c] = s;
        }
        for (i = 2; i >= 0; i--) {
            double s = x[i][c];
            for (j = i + 1; j < 3; j++)
                s -= m[i][j] * x[j][c];
            x[i][c] = s / m[i][i];
        }
    }
    for (k = 0; k < 9; k++)
        out[k] = x[k / 3][k % 3];
    return 0;
}

int pc_eigvalsh3(const double *a, double *out)
{
    double m[3][3], w[3];
    int i, j, sweep;
    static const int P[3] = {0, 0, 1}, Q[3] = {1, 2, 2};
    if (!finite9(a))
        return 1;                                   /* "Eigenvalues did not converge" */
    for (i = 0; i < 3; i++)
        for (j = 0; j <= i; j++)
            m[i][j] = m[j][i] = a[3 * i + j];       /* the lower triangle, as eigvalsh reads */
    for (sweep = 0; sweep < 60; sweep++) {          /* cyclic Jacobi rotations */
        int r, changed = 0;
        for (r = 0; r < 3; r++) {
            const int p = P[r], q = Q[r];
            double theta, t, c, s;
            int k;
            if (m[p][q] == 0.0 || fabs(m[p][q]) <= 1e-300)
                continue;
            theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
            t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
            c = 1.0 / sqrt(t * t + 1.0);
            s = t * c;
            for (k = 0; k < 3; k++) {               /* rotate rows and columns p, q */
                const double mkp = m[k][p], mkq = m[k][q];
                m[k][p] = c * mkp - s * mkq;
                m[k][q] = s * mkp + c * mkq;
            }
            for (k = 0; k < 3; k++) {
                const double mpk = m[p][k], mqk = m[q][k];
                m[p][k] = c * mpk - s * mqk;
                m[q][k] = s * mpk + c * mqk;
            }
            m[p][q] = m[q][p] = 0.0;
            changed = 1;
        }
        if (!changed)
            break;
    }
    for (i = 0; i < 3; i++)
        w[i] = m[i][i];
    for (i = 0; i < 3; i++)                         /* ascending */
        for (j = i + 1; j < 3; j++)
            if (w[j] < w[i]) {
                const double t = w[i];
                w[i] = w[j];
                w[j] = t;
            }
    for (i = 0; i < 3; i++)
        out[i] = w[i];
    return 0;
}

/* -- CPython's math.hypot ------------------------------------------------------------------
 * The norm of (x, y) as CPython 3.11 computes it (vector_norm in Modules/mathmodule.c), for two
 * coordinates: lossless scaling by a power of two, exact squares (Veltkamp-Dekker splitting),
 * a compensated sum started at 1.0, and a square root corrected by one differential step; for
 * a largest coordinate below 2**-1023, division by it and a once-compensated sum.  Checked
 * against math.hypot on random pairs over the whole range (tests/fmi/native/test_native_plants.py). */
typedef struct {
    double hi, lo;
} pc_dd;

static pc_dd pc_square(double x)
{
    const double t = x * 134217729.0;               /* 2**27 + 1 */
    const double hi = t - (t - x), lo = x - hi;
    const double p = hi * hi, q = hi * lo + lo * hi, z = p + q;
    pc_dd r;
    r.hi = z;
    r.lo = p - z + q + lo * lo;
    return r;
}

static pc_dd pc_product(double x, double y)
{
    const double tx = x * 134217729.0, ty = y * 134217729.0;
    const double xh = tx - (tx - x), xl = x - xh, yh = ty - (ty - y), yl = y - yh;
    const double p = xh * yh, q = xh * yl + xl * yh, z = p + q;
    pc_dd r;
    r.hi = z;
    r.lo = p - z + q + xl * yl;
    return r;
}

static double pc_norm2(double a, double b, double max)
{
    double scale, csum = 1.0, frac1 = 0.0, frac2 = 0.0, h, x, s;
    double v[2];
    pc_dd sq;
    int e, k;
    if (isinf(max))
        return max;
    if (max == 0.0)
        return max;
    v[0] = a;
    v[1] = b;
    frexp(max, &e);
    if (e < -1023) {
        /* deep subnormals: 2**-e would overflow; CPython 3.11 divides by max and sums the
           squares with one compensation term */
        for (k = 0; k < 2; k++) {
            x = v[k] / max;
            x = x * x;
            s = csum + x;
            frac1 += (csum - s) + x;
            csum = s;
        }
        return max * sqrt(csum - 1.0 + frac1);
    }
    scale = ldexp(1.0, -e);
    for (k = 0; k < 2; k++) {
        x = v[k] * scale;
        sq = pc_square(x);
        s = csum + sq.hi;                           /* fast two-sum, |csum| >= |sq.hi| */
        frac1 += sq.lo;
        frac2 += sq.hi - (s - csum);
        csum = s;
    }
    h = sqrt(csum - 1.0 + (frac1 + frac2));
    sq = pc_product(-h, h);
    s = csum + sq.hi;
    frac1 += sq.lo;
    frac2 += sq.hi - (s - csum);
    csum = s;
    x = csum - 1.0 + (frac1 + frac2);
    h += x / (2.0 * h);
    return h / scale;
}

double py_hypot(double x, double y)
{
    const double a = fabs(x), b = fabs(y);
    double max = 0.0;
    if (isnan(a) || isnan(b)) {
        if (isinf(a) || isinf(b))
            return INFINITY;
        return NAN;
    }
    if (a > max)
        max = a;
    if (b > max)
        max = b;
    return pc_norm2(a, b, max);
}

/* -- float formatting as Python's format() ------------------------------------------------ */
void pc_format(char *buf, size_t size, double x, const char *spec)
{
    char fmt[24], text[40];
    if (isnan(x) || isinf(x) || spec[0] == '\0') {   /* Python: nan, inf, -inf for any spec */
        snprintf(buf, size, "%s", py_repr(x, text));
        return;
    }
    snprintf(fmt, sizeof fmt, "%%%s", spec);
    snprintf(buf, size, fmt, x);
}
