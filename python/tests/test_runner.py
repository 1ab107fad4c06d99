"""How hrc run wires a trial's services together (no processes started here)."""

from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from hrc import priority, service_table
from hrc.bus import access
from hrc.paths import project_root
from hrc.trial import TrialOptions, processes
from hrc.trial import options as trial_options
from hrc.trial.options import fits_lowlatency, service_argv

THESIS = project_root() / "scenarios" / "thesis.toml"
SERVICES = service_table.names()  # the clock master first


def _argv(name: str, sock: Path | None, lowlatency: bool) -> list[str]:
    opts = TrialOptions(scenario=THESIS)
    return service_argv(name, opts, "s1", 7471, Path("/tmp/trial"), sock, lowlatency)


def _values(argv: list[str], flag: str) -> list[str]:
    return [argv[i + 1] for i, a in enumerate(argv) if a == flag]


def test_physics_listens_on_the_port_and_the_socket_and_the_others_connect_to_the_socket() -> None:
    sock = Path("/tmp/hrc-s1.sock")
    assert _values(_argv("physics", sock, True), "--listen") == [
        "tcp/127.0.0.1:7471",
        f"unixsock-stream/{sock}",
    ]
    for name in SERVICES[1:]:
        assert _values(_argv(name, sock, True), "--connect") == [f"unixsock-stream/{sock}"], name


def test_without_a_socket_everything_goes_over_the_tcp_port() -> None:
    assert _values(_argv("physics", None, False), "--listen") == ["tcp/127.0.0.1:7471"]
    for name in SERVICES[1:]:
        assert _values(_argv(name, None, False), "--connect") == ["tcp/127.0.0.1:7471"], name


@pytest.mark.parametrize("lowlatency", [True, False])
def test_every_participant_gets_the_same_transport_and_observers_the_standard_one(
    lowlatency: bool,
) -> None:
    for name in SERVICES:
        asked = "--zenoh-lowlatency" in _argv(name, None, lowlatency)
        assert asked == (lowlatency and name not in service_table.OBSERVERS), name


def test_a_scenario_too_large_for_the_low_latency_transport_falls_back(monkeypatch) -> None:
    assert fits_lowlatency(THESIS)  # 18 parts: about 9 KiB on the wire
    monkeypatch.setattr(trial_options, "LOWLATENCY_MAX_SCENARIO_BYTES", 4096)
    assert not fits_lowlatency(THESIS)
    assert not fits_lowlatency(Path("/nonexistent/scenario.toml"))  # the orchestrator says why


def test_a_trials_private_folder_holds_its_socket_and_credentials(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    a = access.TrialAccess.create("s1", ["physics", "logger"])
    assert a is not None and a.folder == tmp_path / f"hrc-{os.getuid()}" / "s1"
    assert stat.S_IMODE(a.folder.parent.stat().st_mode) == 0o700
    assert stat.S_IMODE(a.folder.stat().st_mode) == 0o700
    assert a.socket == a.folder / "bus.sock"
    users = dict(line.split(":") for line in (a.folder / "users").read_text().splitlines())
    assert sorted(users) == ["experimenter", "logger", "physics"]
    assert len(set(users.values())) == 3  # a password each
    for name in users:
        cfg = json.loads(a.config(name).read_text())["transport"]["auth"]["usrpwd"]
        assert (cfg["user"], cfg["password"]) == (name, users[name])
        assert stat.S_IMODE(a.config(name).stat().st_mode) == 0o600
    assert access.tool_config("s1") == a.config("experimenter")
    # the router's access control: default deny, a key's own publishers only
    acl = json.loads(a.config("physics").read_text())["access_control"]
    assert acl["default_permission"] == "deny"
    putters = {
        u: sorted(
            k
            for r in acl["rules"]
            if r["id"] in p["rules"] and "put" in r["messages"]
            for k in r["key_exprs"]
        )
        for p in acl["policies"]
        for s in acl["subjects"]
        if s["id"] in p["subjects"] and len(s["usernames"]) == 1
        for u in s["usernames"]
    }
    # (and acks: a tool joining as an extra observer)
    assert putters["experimenter"] == ["hrc/s1/clock/ack/*", "hrc/s1/run/control/experimenter"]
    assert putters["logger"] == ["hrc/s1/clock/ack/logger"]
    assert "physics" not in putters  # physics's own puts never come in: nobody may make them
    assert "access_control" not in json.loads(a.config("logger").read_text())
    assert access.TrialAccess.create("s1", ["physics"]) is None  # one folder per session
    # a trial that joins other hosts' routers: files without credentials
    b = access.TrialAccess.create("s2", ["physics"], authenticate=False)
    assert b is not None and "auth" not in json.loads(b.config("physics").read_text())["transport"]
    assert "access_control" not in json.loads(b.config("physics").read_text())
    # what the router may drop: only what goes to the observers, known by their Zenoh ids
    qos = json.loads(a.config("physics").read_text())["qos"]["network"][0]
    assert qos["zids"] == [json.loads(a.config("logger").read_text())["id"]]
    assert qos["flows"] == ["egress"]
    assert qos["overwrite"] == {"congestion_control": "drop", "express": False}  # batched
    # the folder of a run that is gone goes with the next run; a living one stays
    (b.folder / "pid").write_text("999999999")
    access.TrialAccess.create("s3", ["physics"])
    assert a.folder.is_dir() and not b.folder.exists()
    a.remove()
    assert not a.folder.exists() and access.tool_config("s1") is None


def test_no_socket_where_its_path_would_be_too_long(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / ("x" * 100)))
    (tmp_path / ("x" * 100)).mkdir()
    a = access.TrialAccess.create("s1", ["physics"])
    assert a is not None and a.socket is None  # hrc run then uses the TCP port


