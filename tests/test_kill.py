"""SIGKILL of any one service during a lockstep run ends the run promptly, naming it: within
2 s on a quiet machine; the test allows 4 s for a loaded one, still below every timeout a missed
death would fall back on (the 5 s the others get to leave, the 10 s barrier timeout)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import stat
import tempfile
import time
from pathlib import Path

import pytest

from hrc.bus import access

from .conftest import gone, wait_until


@pytest.mark.parametrize("victim", ["physics", "orchestrator", "ik_cpp", "human_input", "logger"])
def test_killing_a_service_ends_the_run_naming_it(trial_factory, victim: str) -> None:
    trial = trial_factory()
    trial.wait_ticking()
    pid = trial.service_pids()[victim]
    t0 = time.monotonic()
    os.kill(pid, signal.SIGKILL)
    code, _out, err = trial.communicate(timeout=30)
    elapsed = time.monotonic() - t0
    print(f"{victim}: run ended {elapsed:.2f} s after SIGKILL")
    assert code != 0
    assert f"'{victim}'" in err and "SIGKILL" in err, err
    assert elapsed < 4.0, f"took {elapsed:.2f} s"


def test_killing_hrc_run_itself_ends_every_service_keeping_metrics_and_its_folder_goes(
    trial_factory, monkeypatch
) -> None:
    """SIGKILL of ``hrc run`` (nothing of it can clean up): its services end, the orchestrator
    still writes metrics.json, and the trial's private folder (socket, credentials) is removed
    by the next run. The trial keeps its folders in a temporary folder of its own (TMPDIR): any
    other ``hrc run`` on the machine (another test worker's) would be that next run, at any
    moment."""
    private = Path(tempfile.mkdtemp(prefix="hrc-kill-"))  # short: the socket's path must fit
    monkeypatch.setattr(tempfile, "tempdir", str(private))
    trial = trial_factory(env={"TMPDIR": str(private)})
    trial.wait_ticking()
    pids = trial.service_pids()
    config = access.tool_config(trial.session)
    assert config is not None
    folder = config.parent
    assert stat.S_IMODE(folder.parent.stat().st_mode) == 0o700
    assert (folder / access.SOCKET).exists(), sorted(folder.iterdir())
    os.kill(trial.proc.pid, signal.SIGKILL)
    trial.proc.wait(timeout=10)

    assert wait_until(lambda: all(gone(p) for p in pids.values()), 15, 0.1), pids
    metrics = json.loads((trial.out / "metrics.json").read_text())
    assert metrics["run"]["ok"] is False and metrics["run"]["end_reason"], metrics["run"]
    assert folder.exists()  # nobody was left to remove it ...
    nxt = access.TrialAccess.create(f"next-{trial.session}", ["physics"])  # ... the next run does
    assert nxt is not None
    nxt.remove()
    assert not folder.exists()
    shutil.rmtree(private, ignore_errors=True)
