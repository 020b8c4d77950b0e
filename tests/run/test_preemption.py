"""Long runs in real environments: signals, parent death, full disks, files only when asked.

Real processes throughout: ``descent-fmus synthesize`` started in its own session (its process
group holds every process of the run: the CLI and its pool workers), real signals, a real
size-limited tmpfs (mounted in a private user and mount namespace with ``unshare``).  Oracles:
the process table (/proc), the uninterrupted run of the same seed (same Pareto set), the
checkpoint file.
"""
from __future__ import annotations

import json
import os
import shlex
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from processes import cli, group, wait_empty

ROOT = Path(__file__).resolve().parents[2]
# the reentry problem as a problem file (the variational GA alone), a small budget
SMALL = ["--problem", ROOT / "synthesis/systems/reentry/reentry.toml", "--population", "16",
         "--crossovers", "6", "--lchr", "4", "--epoch", "3", "--seed", "6", "--refine-basis",
         "0", "--refine-evals", "0", "--flights", "0", "--basis-rule", "compromise",
         "--input-scaling", "given", "--equivalence-probes", "0", "--quiet",
         "--no-export", "--no-reference"]

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="reads the process table from /proc")


def _start_run(out: Path, fmu_dir, generations: int, *extra):
    proc = subprocess.Popen(cli("synthesize", *SMALL, "--generations", generations,
                                 "--fmus", fmu_dir, "--out", out, *extra),
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    deadline = time.time() + 180
    while time.time() < deadline and proc.poll() is None:
        try:
            if json.loads((out / "checkpoint.json").read_text())["generation"] >= 2:
                break
        except (OSError, ValueError, KeyError):
            pass
        time.sleep(0.05)
    assert proc.poll() is None, "the run ended before it could be interrupted"
    return proc


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM, signal.SIGINT],
                         ids=["SIGKILL", "SIGTERM", "SIGINT"])
def test_no_process_outlives_a_stopped_run(fmu_dir, tmp_path, sig):
    out = tmp_path / "run"
    proc = _start_run(out, fmu_dir, 40, "--workers", "2")
    pgid = proc.pid
    assert len(group(pgid)) >= 3                  # the CLI and its two pool workers
    if sig == signal.SIGINT:
        os.killpg(pgid, sig)                       # Ctrl-C reaches the whole group
    else:
        os.kill(proc.pid, sig)                     # a batch system signals the job's process
    _, stderr = proc.communicate(timeout=60)
    assert wait_empty(pgid) == [], "processes of the run survived it"
    if sig == signal.SIGKILL:
        return
    # one line: where the run stands and how to continue; exit 128 + signal number
    assert proc.returncode == 128 + sig, stderr
    line = stderr.strip().splitlines()[-1]
    assert f"interrupted by {signal.Signals(sig).name}: generation" in line
    # the hint repeats the program as it was launched (here: python -m ...)
    assert f"continue with: {shlex.join(cli()[:3])} synthesize --problem" in line
    assert line.endswith("--resume")
    ck = json.loads((out / "checkpoint.json").read_text())    # valid: it parses, it resumes
    assert ck["generation"] >= 2 and not list(out.glob("*.tmp"))


# a process that computes readable forms in a forked pool the way the report does and is
# SIGKILLed while its pool works (its ``meanwhile``); argv: cache folder, "watch" or "bare"
_REPORT_POOL = """
import functools, os, signal, sys
from descent_fmus.synthesis.fmi.law_files import prefetch_readable
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.run.signals import watch_parent
os.environ["DESCENT_FMUS_CACHE"] = sys.argv[1]
base = NetworkOperator.linear([[-1.0, -2.0, 0.5]], size=12)
laws = []
for k in range(8):
    d = base.to_dict(formula=False)
    d["q"] = [v * (1.0 + 0.5 * k) + 0.25 * k for v in d["q"]]
    laws.append(NetworkOperator.from_dict(d))
init = functools.partial(watch_parent, os.getpid()) if sys.argv[2] == "watch" else None
prefetch_readable(laws, processes=2, initializer=init,
                  meanwhile=lambda: os.kill(os.getpid(), signal.SIGKILL))
"""


@pytest.mark.parametrize("how", ["watch", "bare"])
def test_no_process_outlives_a_run_killed_while_its_report_is_written(tmp_path, how):
    # the report computes the Pareto laws' readable forms in a forked pool; a run SIGKILLed
    # then (seen in a full test run: the run's process group kept two pool workers alive,
    # blocked on their task queue, half an hour later).  With the report's initializer the
    # workers follow their parent within seconds; without it ("bare", the former pool) they
    # would not -- the oracle that this is the case the initializer fixes (they are then
    # killed here)
    proc = subprocess.Popen([sys.executable, "-c", _REPORT_POOL, str(tmp_path / "cache"), how],
                            cwd=ROOT, start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)    # no pipe a surviving worker holds
    proc.wait(timeout=120)
    assert proc.returncode == -signal.SIGKILL
    left = wait_empty(proc.pid, 10.0 if how == "watch" else 3.0)
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    assert (left == []) == (how == "watch"), left


