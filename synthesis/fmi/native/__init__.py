"""Native (compiled C) FMUs of synthesis results: laws and program tables with no Python inside.

* :mod:`.ccode` -- the operation table rendered to C; a law as a straight-line C function
  (``law.h`` / ``law.c``);
* :mod:`.build` -- the generic FMI 2.0 co-simulation wrapper (``c/fmi2_cs.c``, written once) +
  a model's C files, compiled with the system's C compiler into an FMU that ships its sources;
* :mod:`.law_fmu` -- a network-operator law as a native FMU (the variables of the pythonfmu
  ``NetworkOperatorController``);
* :mod:`.table_fmu` -- program tables as native FMUs (one table player, ``c/table_model.c``).

Nothing here is imported by the GA's evaluator: the synthesis flies the generic pythonfmu
controller; what a run *exports* is native (``synthesis.fmi.law_files``).
"""
