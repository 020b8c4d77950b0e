/* lp_export.c -- lp.h's solver as a shared library, for checking it against SciPy's HiGHS and
 * timing it from Python (synthesis/systems/reentry/native/onboard_lp.py); the FMUs include lp.h directly.
 *
 * descent-fmus (MIT licence).
 */
#include "lp.h"

#if defined(_WIN32)
#define LP_EXPORT __declspec(dllexport)
#else
#define LP_EXPORT __attribute__((visibility("default")))
#endif

LP_EXPORT int descent_lp_solve(int n, const double *c, int m_ub, const double *a_ub,
                               const double *b_ub, int m_eq, const double *a_eq,
                               const double *b_eq, const double *lo, const double *hi,
                               double *x, double *value)
{
    return lp_solve(n, c, m_ub, a_ub, b_ub, m_eq, a_eq, b_eq, lo, hi, x, value);
}
