"""A trial's disk, small or filling up (hrc.diskspace.SpaceGuard):

- a folder with too little room is refused before the start, naming the figures;
- a disk that fills during a trial (the trial's own writing, lockstep; another process's,
  realtime) stops it within a second of reaching the margin, naming the disk (exit 3), and
  every record is whole: metrics.json written (room was kept aside for it), every line of
  events.jsonl a JSON object, log.txt's last line the end, the recording read by rerun.

The folder is a small tmpfs in a mount namespace of the test's own (needs root, or user
namespaces)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from datetime import datetime
from pathlib import Path

import pytest

from hrc import diskspace

from .conftest import HRC
from .goldens import THESIS, with_robot_speed

pytestmark = [pytest.mark.e2e]
MIB = 1024 * 1024


def _unshare() -> list[str]:
    if shutil.which("unshare") is None:
        pytest.skip("no unshare (util-linux)")
    return (
        ["unshare", "--mount"] if os.geteuid() == 0 else ["unshare", "--mount", "--map-root-user"]
    )


def _in_tmpfs(small: Path, copy: Path, size_mib: float, body: str) -> subprocess.CompletedProcess:
    """Runs the shell ``body`` with a tmpfs of ``size_mib`` mounted on ``small``; what it holds
    is copied to ``copy`` before the namespace (and the tmpfs) goes."""
    small.mkdir()
    script = (
        f"mount -t tmpfs -o size={int(size_mib * 1024)}k none {small} || exit 97; "
        f"{body}; rc=$?; cp -a {small}/t {copy} 2>/dev/null; exit $rc"
    )
    proc = subprocess.run(
        [*_unshare(), "sh", "-c", script],
        capture_output=True,
        text=True,
        timeout=300,
        stdin=subprocess.DEVNULL,
    )
    if proc.returncode == 97:
        pytest.skip(f"cannot mount a tmpfs here: {proc.stderr.strip()}")
    sys.stderr.write(proc.stderr[-2000:])
    return proc


def _whole_records(copy: Path, small: Path) -> dict:
    """Every record of a trial stopped for want of space is whole; returns its metrics."""
    assert not (copy / diskspace.RESERVE_FILE).exists()  # the room kept aside is given back
    metrics = json.loads((copy / "metrics.json").read_text())
    run = metrics["run"]
    assert run["ok"] is False and f"no space left on {small}/t" in run["end_reason"], run
    for jsonl in copy.rglob("*.jsonl"):  # every line, the last one too
        for line in jsonl.read_text().splitlines():
            json.loads(line)
    ends = [
        json.loads(line)
        for line in (copy / "events.jsonl").read_text().splitlines()
        if '"run_end"' in line
    ]
    assert ends and "no space left" in ends[-1]["reason"], ends
    lines = (copy / "log.txt").read_text().splitlines()
    assert lines[0].startswith("SETTINGS") and "no space left" in lines[-1], lines[-2:]
    rerun = str(Path(sys.executable).with_name("rerun"))
    shown = subprocess.run(
        [rerun, "rrd", "print", str(copy / "recording.rrd")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert shown.returncode == 0, shown.stderr[-2000:]
    assert shown.stdout.count("Chunk(") > 10, shown.stdout[-2000:]
    return metrics


def _failed_line(stderr: str) -> str:
    failed = [ln for ln in stderr.splitlines() if ln.startswith("trial FAILED")]
    assert failed, stderr[-3000:]
    assert "Traceback" not in stderr, stderr[-3000:]
    return failed[0]


def test_a_folder_with_too_little_room_is_refused_before_the_start(tmp_path: Path) -> None:
    small, copy = tmp_path / "small", tmp_path / "copy"
    proc = _in_tmpfs(small, copy, 2, f"{HRC} run {THESIS} --out {small}/t")
    assert proc.returncode == 2, proc.stderr[-3000:]
    need = diskspace.START_BYTES / MIB
    said = f"free on {small}/t: a trial needs at least {need:.1f} MiB to start"
    assert said in _failed_line(proc.stderr), proc.stderr[-2000:]


def test_a_trial_that_fills_its_disk_is_stopped_with_whole_records(tmp_path: Path) -> None:
    """Lockstep: the thesis trial with its robots at 0.2 m/s (twice as long: about 4 MB);
    on 2.6 MiB (0.5 kept aside, a 1 MiB margin) it reaches the margin at about a quarter of
    its run. (The plain thesis trial writes 2.2 MB and its logger may catch up after the run:
    on a loaded machine the run could end before the margin, then everything fits.)"""
    slow = with_robot_speed(THESIS, tmp_path, 0.2)
    small, copy = tmp_path / "small", tmp_path / "copy"
    proc = _in_tmpfs(small, copy, 2.6, f"{HRC} run {slow} --out {small}/t")
    assert proc.returncode == 3, proc.stderr[-3000:]
    assert f"no space left on {small}/t" in _failed_line(proc.stderr)
    metrics = _whole_records(copy, small)
    assert metrics["task"]["finished"] is False, metrics["task"]


def test_a_disk_filled_by_another_process_stops_a_realtime_trial_within_a_second(
    tmp_path: Path,
) -> None:
    """Realtime: once the trial runs, another process fills the disk to the margin; the
    trial's simulated time (which follows the wall clock) ends within a second of it."""
    small, copy = tmp_path / "small", tmp_path / "copy"
    log = f"{small}/t/services/logger.log"
    body = (
        f"{HRC} run {THESIS} --out {small}/t --mode realtime & pid=$!; "
        # the run is on once the logger's view is up (at most 60 s): its recording exists (a
        # stop that comes before, on a loaded machine, leaves the view unbuilt: no recording)
        f"n=0; while ! grep -qs 'view ready' {log} && [ $n -lt 600 ]; do sleep 0.1; "
        "n=$((n+1)); done; "
        "sleep 1; "
        # fill to 0.5 MiB below the margin, and note the wall clock of it
        f"free=$(df --output=avail -B1 {small} | tail -1); "
        f"fill=$(( free - {diskspace.LOW_BYTES} + 512 * 1024 )); "
        f"head -c $fill /dev/zero > {small}/filler; date +%s.%N > {small}/t/filled_at; "
        "wait $pid"
    )
    proc = _in_tmpfs(small, copy, 6, body)
    assert proc.returncode == 3, proc.stderr[-3000:]
    assert f"no space left on {small}/t" in _failed_line(proc.stderr)
    metrics = _whole_records(copy, small)
    # hrc run saw the disk at its margin, and asked for the stop, within a second of the fill
    filled_at = float((copy / "filled_at").read_text())
    said = [ln for ln in proc.stderr.splitlines() if " hrc ERROR " in ln and "no space" in ln]
    assert said, proc.stderr[-3000:]
    stamp = datetime.strptime(said[0][:23], "%Y-%m-%d %H:%M:%S,%f").timestamp()
    print(f"stop asked {stamp - filled_at:.2f} s after the fill")
    assert stamp - filled_at < 1.0, (said[0], filled_at)
    assert metrics["run"]["ticks"] > 0, metrics["run"]  # it was running