def test_resume_after_sigterm_reproduces_the_uninterrupted_run(fmu_dir, tmp_path):
    ref = subprocess.run(cli("synthesize", *SMALL, "--generations", 10,
                              "--workers", 2, "--fmus", fmu_dir, "--out", tmp_path / "ref"),
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert ref.returncode == 0, ref.stderr
    out = tmp_path / "run"
    proc = _start_run(out, fmu_dir, 10, "--workers", "2")
    os.kill(proc.pid, signal.SIGTERM)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 143, stderr
    assert not (out / "pareto.csv").exists()
    res = subprocess.run(cli("synthesize", *SMALL, "--generations", 10,
                              "--workers", 2, "--fmus", fmu_dir, "--out", out, "--resume",
                              "--json"), cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["generations"] == 10
    assert (out / "pareto.csv").read_text() == (tmp_path / "ref" / "pareto.csv").read_text()


def test_no_process_outlives_a_run_that_fails(fmu_dir, tmp_path):
    # an exception ends the run (here: every candidate fails, a broken setup): exit 2 with the
    # FMU's message, and the pool's workers go with it
    toml = (ROOT / "synthesis/systems/reentry/reentry.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(toml.replace("states = [ {} ]", "states = [ { m = -5.0 } ]"))
    args = [a if a != SMALL[1] else bad for a in SMALL]
    proc = subprocess.Popen(cli("synthesize", *args, "--generations", 3, "--workers", 2,
                                 "--fmus", fmu_dir, "--out", tmp_path / "run"),
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    _, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 2, stderr
    assert "parameter m must be > 0, got -5.0" in stderr and "Traceback" not in stderr
    assert wait_empty(proc.pid) == []


def test_dask_local_cluster_dies_with_its_run(fmu_dir, tmp_path):
    # the Dask backend's own LocalCluster (--scheduler local): its nannies and worker
    # processes watch the run's process and go when it is killed
    proc = _start_run(tmp_path / "run", fmu_dir, 40, "--scheduler", "local", "--workers", "2")
    pgid = proc.pid
    assert len(group(pgid)) >= 3
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert wait_empty(pgid) == [], "Dask processes survived the run"


# -- full disks -----------------------------------------------------------------------------------
SMALL_DISK = r"""
set -u
mount -t tmpfs -o size={size} tmpfs "$MNT" || exit 97
"$@" > "$LOG.out" 2> "$LOG.err"
echo $? > "$LOG.rc"
cp "$MNT/run/checkpoint.json" "$LOG.checkpoint" 2>/dev/null
ls -A "$MNT/run" > "$LOG.ls" 2>/dev/null
exit 0
"""


def _on_small_disk(tmp_path, size, args):
    """Run ``args`` with ``$MNT`` a fresh tmpfs of ``size`` (private mount namespace)."""
    unshare = shutil.which("unshare")
    if unshare is None:
        pytest.skip("needs unshare (util-linux) for a size-limited tmpfs")
    mnt, log = tmp_path / "mnt", tmp_path / "log"
    mnt.mkdir()
    env = dict(os.environ, MNT=str(mnt), LOG=str(log))
    r = subprocess.run([unshare, "--user", "--map-root-user", "--mount", "sh", "-c",
                        SMALL_DISK.format(size=size), "sh", *map(str, args)],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    if r.returncode != 0 or not (tmp_path / "log.rc").exists():
        pytest.skip(f"cannot mount a tmpfs in a user namespace here: {r.stderr.strip()}")
    read = lambda ext: (tmp_path / f"log.{ext}").read_text() if (   # noqa: E731
        tmp_path / f"log.{ext}").exists() else None
    return mnt, int(read("rc")), read("err"), read("checkpoint"), read("ls")


def test_export_on_a_too_small_disk_names_the_folder(fmu_dir, tmp_path):
    # 2 MB: the run and its results fit, the export of the Pareto laws with their closed loops
    # (several MB per law) does not -- checked before writing anything of it
    run = tmp_path / "mnt" / "run"
    args = cli("synthesize", *[a for a in SMALL if a != "--no-export"], "--export", "all",
                "--generations", 3, "--workers", 1, "--fmus", fmu_dir, "--out", run)
    _, rc, err, checkpoint, listing = _on_small_disk(tmp_path, "2m", args)
    assert rc == 2, err
    line = err.strip().splitlines()[-1]
    assert f"not enough disk space in {run} for the export" in line, line
    assert "needs about" in line and "MB free" in line and "--resume" in line
    assert "Traceback" not in err
    assert json.loads(checkpoint)["generation"] == 3           # intact, resumable
    assert "laws" not in listing.split()                         # nothing of the export


def test_checkpoint_on_a_full_disk_names_the_folder(fmu_dir, tmp_path):
    # 16 kB: run.json fits, the first checkpoint does not (ENOSPC in the middle of the write)
    run = tmp_path / "mnt" / "run"
    args = cli("synthesize", *SMALL, "--generations", 3, "--workers", 1,
                "--fmus", fmu_dir, "--out", run)
    _, rc, err, checkpoint, listing = _on_small_disk(tmp_path, "16k", args)
    assert rc == 2, err
    line = err.strip().splitlines()[-1]
    assert f"no space left on the device of {run}" in line, line
    assert "Traceback" not in err
    assert checkpoint is None and listing.split() == []     # nothing half-written is left


# -- files only when asked -------------------------------------------------------------------------
def test_json_commands_write_nothing(fmu_dir, tmp_path):
    r = subprocess.run(cli("lunar-landing", "solve", "--json"), cwd=tmp_path,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    json.loads(r.stdout)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args", [
    ["problems"], ["info", "mars"], ["reentry", "fly"], ["mars", "fly"],
    ["lunar-landing", "fly"], ["lunar-landing", "solve"]],
    ids=lambda a: " ".join(a))
def test_commands_write_only_what_is_asked(fmu_dir, tmp_path, monkeypatch, capsys, args):
    from descent_fmus.synthesis.cli.main import main
    monkeypatch.chdir(tmp_path)
    fmus = ["--fmus", str(fmu_dir)] if args[-1] in ("fly",) else []
    assert main(args + fmus) == 0
    assert list(tmp_path.iterdir()) == []
    assert main(args + fmus + ["--json"]) == 0
    assert list(tmp_path.iterdir()) == []
    capsys.readouterr()
