"""The folder of a synthesis run: what was asked, the checkpoint, and the refusal to mix runs.

* ``run.json`` -- what was asked (problem, its source, method, recipe); a different run refuses
  the folder, and ``--resume`` continues only the same run;
* ``checkpoint.json`` -- the run loop's state at the last checkpoint (the method's state, the
  archive, the flights spent); written atomically, so a killed run never leaves a half-written
  file and resumes from the last one;
* ``flown.bin`` -- the 16-byte fingerprints of the laws flown so far, appended before each
  checkpoint (a resumed run counts a law flown before the stop as no new flight, as the
  uninterrupted run would); the checkpoint's flight count says how many of them it covers;
* ``behaviour.jsonl`` -- the outcome of the first law flown with each behaviour (the evaluator's
  equivalence test), one JSON line each, appended before each checkpoint (a resumed run gives a
  law equivalent to one flown before the stop that law's outcome, as the uninterrupted run
  would); the checkpoint's ``behaviour_bytes`` says how much of the file it covers;
* ``journal.jsonl`` -- the outcomes of the laws flown since the last checkpoint, one JSON line
  each, appended after every chunk of flights (:attr:`synthesis.run.evaluation.Evaluator.journal`)
  and emptied by the next checkpoint: a resumed run takes them instead of flying those laws
  again, so a stop loses only the chunk in flight, not the generation (a line a stop cut short
  is skipped).
"""
from __future__ import annotations

import json
import os

import numpy as np
from dataclasses import asdict
from pathlib import Path

__all__ = ["RunDirError", "RunFolder", "write_json", "run_spec", "recipe_defaults", "RUN_FILE",
           "CHECKPOINT",
           "FLOWN", "BEHAVIOUR", "JOURNAL"]

RUN_FILE, CHECKPOINT, FLOWN = "run.json", "checkpoint.json", "flown.bin"
BEHAVIOUR, JOURNAL = "behaviour.jsonl", "journal.jsonl"
#: Bytes of a law's fingerprint (:func:`synthesis.run.evaluation.law_key`).
FINGERPRINT = 16


class RunDirError(ValueError):
    """The output directory holds a different run (or no run to resume)."""


