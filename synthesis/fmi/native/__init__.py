"""Native (compiled C) FMUs: plants, controllers, laws and program tables with no Python inside.

Folders by job:

* :mod:`.tracer` -- Python models run on traced values and rendered to C (the plants, and
  whatever a system traces with it: S1's estimator and on-board predictions);
* :mod:`.builders` -- the compiler, the FMU writer, the native twins of the generic
  controllers, laws, program tables and plants as FMUs, the native closed-loop FMUs;
* ``c/fmi2/`` -- the generic FMI 2.0 co-simulation wrapper (``fmi2_cs.c``, written once), the
  vendored FMI 2.0 headers and the status wrapper of pythonfmu FMUs;
* ``c/fmi3/`` -- the FMI 3.0 co-simulation wrapper (``fmi3_cs.c``: an adapter over
  ``fmi2_cs.c``, compiled into it) and the vendored FMI 3.0.2 headers;
* ``c/runtime/`` -- the C runtime of the traced code (Python-exact helpers, the stepping loops,
  the plant model glue, CPython's random generator, Brent's root search);
* ``c/controllers/`` -- the generic controllers in C (the network-operator interpreter, the
  table player, a law's model);
* ``c/master/`` -- the C master that flies two native FMUs in closed loop.

A system's own native code lives in its package (S1: ``synthesis/systems/reentry/native/``);
nothing here imports a system.  The closed loops that fly the native FMUs are in
:mod:`synthesis.fmi` (``c_master_loop``, ``native_loop``).
"""
