"""The tracer: a Python plant (or estimator, or prediction) run on traced values, rendered to C.

* :mod:`.plant_trace` -- traced values, the tracer and its exploration of every branch;
* :mod:`.plant_codegen` -- the recorded operations rendered to C statements;
* :mod:`.plant_calls` -- calls to model functions inside a traced phase (C helpers, units);
* :mod:`.plant_phases` -- a pythonfmu plant's phases (check, prepare, step, outputs) traced;
* :mod:`.plant_shims` -- the patched numpy and math names a traced model calls;
* :mod:`.plant_numpy` -- numpy's array functions on traced values;
* :mod:`.plant_library` -- model functions exported with stable C names (a C library of the
  plant for other C code).

The C it writes compiles against the C runtime (``../c/runtime/``); the builders
(:mod:`..builders`) turn it into FMUs.
"""
