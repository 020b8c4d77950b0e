"""Exporting laws: ``descent-fmus export-law``, what a synthesis run writes per Pareto law, lean
pythonfmu FMUs, bad input.

Oracles: the law files themselves (the native FMU flown by the Python master reproduces the
run's Pareto row), the registry (the modules each pythonfmu FMU needs), and the rules of the
command line (one-line errors, exit code 2, nothing overwritten)."""
from __future__ import annotations

import csv
import json
import zipfile
from pathlib import Path

import pytest

from descent_fmus.synthesis.cli.main import main
from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
from descent_fmus.synthesis.fmi.compose import model_closure
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.fmi.native.builders.build import find_compiler
from descent_fmus.synthesis.registry import fmu_classes, get_problem

# a five-term reentry law whose readable form is known by hand (see test_law_formula)
REENTRY_LAW = Path(__file__).resolve().parents[1] / "reference" / "reentry_five_term_law.json"
needs_cc = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (CI installs gcc)")


def test_pythonfmu_fmus_carry_only_the_modules_they_import(fmu_dir):
    # every pythonfmu FMU bundles exactly the models modules its class imports (the closure),
    # e.g. the generic controller carries no plant
    for spec in fmu_classes():
        module, cls = spec.split(":")
        with zipfile.ZipFile(fmu_dir / f"{cls}.fmu") as z:
            bundled = {n[len("resources/descent_fmus/models/"):-3].replace("/", ".")
                       for n in z.namelist()
                       if n.startswith("resources/descent_fmus/models/") and n.endswith(".py")}
        bundled = {m for m in bundled if not m.endswith("__init__") and m != "__init__"}
        assert bundled == set(model_closure(module)), cls
    assert "reentry" not in model_closure("controllers.network_operator")


