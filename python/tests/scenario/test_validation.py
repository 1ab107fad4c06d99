"""Each rejection class of docs/scenario.md ("What is checked"): the problem names the offending
key or id."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from hrc.scenario import Problem, ScenarioError, load

Data = dict[str, Any]


def part(raw: Data, pid: str) -> Data:
    return next(p for p in raw["parts"] if p["id"] == pid)


def only(problems: list[Problem], key: str) -> Problem:
    hits = [p for p in problems if p.key == key]
    assert len(hits) == 1, f"expected one problem at {key}, got {problems}"
    return hits[0]


def add_r1_part(raw: Data, pid: str, **extra: Any) -> None:
    raw["parts"].append(
        {
            "id": pid,
            "owner": "r1",
            "kind": "resistor",
            "size": [0.06, 0.02, 0.02],
            "start": {"xyz": [0.80, 0.30, 0.01], "yaw": 0},
            "target": {"xyz": [0.20, 0.02, 0.01], "yaw": 0},
            **extra,
        }
    )


def add_human_part(raw: Data, pid: str, **extra: Any) -> None:
    raw["parts"].append(
        {
            "id": pid,
            "owner": "human",
            "kind": "relay",
            "size": [0.05, 0.05, 0.06],
            "start": {"xyz": [-0.10, -0.38, 0.03]},
            "target": {"xyz": [-0.22, 0.10, 0.03]},
            **extra,
        }
    )


def test_the_base_case_is_clean(minimal_raw: Data, problems_of) -> None:
    assert problems_of(minimal_raw) == []


# ---------------------------------------------------------------- schema


def test_unknown_keys_are_named(minimal_raw: Data, problems_of) -> None:
    minimal_raw["participant"]["speed"] = 2.0
    part(minimal_raw, "H1")["colour"] = "red"
    minimal_raw["robots"]["r1"]["base"]["roll"] = 3
    minimal_raw["extras"] = {"a": 1}
    problems = problems_of(minimal_raw)
    for key in ("participant.speed", "parts.H1.colour", "robots.r1.base.roll", "extras"):
        assert "unknown key" in only(problems, key).message


def test_missing_required_keys_are_named(minimal_raw: Data, problems_of) -> None:
    del minimal_raw["robots"]["r1"]["max_tcp_speed"]
    del minimal_raw["scenario"]["name"]
    del part(minimal_raw, "RA1")["target"]
    del minimal_raw["workspace"]
    problems = problems_of(minimal_raw)
    for key in ("robots.r1.max_tcp_speed", "scenario.name", "parts.RA1.target", "workspace"):
        assert "missing required key" in only(problems, key).message


def test_wrong_types_are_named(minimal_raw: Data, problems_of) -> None:
    minimal_raw["scenario"]["tick_hz"] = "240"
    minimal_raw["conditions"]["anticipation"] = "yes"
    part(minimal_raw, "H1")["after"] = "RA1"
    minimal_raw["robots"]["r1"]["home"] = [0.3, 0.3]
    problems = problems_of(minimal_raw)
    assert "number" in only(problems, "scenario.tick_hz").message
    assert "'240'" in only(problems, "scenario.tick_hz").message
    assert "bool" in only(problems, "conditions.anticipation").message
    assert "list" in only(problems, "parts.H1.after").message
    assert "3 items" in only(problems, "robots.r1.home").message


@pytest.mark.parametrize(
    ("path", "value", "key"),
    [
        (("scenario", "tick_hz"), 0, "scenario.tick_hz"),
        (("scenario", "tick_hz"), 2001, "scenario.tick_hz"),
        (("scenario", "seed"), -1, "scenario.seed"),
        (("robots", "r1", "max_tcp_speed"), 0.0, "robots.r1.max_tcp_speed"),
        (("robots", "r1", "max_tcp_speed"), 1.6, "robots.r1.max_tcp_speed"),
        (("robots", "r2", "screw_time_s"), -1.0, "robots.r2.screw_time_s"),
        (("robots", "r1", "near_margin"), -0.01, "robots.r1.near_margin"),
        (("participant", "caution"), 1.5, "participant.caution"),
        (("participant", "caution"), -0.1, "participant.caution"),
        (("participant", "input"), "keyboard", "participant.input"),
        (("conditions", "safety_policy"), "pray", "conditions.safety_policy"),
        (("robots", "r1", "role"), "welding", "robots.r1.role"),
        (("robots", "r1", "color"), "chartreuse", "robots.r1.color"),
        (("robots", "r1", "color"), "#12345", "robots.r1.color"),
        (("placement", "tolerance_m"), 0.0, "placement.tolerance_m"),
        (("placement", "tolerance_deg"), 200, "placement.tolerance_deg"),
        (("scenario", "name"), "a/b", "scenario.name"),
    ],
)
def test_out_of_range_values_are_named(
    minimal_raw: Data, problems_of, path: tuple[str, ...], value: Any, key: str
) -> None:
    node = minimal_raw
    for step in path[:-1]:
        node = node.setdefault(step, {})
    node[path[-1]] = value
    problems = problems_of(minimal_raw)
    assert [p.key for p in problems] == [key], problems


def test_sizes_must_be_positive_and_poses_finite(minimal_raw: Data, problems_of) -> None:
    part(minimal_raw, "H1")["size"] = [0.1, -0.02, 0.04]
    part(minimal_raw, "RA1")["target"]["xyz"] = [0.04, math.nan, 0.03]
    minimal_raw["robots"]["r2"]["feeder"] = [math.inf, 0.35, 0.05]
    problems = problems_of(minimal_raw)
    assert "greater than 0" in only(problems, "parts.H1.size[1]").message
    assert "finite" in only(problems, "parts.RA1.target.xyz[1]").message
    assert "finite" in only(problems, "robots.r2.feeder[0]").message


def test_colors_accept_names_and_hex(minimal_raw: Data, problems_of) -> None:
    minimal_raw["robots"]["r1"]["color"] = "#FFcc00"
    minimal_raw["robots"]["r2"]["color"] = "Blue"
    assert problems_of(minimal_raw) == []


def test_bad_toml_is_reported_with_its_line(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text("[scenario]\nname = \n", encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load(path, motion_check=False)
    (problem,) = info.value.problems
    assert problem.key == "toml" and "line 2" in problem.message


def test_missing_file_is_reported(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError) as info:
        load(tmp_path / "nope.toml", motion_check=False)
    assert info.value.problems[0].key == "file"


# ---------------------------------------------------------------- ids, owners, sequences


def test_unknown_ids_are_named(minimal_raw: Data, problems_of) -> None:
    part(minimal_raw, "H1")["after"] = ["RA9"]
    part(minimal_raw, "RA1")["owner"] = "r7"
    minimal_raw["sequence"]["human"] = ["H1", "H7"]
    minimal_raw["sequence"]["r3"] = []
    problems = problems_of(minimal_raw)
    assert "'RA9'" in only(problems, "parts.H1.after").message
    assert "'r7'" in only(problems, "parts.RA1.owner").message
    assert "'H7'" in only(problems, "sequence.human").message
    assert "'r3'" in only(problems, "sequence.r3").message


def test_duplicate_part_ids_are_named(minimal_raw: Data, problems_of) -> None:
    add_human_part(minimal_raw, "H1")
    problems = problems_of(minimal_raw)
    assert "duplicate part id 'H1'" in only(problems, "parts.H1").message


def test_a_part_listed_twice_in_a_sequence(minimal_raw: Data, problems_of) -> None:
    minimal_raw["sequence"]["r1"] = ["RA1", "RA1"]
    assert "RA1 is listed twice" in only(problems_of(minimal_raw), "sequence.r1").message


def test_a_part_in_two_sequences(minimal_raw: Data, problems_of) -> None:
    minimal_raw["sequence"]["r1"] = ["RA1", "H1"]
    message = only(problems_of(minimal_raw), "sequence.r1").message
    assert "H1 is in two sequences" in message and "belongs to human" in message


def test_a_part_in_the_wrong_owners_sequence(minimal_raw: Data, problems_of) -> None:
    minimal_raw["sequence"]["r1"] = []
    minimal_raw["sequence"]["human"] = ["H1", "RA1"]
    problems = problems_of(minimal_raw)
    assert "RA1 belongs to r1" in only(problems, "sequence.human").message
    # and, being in no sequence of r1, RA1 would never be done
    assert "never be done" in only(problems, "parts.RA1").message


def test_a_part_in_no_sequence_is_never_used(minimal_raw: Data, problems_of) -> None:
    minimal_raw["sequence"]["r2"] = []
    message = only(problems_of(minimal_raw), "parts.S1").message
    assert "not in sequence.r2" in message and "never be done" in message


def test_the_human_id_is_reserved(minimal_raw: Data, problems_of) -> None:
    minimal_raw["robots"]["human"] = dict(minimal_raw["robots"]["r1"])
    assert "reserved" in only(problems_of(minimal_raw), "robots.human").message


def test_start_is_required_except_for_screws(minimal_raw: Data, problems_of) -> None:
    del part(minimal_raw, "H1")["start"]
    part(minimal_raw, "S1")["start"] = {"xyz": [0.0, 0.0, 0.0]}
    problems = problems_of(minimal_raw)
    assert "needs a start pose" in only(problems, "parts.H1.start").message
    assert "feeder" in only(problems, "parts.S1.start").message


def test_role_specific_robot_keys(minimal_raw: Data, problems_of) -> None:
    del minimal_raw["robots"]["r2"]["feeder"]
    minimal_raw["robots"]["r1"]["screw_time_s"] = 1.0
    problems = problems_of(minimal_raw)
    assert "missing required key" in only(problems, "robots.r2.feeder").message
    assert "only screwing robots" in only(problems, "robots.r1.screw_time_s").message


# ---------------------------------------------------------------- dependencies and deadlocks


def test_a_part_waiting_for_itself(minimal_raw: Data, problems_of) -> None:
    part(minimal_raw, "H1")["after"] = ["H1"]
    assert "waits for itself" in only(problems_of(minimal_raw), "parts.H1.after").message


def test_a_part_listed_twice_in_after(minimal_raw: Data, problems_of) -> None:
    part(minimal_raw, "S1")["after"] = ["H1", "H1"]
    assert "H1 is listed twice" in only(problems_of(minimal_raw), "parts.S1.after").message


def test_dependency_cycle_names_its_parts(minimal_raw: Data, problems_of) -> None:
    part(minimal_raw, "H1")["after"] = ["RA1"]
    part(minimal_raw, "RA1")["after"] = ["S1"]  # S1 is after H1: H1 -> S1 -> RA1 -> H1
    (problem,) = problems_of(minimal_raw)
    assert problem.key.startswith("parts.") and problem.key.endswith(".after")
    assert problem.message.startswith("dependency cycle")
    for pid in ("H1", "RA1", "S1"):
        assert pid in problem.message


def test_deadlock_through_sequence_order(minimal_raw: Data, problems_of) -> None:
    # human: H1, H2 and r1: RA1, RA2. H1 waits for RA2 (the second), RA1 waits for H2 (the
    # second): each side waits for the other's second part before its own first -> deadlock.
    add_human_part(minimal_raw, "H2")
    add_r1_part(minimal_raw, "RA2")
    minimal_raw["sequence"]["human"] = ["H1", "H2"]
    minimal_raw["sequence"]["r1"] = ["RA1", "RA2"]
    part(minimal_raw, "H1")["after"] = ["RA2"]
    part(minimal_raw, "RA1")["after"] = ["H2"]
    (problem,) = problems_of(minimal_raw)
    assert problem.message.startswith("deadlock")
    assert problem.key in ("parts.H1.after", "parts.RA1.after")
    for pid in ("H1", "H2", "RA1", "RA2"):
        assert pid in problem.message
    assert "sequence.human" in problem.message and "sequence.r1" in problem.message


def test_waits_both_ways_without_cycle_are_fine(minimal_raw: Data, problems_of) -> None:
    add_human_part(minimal_raw, "H2")
    add_r1_part(minimal_raw, "RA2")
    minimal_raw["sequence"]["human"] = ["H1", "H2"]
    minimal_raw["sequence"]["r1"] = ["RA1", "RA2"]
    part(minimal_raw, "H2")["after"] = ["RA1"]
    part(minimal_raw, "RA2")["after"] = ["H1"]
    assert problems_of(minimal_raw) == []


def test_each_deadlock_is_reported_once(minimal_raw: Data, problems_of) -> None:
    add_human_part(minimal_raw, "H2")
    add_r1_part(minimal_raw, "RA2")
    minimal_raw["sequence"]["human"] = ["H1", "H2"]
    minimal_raw["sequence"]["r1"] = ["RA1", "RA2"]
    part(minimal_raw, "H1")["after"] = ["H2"]  # cycle 1: H1 -> H2 -> H1
    part(minimal_raw, "RA1")["after"] = ["RA2"]  # cycle 2: RA1 -> RA2 -> RA1
    problems = problems_of(minimal_raw)
    assert sorted(p.key for p in problems) == ["parts.H1.after", "parts.RA1.after"]


# ---------------------------------------------------------------- workspace and files


def test_envelope_boxes_and_continue_button(minimal_raw: Data, problems_of) -> None:
    minimal_raw["workspace"]["envelope"][1]["max"][2] = -0.1
    del minimal_raw["workspace"]["continue_button"]
    minimal_raw["conditions"]["safety_policy"] = "retreat_button"
    problems = problems_of(minimal_raw)
    assert "z: -0.05 >= -0.1" in only(problems, "workspace.envelope[1]").message
    assert "retreat_button" in only(problems, "workspace.continue_button").message


def test_an_envelope_is_required(minimal_raw: Data, problems_of) -> None:
    minimal_raw["workspace"]["envelope"] = []
    assert "at least 1" in only(problems_of(minimal_raw), "workspace.envelope").message


def test_unresolvable_files_are_named(minimal_raw: Data, problems_of) -> None:
    minimal_raw["robots"]["r1"]["urdf"] = "robots/nope.urdf"
    minimal_raw["participant"]["input"] = "replay"
    minimal_raw["participant"]["replay_file"] = "recordings/missing.jsonl"
    problems = problems_of(minimal_raw)
    assert "robots/nope.urdf" in only(problems, "robots.r1.urdf").message
    assert "recordings/missing.jsonl" in only(problems, "participant.replay_file").message


def test_replay_needs_a_file(minimal_raw: Data, problems_of) -> None:
    minimal_raw["participant"]["input"] = "replay"
    assert "replay_file" in only(problems_of(minimal_raw), "participant.replay_file").message


def test_paths_resolve_against_the_file_folder_first(
    minimal_raw: Data, tmp_path: Path, arm_root: Path, write_scenario
) -> None:
    (tmp_path / "robots").mkdir()
    local = tmp_path / "robots" / "arm5.urdf"
    local.write_text((arm_root / "robots" / "arm5.urdf").read_text(), encoding="utf-8")
    (arm_root / "rec.jsonl").write_text("", encoding="utf-8")  # only in the project root
    minimal_raw["participant"].update(input="replay", replay_file="rec.jsonl")
    scenario = load(write_scenario(minimal_raw), project_root=arm_root, motion_check=False)
    assert scenario.urdf_path("r1") == local.resolve()  # the file's folder wins
    assert scenario.resolve("rec.jsonl") == (arm_root / "rec.jsonl").resolve()  # then the root


def test_project_root_comes_from_hrc_root_or_the_scenarios_folder(
    minimal_raw: Data, tmp_path: Path, arm_root: Path, monkeypatch: pytest.MonkeyPatch, to_toml
) -> None:
    nested = arm_root / "scenarios" / "studies"
    nested.mkdir(exist_ok=True)
    path = nested / "case.toml"
    path.write_text(to_toml(minimal_raw), encoding="utf-8")
    monkeypatch.delenv("HRC_ROOT", raising=False)
    scenario = load(path, motion_check=False)  # walks up to the folder holding scenarios/
    assert scenario.project_root == arm_root.resolve()
    assert scenario.urdf_path("r2") == (arm_root / "robots" / "arm5.urdf").resolve()

    elsewhere = tmp_path / "x.toml"
    elsewhere.write_text(to_toml(minimal_raw), encoding="utf-8")
    monkeypatch.setenv("HRC_ROOT", str(arm_root))
    assert load(elsewhere, motion_check=False).project_root == arm_root.resolve()


# ---------------------------------------------------------------- all at once, and the error text


def test_every_problem_is_reported_not_just_the_first(minimal_raw: Data, problems_of) -> None:
    minimal_raw["scenario"]["tick_hz"] = -5  # schema
    minimal_raw["robots"]["r1"]["max_tcp_speed"] = 3.0  # schema
    part(minimal_raw, "H1")["after"] = ["NOPE"]  # reference
    minimal_raw["sequence"]["r2"] = []  # never used
    minimal_raw["robots"]["r2"]["urdf"] = "missing.urdf"  # file
    keys = {p.key for p in problems_of(minimal_raw)}
    assert keys == {
        "scenario.tick_hz",
        "robots.r1.max_tcp_speed",
        "parts.H1.after",
        "parts.S1",
        "robots.r2.urdf",
    }


def test_error_text_is_one_line_per_problem(minimal_raw: Data, write_scenario, arm_root) -> None:
    minimal_raw["scenario"]["tick_hz"] = 0
    part(minimal_raw, "H1")["after"] = ["X"]
    path = write_scenario(minimal_raw)
    with pytest.raises(ScenarioError) as info:
        load(path, project_root=arm_root, motion_check=False)
    lines = str(info.value).splitlines()
    assert len(lines) == 2
    assert lines[0].startswith(f"{path}: scenario.tick_hz: ")
    assert lines[1] == f"{path}: parts.H1.after: unknown part 'X'"


# ---------------------------------------------------------------- provoke_collisions shapes


@pytest.mark.parametrize(
    ("value", "times", "probability"),
    [
        (False, [], 0.0),
        (True, [], 1.0),
        (0.25, [], 0.25),
        (1, [], 1.0),
        ([12, 3.5], [3.5, 12.0], 0.0),
        ([], [], 0.0),
    ],
)
def test_provoke_collisions_shapes(
    minimal_raw: Data, write_scenario, arm_root, value: Any, times: list[float], probability: float
) -> None:
    minimal_raw["participant"]["provoke_collisions"] = value
    participant = load(
        write_scenario(minimal_raw), project_root=arm_root, motion_check=False
    ).participant
    assert participant.provoke_times_s == times
    assert participant.provoke_probability == probability


@pytest.mark.parametrize("value", [1.5, -0.1, "often", [1.0, "x"], [-2.0], {"p": 1}])
def test_provoke_collisions_rejects_other_shapes(
    minimal_raw: Data, problems_of, value: Any
) -> None:
    minimal_raw["participant"]["provoke_collisions"] = value
    (problem,) = problems_of(minimal_raw)
    assert problem.key == "participant.provoke_collisions"
