/* brent.h -- the root search of a native controller, operation for operation as Python runs it:
 *
 *   br_brentq        -- scipy.optimize.brentq(f, a, b, xtol, rtol, maxiter, disp=False), the
 *                       algorithm of SciPy's C implementation of Brent's method behind the
 *                       checks of its Python function;
 *   br_solve_control -- models.controllers.reentry_prediction.solve_control(miss, u0, tol,
 *                       max_iter, (lo, hi)): the guess and a bound bracket the root, brentq finds it.
 *
 * Same root, same number of calls of f, bit for bit: every comparison, every operation and its
 * order is SciPy's (and Python's: min/max keep their first argument unless the other compares
 * less/greater, a float division by zero raises).  Compile with -ffp-contract=off (no fused
 * multiply-add: each operation rounds as in SciPy's build and in Python).
 *
 * Errors (Python raises) are negative codes below, or the callback's own nonzero code, returned
 * at once: callbacks should use positive codes to stay apart from these.
 *
 * descent-fmus (MIT licence).
 */
#ifndef DESCENT_BRENT_H
#define DESCENT_BRENT_H

#include <float.h>
#include <math.h>

/* f(x) -> *out; nonzero return: an error (Python raises), propagated as is */
typedef int (*br_fn)(double x, void *ctx, double *out);

/* SciPy's smallest relative tolerance, 4 * np.finfo(float).eps (the default rtol) */
#define BR_RTOL (4.0 * DBL_EPSILON)

#define BR_SIGN (-100)      /* f(a) and f(b) of the same sign: SciPy raises ValueError */
#define BR_ARGS (-101)      /* xtol <= 0, rtol < BR_RTOL or maxiter < 0: SciPy raises ValueError */
#define BR_NAN (-102)       /* f returned NaN inside brentq: SciPy raises ValueError */
#define BR_ZERODIV (-103)   /* solve_control's slope: Python raises ZeroDivisionError */

/* one call of f as SciPy's brentq makes it: counted, then a NaN value raises */
static inline int br_call(br_fn f, void *ctx, double x, double *fx, int *calls)
{
    int rc = f(x, ctx, fx);
    ++*calls;
    if (rc != 0)
        return rc;
    if (isnan(*fx))
        return BR_NAN;
    return 0;
}

/* scipy.optimize.brentq(f, a, b, xtol, rtol, maxiter, disp=False): 0 and *root, or an error;
   *calls counts the calls of f made (also on error).
 *
 * The state at the top of the loop (SciPy's names): the root lies between xcur, the best
 * estimate, and xblk, the contrapoint (f of opposite sign); xpre is the previous estimate;
 * spre, scur are the steps before last and last; sbis half the bracket towards xblk.  A step is
 * an inverse quadratic (or secant, when xpre is the contrapoint) extrapolation when it is short
 * enough, else a bisection; never shorter than delta, the tolerance's half. */