def write_json(path: Path, data, indent: int | None = 1) -> None:
    """Write ``data`` as JSON atomically (a temporary file renamed over the target);
    ``indent=None``: on one line, by the json module's C encoder.

    [choice] The checkpoint is written on one line: an indent sends ``json.dumps`` through its
    pure-Python encoder, which made most of a checkpoint's cost (about 280 kB each in a default
    S1 run); the report's files keep their indent for readers."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=indent, default=float))
    os.replace(tmp, path)


def run_spec(problem, method: str) -> dict:
    """What identifies a run: the problem and its source, the method and the whole recipe."""
    return {"problem": problem.name, "source": problem.source, "method": method,
            "seed": problem.budget.seed, "budget": asdict(problem.budget),
            "ga": asdict(problem.ga), "refine": asdict(problem.refine),
            "operations": [list(problem.unary), list(problem.binary)],
            "q_bits": list(problem.q_bits), "input_scaling": problem.input_scaling,
            **({"gp": asdict(problem.gp)} if method == "gp" else {})}


def recipe_defaults(problem) -> dict:
    """The defaults of the recipe's sections (``ga``, ``refine``, ``gp``) of ``problem``'s
    setting classes: what a setting added after a run was written means for that run."""
    return {k: asdict(type(getattr(problem, k))()) for k in ("ga", "refine", "gp")
            if hasattr(problem, k)}


def _differs(old, new, defaults: dict | None) -> bool:
    """``old`` (a run.json's field) differs from ``new``; a setting missing from an old
    section counts as its default.

    [choice] A run written before a setting existed resumes when the setting is at its default:
    a new setting's default keeps the behaviour it had before (the package's rule for new
    recipe settings), so the run is the same run; any other value is a different run."""
    if isinstance(old, dict) and isinstance(new, dict) and defaults:
        old = {**{k: v for k, v in defaults.items() if k in new and k not in old}, **old}
    return old != new


# the fields a resumed run may change: the budget's (a longer run of the same search)
_SAME = ("problem", "source", "method", "seed", "ga", "refine", "operations", "q_bits",
         "input_scaling", "gp")


class RunFolder:
    """A run's output folder (see the module docstring)."""

    def __init__(self, out):
        self.path = Path(out)
        self.run_file, self.checkpoint = self.path / RUN_FILE, self.path / CHECKPOINT
        self._behaviour_bytes = 0
        #: [choice] the outcomes' JSON text after the key (``id(outcome) -> (outcome, text)``)
        #: of the laws journaled since the last checkpoint: the checkpoint appends most of the
        #: same outcomes to ``behaviour.jsonl``, and encoding an outcome (its floats' shortest
        #: text) was most of either line's cost; held until that checkpoint
        self._texts: dict = {}

    def open(self, spec: dict, resume: bool, defaults: dict | None = None) -> dict | None:
        """Check the folder against ``spec`` and prepare it; the checkpoint to resume from
        (None for a fresh run). ``defaults`` (:func:`recipe_defaults`) stand for the settings
        a resumed run's ``run.json`` does not name (written before they existed).

        Raises
        ------
        RunDirError
            ``resume`` without a run, a different run, or a fresh run into a folder that
            holds anything (nothing is overwritten).
        """
        if resume:
            if not self.run_file.exists() or not self.checkpoint.exists():
                raise RunDirError(f"{self.path} holds no run to resume (no {RUN_FILE}/"
                                  f"{CHECKPOINT})")
            old = json.loads(self.run_file.read_text())
            if any(_differs(old.get(k), spec.get(k), (defaults or {}).get(k)) for k in _SAME):
                raise RunDirError(f"{self.path} holds a different run ({old.get('problem')}, "
                                  f"method {old.get('method')}, seed {old.get('seed')}); resume "
                                  f"it with the same options or choose another --out")
            write_json(self.run_file, spec)        # a larger budget is recorded
            return json.loads(self.checkpoint.read_text())
        if self.path.exists() and any(self.path.iterdir()):
            if self.run_file.exists():
                raise RunDirError(f"{self.path} already holds a run: continue it with --resume "
                                  f"or choose another --out (nothing was overwritten)")
            raise RunDirError(f"{self.path} is not empty and holds no descent-fmus run; choose "
                              f"another --out (nothing was overwritten)")
        self.path.mkdir(parents=True, exist_ok=True)
        write_json(self.run_file, spec)
        return None

    def save(self, state: dict, new_flown=(), new_behaviour=()) -> None:
        """Append the fingerprints and behaviour outcomes flown since the last checkpoint, then
        write the checkpoint (atomically); ``state["simulated"]`` is the number of fingerprints
        it covers (``state["behaviour_bytes"]`` is set here)."""
        covered = state["simulated"] - len(new_flown)
        _append(self.path / FLOWN, covered * FINGERPRINT, b"".join(new_flown))
        lines = "".join(_line("b", b, o, self._texts) for b, o in new_behaviour)
        self._texts = {}
        state["behaviour_bytes"] = _append(self.path / BEHAVIOUR,
                                           self._behaviour_bytes, lines.encode())
        write_json(self.checkpoint, state, indent=None)
        self._behaviour_bytes = state["behaviour_bytes"]
        (self.path / JOURNAL).unlink(missing_ok=True)     # the checkpoint covers it now

    def journal(self, outcomes) -> None:
        """Append ``(fingerprint, Outcome)`` pairs flown since the last checkpoint to
        ``journal.jsonl`` (see the module docstring)."""
        if outcomes:
            with open(self.path / JOURNAL, "a") as fh:
                fh.write("".join(_line("k", k, o, self._texts) for k, o in outcomes))

    def journaled(self) -> list:
        """The ``(fingerprint, Outcome)`` pairs of ``journal.jsonl`` (a line cut short by a
        stop is skipped)."""
        path = self.path / JOURNAL
        if not path.exists():
            return []
        out = []
        for text in path.read_text(errors="replace").splitlines():
            try:
                out.append(_outcome("k", json.loads(text)))
            except (ValueError, KeyError, TypeError):
                continue
        return out

    def behaviour(self, nbytes: int) -> list:
        """The ``(behaviour key, Outcome)`` pairs of the first ``nbytes`` of
        ``behaviour.jsonl`` (what the checkpoint covers)."""
        path = self.path / BEHAVIOUR
        data = path.read_bytes()[:nbytes] if path.exists() else b""
        self._behaviour_bytes = nbytes
        try:
            if len(data) != nbytes:
                raise ValueError("shorter than the checkpoint says")
            return [_outcome("b", json.loads(line)) for line in data.decode().splitlines()]
        except (ValueError, KeyError, TypeError) as exc:
            raise RunDirError(f"{path} does not hold what the checkpoint covers ({exc}): the "
                              f"run folder was altered") from None

    def flown(self, count: int) -> list:
        """The first ``count`` fingerprints of ``flown.bin`` (what the checkpoint covers)."""
        path = self.path / FLOWN
        data = path.read_bytes()[:count * FINGERPRINT] if path.exists() else b""
        if len(data) != count * FINGERPRINT:
            raise RunDirError(f"{path} holds {len(data) // FINGERPRINT} flown laws, the "
                              f"checkpoint counts {count}: the run folder was altered")
        return [data[i:i + FINGERPRINT] for i in range(0, len(data), FINGERPRINT)]


def _append(path: Path, covered: int, data: bytes) -> int:
    """Cut ``path`` to the ``covered`` bytes a checkpoint covers (a stop between an append and
    its checkpoint leaves bytes no checkpoint covers), append ``data`` durably; the new size."""
    if path.exists() and path.stat().st_size > covered:
        with open(path, "r+b") as fh:
            fh.truncate(covered)
    if data:
        with open(path, "ab") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
    return covered + len(data)


def _line(name: str, key: bytes, o, texts: dict | None = None) -> str:
    """One JSON line: ``key`` (hex, under ``name``) and the Outcome ``o`` -- the text of
    ``{name: key.hex(), "f": ..., "cv": ..., "extras": ...}`` as the encoder writes it (a hex
    key needs no escapes); ``texts``: the outcomes' texts encoded before, by ``id``."""
    got = texts.get(id(o)) if texts is not None else None
    if got is not None and got[0] is o:
        text = got[1]
    else:
        text = _ENCODER.encode({"f": list(o.f), "cv": o.cv, "extras": o.extras})
        if texts is not None:
            texts[id(o)] = (o, text)
    return f'{{"{name}": "{key.hex()}", {text[1:]}\n'


#: ``json.dumps(..., default=_plain)``'s encoder, made once (the same text: one line per law)
_ENCODER = json.JSONEncoder(default=lambda value: _plain(value))


def _outcome(name: str, r: dict) -> tuple:
    """``(key, Outcome)`` of a :func:`_line` read back."""
    from descent_fmus.synthesis.problems.contract import Outcome
    return bytes.fromhex(r[name]), Outcome(tuple(r["f"]), r["cv"], r["extras"])


def _plain(value):
    """JSON for the NumPy values a problem's reported extras may hold."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")
