"""The readable forms of a run's Pareto laws at once (synthesis/fmi/law_files.prefetch_readable).

Oracle: each law's readable form computed alone in this process (``law.readable().to_dict()``,
the route every law took before); the batch -- in forked processes, then read back from the cache
folder -- must give exactly the same dictionaries.
"""
from __future__ import annotations

import numpy as np
import pytest

from descent_fmus.synthesis.fmi import law_files
from descent_fmus.synthesis.methods.law import NetworkOperator


def _laws() -> list:
    # the reentry problem's basic law and variants: other parameters and an extra connection
    from descent_fmus.synthesis.registry import get_problem
    base = get_problem("reentry").basic()
    out = []
    for k in range(4):
        d = base.to_dict(formula=False)
        d["q"] = [v * (1.0 + 0.25 * k) + 0.125 * k for v in d["q"]]
        if k % 2:
            psi = np.array(d["psi"])
            free = [(i, j) for j in range(psi.shape[0]) for i in range(j)
                    if psi[i, j] == 0 and psi[j, j] and i >= base.nx]
            i, j = free[k]
            psi[i, j] = 1                         # the identity operation on a new edge
            d["psi"] = psi.tolist()
        out.append(NetworkOperator.from_dict(d))
    return out


def test_prefetched_forms_equal_each_law_alone(tmp_path, monkeypatch):
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path))
    monkeypatch.setattr(law_files, "_READABLE", {})
    laws = _laws()
    alone = [law.readable().to_dict() for law in laws]
    assert len({d["exact"] for d in alone}) == len(laws)        # four different laws
    ran = []
    law_files.prefetch_readable(laws, processes=2, meanwhile=lambda: ran.append(1))
    assert ran == [1]
    assert [law_files.law_document(law)["readable"] for law in laws] == alone
    assert [law_files.readable_text(law) for law in laws] == [d["text"] for d in alone]
    kept = sorted(law_files._readable_folder().glob("*.json"))
    assert len(kept) == len(laws)


def test_a_second_run_reads_the_kept_forms(tmp_path, monkeypatch):
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path))
    monkeypatch.setattr(law_files, "_READABLE", {})
    laws = _laws()[:2]
    alone = [law.readable().to_dict() for law in laws]
    law_files.prefetch_readable(laws, processes=1)
    monkeypatch.setattr(law_files, "_READABLE", {})          # a new process: nothing in memory

    def compute(law):
        raise AssertionError("computed although the cache folder holds it")
    monkeypatch.setattr(law_files, "_compute_readable", compute)
    law_files.prefetch_readable(laws, processes=2)
    assert [law_files.law_document(law)["readable"] for law in laws] == alone


def test_another_formula_code_uses_another_folder(tmp_path, monkeypatch):
    # the folder's key covers SymPy's version and the formula code (a changed printer: new forms)
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path))
    first = law_files._readable_folder()
    monkeypatch.setattr("importlib.metadata.version", lambda name: "0.0-other")
    assert law_files._readable_folder() != first
    assert first.parent == tmp_path


@pytest.mark.parametrize("processes", [1, 2])
def test_a_failing_formula_still_gives_the_network_operator_print(tmp_path, monkeypatch,
                                                                  processes):
    # SymPy failing on a law: its text is the law's own print, and nothing is kept
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path))
    monkeypatch.setattr(law_files, "_READABLE", {})
    law = _laws()[0]
    monkeypatch.setattr(NetworkOperator, "readable", lambda self, digits=6: 1 / 0)
    law_files.prefetch_readable([law], processes=processes)
    d = law_files.law_document(law)["readable"]
    assert d["text"] == law.formula(6) and d["error"].startswith("ZeroDivisionError")
    assert not law_files._readable_folder().exists()
