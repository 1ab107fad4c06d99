"""Fixtures for cross-service tests: real processes, real Zenoh sessions on loopback."""

from __future__ import annotations

import contextlib
import fcntl
import json
import logging
import os
import signal
import subprocess
import sys
import time
import uuid
from collections import Counter
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest
import zenoh

from hrc.bus import Bus, BusConfig, access
from hrc.paths import ik_binary, project_root
from hrc.ports import free_port  # tests import it from here too
from hrc.priority import carry_niceness
from hrc.service_table import EXPERIMENTER, SERVICES
from hrc.wire import pb

from .goldens import THESIS, Finished, run_trial

log = logging.getLogger(__name__)

ROOT = project_root()
HRC = str(Path(sys.executable).with_name("hrc"))
# what identifies each service's process on its command line (hrc run: python -m / the binary)
SERVICE_MARKERS = {s.name: s.module or s.script for s in SERVICES}


def strip_fields(obj: Any, fields: set[str]) -> Any:
    """``obj`` without the keys in ``fields`` at any depth (wall-clock fields, which legitimately
    differ between two runs of the same trial)."""
    if isinstance(obj, dict):
        return {k: strip_fields(v, fields) for k, v in obj.items() if k not in fields}
    if isinstance(obj, list):
        return [strip_fields(v, fields) for v in obj]
    return obj


def wait_until(pred, timeout: float = 10.0, step: float = 0.02) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(step)
    return bool(pred())


@pytest.fixture(scope="session")
def ik_bin() -> Path:
    path = ik_binary()
    if not path.exists():
        pytest.fail(
            f"{path} is missing: build it with scripts/setup.sh (the tests need the real "
            "C++ service)"
        )
    return path


def gone(pid: int) -> bool:
    """The process has ended (a zombie, reaped by nobody yet, counts as ended)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


def _children(pid: int) -> list[int]:
    out: list[int] = []
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as f:
            kids = [int(x) for x in f.read().split()]
    except OSError:
        return out
    for k in kids:
        out.append(k)
        out.extend(_children(k))
    return out


def _cmdline(pid: int) -> str:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def ignore_sigint() -> None:
    """A child's pre-exec: SIGINT ignored, as a script's background job (or nohup, or a CI
    runner) starts a program."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


# what a C++ or a Python service says when its bus connect timed out at start-up
BUS_UNREACHED = ("cannot open zenoh session", "cannot join the trial's bus")


class StartFailed(AssertionError):
    """A trial's service could not reach its bus at start-up (BUS_UNREACHED)."""


