/* py_repr.h -- a double written as Python writes it (repr), so that the native controllers'
 * messages read exactly as the pythonfmu controllers' (``parameter q[2] must be finite, got
 * inf``, ``u_min[1] = 1.0, ...``).
 *
 * Python's repr is the shortest decimal string that reads back as the same double, in fixed
 * notation for decimal exponents -4 <= e < 16 (``0.0001``, ``1e-05``, ``123.0``, ``1e+16``).
 *
 * descent-fmus (MIT licence).
 */
#ifndef DESCENT_PY_REPR_H
#define DESCENT_PY_REPR_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* write repr(v) into out (at least 32 bytes); returns out */
static inline char *py_repr(double v, char *out)
{
    char sci[40], digits[24];
    int p, e, n = 0, k;
    char *o = out;
    if (isnan(v))
        return strcpy(out, "nan");
    if (isinf(v))
        return strcpy(out, v > 0 ? "inf" : "-inf");
    for (p = 1; p <= 17; p++) {            /* the shortest round-trip precision */
        snprintf(sci, sizeof sci, "%.*e", p - 1, v);
        if (strtod(sci, NULL) == v)
            break;
    }
    if (signbit(v))
        *o++ = '-';
    for (k = (sci[0] == '-'); sci[k] != 'e'; k++)
        if (sci[k] != '.')
            digits[n++] = sci[k];
    e = atoi(sci + k + 1);
    while (n > 1 && digits[n - 1] == '0')  /* drop the trailing zeros of the mantissa */
        n--;
    digits[n] = '\0';
    if (e < -4 || e >= 16) {                /* d.ddde+XX */
        *o++ = digits[0];
        if (n > 1) {
            *o++ = '.';
            memcpy(o, digits + 1, (size_t)(n - 1));
            o += n - 1;
        }
        sprintf(o, "e%c%02d", e < 0 ? '-' : '+', abs(e));
        return out;
    }
    if (e < 0) {                            /* 0.000ddd */
        *o++ = '0';
        *o++ = '.';
        for (k = 0; k < -e - 1; k++)
            *o++ = '0';
        memcpy(o, digits, (size_t)n);
        o[n] = '\0';
        return out;
    }
    for (k = 0; k <= e || k < n; k++) {     /* ddd.ddd, at least one digit after the point */
        if (k == e + 1)
            *o++ = '.';
        *o++ = k < n ? digits[k] : '0';
    }
    if (n <= e + 1) {
        *o++ = '.';
        *o++ = '0';
    }
    *o = '\0';
    return out;
}

#endif
