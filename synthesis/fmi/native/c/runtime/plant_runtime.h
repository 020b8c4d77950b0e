/* plant_runtime.h -- the hand-written part of every descent-fmus native plant (written once).
 *
 * The plant-specific C (<plant>_plant.c, generated from the model's Python functions by
 * synthesis/fmi/native/tracer/plant_codegen.py) computes with the functions below; the stepping loops
 * mirror models/integrators.py and models/rk4_input.py operation for operation:
 *
 *   pc_advance_to    -- advance_to(): RK4 sub-steps dividing the span evenly, the event located
 *                       inside a sub-step by locate_crossing() (Illinois regula falsi on
 *                       fractional RK4 steps), divergence (an error or a non-finite state)
 *                       stopping at the last finite state, on_step() at every sub-step;
 *   pc_propagate_linear -- propagate_linear_input(): RK4 with the input linear over the span.
 *
 * The math functions compute what CPython computes: py_<f>(x, &err) is the C library's f
 * (CPython calls the same one) and sets err where CPython raises (ValueError, OverflowError,
 * ZeroDivisionError); py_hypot is CPython's own hypot algorithm (the C library's differs in the
 * last bit in about 0.1 % of cases).  Compile with -ffp-contract=off (no fused multiply-add).
 *
 * descent-fmus (MIT licence).
 */
#ifndef DESCENT_PLANT_RUNTIME_H
#define DESCENT_PLANT_RUNTIME_H

#include <math.h>
#include <stddef.h>
#include <stdio.h>

/* results of the generated functions */
#define PC_OK 0
#define PC_ERROR 1          /* Python would raise ArithmeticError / ValueError */
#define PC_RAISE 2          /* a ParameterError: the message is in msg */
#define PC_MSG 400          /* size of a message buffer */

/* outcomes of pc_advance_to (models.integrators OK, EVENT, DIVERGED); -1: an error outside the
   protected part of the loop (the event function or its location), where Python raises */
#define PC_OUT_OK 0
#define PC_OUT_EVENT 1
#define PC_OUT_DIVERGED 2
#define PC_OUT_ERROR (-1)

/* largest state of a plant */
#define PC_NMAX 64

/* f(x, *args) -> dx; the function's own context values in ctx; nonzero = Python would raise */
typedef int (*pc_rhs)(const double *x, const double *args, const double *ctx, double *dx);
/* event(x) -> g (positive before the event) */
typedef int (*pc_event)(const double *x, const double *ctx, double *g);
/* on_step(x, k1): bookkeeping at the start of every sub-step, written into the slots S */
typedef int (*pc_on_step)(const double *x, const double *k1, const double *ctx, double *S);

typedef struct {
    int n;                       /* state size */
    pc_rhs f;
    const double *f_ctx;
    const double *args;
    pc_event event;              /* NULL: none */
    const double *event_ctx;
    double tol;                  /* event location tolerance */
    pc_on_step on_step;          /* NULL: none */
    const double *on_step_ctx;
    double *S;                   /* the plant's slots, for on_step */
} pc_system;

/* advance_to(f, x, t0, t_end, dt, args, event, on_step, tol): x in/out, *t the time reached */
int pc_advance_to(const pc_system *p, double *x, double t0, double t_end, double dt, double *t);

/* propagate_linear_input(f, x, span, u0, du, n): x in/out (f's args are the input u, m
   values); PC_OK or PC_ERROR (Python raised: x is then undefined) */
int pc_propagate_linear(pc_rhs f, const double *f_ctx, int n, double *x, double span,
                        const double *u0, const double *du, int m, double steps);

/* numpy.linalg of a 3x3 matrix a (row-major): the inverse, the determinant, the eigenvalues of
   the symmetric matrix whose lower triangle a holds (ascending).  Not NumPy's LAPACK/BLAS
   arithmetic: the results may differ from NumPy's in the last bits.  Nonzero: NumPy raises
   LinAlgError (a singular matrix, a non-finite one). */
int pc_inv3(const double *a, double *out);
int pc_det3(const double *a, double *out);
int pc_eigvalsh3(const double *a, double *out);

/* Python's math.hypot(x, y) */
double py_hypot(double x, double y);

/* Python's format(x, spec) of a float; spec "" = repr(x) (shortest round-trip digits) */
void pc_format(char *buf, size_t size, double x, const char *spec);

#define PC_MATH1(name)                                                                     \
    static inline double py_##name(double x, int *err)                                     \
    {                                                                                      \
        double r = name(x);                                                                \
        if ((isnan(r) && !isnan(x)) || (isinf(r) && isfinite(x)))                          \
            *err = 1;                                                                      \
        return r;                                                                          \
    }
PC_MATH1(sqrt)
PC_MATH1(exp)
PC_MATH1(log)
PC_MATH1(log1p)
PC_MATH1(sin)
PC_MATH1(cos)
PC_MATH1(tan)
PC_MATH1(asin)
PC_MATH1(acos)
PC_MATH1(atan)
PC_MATH1(tanh)
#undef PC_MATH1

/* a / b: ZeroDivisionError for b == 0 (whatever a is) */
static inline double py_div(double a, double b, int *err)
{
    if (b == 0.0)
        *err = 1;
    return a / b;
}

/* a ** b (CPython's float power: the C library's pow and its special cases; an error where the
   result is NaN from numbers or infinite from finite numbers: negative base and fractional
   exponent, 0 ** negative, overflow) */
static double (*volatile const pc_libm_pow)(double, double) = pow;

static inline double py_pow(double a, double b, int *err)
{
    /* through a pointer the compiler cannot see through: GCC would fold pow(x, 2.0) into x * x,
       which rounds differently from the C library's pow (Python's x ** 2) now and then */
    double r = pc_libm_pow(a, b);
    if ((isnan(r) && !isnan(a) && !isnan(b)) || (isinf(r) && isfinite(a) && isfinite(b)))
        *err = 1;
    return r;
}

/* math.fmod(a, b): the C library's fmod, a for a finite a and an infinite b, and an error where
   the result is NaN from numbers (b == 0 or an infinite a) */
static inline double py_fmod(double a, double b, int *err)
{
    double r;
    if (isinf(b) && isfinite(a))
        return a;
    r = fmod(a, b);
    if (isnan(r) && !isnan(a) && !isnan(b))
        *err = 1;
    return r;
}

/* math.ceil / math.floor (an integer in Python: an error for a non-finite value) */
static inline double py_ceil(double x, int *err)
{
    if (!isfinite(x))
        *err = 1;
    return ceil(x);
}

static inline double py_floor(double x, int *err)
{
    if (!isfinite(x))
        *err = 1;
    return floor(x);
}

#endif
