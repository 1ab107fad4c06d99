"""A trial whose output folder fills up: hrc run says "no space left on <folder>" (exit 3, no
traceback of its own), and everything written so far stays readable (whole JSON lines, the
recording up to its last complete message), with no temporary file left. The folder is a 1 MiB
tmpfs in a mount namespace of the test's own (needs root, or user namespaces)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from .conftest import HRC, ROOT

THESIS = ROOT / "scenarios" / "thesis.toml"


def _unshare() -> list[str]:
    if shutil.which("unshare") is None:
        pytest.skip("no unshare (util-linux)")
    return (
        ["unshare", "--mount"] if os.geteuid() == 0 else ["unshare", "--mount", "--map-root-user"]
    )


def test_a_full_disk_ends_the_trial_saying_so_and_keeps_what_was_written(tmp_path) -> None:
    small, copy = tmp_path / "small", tmp_path / "copy"
    small.mkdir()
    # the tmpfs goes with the namespace: what the trial wrote is copied out before
    script = (
        f"mount -t tmpfs -o size=1m none {small} || exit 97; "
        f"{HRC} run {THESIS} --out {small}/t; rc=$?; cp -a {small}/t {copy}; exit $rc"
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
    assert proc.returncode == 3, proc.stderr[-3000:]
    failed = [ln for ln in proc.stderr.splitlines() if ln.startswith("trial FAILED")]
    assert failed and f"no space left on {small}/t" in failed[0], proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert not list(copy.rglob("*.tmp")), sorted(copy.rglob("*"))
    for jsonl in copy.rglob("*.jsonl"):  # every complete line parses
        lines = jsonl.read_text().splitlines()
        for line in lines[:-1]:
            json.loads(line)
    assert (copy / "log.txt").read_text().startswith("SETTINGS")  # what it holds is readable
    for js in ("metrics.json", "logger_stats.json"):
        if (copy / js).exists():
            json.loads((copy / js).read_text())
    # the recording reads up to its last complete message (it has no footer: never closed)
    rrd = copy / "recording.rrd"
    assert rrd.stat().st_size > 0
    rerun = str(Path(sys.executable).with_name("rerun"))
    shown = subprocess.run(
        [rerun, "rrd", "print", str(rrd)], capture_output=True, text=True, timeout=120
    )
    assert shown.returncode == 0, shown.stderr[-2000:]
    assert shown.stdout.count("Chunk(") > 10, shown.stdout[-2000:]
