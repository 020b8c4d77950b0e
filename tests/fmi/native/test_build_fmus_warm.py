"""``build_fmus.py`` warms the caches a fresh machine's first main job would fill
(``warm_caches``: docs/methods/run_loop.md, "A fresh machine's first run").

Oracle: the main job's own functions (``master_library``, ``interpreter_fmu``,
``native_prober``) afterwards find every library in the cache folder without compiling
anything -- the C compiler is replaced by a function that fails the test -- and, in an empty
cache folder, each still builds its own (the main job never depends on the warming).
"""
from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]


def _build_fmus():
    spec = importlib.util.spec_from_file_location("build_fmus_script", ROOT / "build_fmus.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _the_main_jobs_libraries(fmu_dir):
    from descent_fmus.synthesis.fmi.c_master_loop import master_library
    from descent_fmus.synthesis.fmi.native.builders import law_fmu
    from descent_fmus.synthesis.registry import get_problem
    from descent_fmus.synthesis.run.probes import native_prober
    law_fmu._INTERPRETERS.clear()                 # the cache folder is found again
    problem = get_problem("reentry")
    prober = native_prober(problem, problem.fmu_paths(fmu_dir))
    return master_library(), law_fmu.interpreter_fmu(), prober


@pytest.mark.slow            # two rounds of C compiles (~10-20 s)
def test_the_main_job_finds_what_build_fmus_warmed(fmu_dir, tmp_path, monkeypatch, capsys):
    from descent_fmus.synthesis.fmi.native.builders import build
    from descent_fmus.synthesis.registry import get_system
    if build.find_compiler() is None or not (fmu_dir / "native" / "Reentry.fmu").is_file():
        pytest.skip("needs a C compiler and the native twins")
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("MPLCONFIGDIR", str(tmp_path / "mpl"))
    _build_fmus().warm_caches(fmu_dir, [get_system("reentry")])
    line = capsys.readouterr().out
    assert "the C master, the probe library and the interpreter law FMU" in line, line
    assert list((tmp_path / "mpl").glob("fontlist-*.json"))      # matplotlib's font list

    def no_compile(*args, **kwargs):
        raise AssertionError("compiled although build_fmus.py warmed the cache")
    with monkeypatch.context() as m:
        m.setattr(build, "compile_sources", no_compile)
        m.setattr("descent_fmus.synthesis.fmi.native.builders.controllers."
                  "build_network_operator_controller", no_compile)
        master, interpreter, prober = _the_main_jobs_libraries(fmu_dir)
    assert prober is not None                                   # the native probes' route
    for path in (master, interpreter):
        assert path.is_file() and (tmp_path / "cache") in path.parents

    shutil.rmtree(tmp_path / "cache")             # no warming: the main job builds its own
    master, interpreter, prober = _the_main_jobs_libraries(fmu_dir)
    assert master.is_file() and interpreter.is_file() and prober is not None