@needs_cc
def test_export_law_native(fmu_dir, tmp_path, capsys):
    # the default native FMU: the interpreter with the law's start values, no law.c inside;
    # with --compiled the law's own C, flying the same (tests/fmi/native/test_native_law.py)
    out = tmp_path / "interpreted"
    assert main(["export-law", str(REENTRY_LAW), "--out", str(out), "--name", "BestLaw",
                 "--fmus", str(fmu_dir)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["BestLaw.fmu", "law.c", "law.h",
                                                      "law.json"]
    with zipfile.ZipFile(out / "BestLaw.fmu") as z:
        assert "sources/law.c" not in z.namelist()
        assert "resources/start_values.txt" in z.namelist()
    capsys.readouterr()
    out = tmp_path / "law"
    assert main(["export-law", str(REENTRY_LAW), "--compiled", "--out", str(out), "--name",
                 "BestLaw", "--fmus", str(fmu_dir), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["law_fmu"] == "native"
    assert sorted(p.name for p in out.iterdir()) == ["BestLaw.fmu", "law.c", "law.h",
                                                      "law.json"]
    assert (out / "BestLaw.fmu").stat().st_size <= 200 * 1024
    doc = json.loads((out / "law.json").read_text())
    assert doc["readable"]["text"].startswith("u = clip(-1.413 + 5.50221*y1")
    assert doc["readable"]["latex"].startswith(r"u = \operatorname{clip}")
    assert NetworkOperator.from_dict(doc)((0.01, 0.02)) == \
        NetworkOperator.load(REENTRY_LAW)((0.01, 0.02))
    assert "void BestLaw(const double *x, double *u);" in (out / "law.h").read_text()
    # the plain C file beside the FMU is the one inside it
    with zipfile.ZipFile(out / "BestLaw.fmu") as z:
        assert z.read("sources/law.c").decode() == (out / "law.c").read_text()


def test_export_law_python(fmu_dir, tmp_path, capsys):
    out = tmp_path / "law"
    assert main(["export-law", str(REENTRY_LAW), "--python", "--out", str(out), "--fmus",
                 str(fmu_dir)]) == 0
    text = capsys.readouterr().out
    assert "u = clip(-1.413 + 5.50221*y1" in text
    assert (out / "NetworkOperatorController.fmu").is_file()


# -- bad input ----------------------------------------------------------------------------------
def _law_file(tmp_path, edit) -> Path:
    d = json.loads(REENTRY_LAW.read_text())
    edit(d)
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(d))
    return p


@pytest.mark.parametrize("edit,message", [
    (lambda d: d["psi"][0].__setitem__(11, 99), "unknown unary operation 99 on arc 1->12"),
    (lambda d: d["psi"][9].__setitem__(9, 12), "unknown binary operation 12 at node 10"),
    (lambda d: d["psi"].pop(), "matrix must be square"),
    (lambda d: d["psi"][3].__setitem__(1, 1), "not upper-triangular"),
    (lambda d: d.pop("q"), "missing the field 'q'"),
])
def test_bad_law_file(tmp_path, capsys, edit, message):
    out = tmp_path / "out"
    assert main(["export-law", str(_law_file(tmp_path, edit)), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_compiled_python_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["export-law", str(REENTRY_LAW), "--compiled", "--python", "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err
    assert "--compiled is a native FMU" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_existing_output_folder_is_left_alone(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "law.json").write_text("mine")
    assert main(["export-law", str(REENTRY_LAW), "--out", str(out)]) == 2
    assert "nothing was overwritten" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["law.json"]
    assert (out / "law.json").read_text() == "mine"


def test_no_compiler(fmu_dir, tmp_path, monkeypatch, capsys):
    # no C compiler on the PATH: by default a clear note and the pythonfmu fallback; asked for
    # --native, a one-line error
    empty = tmp_path / "bin"
    empty.mkdir()
    monkeypatch.setenv("PATH", str(empty))
    monkeypatch.delenv("CC", raising=False)
    assert find_compiler() is None
    out = tmp_path / "auto"
    assert main(["export-law", str(REENTRY_LAW), "--out", str(out), "--fmus", str(fmu_dir)]) == 0
    captured = capsys.readouterr()
    assert "no C compiler found" in captured.err and "pythonfmu" in captured.err
    assert (out / "NetworkOperatorController.fmu").is_file() and (out / "law.c").is_file()
    assert main(["export-law", str(REENTRY_LAW), "--native", "--out", str(tmp_path / "n")]) == 2
    assert "no C compiler found" in capsys.readouterr().err
    assert not (tmp_path / "n").exists()


# -- a synthesis run's export ---------------------------------------------------------------------
@needs_cc
def test_synthesize_exports_laws_compactly(fmu_dir, tmp_path, capsys):
    # the default export: per Pareto law law.json (readable form), law.h/law.c and the native
    # law FMU -- no closed-loop FMU; the native law flown with the plant FMU reproduces its row
    out = tmp_path / "run"
    assert main(["synthesize", "reentry", "--population", "16", "--generations", "2",
                 "--crossovers", "4", "--lchr", "4", "--epoch", "2", "--seed", "3",
                 "--flights", "60", "--refine-basis", "0", "--workers", "1", "--quiet",
                 "--no-reference", "--json",
                 "--out", str(out),
                 "--fmus", str(fmu_dir)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["law_fmus"] == "native"
    rows = list(csv.DictReader(open(out / "pareto.csv")))
    assert rows and "readable" in rows[0]
    problem = get_problem("reentry")
    for r in rows[:3]:
        d = out / "laws" / r["k"]
        assert sorted(p.name for p in d.iterdir()) == sorted(
            ["law.json", "law.c", "law.h", f"ReentryLaw{r['k']}.fmu"])
        assert sum(p.stat().st_size for p in d.iterdir()) <= 200 * 1024
        doc = json.loads((d / "law.json").read_text())
        assert doc["readable"]["text"] == r["readable"] and doc["problem"] == "reentry"
        with ClosedLoop(problem.wiring, fmu_dir / "Reentry.fmu",
                        d / f"ReentryLaw{r['k']}.fmu") as loop:
            f = problem.evaluate([loop.run(s) for s in problem.initial_states]).f
        assert f == pytest.approx((float(r["J1"]), float(r["J2"])), rel=1e-9)
    assert not list(out.rglob("*ClosedLoop.fmu"))


def test_synthesize_refuses_native_without_compiler(fmu_dir, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.delenv("CC", raising=False)
    assert main(["synthesize", "reentry", "--law-fmu", "native", "--generations", "1",
                 "--out", str(tmp_path / "run"), "--fmus", str(fmu_dir)]) == 2
    assert "no C compiler found" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
