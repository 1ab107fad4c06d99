"""Checks of the deployment files: the Zenoh router config, deploy/process-compose.yaml,
deploy/compose.yaml, scripts.

Both compose files are generated from the service table (hrc.service_table, `hrc deploy-files`): the
committed files must equal the generated ones, and read back as YAML they must say what the table
says (services, commands, start dependencies, readiness probes). The process-compose tests also
run the real process-compose binary (built by scripts/setup.sh into tools/bin/) against fake
services, so they check what the file makes process-compose do: the command lines, the readiness
probes, and that one failing service ends the session non-zero.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import re
import socket
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
import zenoh

from hrc import deploy_files, service_table
from hrc.service_table import Role, Settings

ROOT = Path(__file__).resolve().parents[2]
ROUTER_CONFIG = ROOT / "deploy" / "zenoh-router.json5"
PC_FILE = ROOT / "deploy" / "process-compose.yaml"
COMPOSE_FILE = ROOT / "deploy" / "compose.yaml"
PC_BIN = ROOT / "tools" / "bin" / "process-compose"


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
        alive = [
            str(r.ok.key_expr)
            for r in b.liveliness().get("hrc/deploytest/alive/*", timeout=5)
            if r.ok is not None
        ]
        token.undeclare()
    assert got and got[0] == b"hello"
    assert alive == ["hrc/deploytest/alive/a"]


# --------------------------------------------------------------------------- against the table


def test_committed_deploy_files_are_the_generated_ones() -> None:
    for path, text in deploy_files.files(ROOT).items():
        assert path.read_text() == text, f"{path} is out of date: run `hrc deploy-files`"


def test_hrc_deploy_files_check_says_up_to_date() -> None:
    hrc = Path(sys.executable).with_name("hrc")
    proc = subprocess.run(
        [str(hrc), "deploy-files", "--check"], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_process_compose_file_says_what_the_table_says() -> None:
    pc = yaml.safe_load(PC_FILE.read_text())
    procs = pc["processes"]
    assert list(procs) == ["access", *service_table.names()]
    assert procs["access"]["command"].split()[:2] == [".venv/bin/hrc", "deploy-access"]
    # one machine: Zenoh's lease, as hrc run's links, unless HRC_LEASE_S says otherwise
    assert procs["access"]["command"].split()[-2:] == ["--lease-s", "{{.LEASE_S}}"]
    assert pc["vars"]["LEASE_S"] == f"${{HRC_LEASE_S:-{deploy_files.LEASE_S:g}}}"
    for svc in service_table.SERVICES:
        p = procs[svc.name]
        program = f".venv/bin/{svc.script}" if svc.module else f"build/{svc.binary}"
        assert p["command"].split() == [program, *service_table.argv(svc, deploy_files.PC_SETTINGS)]
        if svc.role is Role.CLOCK_MASTER:  # after the credentials are written
            assert p["depends_on"] == {"access": {"condition": "process_completed_successfully"}}
        else:
            assert p["depends_on"] == {service_table.CLOCK_MASTER: {"condition": "process_started"}}
        probe = p["readiness_probe"]["exec"]["command"].split()
        assert probe[:4] == [".venv/bin/hrc", "alive", svc.name, "--wait"]
        assert probe[-2:] == ["--zenoh-config", "{{.ACCESS}}/{{.SESSION}}/experimenter.json5"]
        assert f"{{{{.ACCESS}}}}/{{{{.SESSION}}}}/{svc.name}.json5" in p["command"]
        assert p["availability"] == {"restart": "exit_on_failure"}
        assert p["shutdown"]["timeout_seconds"] == svc.stop_timeout_s


def test_compose_file_says_what_the_table_says() -> None:
    compose = yaml.safe_load(COMPOSE_FILE.read_text())
    got = {n: s for n, s in compose["services"].items() if "profiles" not in s}  # not the router
    assert list(got) == ["access", *service_table.names()]
    access = got.pop("access")["command"]
    assert access[0] == "deploy-access"
    assert access[-2:] == ["--lease-s", f"${{HRC_LEASE_S:-{deploy_files.LEASE_S:g}}}"]
    for svc in service_table.SERVICES:
        c = got[svc.name]
        assert c["entrypoint"] == [svc.script]
        assert c["command"] == service_table.argv(svc, deploy_files.COMPOSE_SETTINGS)
        if svc.role is Role.CLOCK_MASTER:
            assert c["depends_on"] == {"access": {"condition": "service_completed_successfully"}}
        else:
            assert c["depends_on"] == {service_table.CLOCK_MASTER: {"condition": "service_started"}}
        assert c["healthcheck"]["test"][:4] == ["CMD", "hrc", "alive", svc.name]
        assert c["healthcheck"]["test"][-1] == "/opt/hrc/access/experimenter.json5"
        assert f"/opt/hrc/access/{svc.name}.json5" in c["command"]
        assert "access:/opt/hrc/access" in c["volumes"]
        assert c["stop_grace_period"] == f"{svc.stop_timeout_s}s"
        assert c["restart"] == "no" and c["network_mode"] == "host"  # from x-service


# --------------------------------------------------------------------------- process-compose

FAKE_SERVICE = """#!/bin/sh
# fake hrc service: records its command line, stays up a moment, then exits
echo "$(basename "$0") $*" > "$FAKE_DIR/argv-$(basename "$0")"
if [ "$(basename "$0")" = "${FAKE_FAIL:-}" ]; then sleep "${FAKE_SLEEP:-1}"; exit 3; fi
sleep "${FAKE_OTHERS_SLEEP:-${FAKE_SLEEP:-1}}"
exit 0
"""

FAKE_HRC = """#!/bin/sh
# fake `hrc alive` (records the probe and says yes) and `hrc deploy-access` (records it)
if [ "$1" = deploy-access ]; then echo "$*" > "$FAKE_DIR/access"; exit 0; fi
echo "$*" >> "$FAKE_DIR/probes"
exit 0
"""


def _fake_root(tmp: Path) -> Path:
    root = tmp / "root"
    (root / ".venv" / "bin").mkdir(parents=True)
    (root / "build" / "ik_cpp").mkdir(parents=True)
    exes = [
        root / (f".venv/bin/{s.script}" if s.module else f"build/{s.binary}")
        for s in service_table.SERVICES
    ]
    for exe in exes:
        exe.write_text(FAKE_SERVICE)
    (root / ".venv" / "bin" / "hrc").write_text(FAKE_HRC)
    for exe in [*exes, root / ".venv" / "bin" / "hrc"]:
        exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    return root


def _run_pc(tmp: Path, **env: str) -> tuple[int, Path]:
    if not PC_BIN.exists():
        pytest.skip(
            "tools/bin/process-compose not built (scripts/setup.sh builds it when Go >= 1.24)"
        )
    root = _fake_root(tmp)
    fake_dir = tmp / "out"
    fake_dir.mkdir()
    full_env = {k: v for k, v in os.environ.items() if not k.startswith(("HRC_", "PC_"))}
    full_env.update(HRC_ROOT=str(root), FAKE_DIR=str(fake_dir), **env)
    proc = subprocess.run(
        [
            str(PC_BIN),
            "-f",
            str(PC_FILE),
            "up",
            "--no-server",
            "-t=false",
            "-L",
            str(tmp / "pc.log"),
        ],
        env=full_env,
        cwd=tmp,
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=60,
    )
    return proc.returncode, fake_dir


def test_process_compose_file_validates() -> None:
    if not PC_BIN.exists():
        pytest.skip("tools/bin/process-compose not built")
    proc = subprocess.run(
        [str(PC_BIN), "-f", str(PC_FILE), "--dry-run"],
        capture_output=True,
        text=True,
        timeout=60,
        stdin=subprocess.DEVNULL,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert re.search(  # the services and `access`
        rf"Validated {len(service_table.SERVICES) + 1} configured processes",
        proc.stdout + proc.stderr,
    )


def _expected(settings: Settings) -> dict[str, list[str]]:
    return {s.script: [s.script, *service_table.argv(s, settings)] for s in service_table.SERVICES}


def test_process_compose_starts_every_service_with_session_settings(tmp_path: Path) -> None:
    code, out = _run_pc(
        tmp_path,
        HRC_SESSION="s7",
        HRC_PORT="7999",
        HRC_TICKS="123",
        HRC_SCENARIO="scenarios/x.toml",
        HRC_OUT="runs/x",
        HRC_LEASE_S="2.5",
        FAKE_SLEEP="3",
    )
    assert code == 0
    argv = {p.name.removeprefix("argv-"): p.read_text().split() for p in out.glob("argv-*")}
    bus = "tcp/127.0.0.1:7999"
    assert argv == _expected(
        Settings(
            session="s7",
            bus=bus,
            listen=(bus,),
            clock="lockstep",
            ticks="123",
            scenario="scenarios/x.toml",
            out="runs/x",
            zenoh_config="runs/.access/s7/{service}.json5",
        )
    )
    # the credentials first, for this session
    assert (out / "access").read_text().split() == [
        "deploy-access",
        "--session",
        "s7",
        "--out",
        "runs/.access/s7",
        "--lease-s",
        "2.5",
    ]
    # star: physics routes for all
    assert argv["hrc-physics"][:9] == [
        "hrc-physics",
        "--session",
        "s7",
        "--zenoh-config",
        "runs/.access/s7/physics.json5",
        "--zenoh-mode",
        "router",
        "--listen",
        bus,
    ]
    assert argv["hrc-ik"][:9] == [
        "hrc-ik",
        "--session",
        "s7",
        "--zenoh-config",
        "runs/.access/s7/ik_cpp.json5",
        "--zenoh-mode",
        "client",
        "--connect",
        bus,
    ]
    probes = (out / "probes").read_text().splitlines()
    probed = {line.split()[1] for line in probes}
    assert probed == set(service_table.names())
    assert all(f"--session s7 --zenoh-mode client --connect {bus}" in line for line in probes)
    assert all(line.endswith("runs/.access/s7/experimenter.json5") for line in probes)


def test_process_compose_defaults(tmp_path: Path) -> None:
    code, out = _run_pc(tmp_path, FAKE_SLEEP="0")
    assert code == 0
    argv = {p.name.removeprefix("argv-"): p.read_text().split() for p in out.glob("argv-*")}
    bus = "tcp/127.0.0.1:7460"
    assert argv == _expected(
        Settings(
            session="pc",
            bus=bus,
            listen=(bus,),
            clock="lockstep",
            ticks="0",
            scenario="scenarios/thesis.toml",
            out="runs/pc",
            zenoh_config="runs/.access/pc/{service}.json5",
        )
    )
    access = (out / "access").read_text().split()
    assert access[-2:] == ["--lease-s", f"{deploy_files.LEASE_S:g}"]


def test_process_compose_one_failing_service_ends_the_session(tmp_path: Path) -> None:
    # The others would run for 20 s more: the session must end at the failure, non-zero.
    # (process-compose 1.87 exits with the service's code, 3, or with 255 depending on how the
    # shutdown of the others races; both say "failed".)
    t0 = time.monotonic()
    code, _out = _run_pc(tmp_path, FAKE_FAIL="hrc-ik", FAKE_SLEEP="1", FAKE_OTHERS_SLEEP="20")
    assert code in (3, 255)
    assert time.monotonic() - t0 < 15


# --------------------------------------------------------------------------- scripts and pins


@pytest.mark.parametrize(
    "script",
    [
        "scripts/setup.sh",
        "scripts/test-all.sh",
        "scripts/lint.sh",
        "scripts/run-default.sh",
        ".ci/run",
    ],
)
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
