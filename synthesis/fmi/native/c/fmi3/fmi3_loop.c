/* fmi3_loop.c -- the binary of an FMI 3.0 closed-loop FMU: the closed-loop engine
 * (../loop/closed_loop.c, loop_values.c) under the FMI 3.0 wrapper fmi3_cs.c, which compiles it
 * into itself under private names as it does fmi2_cs.c for a native FMU.  The engine still
 * loads its two FMI 2.0 components from resources/; only its own face is FMI 3.0.
 *
 * descent-fmus (MIT licence). */
#define _GNU_SOURCE                 /* strdup and dlopen's flags, before any system header */
#define FMI3_OVER_LOOP
#include "fmi3_cs.c"
