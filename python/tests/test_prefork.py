"""Python services forked from hrc run (hrc.trial.prefork) behave as new interpreters would.

Each case runs hrc run's ServiceGroup in a fresh interpreter (one thread, as hrc run is when it
starts the services) on a small probe module, and reads what the probe wrote to its log."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

PROBE = textwrap.dedent(
    """
    import atexit, json, logging, os, signal, sys, time
    what = sys.argv[1]
    atexit.register(lambda: print("own exit handler ran"))
    logging.basicConfig(level="INFO", format="probe %(levelname)s %(message)s")
    logging.getLogger("probe").info("logging configured by the service")
    print(json.dumps({
        "argv": sys.argv[1:],
        "name": __name__,
        "cmdline": open("/proc/self/cmdline", "rb").read().decode().replace("\\0", " ").strip(),
        "blocked": int(next(l for l in open("/proc/self/status") if l.startswith("SigBlk:"))
                       .split()[1], 16),
        "sigterm_default": signal.getsignal(signal.SIGTERM) == signal.SIG_DFL,
        "unbuffered": os.environ.get("PYTHONUNBUFFERED"),
        "stdin": sys.stdin.read(),
    }))
    if what == "exit3":
        sys.exit(3)
    if what == "message":
        sys.exit("the scenario is wrong")
    if what == "raise":
        raise RuntimeError("probe failed")
    if what == "interrupt":
        raise KeyboardInterrupt
    if what == "wait":
        print("waiting", flush=True)
        time.sleep(60)
    """
)

DRIVER = textwrap.dedent(
    """
    import atexit, json, sys, time
    from pathlib import Path
    from hrc.trial import processes
    from hrc.trial.prefork import ForkedProcess
    atexit.register(lambda: print("parent exit handler ran", file=sys.stderr))
    out, what = Path(sys.argv[1]), sys.argv[2]
    group = processes.ServiceGroup(out)
    group.start("probe", [sys.executable, "-m", "hrc_probe", what], "hrc_probe")
    p = group.procs["probe"]
    if what == "wait":
        log = out / "services" / "probe.log"
        while "waiting" not in log.read_text():
            time.sleep(0.01)
        p.send_signal(15)
    deadline = time.monotonic() + 30
    while group.poll()["probe"] is None and time.monotonic() < deadline:
        time.sleep(0.01)
    group.write_cpu()
    group.close()
    print(json.dumps({"forked": isinstance(p, ForkedProcess), "code": p.returncode}))
    """
)


def _start(tmp_path: Path, what: str, env: dict[str, str] | None = None) -> tuple[dict, str]:
    pkg = tmp_path / "mods" / "hrc_probe"
    pkg.mkdir(parents=True, exist_ok=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "__main__.py").write_text(PROBE)
    # OPENBLAS_NUM_THREADS as hrc run sets it: numpy then starts no threads, so hrc run may fork
    environ = dict(os.environ, PYTHONPATH=str(tmp_path / "mods"), OPENBLAS_NUM_THREADS="1")
    environ.update(env or {})
    environ.pop("HRC_PROFILE_DIR", None)
    done = subprocess.run(
        [sys.executable, "-c", DRIVER, str(tmp_path), what],
        capture_output=True,
        text=True,
        env=environ,
        timeout=60,
        stdin=subprocess.DEVNULL,
    )
    assert done.returncode == 0, done.stderr
    assert done.stderr.count("parent exit handler ran") == 1  # once: the child skips it
    return json.loads(done.stdout.splitlines()[-1]), (
        tmp_path / "services" / "probe.log"
    ).read_text()


def _report(log: str) -> dict:
    return json.loads(next(ln for ln in log.splitlines() if ln.startswith("{")))


def test_a_forked_service_looks_and_starts_like_a_new_interpreter(tmp_path) -> None:
    result, log = _start(tmp_path, "exit3")
    assert result == {"forked": True, "code": 3}
    report = _report(log)
    assert report["argv"] == ["exit3"]
    assert report["name"] == "__main__"
    assert report["cmdline"] == f"{sys.executable} -m hrc_probe exit3"  # what ps shows
    assert report["blocked"] & (1 << (signal.SIGTERM - 1)) == 0
    assert report["sigterm_default"]
    assert report["unbuffered"] == "1"
    assert report["stdin"] == ""
    # its own logging configuration took effect; its exit handlers ran, not hrc run's
    assert "probe INFO logging configured by the service" in log
    assert "own exit handler ran" in log
    assert json.loads((tmp_path / "services" / "cpu.json").read_text())["probe"]["user_s"] >= 0


@pytest.mark.parametrize(
    ("what", "code", "said"),
    [
        ("message", 1, "the scenario is wrong"),
        ("raise", 1, "RuntimeError: probe failed"),
        ("interrupt", -signal.SIGINT, "own exit handler ran"),
        ("wait", -signal.SIGTERM, "waiting"),
    ],
)
def test_a_forked_service_ends_as_an_interpreter_would(tmp_path, what, code, said) -> None:
    result, log = _start(tmp_path, what)
    assert result == {"forked": True, "code": code}
    assert said in log


def test_hrc_service_start_exec_starts_new_interpreters(tmp_path) -> None:
    result, log = _start(tmp_path, "exit3", {"HRC_SERVICE_START": "exec"})
    assert result == {"forked": False, "code": 3}
    assert _report(log)["cmdline"] == f"{sys.executable} -m hrc_probe exit3"
