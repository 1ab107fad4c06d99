"""The service table (hrc.service_table) against what it describes: the installed programs, the
services' own command-line parsers, and the processes ``hrc run`` starts.

Here, not in python/tests, because it imports the services and runs the C++ one. The deploy files
are checked against the table in deploy/tests/test_deploy_files.py.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

from hrc import service_table
from hrc.paths import build_dir
from hrc.service import parse_args
from hrc.service_table import Role, Settings
from hrc.trial import TrialOptions
from hrc.trial import options as trial_options

from .goldens import THESIS

PYTHON = [s for s in service_table.SERVICES if s.module is not None]
CPP = [s for s in service_table.SERVICES if s.binary is not None]


def _trial_argv(name: str, **opts: object) -> list[str]:
    options = TrialOptions(scenario=THESIS, **opts)  # type: ignore[arg-type]
    return trial_options.service_argv(
        name, options, "s1", 7471, Path("/tmp/trial"), Path("/tmp/hrc-s1.sock"), True
    )


def test_one_clock_master_listed_first_and_unique_names() -> None:
    assert [s.role for s in service_table.SERVICES].count(Role.CLOCK_MASTER) == 1
    assert service_table.SERVICES[0].name == service_table.CLOCK_MASTER
    assert len(set(service_table.names())) == len(service_table.SERVICES)
    assert set(service_table.PARTICIPANTS) | set(service_table.OBSERVERS) | {
        service_table.CLOCK_MASTER
    } == set(service_table.names())


@pytest.mark.parametrize("svc", PYTHON, ids=lambda s: s.name)
def test_python_service_script_and_module_start_the_same_main(svc: service_table.Service) -> None:
    scripts = {e.name: e.value for e in importlib.metadata.entry_points(group="console_scripts")}
    assert scripts.get(svc.script) == f"{svc.module}.main:main"
    assert importlib.util.find_spec(f"{svc.module}.__main__") is not None


@pytest.mark.parametrize("svc", CPP, ids=lambda s: s.name)
def test_cpp_service_script_is_its_binary(svc: service_table.Service) -> None:
    assert svc.binary is not None and Path(svc.binary).name == svc.script


@pytest.mark.parametrize("svc", PYTHON, ids=lambda s: s.name)
def test_hrc_run_command_lines_parse_in_the_python_services(svc: service_table.Service) -> None:
    """Every option the table gives (all of them set) is one the service knows."""
    argv = _trial_argv(
        svc.name,
        seed=3,
        ticks=100,
        validated=True,
        viewer=True,
        web=True,
        record=Path("/tmp/r.jsonl"),
        replay=Path("/tmp/p.jsonl"),
        connect=["tcp/10.0.0.1:7447"],
    )
    assert argv[:3] == [sys.executable, "-m", svc.module]
    service_cls = importlib.import_module(f"{svc.module}.main").SERVICE
    assert service_cls.name == svc.name
    args = parse_args(service_cls, argv[3:])
    assert args.session == "s1"
    assert args.zenoh_lowlatency == (svc.role is not Role.OBSERVER)  # an observer never asks
    if svc.role is Role.CLOCK_MASTER:
        assert args.participants.split(",") == list(service_table.PARTICIPANTS)
        assert args.observers.split(",") == list(service_table.OBSERVERS)
        assert args.listen == ["tcp/127.0.0.1:7471", "unixsock-stream//tmp/hrc-s1.sock"]
        assert args.connect == ["tcp/10.0.0.1:7447"]
    else:
        assert args.clock_master == service_table.CLOCK_MASTER
        assert args.connect == ["unixsock-stream//tmp/hrc-s1.sock", "tcp/10.0.0.1:7447"]


@pytest.mark.parametrize("svc", CPP, ids=lambda s: s.name)
def test_hrc_run_command_lines_parse_in_the_cpp_services(svc: service_table.Service) -> None:
    argv = _trial_argv(svc.name, connect=["tcp/10.0.0.1:7447"])
    assert svc.binary is not None and argv[0] == str(build_dir() / svc.binary)
    if not Path(argv[0]).exists():
        pytest.fail(f"{argv[0]} is missing: build it with scripts/setup.sh")
    assert "--clock-master" in argv
    # Unknown options are usage errors (exit 2) before --help is looked at.
    proc = subprocess.run([*argv, "--help"], capture_output=True, text=True, timeout=30)
    assert proc.returncode == 0, proc.stderr


def test_hrc_run_starts_every_service_of_the_table_with_the_table_arguments() -> None:
    opts = TrialOptions(scenario=THESIS, seed=3)
    settings = trial_options.trial_settings(opts, "s1", 7471, Path("/tmp/trial"), None, False)
    for svc in service_table.SERVICES:
        argv = trial_options.service_argv(
            svc.name, opts, "s1", 7471, Path("/tmp/trial"), None, False
        )
        assert argv == trial_options.program(svc) + service_table.argv(svc, settings)


def test_options_left_out_when_unset_and_required_ones_enforced() -> None:
    logger = service_table.service("logger")
    assert "--viewer" not in service_table.argv(logger, Settings(bus="b", out="o"))
    assert "--viewer" in service_table.argv(logger, Settings(bus="b", out="o", viewer=True))
    with pytest.raises(ValueError, match="--out"):
        service_table.argv(logger, Settings(bus="b"))
    with pytest.raises(ValueError, match="no setting"):
        service_table.Option("--x", "no_such_setting")


def test_unknown_service_is_named() -> None:
    with pytest.raises(KeyError, match="nope"):
        service_table.service("nope")
