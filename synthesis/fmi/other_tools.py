"""Run our SSP/FMUs in other FMI hosts: ``ecos`` (ecospy) and libcosim (libcosimpy).

A pythonfmu FMU embeds CPython: in a host that is not itself Python it needs

* ``LD_PRELOAD=<libpython3.x.so>`` -- the FMU's binary resolves CPython symbols at load time;
* ``PYTHONHOME`` -- the base installation of that Python (``sys.base_prefix``);
* ``PYTHONPATH`` -- the site-packages of an environment with the FMU's imports (numpy, ...).

:func:`python_host_env` computes them for the running interpreter; :func:`run_ecos` runs
``ecos simulate`` on an SSP (or FMU) and returns the last row of its CSV as a dict.  The
``ecos`` binary needs Debian's ``libtbb12`` (``apt-get install libtbb12``).

:func:`run_libcosim` loads an SSP into the Open Simulation Platform's libcosim (its C library
through ``libcosimpy``, in this process) and flies it with libcosim's fixed-step master; it
returns the observed variables at every communication point.  libcosim runs in this process,
so it takes the native FMUs (``fmus/native/*.ssp``), which need no Python in the host.

Both hosts are Jacobi masters: every component steps from the values the others had at the
start of the step, so the controller acts on y(t_k-1) -- compare with
``ClosedLoop.run(..., scheme="jacobi")``.
"""
from __future__ import annotations

import csv
import os
import shutil
import site
import stat
import subprocess
import sys
import sysconfig
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["python_host_env", "ecos_binary", "run_ecos", "EcosUnavailable", "run_libcosim",
           "LibcosimUnavailable", "HostRun"]


class EcosUnavailable(RuntimeError):
    """ecospy is not installed or its ``ecos`` binary cannot run here (e.g. no libtbb12)."""


class LibcosimUnavailable(RuntimeError):
    """libcosimpy is not installed or its libcosim library cannot be loaded here."""


def python_host_env(base: dict | None = None) -> dict:
    """Environment variables that let a native FMI host load our pythonfmu FMUs."""
    env = dict(os.environ if base is None else base)
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    ldlib = sysconfig.get_config_var("LDLIBRARY") or ""
    lib = Path(libdir) / ldlib
    if not lib.exists():
        raise EcosUnavailable(f"no shared libpython at {lib}: this Python was built without "
                              f"--enable-shared, so native hosts cannot load pythonfmu FMUs")
    env["LD_PRELOAD"] = str(lib)
    env["PYTHONHOME"] = sys.base_prefix
    # the FMUs carry their own modules; the environment gives numpy & co.
    env["PYTHONPATH"] = os.pathsep.join(site.getsitepackages())
    return env


