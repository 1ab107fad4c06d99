"""One trial of a sweep: write its resolved scenario, run `hrc run` on it, read the outcome.

`run_job` is what a local worker thread or a Dask worker executes: plain data in, plain data
out (picklable), the five services started on the machine that runs it.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Collection
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from hrc import privacy
from hrc.priority import carry_niceness, format_cpus
from hrc.study.warm import WarmError, WarmStarter

if TYPE_CHECKING:
    from hrc.study.spec import Trial

log = logging.getLogger(__name__)

STDERR_TAIL_LINES = 12
OUTCOMES = ("ok", "failed", "stalled")
RECORDING_FILE = "participant-input.jsonl"  # a trial's recorded input, as live sessions keep it


@dataclass(frozen=True)
class Job:
    trial: str
    out: str  # the sweep folder (as the machine running the trial sees it)
    scenario_text: str
    seed: int
    input_hash: str
    timeout_s: float
    record: bool = False  # record the participant's input into the trial folder
    view: bool = True  # False: the trial keeps no 3D recording (hrc run --no-view)


@dataclass
class Record:
    """What became of one trial (kept in the sweep's manifest; one row of the table)."""

    trial: str
    input_hash: str
    outcome: str  # ok | failed | stalled
    reason: str = ""
    exit_code: int | None = None
    wall_s: float = 0.0
    host: str = ""
    finished_at: float = 0.0
    metrics: dict[str, Any] | None = field(default=None)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Record:
        return cls(**{k: d[k] for k in cls.__dataclass_fields__ if k in d})


class TrialProcess(Protocol):
    """An `hrc run` in progress: a subprocess, or a fork of the warm worker (hrc.study.warm)."""

    pid: int
    returncode: int | None

    def wait(self, timeout: float | None = None) -> int: ...

    def communicate(self, *, timeout: float | None = None) -> tuple[str, str]: ...


# the `hrc run` processes of this process's trials in progress (stop_running ends them)
_RUNNING: set[TrialProcess] = set()
_LOCK = threading.Lock()
# set by stop_running: a trial a worker thread starts after it is stopped at once (no trial may
# begin in the window between the snapshot of those running and the pool's shutdown)
_STOPPING = threading.Event()


def allow_trials() -> None:
    """A new sweep in this process may start trials again."""
    _STOPPING.clear()


def stop_running() -> None:
    """SIGTERM to every trial in progress here (an interrupted sweep): `hrc run` stops its
    services and exits; the records of these trials are dropped, so they run again next time."""
    with _LOCK:
        _STOPPING.set()
        procs = list(_RUNNING)
    for proc in procs:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)


def _tail(text: str, lines: int = STDERR_TAIL_LINES) -> str:
    return "\n".join(text.strip().splitlines()[-lines:])


def stop_process(proc: subprocess.Popen[Any] | TrialProcess, grace_s: float = 10.0) -> None:
    """SIGTERM to `hrc run`'s process group (it stops its services), then SIGKILL to the whole
    group after `grace_s`."""
    try:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(timeout=grace_s)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def start(argv: list[str], starter: WarmStarter | None) -> TrialProcess:
    """``argv`` (``python -m hrc.cli.main run ...``) in a session of its own: forked from the
    sweep's warm worker where there is one that works, else a new interpreter."""
    proc: TrialProcess | None = None
    if starter is not None and starter.alive():
        try:
            proc = starter.popen(argv)
        except WarmError as exc:
            log.warning("%s: this trial starts as a new interpreter", exc)
    if proc is None:
        proc = subprocess.Popen(
            argv,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            stdin=subprocess.DEVNULL,
            text=True,
            start_new_session=True,
        )
    carry_niceness(proc.pid)  # `nice hrc sweep` (or a nice test run): its trials are nice too
    return proc


