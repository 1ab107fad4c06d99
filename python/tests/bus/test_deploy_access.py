"""`hrc deploy-access`: a deployed session's credentials, as hrc run writes its trials'."""

from __future__ import annotations

import json
import stat
from pathlib import Path

import pytest

from hrc import service_table
from hrc.bus.access import USERS
from hrc.cli.main import main
from hrc.service_table import EXPERIMENTER


def test_it_writes_one_private_file_per_service_and_the_experimenter(tmp_path: Path) -> None:
    folder = tmp_path / "access" / "s1"
    assert main(["deploy-access", "--session", "s1", "--out", str(folder)]) == 0
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    names = [*service_table.names(), EXPERIMENTER]
    users = dict(line.split(":") for line in (folder / USERS).read_text().splitlines())
    assert sorted(users) == sorted(names)
    for name in names:
        path = folder / f"{name}.json5"
        assert stat.S_IMODE(path.stat().st_mode) == 0o600
        usrpwd = json.loads(path.read_text())["transport"]["auth"]["usrpwd"]
        assert (usrpwd["user"], usrpwd["password"]) == (name, users[name])
    physics = json.loads((folder / f"{service_table.CLOCK_MASTER}.json5").read_text())
    assert physics["access_control"]["enabled"] is True
    assert physics["access_control"]["default_permission"] == "deny"
    # physics as the router: its own puts never come in, so no client may make them
    assert "hrc/s1/run/end" not in json.dumps(physics["access_control"])
    assert "hrc/s1/run/control/experimenter" in json.dumps(physics["access_control"])
    # a separate router (several hosts) checks the same dictionary, with the same rules
    router = folder / "router.json5"
    assert stat.S_IMODE(router.stat().st_mode) == 0o600
    cfg = json.loads(router.read_text())
    assert cfg["mode"] == "router"
    assert cfg["transport"]["auth"]["usrpwd"] == {"dictionary_file": str(folder / USERS)}
    # physics is one of its clients there: its keys are its own
    assert "hrc/s1/run/end" in json.dumps(cfg["access_control"])


def test_written_again_it_gives_new_passwords(tmp_path: Path) -> None:
    argv = ["deploy-access", "--session", "s1", "--out", str(tmp_path)]
    assert main(argv) == 0
    first = (tmp_path / USERS).read_text()
    assert main(argv) == 0
    assert (tmp_path / USERS).read_text() != first


def test_a_file_in_the_way_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "taken"
    path.write_text("not a folder")
    assert main(["deploy-access", "--session", "s1", "--out", str(path)]) == 2
    err = capsys.readouterr().err
    assert "no credentials written" in err and str(path) in err
    assert path.read_text() == "not a folder"