IDLE_CHILD = (
    "import os, sys, threading, time\n"
    "os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))\n"
    "threading.Thread(target=time.sleep, args=(30,), daemon=True).start()\n"
    "print('idle', flush=True)\n"
    "time.sleep(30)\n"
)


@pytest.mark.skipif(not hasattr(os, "SCHED_IDLE"), reason="Linux scheduling policies")
def test_a_service_under_sched_idle_is_back_to_normal_priority_before_it_is_stopped() -> None:
    # Under SCHED_IDLE the logger gets no CPU while anything else runs, not even to act on the
    # stop: stop_all lifts it first, every thread of it.
    with subprocess.Popen([sys.executable, "-c", IDLE_CHILD], stdout=subprocess.PIPE) as child:
        try:
            assert child.stdout is not None and child.stdout.readline() == b"idle\n"
            tids = [int(t) for t in os.listdir(f"/proc/{child.pid}/task")]
            assert len(tids) >= 2
            assert all(os.sched_getscheduler(t) == os.SCHED_IDLE for t in tids)
            priority.leave_idle(child.pid)
            assert all(os.sched_getscheduler(t) == os.SCHED_OTHER for t in tids)
        finally:
            child.kill()
    priority.leave_idle(child.pid)  # gone: nothing to do, no error


def test_a_service_gets_the_signal_mask_hrc_run_had_not_the_held_stop_signals(tmp_path) -> None:
    group = processes.ServiceGroup(tmp_path)
    try:
        group.start("probe", [sys.executable, "-c", "print(open('/proc/self/status').read())"])
        assert group.procs["probe"].wait(timeout=30) == 0
    finally:
        group.stop_all(grace_s=1.0)
        group.close()
    status = (tmp_path / "services" / "probe.log").read_text()
    blocked = int(next(ln for ln in status.splitlines() if ln.startswith("SigBlk:")).split()[1], 16)
    assert blocked & (1 << (signal.SIGTERM - 1)) == 0
    assert blocked & (1 << (signal.SIGINT - 1)) == 0
    # and hrc run itself holds nothing once the service is started
    assert not signal.pthread_sigmask(signal.SIG_BLOCK, set()) & processes.STOP_SIGNALS


def test_observer_ids_are_ones_zenoh_accepts() -> None:
    """Zenoh refuses an id with a leading 0 digit (one hex id in 16 would have one)."""
    import zenoh

    for _ in range(200):
        zid = access.observer_ids(["logger", "physics"])
        assert list(zid) == ["logger"]
        zenoh.Config().insert_json5("id", json.dumps(zid["logger"]))


def test_hrc_run_waits_neither_for_a_hung_nor_for_a_stopped_service(tmp_path) -> None:
    """After the run's end: a service that uses no CPU (hung) is waited for LEAVE_IDLE_S at most,
    a stopped one not at all, and both are ended at once (SIGTERM would not reach the
    stopped one)."""
    import time

    group = processes.ServiceGroup(tmp_path)
    try:
        group.start("hung", ["sleep", "600"])
        group.start("stopped", ["sleep", "600"])
        os.kill(group.procs["stopped"].pid, signal.SIGSTOP)
        deadline = time.monotonic() + 10.0
        while group.stopped() != ["stopped"] and time.monotonic() < deadline:
            time.sleep(0.01)
        assert group.stopped() == ["stopped"]
        t0 = time.monotonic()
        processes.await_leaving(group, 60.0)
        waited = time.monotonic() - t0
        assert processes.LEAVE_IDLE_S <= waited < processes.LEAVE_IDLE_S + 3.0, waited
        t0 = time.monotonic()
        group.stop_all(grace_s=1.0)
        assert time.monotonic() - t0 < 3.0
        assert group.poll() == {"hung": -signal.SIGTERM, "stopped": -signal.SIGKILL}
    finally:
        group.stop_all(grace_s=0.5)
        group.close()


def test_a_services_own_error_is_told_from_its_echo_of_the_runs_end(tmp_path) -> None:
    """hrc run adds a service's own last error to a failed run's reason ("never came up" while
    the service had given up joining the bus): never the service's echo of that end."""
    group = processes.ServiceGroup(tmp_path)
    log = group.log_path("human_input")
    log.write_text(
        "2026-11-29 04:41:19,174 human_input INFO hrc.service: starting\n"
        "2026-11-29 04:42:19,174 human_input ERROR hrc.service: cannot join the trial's bus at "
        "unixsock-stream//tmp/x.sock: Unable to connect to any of [...]. Timeout!\n"
        "2026-11-29 04:42:19,175 human_input ERROR hrc.service: run ended with an error: "
        "services never came up within 60 s: human_input\n"
    )
    assert group.own_error("human_input") == (
        "cannot join the trial's bus at unixsock-stream//tmp/x.sock: "
        "Unable to connect to any of [...]. Timeout!"
    )
    log.write_text("a line\n2026-11-29 04:42:19,175 human_input ERROR x: run ended with an error\n")
    assert group.own_error("human_input") == ""
    assert group.own_error("logger") == ""  # no log at all
    group.close()
