"""The broken scenarios under data/: every problem they were written with is reported."""

from __future__ import annotations

from pathlib import Path

import pytest

from hrc.scenario import ScenarioError, load

DATA = Path(__file__).resolve().parent / "data"


def problems(name: str, root: Path, **kwargs) -> dict[str, list[str]]:
    kwargs.setdefault("motion_check", False)
    with pytest.raises(ScenarioError) as info:
        load(DATA / name, project_root=root, **kwargs)
    out: dict[str, list[str]] = {}
    for p in info.value.problems:
        out.setdefault(p.key, []).append(p.message)
    return out


def test_deadlock_file(arm_root: Path) -> None:
    found = problems("deadlock.toml", arm_root)
    assert len(found) == 1
    (message,) = next(iter(found.values()))
    assert message.startswith("deadlock")
    assert all(pid in message for pid in ("H1", "H2", "RA1", "RA2"))


def test_many_problems_file_reports_each_one(arm_root: Path) -> None:
    found = problems("many_problems.toml", arm_root)
    expected = {
        "scenario.name",
        "scenario.tick_hz",
        "scenario.colour",
        "participant.replay_file",
        "participant.caution",
        "workspace.continue_button",
        "robots.r1.max_tcp_speed",
        "robots.r1.color",
        "robots.r2.feeder",
        "robots.r2.urdf",
        "parts.H1.size[1]",
        "parts.H1.after",
        "parts.H1",
        "parts.RA1.owner",
        "sequence.human",
        "workspace.envelope[0]",
    }
    assert expected <= set(found), sorted(expected - set(found))
    # S1 <-> S2 is a dependency cycle, keyed on one of them
    cycle = [m for k in ("parts.S1.after", "parts.S2.after") for m in found.get(k, [])]
    assert len(cycle) == 1 and cycle[0].startswith("dependency cycle")
    assert "'RA7'" in found["parts.H1.after"][0]
    assert "it belongs to r2" in " ".join(found["sequence.human"])


def test_unreachable_file(arm_root: Path) -> None:
    found = problems("unreachable.toml", arm_root, motion_check=True)
    assert set(found) == {"parts.RA1.target", "robots.r2.feeder"}, found
    messages = [m for ms in found.values() for m in ms]
    assert all("is not feasible" in m and "unreachable" in m for m in messages), messages
    # robot, part, from -> to and the target are named
    assert any(m.startswith("robot r1 RA1: intermediate -> place (target [") for m in messages)
    assert any(m.startswith("robot r2 S1: home -> feeder (target [") for m in messages), messages
