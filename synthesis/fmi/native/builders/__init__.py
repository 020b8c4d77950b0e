"""The builders of native FMUs: C sources + the generic FMI 2.0 (or 3.0) wrapper, compiled here.

* :mod:`.build` -- the compiler, the C folders by job (:func:`.build.c_file`) and the FMU
  writer (model description, sources, binary);
* :mod:`.ccode` -- the operation table rendered to C; a law as a straight-line C function;
* :mod:`.controllers` -- the native twins of the generic controllers (the network-operator
  interpreter, the program-table player) and the twin builder the systems' own twins use;
* :mod:`.law_fmu`, :mod:`.table_fmu` -- a law, a program table as a native FMU;
* :mod:`.plant_fmu` -- a plant as a native FMU (C traced by :mod:`..tracer`);
* :mod:`.closed_loops` -- the container FMUs and SSP files of native closed loops;
* :mod:`.fmi3` -- the FMI 3.0 variant of a native FMU (the same C model, the FMI 3.0 wrapper);
* :mod:`.archives` -- ZIP archives written from members as they are compressed (law FMUs,
  closed-loop FMUs and SSP files per law).

What each system builds natively is named by its ``System`` record (``native_plants``,
``native_controllers``); the builders take it as arguments and know no system.
"""
