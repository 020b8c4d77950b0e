"""Native (compiled C) FMUs of synthesis results: laws and program tables with no Python inside.

* :mod:`.ccode` -- the operation table rendered to C; a law as a straight-line C function
  (``law.h`` / ``law.c``);
* :mod:`.build` -- the generic FMI 2.0 co-simulation wrapper (``c/fmi2_cs.c``, written once) +
  a model's C files, compiled with the system's C compiler into an FMU that ships its sources;
* :mod:`.law_fmu` -- a network-operator law as a native FMU (the variables of the pythonfmu
  ``NetworkOperatorController``);
* :mod:`.table_fmu` -- program tables as native FMUs (one table player, ``c/table_model.c``);
* :mod:`.controllers` -- the native twins of the generic controllers (the matrix interpreter
  ``c/no_interp.c``, the table player, S1's estimator traced by :mod:`.sensing`) and
  :mod:`.loops`, the closed loops of native FMUs; the ``plant_*`` modules generate the native
  plants.

Nothing here is imported by the GA's evaluator: it flies the generic controller FMU (the
native twin where built, ``synthesis.fmi.native_loop``); what a run *exports* is native
(``synthesis.fmi.law_files``).
"""
