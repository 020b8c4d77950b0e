/* py_random.h -- CPython's random.Random in C: the Mersenne Twister MT19937 seeded from an int
 * as random.seed(n) seeds it (init_by_array of the 32-bit words of |n|), random() (53-bit
 * floats) and gauss(mu, sigma) (Box-Muller with the second value kept), so that a native
 * controller draws the numbers its pythonfmu twin draws (random.Random(seed).gauss(...)).
 *
 * MT19937: M. Matsumoto, T. Nishimura, 1997 (the reference code CPython's _randommodule.c
 * uses); random() and gauss(): CPython's Lib/random.py.
 *
 * descent-fmus (MIT licence).
 */
#ifndef DESCENT_PY_RANDOM_H
#define DESCENT_PY_RANDOM_H

#include <math.h>
#include <stdint.h>

#define PY_MT_N 624
#define PY_MT_M 397

typedef struct {
    uint32_t mt[PY_MT_N];
    int index;
    int has_gauss_next;      /* gauss_next is not None */
    double gauss_next;
} PyRandom;

static inline void py_random_init_genrand(PyRandom *r, uint32_t s)
{
    int k;
    r->mt[0] = s;
    for (k = 1; k < PY_MT_N; k++)
        r->mt[k] = 1812433253u * (r->mt[k - 1] ^ (r->mt[k - 1] >> 30)) + (uint32_t)k;
    r->index = PY_MT_N;
}

/* random.seed(seed) of an int seed (its absolute value, 64 bits at most here) */
static inline void py_random_seed(PyRandom *r, long long seed)
{
    unsigned long long n = seed < 0 ? 0ull - (unsigned long long)seed : (unsigned long long)seed;
    uint32_t key[2] = {(uint32_t)(n & 0xffffffffu), (uint32_t)(n >> 32)};
    const int len = key[1] ? 2 : 1;
    int i = 1, j = 0, k;
    py_random_init_genrand(r, 19650218u);
    for (k = PY_MT_N > len ? PY_MT_N : len; k; k--) {
        r->mt[i] = (r->mt[i] ^ ((r->mt[i - 1] ^ (r->mt[i - 1] >> 30)) * 1664525u)) + key[j]
                   + (uint32_t)j;
        i++;
        j++;
        if (i >= PY_MT_N) {
            r->mt[0] = r->mt[PY_MT_N - 1];
            i = 1;
        }
        if (j >= len)
            j = 0;
    }
    for (k = PY_MT_N - 1; k; k--) {
        r->mt[i] = (r->mt[i] ^ ((r->mt[i - 1] ^ (r->mt[i - 1] >> 30)) * 1566083941u))
                   - (uint32_t)i;
        i++;
        if (i >= PY_MT_N) {
            r->mt[0] = r->mt[PY_MT_N - 1];
            i = 1;
        }
    }
    r->mt[0] = 0x80000000u;
    r->has_gauss_next = 0;
    r->gauss_next = 0.0;
}

static inline uint32_t py_random_uint32(PyRandom *r)
{
    static const uint32_t mag01[2] = {0x0u, 0x9908b0dfu};
    uint32_t y;
    int k;
    if (r->index >= PY_MT_N) {
        for (k = 0; k < PY_MT_N - PY_MT_M; k++) {
            y = (r->mt[k] & 0x80000000u) | (r->mt[k + 1] & 0x7fffffffu);
            r->mt[k] = r->mt[k + PY_MT_M] ^ (y >> 1) ^ mag01[y & 0x1u];
        }
        for (; k < PY_MT_N - 1; k++) {
            y = (r->mt[k] & 0x80000000u) | (r->mt[k + 1] & 0x7fffffffu);
            r->mt[k] = r->mt[k + (PY_MT_M - PY_MT_N)] ^ (y >> 1) ^ mag01[y & 0x1u];
        }
        y = (r->mt[PY_MT_N - 1] & 0x80000000u) | (r->mt[0] & 0x7fffffffu);
        r->mt[PY_MT_N - 1] = r->mt[PY_MT_M - 1] ^ (y >> 1) ^ mag01[y & 0x1u];
        r->index = 0;
    }
    y = r->mt[r->index++];
    y ^= (y >> 11);
    y ^= (y << 7) & 0x9d2c5680u;
    y ^= (y << 15) & 0xefc60000u;
    y ^= (y >> 18);
    return y;
}

/* random.random(): a double in [0, 1) with 53 random bits */
static inline double py_random_random(PyRandom *r)
{
    const uint32_t a = py_random_uint32(r) >> 5, b = py_random_uint32(r) >> 6;
    return (a * 67108864.0 + b) * (1.0 / 9007199254740992.0);
}

/* random.gauss(mu, sigma) */
static inline double py_random_gauss(PyRandom *r, double mu, double sigma)
{
    double z;
    if (r->has_gauss_next) {
        z = r->gauss_next;
        r->has_gauss_next = 0;
    } else {
        const double x2pi = py_random_random(r) * (2.0 * 3.141592653589793);
        const double g2rad = sqrt(-2.0 * log(1.0 - py_random_random(r)));
        z = cos(x2pi) * g2rad;
        r->gauss_next = sin(x2pi) * g2rad;
        r->has_gauss_next = 1;
    }
    return mu + z * sigma;
}

#endif
