"""A session started from deploy/process-compose.yaml with the real services: `access` writes
the session's credentials first, every service opens its link with its own, the readiness probes
with the experimenter's; a Zenoh client without them is refused on the session's port, so the
STOP, robot command and TASK_FINISHED it would forge never reach the run, whose task finishes."""

from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
from pathlib import Path

import pytest

from hrc.bus import Keys

from .conftest import HRC, ROOT, free_port, wait_until
from .test_intruders import FORGED, forge, intruder

pytestmark = [pytest.mark.e2e]
# Robots 10 times slower than the thesis's: the lockstep run (the deployment's default) outlives
# the intruder's tries (the thesis's own, 11,489 ticks, once ended in 4 s, before them)
SLOW = ("max_tcp_speed = 0.5", "max_tcp_speed = 0.05")
PC_BIN = ROOT / "tools" / "bin" / "process-compose"
PC_FILE = ROOT / "deploy" / "process-compose.yaml"


@pytest.mark.timeout(400)
def test_a_deployed_session_admits_only_its_own_services(tmp_path: Path) -> None:
    if not PC_BIN.exists():
        pytest.skip(
            "tools/bin/process-compose not built "
            "(scripts/setup.sh --with-process-compose builds it)"
        )
    session, port = f"dep{os.getpid()}", free_port()
    out, access = tmp_path / "trial", tmp_path / "access"
    thesis = (ROOT / "scenarios" / "thesis.toml").read_text()
    assert thesis.count(SLOW[0]) == 2
    scenario = tmp_path / "thesis-slow.toml"
    scenario.write_text(thesis.replace(*SLOW))
    env = {k: v for k, v in os.environ.items() if not k.startswith(("HRC_", "PC_"))}
    env.update(
        HRC_ROOT=str(ROOT),
        HRC_SESSION=session,
        HRC_PORT=str(port),
        HRC_TICKS="0",  # until the task is finished
        HRC_SCENARIO=str(scenario),
        HRC_OUT=str(out),
        HRC_ACCESS=str(access),
    )
    cmd = [str(PC_BIN), "-f", str(PC_FILE), "up", "--no-server", "-t=false"]
    cmd += ["-L", str(tmp_path / "pc.log")]
    proc = subprocess.Popen(
        cmd,
        env=env,
        cwd=tmp_path,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    try:
        folder = access / session
        experimenter = folder / "experimenter.json5"
        assert wait_until(experimenter.exists, 60, 0.1), "no credentials written"
        assert stat.S_IMODE(folder.stat().st_mode) == 0o700
        assert stat.S_IMODE(experimenter.stat().st_mode) == 0o600
        tcp = f"tcp/127.0.0.1:{port}"
        probe = [HRC, "alive", "physics", "--session", session, "--zenoh-mode", "client"]
        probe += ["--connect", tcp, "--wait", "30"]
        # the experimenter's credentials let a tool in; none, or a guess, do not
        alive = subprocess.run(
            [*probe, "--zenoh-config", str(experimenter)], capture_output=True, text=True
        )
        assert alive.returncode == 0, alive.stderr
        admitted = []
        for user in (None, ("orchestrator", "a guess"), ("intruder", "x")):
            s = intruder(tcp, user)
            if s is not None:
                admitted.append(user)
                forge(s, Keys(session))
                s.close()
        assert proc.poll() is None, "the session ended while the intruder tried"
        assert not admitted, admitted
        log, _ = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(30)
    # every service's errors (the first to fail is not always in the log's tail), then the tail
    errors = [ln for ln in log.splitlines() if " ERROR " in ln or "error:" in ln.lower()]
    assert proc.returncode == 0, "\n".join([*errors[:40], "...", log[-3000:]])
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["run"]["ok"] is True, metrics["run"]
    assert metrics["task"]["finished"] is True, metrics["task"]
    assert FORGED not in (out / "log.txt").read_text()
    assert FORGED not in (out / "events.jsonl").read_text()
