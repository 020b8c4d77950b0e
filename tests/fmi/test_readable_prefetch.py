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


# A law genetic programming grew on the parking-box problem (cube of cubes of sums under tanh and
# sin): SymPy's automatic evaluation of its readable form ran for minutes without end in a run's
# report (over 20 s here each time it was tried).  Its arcs (source, target, operation; the
# diagonal: binary operations) as the run stored them.
_GROWN = {"nx": 3, "q": [0.2831632081399176], "outputs": [24, 25], "size": 25,
          "bounds": [[-1.0, 1.0], [-1.0, 1.0]], "input_names": ["x", "y", "theta"],
          "arcs": [[0, 4, 14], [0, 5, 1], [0, 6, 14], [0, 9, 1], [0, 13, 1], [0, 19, 1],
                   [2, 6, 1], [2, 9, 1], [2, 14, 1], [2, 17, 1], [2, 24, 3], [3, 4, 14],
                   [4, 4, 1], [4, 5, 1], [5, 5, 1], [5, 7, 14], [5, 10, 14], [6, 6, 1],
                   [6, 7, 1], [6, 11, 1], [7, 7, 1], [7, 8, 14], [8, 8, 1], [8, 16, 14],
                   [9, 9, 1], [9, 10, 14], [10, 10, 1], [10, 12, 14], [11, 11, 1], [11, 12, 1],
                   [12, 12, 1], [12, 13, 1], [13, 13, 2], [13, 15, 14], [14, 14, 1],
                   [14, 15, 1], [15, 15, 1], [15, 16, 1], [16, 16, 1], [16, 18, 1],
                   [17, 17, 1], [17, 18, 1], [18, 18, 1], [18, 19, 1], [19, 19, 1],
                   [19, 20, 3], [20, 20, 1], [20, 21, 8], [21, 21, 1], [21, 22, 8],
                   [22, 22, 1], [22, 23, 12], [23, 23, 1], [24, 24, 1]]}


def _grown() -> NetworkOperator:
    d = dict(_GROWN)
    n = d.pop("size")
    psi = np.zeros((n, n), dtype=int)
    for i, j, op in d.pop("arcs"):
        psi[i, j] = op
    return NetworkOperator.from_dict({**d, "psi": psi.tolist()})


def test_a_law_sympy_cannot_finish_gets_its_network_operator_print(tmp_path, monkeypatch):
    # oracle: the law's own network-operator print (law.formula), the report's stand-in for a
    # form SymPy could not give; the limit made short so that the test stays short (SymPy takes
    # over 20 s on this law, 40 x the limit here)
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path))
    monkeypatch.setattr(law_files, "_READABLE", {})
    default = law_files.READABLE_SECONDS
    monkeypatch.setattr(law_files, "READABLE_SECONDS", 0.5)
    law = _grown()
    law_files.prefetch_readable([law], processes=1)
    d = law_files._readable(law)
    assert d["text"] == law.formula(6)
    assert d["error"].startswith("ReadableTimeout: SymPy took over 0.5 s")
    # kept in the cache folder: the next run reads the stand-in instead of waiting again
    monkeypatch.setattr(law_files, "_READABLE", {})
    law_files.prefetch_readable([law], processes=1)
    assert law_files._readable(law) == d and len(list(tmp_path.rglob("*.json"))) == 1
    # a law SymPy finishes (in 30-50 ms) is untouched by the default limit: its form as
    # computed alone
    monkeypatch.setattr(law_files, "READABLE_SECONDS", default)
    basic = _laws()[0]
    assert law_files._readable(basic) == basic.readable().to_dict()


def test_the_time_limit_escapes_code_that_swallows_exceptions():
    # SymPy catches Exception in places: a timeout raised there once was swallowed and the
    # report waited without end (seen in CI).  The limit is a BaseException, raised again every
    # READABLE_RETRY_SECONDS: it leaves a loop that swallows every Exception, within a second
    # of CPU time (the limit's clock; oracle: the loop itself, which never ends on its own),
    # and leaves no timer behind
    import signal
    import time
    t0, c0 = time.monotonic(), time.process_time()
    with pytest.raises(law_files.ReadableTimeout):
        with law_files._time_limit(0.2):
            while time.monotonic() - t0 < 60:
                try:
                    sum(range(10_000))
                except Exception:        # noqa: BLE001 (the point of the test)
                    pass
    assert time.process_time() - c0 < 1.0
    assert signal.getitimer(signal.ITIMER_PROF) == (0.0, 0.0)


def test_the_time_limit_counts_cpu_time_not_the_clock():
    # A busy machine stretches the clock, not the CPU time SymPy needs: the limit counts this
    # process's CPU time (oracle: time.process_time against time.monotonic), so that a law's
    # form never depends on the machine's load.  Here the block waits 0.6 s of the clock with
    # almost no CPU time -- over a 0.3 s limit of the clock, far under one of CPU time -- and
    # then burns CPU until the limit stops it
    import time
    t0, c0 = time.monotonic(), time.process_time()
    with pytest.raises(law_files.ReadableTimeout):
        with law_files._time_limit(0.3):
            time.sleep(0.6)                          # no timeout here: no CPU time spent
            slept = time.monotonic() - t0
            while time.monotonic() - t0 < 30:
                sum(range(10_000))
    cpu = time.process_time() - c0
    assert slept >= 0.6 and 0.25 <= cpu <= 1.0, (slept, cpu)