class Trial:
    """``hrc run`` in the background, with a test-side Zenoh session into its bus."""

    def __init__(
        self,
        scenario: str | Path,
        out: Path,
        ticks: int = 0,
        extra: Sequence[str] = (),
        env: dict[str, str] | None = None,
        sigint_ignored: bool = False,
    ) -> None:
        self._args = (scenario, ticks, list(extra), env, sigint_ignored)
        self.out = out
        self._start()

    def _start(self) -> None:
        scenario, ticks, extra, env, sigint_ignored = self._args
        self.session = f"it{uuid.uuid4().hex[:8]}"
        self.port = free_port()
        argv = [
            HRC,
            "run",
            str(scenario),
            "--out",
            str(self.out),
            "--ticks",
            str(ticks),
            "--session",
            self.session,
            "--port",
            str(self.port),
            *extra,
        ]
        self.proc = subprocess.Popen(
            argv,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            stdin=subprocess.DEVNULL,
            text=True,
            env={**os.environ, **(env or {})},
            start_new_session=True,  # its own process group, as a command typed in a terminal
            # as a script's background job (or nohup, or a CI runner) starts it
            preexec_fn=ignore_sigint if sigint_ignored else None,
        )
        if not {"realtime", "vr"} & set(extra):  # (a realtime trial keeps the wall clock's pace)
            carry_niceness(self.proc.pid)  # `nice scripts/test-all.sh`: the trials are nice too
        self._bus: Bus | None = None
        self.stdout = ""
        self.stderr = ""

    def bus(self, name: str = EXPERIMENTER) -> Bus:
        """The experimenter's side of the trial's bus (with its credentials: a stop goes on the
        experimenter's own key, which only this name may put on)."""
        if self._bus is None:
            self._bus = Bus(self.bus_config(), name)
        return self._bus

    def bus_config(self) -> BusConfig:
        """How a tool joins this trial: its TCP port, with the experimenter's credentials."""
        return access.join(self.session, self.port)

    def service_pids(self) -> dict[str, int]:
        pids: dict[str, int] = {}
        for pid in _children(self.proc.pid):
            cmd = _cmdline(pid)
            for name, marker in SERVICE_MARKERS.items():
                if marker in cmd and name not in pids:
                    pids[name] = pid
        return pids

    def stats(self, service: str, timeout: float = 30.0) -> pb.ServiceStats:
        """The service's ServiceStats; a generous bound by default: ik_cpp, busy refusing a
        20 MiB message's fragments beside the live trials, answered after more than 5 s once
        (fresh80)."""
        bus = self.bus()
        return bus.get_one(bus.keys.stats(service), pb.ServiceStats, timeout=timeout)

    def wait_ticking(self, min_tick: int = 20, timeout: float = 90.0) -> None:
        """Until the orchestrator has reached ``min_tick``. The default outlasts the clock
        master's start timeout (60 s, after hrc run's preparation: 9.5 s once on a loaded
        machine), so a service that never comes up is named by hrc run itself.

        A trial whose service could not reach its bus at start-up is started once more (in a
        folder of its own, ``<out>-again``): the first test of the tests that wait beside the
        live trials, at nice 10 while a page and its trial took both cores, saw ik_cpp's
        connect time out after 60 s (fresh80, 2026-12-02), and in fresh82 the test's own
        session did (the router, physics, at nice 10, accepted no link for 60 s): what these
        tests check comes after the start."""
        try:
            self._wait_ticking(min_tick, timeout)
        except StartFailed as exc:
            log.warning("the trial did not start (%s): started once more", exc)
            self.close()
            self.out = self.out.with_name(self.out.name + "-again")
            self._start()
            self._wait_ticking(min_tick, timeout)

    def _wait_ticking(self, min_tick: int, timeout: float) -> None:
        def ticking() -> bool:
            if self.proc.poll() is not None:
                rc, out, err = self.communicate()
                if "at start-up, before the first tick" in err and any(
                    said in err for said in BUS_UNREACHED
                ):
                    raise StartFailed(err.strip().splitlines()[0])
                raise AssertionError(f"hrc run ended early: {(rc, out, err)}")
            try:
                return self.stats("orchestrator", timeout=1.0).last_tick >= min_tick
            except TimeoutError:
                return False
            except zenoh.ZError as exc:  # the test's own session could not reach the router
                raise StartFailed(f"the test's session: {str(exc).split(' at /', 1)[0]}") from exc

        if not wait_until(ticking, timeout, 0.1):
            where = self.where_services_wait()  # before the stop changes it
            self.proc.send_signal(signal.SIGTERM)  # its output says where it was stuck
            _rc, out, err = self.communicate(timeout=30)
            raise AssertionError(
                f"the trial never started ticking within {timeout:g} s:\n{out[-2000:]}\n"
                f"{err[-3000:]}\nwhere each service's threads wait:\n{where}"
            )

    def where_services_wait(self) -> str:
        """Each service's threads (name, state, kernel wait channel) and its log's last line:
        what a stuck start-up leaves to read."""
        lines = []
        for name, pid in sorted(self.service_pids().items()):
            threads = []
            for task in sorted(Path(f"/proc/{pid}/task").glob("*")):
                try:
                    comm = (task / "comm").read_text().strip()
                    state = (task / "stat").read_text().rsplit(")", 1)[1].split()[0]
                    wchan = (task / "wchan").read_text().strip() or "-"
                except OSError:
                    continue
                threads.append(f"{comm}:{state}:{wchan}")
            log_file = self.out / "services" / f"{name}.log"
            try:
                said_lines = log_file.read_text(errors="replace").strip().splitlines()
            except OSError:
                said_lines = ["(no log)"]
            last = said_lines[-1] if said_lines else "(empty)"
            said = " ".join(f"{t} x{n}" if n > 1 else t for t, n in Counter(threads).items())
            lines.append(f"  {name} (pid {pid}): {said}\n    log: {last[-300:]}")
        return "\n".join(lines) or "  (no service process)"

    def stop(self, reason: str = "test done") -> None:
        bus = self.bus()
        bus.publisher(bus.keys.run_control(bus.sender)).put(
            pb.RunControl(command=pb.RunControl.COMMAND_STOP, reason=reason)
        )

    def communicate(self, timeout: float = 60.0) -> tuple[int, str, str]:
        try:
            out, err = self.proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            out, err = self.proc.communicate()
        self.stdout += out or ""
        self.stderr += err or ""
        return self.proc.returncode, self.stdout, self.stderr

    def close(self) -> None:
        if self._bus is not None:
            self._bus.close()
            self._bus = None
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        for pid in _children(self.proc.pid):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)


@pytest.fixture
def trial_factory(tmp_path: Path, ik_bin: Path) -> Iterator:
    trials: list[Trial] = []

    # --ticks is an exact length: a huge one keeps the trial going until the test stops it
    def make(
        scenario: str | Path = ROOT / "scenarios" / "empty.toml",
        ticks: int = 10**9,
        extra: Sequence[str] = (),
        name: str = "trial",
        env: dict[str, str] | None = None,
        sigint_ignored: bool = False,
    ) -> Trial:
        t = Trial(scenario, tmp_path / name, ticks, list(extra), env, sigint_ignored)
        trials.append(t)
        return t

    yield make
    for t in trials:
        t.close()


@pytest.fixture
def session_id() -> str:
    return f"s{uuid.uuid4().hex[:8]}"


def shared_trial(factory: pytest.TempPathFactory, name: str, scenario: Path) -> Finished:
    """`hrc run SCENARIO` once per test session, for every test that only reads its outputs:
    with pytest-xdist the first worker that asks runs it (under a file lock) and the others read
    its folder."""
    root = factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # the workers' base folders sit side by side in one folder
    folder = root / f"shared-{name}"
    with open(root / f"shared-{name}.lock", "a+") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        done = folder / "finished.json"
        if done.exists():
            return Finished(folder / "trial", **json.loads(done.read_text()))
        trial = run_trial(scenario, folder / "trial")
        folder.mkdir(parents=True, exist_ok=True)
        said = {"returncode": trial.returncode, "stdout": trial.stdout, "stderr": trial.stderr}
        done.write_text(json.dumps(said))
        return trial


@pytest.fixture(scope="session")
def thesis_trial(tmp_path_factory: pytest.TempPathFactory, ik_bin: Path) -> Finished:
    """The unmodified thesis trial (`hrc run scenarios/thesis.toml`), run once for every test that
    only reads its outputs (the golden files, the metrics, the logger's files). A test that needs
    a trial of its own, or two runs of one (determinism), runs them itself."""
    return shared_trial(tmp_path_factory, "thesis", THESIS)