static inline int br_brentq(br_fn f, void *ctx, double a, double b, double xtol, double rtol,
                            int maxiter, double *root, int *calls)
{
    double xpre = a, xcur = b, xblk = 0.0, fpre, fcur, fblk = 0.0;
    double spre = 0.0, scur = 0.0, sbis, delta, stry, dpre, dblk, lim;
    int i, rc;

    *calls = 0;
    /* the Python wrapper's checks, then its C module's (the NaN of a tolerance passes) */
    if (xtol <= 0.0 || rtol < BR_RTOL || maxiter < 0)
        return BR_ARGS;

    /* both ends are evaluated before any test */
    rc = br_call(f, ctx, xpre, &fpre, calls);
    if (rc != 0)
        return rc;
    rc = br_call(f, ctx, xcur, &fcur, calls);
    if (rc != 0)
        return rc;
    if (fpre == 0.0) {                      /* a root at an end: returned as given */
        *root = xpre;
        return 0;
    }
    if (fcur == 0.0) {
        *root = xcur;
        return 0;
    }
    if (signbit(fpre) == signbit(fcur))    /* the sign bits, as SciPy compares them */
        return BR_SIGN;

    for (i = 0; i < maxiter; i++) {
        /* the new estimate crossed the root: the previous one is the contrapoint */
        if (fpre != 0.0 && fcur != 0.0 && signbit(fpre) != signbit(fcur)) {
            xblk = xpre;
            fblk = fpre;
            spre = scur = xcur - xpre;
        }
        /* the best estimate is the end of smaller |f| (xpre keeps the one left) */
        if (fabs(fblk) < fabs(fcur)) {
            xpre = xcur;
            xcur = xblk;
            xblk = xpre;
            fpre = fcur;
            fcur = fblk;
            fblk = fpre;
        }

        delta = (xtol + rtol * fabs(xcur)) / 2.0;
        sbis = (xblk - xcur) / 2.0;
        if (fcur == 0.0 || fabs(sbis) < delta) {
            *root = xcur;
            return 0;
        }

        if (fabs(spre) > delta && fabs(fcur) < fabs(fpre)) {
            if (xpre == xblk) {             /* secant through the two ends */
                stry = -fcur * (xcur - xpre) / (fcur - fpre);
            }
            else {                          /* inverse quadratic through the three points */
                dpre = (fpre - fcur) / (xpre - xcur);
                dblk = (fblk - fcur) / (xblk - xcur);
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre));
            }
            /* SciPy's MIN(a, b): (a) < (b) ? (a) : (b), NaN included */
            lim = fabs(spre) < 3.0 * fabs(sbis) - delta ? fabs(spre) : 3.0 * fabs(sbis) - delta;
            if (2.0 * fabs(stry) < lim) {   /* a short step: accepted */
                spre = scur;
                scur = stry;
            }
            else {                          /* too long: bisect */
                spre = sbis;
                scur = sbis;
            }
        }
        else {                              /* slow progress: bisect */
            spre = sbis;
            scur = sbis;
        }

        xpre = xcur;
        fpre = fcur;
        if (fabs(scur) > delta)
            xcur += scur;
        else                                /* at least delta, towards the contrapoint */
            xcur += (sbis > 0.0 ? delta : -delta);

        rc = br_call(f, ctx, xcur, &fcur, calls);
        if (rc != 0)
            return rc;
    }
    /* maxiter exhausted: with disp=False, SciPy returns the current estimate */
    *root = xcur;
    return 0;
}

/* solve_control(miss, u0, tol, max_iter, (lo, hi)): 0 and (*u, *miss_u, *evaluations), or an
   error (*evaluations then counts the calls of miss made, the failed one included).
 *
 * miss decreasing in u: the guess clipped to the bounds, then the bound towards the root; if
 * even that bound cannot null the miss it is the answer, else Brent's method between the two,
 * to xtol = tol / slope of u (the bracket's mean slope turns tol metres of miss into u). */
static inline int br_solve_control(br_fn miss, void *ctx, double u0, double tol, int max_iter,
                                   double lo, double hi, double *u, double *miss_u,
                                   int *evaluations)
{
    double f0, end, fe, den, slope, a, b, root, fr;
    int rc, calls;

    /* u0 = min(max(u0, lo), hi): Python keeps the first argument unless the other compares
       greater (max) or less (min), so a NaN guess stays NaN and -0.0 stays -0.0 */
    if (lo > u0)
        u0 = lo;
    if (hi < u0)
        u0 = hi;

    *evaluations = 1;
    rc = miss(u0, ctx, &f0);
    if (rc != 0)
        return rc;
    if (fabs(f0) <= tol) {
        *u = u0;
        *miss_u = f0;
        return 0;
    }
    end = f0 > 0.0 ? hi : lo;               /* too far: more drag; too short: less */
    *evaluations = 2;
    rc = miss(end, ctx, &fe);
    if (rc != 0)
        return rc;
    if ((fe >= 0.0) == (f0 > 0.0)) {        /* even the bound cannot null the miss */
        *u = end;
        *miss_u = fe;
        return 0;
    }

    /* slope = abs(fe - f0) / abs(end - u0); xtol = tol / slope (float divisions: raise at 0) */
    den = fabs(end - u0);
    if (den == 0.0)
        return BR_ZERODIV;
    slope = fabs(fe - f0) / den;
    if (slope == 0.0)
        return BR_ZERODIV;

    a = end < u0 ? end : u0;                /* min(u0, end) */
    b = end > u0 ? end : u0;                /* max(u0, end) */
    rc = br_brentq(miss, ctx, a, b, tol / slope, BR_RTOL, max_iter, &root, &calls);
    *evaluations = 2 + calls;               /* Python's counted(): calls[0] += 1 per call */
    if (rc != 0)
        return rc;

    ++*evaluations;
    rc = miss(root, ctx, &fr);
    if (rc != 0)
        return rc;
    *u = root;
    *miss_u = fr;
    return 0;
}

#endif
