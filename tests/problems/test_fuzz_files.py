"""Fuzzing the two loaders a user feeds files to: problem files and law files.

Property (Hypothesis, a bounded number of examples so that it runs in CI): a random mutation of
a valid file -- a value replaced by a random one (huge or negative integers, NaN, infinities,
strings, lists, tables), a key removed or added, the text cut or a character changed -- never
raises anything but the loader's one-line error, never hangs (each load within Hypothesis'
deadline) and never allocates beyond the limits (traced peak of Python allocations per load);
otherwise it is a valid problem or law.  Oracle: the loaders' own contract (ProblemFileError /
LawFileError, one line naming the file).
"""
from __future__ import annotations

import json
import tracemalloc
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

try:
    import tomllib
except ModuleNotFoundError:          # Python 3.10
    import tomli as tomllib
import tomli_w

from descent_fmus.synthesis.methods.law import LawFileError, NetworkOperator
from descent_fmus.synthesis.problems.contract import SynthesisProblem
from descent_fmus.synthesis.problems.files import ProblemFileError, load_problem_file

ROOT = Path(__file__).resolve().parents[2]
TUTORIAL = ROOT / "docs" / "tutorials"
LAW = ROOT / "tests" / "reference" / "reentry_best_law.json"
#: Peak of traced Python allocations one load may reach [bytes] (a valid load: about 2 MB).
PEAK = 64 * 2 ** 20

VALUES = st.one_of(
    st.integers(min_value=-2 ** 63, max_value=2 ** 63 - 1),
    st.sampled_from([0, -1, 10 ** 9, 10 ** 18, 2 ** 62]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=20), st.booleans(),
    st.lists(st.integers(-10, 10 ** 9), max_size=6),
    st.dictionaries(st.text(max_size=6), st.integers(-5, 5), max_size=3),
)


def _paths(doc, prefix=()):
    """Every key path of a nested document (tables and lists of tables)."""
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield prefix + (k,)
            yield from _paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield prefix + (i,)
            yield from _paths(v, prefix + (i,))


def _mutate(doc, path, how, value):
    doc = json.loads(json.dumps(doc))                 # a deep copy of a JSON-able document
    *head, last = path
    node = doc
    for k in head:
        node = node[k]
    if how == "replace":
        node[last] = value
    elif how == "delete":
        del node[last]
    elif isinstance(node, dict):                      # "add": an unknown key beside it
        node[f"{last}_x"] = value
    return doc


@st.composite
def mutations(draw, doc):
    paths = list(_paths(doc))
    edits = draw(st.lists(st.tuples(st.sampled_from(paths),
                                    st.sampled_from(["replace", "delete", "add"]), VALUES),
                          min_size=1, max_size=3))
    for path, how, value in edits:
        try:
            doc = _mutate(doc, path, how, value)
        except (KeyError, IndexError, TypeError):
            pass                                      # an earlier edit removed the path
    return doc


def _load_within_limits(load):
    tracemalloc.start()
    try:
        return load()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert peak < PEAK, f"a load allocated {peak / 2 ** 20:.0f} MiB"


@pytest.fixture(scope="module")
def hopper(hopper_dir):
    """The tutorial's plant and its problem file, parsed."""
    return hopper_dir, tomllib.loads((hopper_dir / "hopper.toml").read_text())


def _check_problem_file(path: Path, fmu_dir):
    try:
        problem = _load_within_limits(lambda: load_problem_file(path, fmu_dir=fmu_dir))
    except ProblemFileError as exc:
        msg = str(exc)
        assert "\n" not in msg and str(path) in msg, msg
        return
    assert isinstance(problem, SynthesisProblem)


SETTINGS = settings(max_examples=120, deadline=5000, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow])


def test_the_valid_file_loads(hopper, fmu_dir):
    d, _ = hopper
    assert isinstance(load_problem_file(d / "hopper.toml", fmu_dir=fmu_dir), SynthesisProblem)


@SETTINGS
@given(data=st.data())
def test_mutated_problem_files_load_or_fail_in_one_line(hopper, fmu_dir, data):
    d, doc = hopper
    mutated = data.draw(mutations(doc))
    path = d / "mutated.toml"
    try:
        path.write_text(tomli_w.dumps(mutated))
    except (TypeError, ValueError):                   # not representable in TOML
        return
    _check_problem_file(path, fmu_dir)


@SETTINGS
@given(cut=st.integers(0, 4000), pos=st.integers(0, 4000),
       char=st.sampled_from(list("[]{}=\"'#,.\n0 9-e") + ["nan", "1e999", "\x00", "é"]))
def test_damaged_problem_file_text_loads_or_fails_in_one_line(hopper, fmu_dir, cut, pos, char):
    d, _ = hopper
    text = (TUTORIAL / "hopper.toml").read_text()
    text = text[:pos] + char + text[pos + 1:]
    path = d / "damaged.toml"
    path.write_text(text[:max(cut, 200)], encoding="utf-8")
    _check_problem_file(path, fmu_dir)


@SETTINGS
@given(data=st.data())
def test_mutated_law_files_load_or_fail_in_one_line(tmp_path_factory, data):
    doc = json.loads(LAW.read_text())
    mutated = data.draw(mutations(doc))
    path = tmp_path_factory.mktemp("law") / "law.json"
    path.write_text(json.dumps(mutated))
    try:
        law = _load_within_limits(lambda: NetworkOperator.load(path))
    except LawFileError as exc:
        assert "\n" not in str(exc), str(exc)
        return
    assert law.size <= 1024 and all(v == v for v in law.q)      # finite, bounded