def ecos_binary() -> Path:
    """Path of the ``ecos`` executable shipped by ecospy (made executable if needed)."""
    try:
        import ecospy
    except ImportError:
        raise EcosUnavailable("ecospy is not installed: pip install ecospy") from None
    except OSError as exc:            # its library loads libtbb at import
        raise EcosUnavailable(f"ecospy cannot load ({exc}); ecos needs Debian's libtbb12: "
                              f"apt-get install libtbb12") from None
    exe = Path(ecospy.__file__).parent / "binaries" / ("ecos.exe" if os.name == "nt" else "ecos")
    if not exe.exists():
        raise EcosUnavailable(f"ecospy ships no ecos binary at {exe}")
    if not os.access(exe, os.X_OK):
        try:
            exe.chmod(exe.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
        except OSError as exc:
            raise EcosUnavailable(f"{exe} is not executable: {exc}") from None
    return exe


def _csv_config(log: dict) -> str:
    comps = "".join(
        f'<ecos:component name="{c}">' + "".join(f'<ecos:variable name="{v}"/>' for v in vs)
        + "</ecos:component>" for c, vs in log.items())
    return ('<?xml version="1.0" encoding="UTF-8"?>\n<ecos:CsvConfig xmlns:ecos='
            '"http://github.com/Ecos-platform/libecos/resources/schema/CsvConfig">'
            f"<ecos:components>{comps}</ecos:components></ecos:CsvConfig>\n")


def run_ecos(path, step: float, stop_time: float, log: dict, workdir=None,
             timeout: float = 300.0) -> dict:
    """Run ``ecos simulate`` on an SSP/FMU; return the last CSV row {``comp::var``: value}.

    ``log`` names the variables to write, {component: [variable, ...]} (ecos's CsvConfig).

    Raises
    ------
    EcosUnavailable
        If ecos cannot be started (missing package, missing libtbb12, no shared libpython).
    RuntimeError
        If ecos runs but fails or writes no CSV.
    """
    exe = ecos_binary()
    env = python_host_env()
    path = Path(path).resolve()
    own = workdir is None
    work = Path(tempfile.mkdtemp(prefix="ecos_")) if own else Path(workdir)
    try:
        (work / "CsvConfig.xml").write_text(_csv_config(log))
        proc = subprocess.run([str(exe), "simulate", "--path", str(path), "--stepSize",
                               repr(step), "--stopTime", repr(stop_time), "--noParallel",
                               "--csvConfig", str(work / "CsvConfig.xml")],
                              cwd=work, env=env, capture_output=True, text=True, timeout=timeout)
        if proc.returncode != 0:
            msg = (proc.stderr or proc.stdout).strip()
            if "libtbb" in msg:
                raise EcosUnavailable("ecos needs Debian's libtbb12: apt-get install libtbb12")
            raise RuntimeError(f"ecos failed ({proc.returncode}): {msg[-2000:]}")
        csvs = sorted(p for p in work.glob("*.csv"))
        if not csvs:
            raise RuntimeError(f"ecos wrote no CSV: {proc.stdout[-2000:]}")
        with open(csvs[0], newline="") as fh:
            rows = list(csv.reader(fh))
        header = [h.strip() for h in rows[0]]
        last = rows[-1]
        out = {}
        for name, value in zip(header, last):
            key = name.rsplit("[", 1)[0] if name.endswith("]") and "::" in name else name
            try:
                out[key] = float(value)
            except ValueError:
                out[key] = value.strip()
        return out
    finally:
        if own:
            shutil.rmtree(work, ignore_errors=True)


@dataclass
class HostRun:
    """The observed variables of a flight in an external host.

    Attributes
    ----------
    time : ndarray
        The communication points t_1 .. t_n after each step [s].
    series : dict of str -> ndarray
        ``"component::variable"`` -> its value at ``time``.
    """

    time: np.ndarray
    series: dict

    @property
    def final(self) -> dict:
        """``"component::variable"`` -> its value at the last communication point."""
        return {k: v[-1].item() for k, v in self.series.items()}


_NANO = 10 ** 9           # libcosim's clock counts integer nanoseconds


def _libcosim():
    try:
        from libcosimpy import CosimExecution, CosimLogging, CosimObserver
    except ImportError:
        raise LibcosimUnavailable("libcosimpy is not installed: pip install libcosimpy") from None
    except OSError as exc:         # its shared library did not load
        raise LibcosimUnavailable(f"libcosimpy cannot load libcosim ({exc})") from None
    CosimLogging.log_output_level(CosimLogging.CosimLogLevel.ERROR)
    return CosimExecution.CosimExecution, CosimObserver.CosimObserver


def run_libcosim(path, step: float, stop_time: float, log: dict) -> HostRun:
    """Fly the SSP ``path`` in libcosim (fixed step ``step`` [s], to ``stop_time`` [s]) and
    return the variables ``log`` names ({component: [variable, ...]}) at every communication
    point.  ``step`` and ``stop_time`` must be whole nanoseconds (libcosim's clock).

    Raises
    ------
    LibcosimUnavailable
        libcosimpy missing or not loadable.
    ValueError
        A step or stop time that is not whole nanoseconds, an unknown component or variable.
    RuntimeError
        libcosim cannot load the SSP or fails while simulating.
    """
    execution_cls, observer_cls = _libcosim()
    step_ns, stop_ns = round(step * _NANO), round(stop_time * _NANO)
    if step_ns <= 0 or step_ns / _NANO != step or stop_ns / _NANO != stop_time:
        raise ValueError(f"libcosim steps whole nanoseconds: step {step!r} s and stop time "
                         f"{stop_time!r} s must be such (and the step > 0)")
    try:
        ex = execution_cls.from_ssp_file(str(Path(path).resolve()), step_size=step_ns)
    except AssertionError as exc:           # libcosimpy reports failures by assert
        raise RuntimeError(f"libcosim cannot load {path}: {exc}") from None
    n = -(-stop_ns // step_ns)
    observer = observer_cls.create_time_series(buffer_size=n + 1)
    ex.add_observer(observer)
    wanted = []
    for comp, names in log.items():
        index = ex.slave_index_from_instance_name(comp)     # None or -1 if there is none
        if index is None or index < 0:
            raise ValueError(f"{Path(path).name} has no component {comp!r}")
        refs = {_text(v.name): (v.reference, v.type) for v in ex.slave_variables(index)}
        for name in names:
            if name not in refs:
                raise ValueError(f"component {comp!r} has no variable {name!r}")
            wanted.append((f"{comp}::{name}", index, *refs[name]))
    kinds = _variable_kinds()
    for _, index, ref, type_ in wanted:
        observer.start_time_series(index, ref, kinds[type_])
    if not ex.simulate_until(stop_ns):
        raise RuntimeError(f"libcosim failed while simulating {Path(path).name}")
    return _samples(observer, wanted, n, step_ns)


def _text(name) -> str:
    return name.decode() if isinstance(name, bytes) else name


def _variable_kinds() -> dict:
    from libcosimpy.CosimEnums import CosimVariableType
    return {t.value: t for t in CosimVariableType}


def _samples(observer, wanted, n: int, step_ns: int) -> HostRun:
    """The observed series from step 1 on (libcosimpy's reader trims samples of step 0)."""
    series, steps = {}, None
    for key, index, ref, type_ in wanted:
        read = (observer.time_series_real_samples if type_ == 0
                else observer.time_series_integer_samples)
        _, step_numbers, values = read(index, ref, from_step=1, sample_count=n)
        if steps is None:
            steps = list(step_numbers)
        elif list(step_numbers) != steps:
            raise RuntimeError(f"libcosim observed {key} at other steps than the others")
        series[key] = np.array(values)
    times = np.array(steps if steps is not None else [], dtype=np.int64) * step_ns / _NANO
    return HostRun(time=times, series=series)