def run_job(
    job: Job, starter: WarmStarter | None = None, cpus: Collection[int] | None = None
) -> Record:
    """Run one trial to its end (bounded by ``job.timeout_s`` of wall time), through the warm
    worker ``starter`` if given (the same outputs, less start-up), on ``cpus`` if given (the
    same outputs, `hrc run --cpus`)."""
    privacy.apply()  # a Dask worker's process too: what it writes here is participant data
    out = Path(job.out)
    scen = out / "resolved" / f"{job.trial}.toml"
    trial_dir = out / "trials" / job.trial
    scen.parent.mkdir(parents=True, exist_ok=True)
    scen.write_text(job.scenario_text, encoding="utf-8")
    if trial_dir.exists():  # an earlier, failed or different, run of this trial
        shutil.rmtree(trial_dir)
    argv = [
        sys.executable,
        "-m",
        "hrc.cli.main",
        "run",
        str(scen),
        "--out",
        str(trial_dir),
        "--seed",
        str(job.seed),
        "--no-reach-check",
    ]
    if job.record:
        argv += ["--record", str(trial_dir / RECORDING_FILE)]
    if not job.view:
        argv.append("--no-view")
    if cpus:
        argv += ["--cpus", format_cpus(cpus)]
    t0 = time.monotonic()
    host = os.uname().nodename
    # own process group: a timeout stops hrc run and everything it started
    proc = start(argv, starter)
    with _LOCK:
        _RUNNING.add(proc)
        stopping = _STOPPING.is_set()
    if stopping:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)
    try:
        stdout, stderr = proc.communicate(timeout=job.timeout_s)
        timed_out = False
    except subprocess.TimeoutExpired:
        stop_process(proc)
        stdout, stderr = proc.communicate()
        timed_out = True
    finally:
        with _LOCK:
            _RUNNING.discard(proc)
    wall = round(time.monotonic() - t0, 3)
    (trial_dir).mkdir(parents=True, exist_ok=True)
    (trial_dir / "hrc-run.log").write_text(stdout + stderr, encoding="utf-8")
    metrics = read_metrics(trial_dir / "metrics.json")
    rec = Record(job.trial, job.input_hash, "ok", "", proc.returncode, wall, host, time.time())
    rec.metrics = metrics
    timeout = f"timed out after {job.timeout_s:g} s of wall time (hrc run stopped)"
    rec.outcome, rec.reason = judge(proc.returncode, metrics, stderr, timeout if timed_out else "")
    return rec


def judge(
    returncode: int | None, metrics: dict[str, Any] | None, stderr: str, stopped: str = ""
) -> tuple[str, str]:
    """(outcome, reason) of one `hrc run`: `stopped` names why it was stopped, if it was."""
    run = (metrics or {}).get("run") or {}
    if stopped:
        return "failed", stopped
    if run.get("end_reason") == "stalled" or run.get("stall"):
        return "stalled", str(run.get("stall") or _tail(stderr, 1))
    if returncode != 0:
        return "failed", f"hrc run exited with code {returncode}: {_tail(stderr)}"
    if metrics is None:
        return "failed", "hrc run succeeded but wrote no readable metrics.json"
    return "ok", ""


def read_metrics(path: Path) -> dict[str, Any] | None:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


MANIFEST = "manifest.json"
DONE = ("ok", "stalled")  # outcomes a resumed sweep keeps (deterministic in the inputs)


class Manifest:
    """`<out>/manifest.json`: each trial's input hash and record, rewritten after every trial
    (atomically: an interrupted sweep leaves a readable manifest)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.records: dict[str, Record] = {}
        if path.exists():
            try:
                data = json.loads(path.read_text(encoding="utf-8"))
                self.records = {k: Record.from_dict(v) for k, v in data["trials"].items()}
            except (OSError, ValueError, KeyError, TypeError) as exc:
                log.warning("%s unreadable (%s): every trial runs again", path, exc)

    def done(self, trial: Trial) -> bool:
        rec = self.records.get(trial.id)
        return rec is not None and rec.input_hash == trial.input_hash and rec.outcome in DONE

    def put(self, rec: Record) -> None:
        self.records[rec.trial] = rec
        tmp = self.path.with_suffix(".tmp")
        doc = {"trials": {k: v.to_dict() for k, v in sorted(self.records.items())}}
        tmp.write_text(json.dumps(doc, indent=1), encoding="utf-8")
        os.replace(tmp, self.path)
