"""Checks of the deployment files: the Zenoh router config, deploy/process-compose.yaml, scripts.

The process-compose tests run the real process-compose binary (built by scripts/setup.sh into
tools/bin/) against fake services, so they check what the file makes process-compose do: the
command lines, the readiness probes, and that one failing service ends the session non-zero.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import re
import socket
import stat
import subprocess
import time
from pathlib import Path

import pytest
import zenoh

ROOT = Path(__file__).resolve().parents[2]
ROUTER_CONFIG = ROOT / "deploy" / "zenoh-router.json5"
PC_FILE = ROOT / "deploy" / "process-compose.yaml"
PC_BIN = ROOT / "tools" / "bin" / "process-compose"
SERVICES = ("physics", "orchestrator", "ik_cpp", "human_input", "logger")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


# --------------------------------------------------------------------------- router config


def test_router_config_is_a_router_on_7447_without_multicast() -> None:
    cfg = zenoh.Config.from_file(str(ROUTER_CONFIG))
    assert json.loads(cfg.get_json("mode")) == "router"
    assert json.loads(cfg.get_json("listen/endpoints")) == ["tcp/0.0.0.0:7447"]
    assert json.loads(cfg.get_json("scouting/multicast/enabled")) is False


def test_router_config_routes_between_clients() -> None:
    """Two clients that cannot reach each other meet through a router made from the file."""
    port = _free_port()
    rcfg = zenoh.Config.from_file(str(ROUTER_CONFIG))
    rcfg.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))

    def client() -> zenoh.Config:
        c = zenoh.Config()
        c.insert_json5("mode", '"client"')
        c.insert_json5("scouting/multicast/enabled", "false")
        c.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
        return c

    got: list[bytes] = []
    with zenoh.open(rcfg), zenoh.open(client()) as a, zenoh.open(client()) as b:
        b.declare_subscriber("hrc/deploytest/data", lambda s: got.append(s.payload.to_bytes()))
        token = a.liveliness().declare_token("hrc/deploytest/alive/a")
        deadline = time.monotonic() + 10
        while not got and time.monotonic() < deadline:
            a.put("hrc/deploytest/data", b"hello")
            time.sleep(0.1)
        alive = [str(r.ok.key_expr) for r in b.liveliness().get("hrc/deploytest/alive/*", timeout=5)
                 if r.ok is not None]
        token.undeclare()
    assert got and got[0] == b"hello"
    assert alive == ["hrc/deploytest/alive/a"]


# --------------------------------------------------------------------------- process-compose

FAKE_SERVICE = """#!/bin/sh
# fake hrc service: records its command line, stays up a moment, then exits
echo "$(basename "$0") $*" > "$FAKE_DIR/argv-$(basename "$0")"
if [ "$(basename "$0")" = "${FAKE_FAIL:-}" ]; then sleep "${FAKE_SLEEP:-1}"; exit 3; fi
sleep "${FAKE_OTHERS_SLEEP:-${FAKE_SLEEP:-1}}"
exit 0
"""

FAKE_HRC = """#!/bin/sh
# fake `hrc alive`: records the probe and says yes
echo "$*" >> "$FAKE_DIR/probes"
exit 0
"""


def _fake_root(tmp: Path) -> Path:
    root = tmp / "root"
    (root / ".venv" / "bin").mkdir(parents=True)
    (root / "build" / "ik_cpp").mkdir(parents=True)
    exes = [root / ".venv" / "bin" / n for n in
            ("hrc-physics", "hrc-orchestrator", "hrc-human-input", "hrc-logger")]
    exes.append(root / "build" / "ik_cpp" / "hrc-ik")
    for exe in exes:
        exe.write_text(FAKE_SERVICE)
    (root / ".venv" / "bin" / "hrc").write_text(FAKE_HRC)
    for exe in [*exes, root / ".venv" / "bin" / "hrc"]:
        exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    return root


def _run_pc(tmp: Path, **env: str) -> tuple[int, Path]:
    if not PC_BIN.exists():
        pytest.skip("tools/bin/process-compose not built (scripts/setup.sh builds it when Go >= 1.24)")
    root = _fake_root(tmp)
    fake_dir = tmp / "out"
    fake_dir.mkdir()
    full_env = {k: v for k, v in os.environ.items() if not k.startswith(("HRC_", "PC_"))}
    full_env.update(HRC_ROOT=str(root), FAKE_DIR=str(fake_dir), **env)
    proc = subprocess.run(
        [str(PC_BIN), "-f", str(PC_FILE), "up", "--no-server", "-t=false", "-L", str(tmp / "pc.log")],
        env=full_env, cwd=tmp, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60,
    )
    return proc.returncode, fake_dir


def test_process_compose_file_validates() -> None:
    if not PC_BIN.exists():
        pytest.skip("tools/bin/process-compose not built")
    proc = subprocess.run([str(PC_BIN), "-f", str(PC_FILE), "--dry-run"], capture_output=True,
                          text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert re.search(r"Validated 5 configured processes", proc.stdout + proc.stderr)


def test_process_compose_starts_five_services_with_session_settings(tmp_path: Path) -> None:
    code, out = _run_pc(tmp_path, HRC_SESSION="s7", HRC_PORT="7999", HRC_TICKS="123",
                        HRC_SCENARIO="scenarios/x.toml", HRC_OUT="runs/x", FAKE_SLEEP="3")
    assert code == 0
    argv = {p.name.removeprefix("argv-"): p.read_text().split() for p in out.glob("argv-*")}
    bus = "tcp/127.0.0.1:7999"
    client = ["--zenoh-mode", "client", "--connect", bus]  # star: physics routes for all
    assert argv["hrc-physics"] == ["hrc-physics", "--session", "s7", "--zenoh-mode", "router",
                                   "--listen", bus, "--clock", "lockstep", "--ticks", "123"]
    assert argv["hrc-orchestrator"] == ["hrc-orchestrator", "--session", "s7", *client,
                                        "--scenario", "scenarios/x.toml", "--out", "runs/x"]
    assert argv["hrc-ik"] == ["hrc-ik", "--session", "s7", *client]
    assert argv["hrc-human-input"] == ["hrc-human-input", "--session", "s7", *client]
    assert argv["hrc-logger"] == ["hrc-logger", "--session", "s7", *client, "--out", "runs/x"]
    probes = (out / "probes").read_text().splitlines()
    probed = {line.split()[1] for line in probes}
    assert probed == set(SERVICES)
    assert all(f"--session s7 --zenoh-mode client --connect {bus}" in line for line in probes)


def test_process_compose_defaults(tmp_path: Path) -> None:
    code, out = _run_pc(tmp_path, FAKE_SLEEP="0")
    assert code == 0
    physics = (out / "argv-hrc-physics").read_text().split()
    assert physics == ["hrc-physics", "--session", "pc", "--zenoh-mode", "router", "--listen",
                       "tcp/127.0.0.1:7460", "--clock", "lockstep", "--ticks", "0"]
    orch = (out / "argv-hrc-orchestrator").read_text().split()
    assert orch[-4:] == ["--scenario", "scenarios/thesis.toml", "--out", "runs/pc"]


def test_process_compose_one_failing_service_ends_the_session(tmp_path: Path) -> None:
    # The others would run for 20 s more: the session must end at the failure, non-zero.
    # (process-compose 1.87 exits with the service's code, 3, or with 255 depending on how the
    # shutdown of the others races; both say "failed".)
    t0 = time.monotonic()
    code, _out = _run_pc(tmp_path, FAKE_FAIL="hrc-ik", FAKE_SLEEP="1", FAKE_OTHERS_SLEEP="20")
    assert code in (3, 255)
    assert time.monotonic() - t0 < 15


# --------------------------------------------------------------------------- scripts and pins


@pytest.mark.parametrize("script", ["scripts/setup.sh", "scripts/test-all.sh",
                                    "scripts/run-default.sh", ".ci/run"])
def test_scripts_parse_and_are_executable(script: str) -> None:
    path = ROOT / script
    assert os.access(path, os.X_OK), f"{script} is not executable"
    proc = subprocess.run(["bash", "-n", str(path)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_python_and_rust_zenoh_versions_match() -> None:
    lock = (ROOT / "requirements.lock").read_text()
    py = re.search(r"^eclipse-zenoh==(\S+)", lock, re.M)
    cargo = (ROOT / "services" / "ik_cpp" / "zenoh_ffi" / "Cargo.toml").read_text()
    rs = re.search(r'^zenoh\s*=\s*\{[^}]*version\s*=\s*"=?([^"]+)"', cargo, re.M)
    assert py and rs, "zenoh pins not found"
    assert py.group(1) == rs.group(1) == importlib.metadata.version("eclipse-zenoh")
