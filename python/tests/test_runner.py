"""How hrc run wires a trial's services together (no processes started here)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest

from hrc import services
from hrc.cli import runner
from hrc.cli.runner import TrialOptions, fits_lowlatency, local_socket, service_argv
from hrc.paths import project_root

THESIS = project_root() / "scenarios" / "thesis.toml"
SERVICES = services.names()  # the clock master first


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
def test_every_service_gets_the_same_transport(lowlatency: bool) -> None:
    for name in SERVICES:
        assert ("--zenoh-lowlatency" in _argv(name, None, lowlatency)) == lowlatency, name


def test_a_scenario_too_large_for_the_low_latency_transport_falls_back(monkeypatch) -> None:
    assert fits_lowlatency(THESIS)  # 18 parts: about 9 KiB on the wire
    monkeypatch.setattr(runner, "LOWLATENCY_MAX_SCENARIO_BYTES", 4096)
    assert not fits_lowlatency(THESIS)
    assert not fits_lowlatency(Path("/nonexistent/scenario.toml"))  # the orchestrator says why


def test_no_socket_where_its_path_would_be_too_long(monkeypatch) -> None:
    assert local_socket("s1") == Path(tempfile.gettempdir()) / "hrc-s1.sock"
    monkeypatch.setattr(tempfile, "tempdir", "/tmp/" + "x" * 120)
    assert local_socket("s1") is None
