/* c_master.c -- flights of a closed loop of two FMI 2.0 co-simulation FMUs with no Python in the
 * process: the pure-C reference of benchmarks/native_paths.py.  The flights are those of the
 * evaluator's C master (dm_fly of synthesis/fmi/native/c/master/master.c, compiled in), driven from
 * a text file instead of Python.
 *
 *   c_master PLANT.so PLANT_GUID CTRL.so CTRL_GUID SPEC FLIGHTS
 *
 * SPEC is a text file of lines "<p|c> <R|I> <vr> <value>" (start values of the plant or the
 * controller, values as C99 hexadecimal floats or integers), "y <plant vr> <controller vr>"
 * (a plant output to a controller input), "u <controller vr> <plant vr>", "o <plant vr>" (a
 * Real output printed at the end), "h <step>", "t <stop time>" and
 * "s <type 1-3> <vr> <op 0-2> <value> <check every>" (the stop condition, as dm_wire takes it).
 * Prints the outputs of the last flight (hexadecimal floats, one line) and
 * "seconds_per_flight <s>" on stderr.
 *
 * Build: cc -std=c99 -O2 -I synthesis/fmi/native/c/master -I synthesis/fmi/native/c/fmi2 \
 *            -o c_master benchmarks/c_master.c \
 *            synthesis/fmi/native/c/master/master.c -ldl -lm
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "master.h"

#define MAXV 4096

int main(int argc, char **argv)
{
    static fmi2ValueReference rvr[2][MAXV], ivr[2][MAXV], y_p[64], y_c[64], u_c[64], u_p[64],
        out[64];
    static double rval[2][MAXV], o[64];
    static int ival[2][MAXV];
    size_t nr[2] = {0, 0}, ni[2] = {0, 0}, ny = 0, nu = 0, no = 0;
    double h = 1.0, t_end = 300.0, stop_value = 0.0;
    int stop_type = 0, stop_op = 0, stopped, flights;
    unsigned stop_vr = 0;
    long check_every = 1, steps;
    char line[256];
    struct timespec t0, t1;
    DmMaster *m;
    FILE *spec;
    if (argc != 7) {
        fprintf(stderr, "usage: c_master PLANT.so GUID CTRL.so GUID SPEC FLIGHTS\n");
        return 2;
    }
    if ((spec = fopen(argv[5], "r")) == NULL)
        return 2;
    while (fgets(line, sizeof line, spec)) {
        unsigned a, b;
        char kind, type, value[128];
        if (sscanf(line, "%c %c %u %127s", &kind, &type, &a, value) == 4
            && (kind == 'p' || kind == 'c')) {
            int f = kind == 'c';
            if (type == 'R') {
                rvr[f][nr[f]] = a;
                rval[f][nr[f]++] = strtod(value, NULL);
            } else {
                ivr[f][ni[f]] = a;
                ival[f][ni[f]++] = atoi(value);
            }
        } else if (sscanf(line, "y %u %u", &a, &b) == 2) {
            y_p[ny] = a, y_c[ny++] = b;
        } else if (sscanf(line, "u %u %u", &a, &b) == 2) {
            u_c[nu] = a, u_p[nu++] = b;
        } else if (sscanf(line, "o %u", &a) == 1) {
            out[no++] = a;
        } else if (sscanf(line, "s %d %u %d %lf %ld", &stop_type, &stop_vr, &stop_op,
                          &stop_value, &check_every) == 5) {
        } else if (line[0] == 'h') {
            h = strtod(line + 1, NULL);
        } else if (line[0] == 't') {
            t_end = strtod(line + 1, NULL);
        }
    }
    fclose(spec);
    flights = atoi(argv[6]);
    m = dm_open(argv[1], argv[2], "", argv[3], argv[4], "");
    if (m == NULL || dm_message(m)[0]
        || dm_wire(m, ny, y_p, y_c, nu, u_c, u_p, h, stop_type, stop_vr, stop_op, stop_value,
                   check_every)) {
        fprintf(stderr, "c_master: %s\n", m ? dm_message(m) : "out of memory");
        return 3;
    }
    {
        const DmValues pv = {nr[0], rvr[0], rval[0], ni[0], ivr[0], ival[0]};
        const DmValues cv = {nr[1], rvr[1], rval[1], ni[1], ivr[1], ival[1]};
        const DmOutputs ov = {no, 0, 0, out, NULL, NULL, o, NULL, NULL, 0, NULL, NULL};
        clock_gettime(CLOCK_MONOTONIC, &t0);
        for (int flight = 0; flight < flights; flight++)
            if (dm_fly(m, t_end, &pv, &cv, &ov, &steps, &stopped)) {
                fprintf(stderr, "c_master: flight %d: %s\n", flight, dm_message(m));
                return 5;
            }
        clock_gettime(CLOCK_MONOTONIC, &t1);
    }
    for (size_t k = 0; k < no; k++)
        printf(k ? " %a" : "%a", o[k]);
    printf("\n");
    fprintf(stderr, "seconds_per_flight %.9g\n",
            ((t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec)) / flights);
    dm_close(m);
    return 0;
}
