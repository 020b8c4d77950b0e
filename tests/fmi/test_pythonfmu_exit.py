"""pythonfmu 0.7's write to freed memory at a process's exit, and the two guards against it.

The pythonfmu binary releases its static interpreter-state pointer twice when it is unloaded
(the C++ exit handler, then its destructor function ``finalizePythonInterpreter``): the second
release decrements a count inside a freed block, which glibc may report at exit as "corrupted
double-linked list".  The guards (see ``synthesis.fmi.slave`` and the status wrapper
``synthesis/fmi/native/c/fmi2/pythonfmu_status.c``) call that function first, while the pointer
is valid.  Oracle: valgrind's memcheck, which reports every read of freed memory with its stack
(the bug: an invalid read in ``finalizePythonInterpreter`` of a block freed by the exit
handlers).
"""
from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile

import pytest

from descent_fmus.synthesis.fmi import slave as slave_module
from descent_fmus.synthesis.fmi.slave import load_slave

VALGRIND = shutil.which("valgrind")
PLANT = "Reentry"


@pytest.fixture(scope="module")
def raw_fmu(fmu_dir, tmp_path_factory):
    """``Reentry.fmu`` with pythonfmu's own binary in place of the status wrapper (an FMU built
    by pythonfmu alone, as a user's may be)."""
    src = fmu_dir / f"{PLANT}.fmu"
    out = tmp_path_factory.mktemp("raw") / f"{PLANT}.fmu"
    binary, real = f"binaries/linux64/{PLANT}.so", f"binaries/linux64/{PLANT}.pythonfmu.so"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zout:
        names = zin.namelist()
        if real not in names:
            pytest.skip("the build has no status wrapper (no C compiler)")
        for name in names:
            if name == binary:
                continue
            zout.writestr(binary if name == real else name, zin.read(name))
    return out


def test_load_slave_registers_a_bare_pythonfmu_binary_and_not_the_wrapper(fmu_dir, raw_fmu):
    # the Python guard is for pythonfmu binaries loaded as they are; the wrapper (no
    # finalizePythonInterpreter of its own) guards itself
    for path, bare in ((fmu_dir / f"{PLANT}.fmu", False), (raw_fmu, True)):
        fmu = load_slave(path, "plant")
        try:
            name = fmu.slave.dll._name
            assert (name in slave_module._PYTHONFMU_BINARIES) is bare, path
        finally:
            fmu.freeInstance()


_FLY = """
import sys
from fmpy import simulate_fmu
from descent_fmus.synthesis.fmi.slave import load_slave
if sys.argv[1] == "fmpy":
    simulate_fmu(sys.argv[2], stop_time=0.5)      # loads, frees and unloads it (fmpy simulate)
else:
    fmu = load_slave(sys.argv[2], "plant")
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.1)
    fmu.free()
"""


def _freed_reads(tmp_path, how: str, fmu) -> int:
    """How many reads of freed memory valgrind reports in pythonfmu's release at exit."""
    log = tmp_path / f"memcheck-{how}.log"
    subprocess.run([VALGRIND, "--quiet", "--undef-value-errors=no", f"--log-file={log}",
                    sys.executable, "-c", _FLY, how,
                    str(fmu)], check=True, timeout=900)
    text = log.read_text()
    return sum("finalizePythonInterpreter" in error and "free'd" in error
               for error in text.split("Invalid read")[1:])


needs_valgrind = pytest.mark.skipif(VALGRIND is None,
                                    reason="valgrind is not installed (CI installs it)")


@pytest.fixture(scope="module")
def unguarded(raw_fmu, tmp_path_factory) -> int:
    """The control: the bare binary flown by fmpy alone (no guard) -- the reads the bug makes,
    which shows the oracle sees it here (none: a pythonfmu without the bug)."""
    return _freed_reads(tmp_path_factory.mktemp("control"), "fmpy", raw_fmu)


@pytest.mark.slow
@needs_valgrind
@pytest.mark.parametrize("how, wrapped", [("fmpy", True), ("load_slave", False)],
                         ids=["wrapper-under-fmpy", "bare-binary-under-load_slave"])
def test_no_pythonfmu_fmu_reads_freed_memory_at_exit(tmp_path, fmu_dir, raw_fmu, unguarded,
                                                     how, wrapped):
    # a guarded run -- the wrapper in fmpy's hands (it loads, frees and unloads it, as
    # `fmpy simulate` does), or the bare binary through load_slave -- reads no freed memory
    if unguarded == 0:
        pytest.skip("this pythonfmu does not read freed memory at exit: nothing to guard")
    assert _freed_reads(tmp_path, how, fmu_dir / f"{PLANT}.fmu" if wrapped else raw_fmu) == 0
