"""Run our SSP/FMUs in a native FMI host: ``ecos`` from the ``ecospy`` package.

A pythonfmu FMU embeds CPython: in a host that is not itself Python it needs

* ``LD_PRELOAD=<libpython3.x.so>`` -- the FMU's binary resolves CPython symbols at load time;
* ``PYTHONHOME`` -- the base installation of that Python (``sys.base_prefix``);
* ``PYTHONPATH`` -- the site-packages of an environment with the FMU's imports (numpy, ...).

:func:`python_host_env` computes them for the running interpreter; :func:`run_ecos` runs
``ecos simulate`` on an SSP (or FMU) and returns the last row of its CSV as a dict.  The
``ecos`` binary needs Debian's ``libtbb12`` (``apt-get install libtbb12``).
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
from pathlib import Path

__all__ = ["python_host_env", "ecos_binary", "run_ecos", "EcosUnavailable"]


class EcosUnavailable(RuntimeError):
    """ecospy is not installed or its ``ecos`` binary cannot run here (e.g. no libtbb12)."""


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
