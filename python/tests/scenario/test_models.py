"""Accessors the task logic uses, and the graph helper on its own."""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest

from hrc.scenario import HUMAN, load, validate
from hrc.scenario.graph import Edge, find_cycles

REPO = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def thesis(arm_root: Path):
    return load(REPO / "scenarios" / "thesis.toml", project_root=arm_root, motion_check=False)


def test_accessors(thesis) -> None:
    assert thesis.agents == [HUMAN, "r1", "r2"]
    assert thesis.part("RA3").kind == "mounting plate"
    with pytest.raises(KeyError, match="ZZ"):
        thesis.part("ZZ")
    assert thesis.sequence_of("r1")[:2] == ["RA1", "RA2"]
    with pytest.raises(KeyError, match="r9"):
        thesis.sequence_of("r9")
    assert next(p.id for p in thesis.parts_in_sequence(HUMAN)) == "H1"
    assert list(thesis.robots_by_role("screwing")) == ["r2"]
    with pytest.raises(ValueError):
        thesis.robots_by_role("painting")
    assert thesis.robot("r1").id == "r1"
    assert sorted(thesis.dependents("H3")) == ["RA4", "RA6"]
    assert {p.owner for p in thesis.parts_of("r2")} == {"r2"}
    assert thesis.parts_by_id["S1"].after == ["H1"]
    assert thesis.robot("r2").screw_time_or_default == 1.0
    assert thesis.robot("r1").screw_time_or_default == 0.0
    assert thesis.placement.tolerance_m == 0.02 and thesis.scenario.tick_hz == 240


def test_validate_sees_changes_made_in_code(thesis) -> None:
    changed = thesis.model_copy(deep=True)
    changed.part("H1").after = ["S6"]  # S6 waits (via H5, RA3 ...) for the human after H1
    problems = validate(changed)
    assert len(problems) == 1 and problems[0].message.startswith("deadlock")
    assert "H1" in problems[0].message and "S6" in problems[0].message


def test_find_cycles_handles_long_chains_without_recursion() -> None:
    nodes = [f"P{i}" for i in range(5000)]
    edges = [Edge(a, b, "human") for a, b in itertools.pairwise(nodes)]
    assert find_cycles(nodes, edges) == []
    edges.append(Edge(nodes[-1], nodes[0], "after"))
    (cycle,) = find_cycles(nodes, edges)
    assert len(cycle) == 5000 and cycle[0].src == "P0"


def test_find_cycles_one_per_component() -> None:
    nodes = ["a", "b", "c", "d"]
    edges = [
        Edge("a", "b", "after"),
        Edge("b", "a", "after"),
        Edge("c", "d", "x"),
        Edge("d", "c", "after"),
        Edge("b", "c", "after"),
    ]
    cycles = find_cycles(nodes, edges)
    assert [{e.src for e in c} for c in cycles] == [{"a", "b"}, {"c", "d"}]
