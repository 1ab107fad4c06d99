"""`pb.Metrics` and its JSON form (hrc.metrics, hrc.wire.jsonmap): the one metrics schema."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import pytest
from google.protobuf.descriptor import Descriptor, FieldDescriptor
from google.protobuf.message import Message

from hrc import metrics
from hrc.paths import project_root
from hrc.wire import pb

ROOT = project_root()


def full_metrics() -> pb.Metrics:
    """Every field set, maps given out of order."""
    m = pb.Metrics(scenario="s", participant="P", seed=2**63 + 5)
    m.conditions.anticipation = True
    m.conditions.safety_policy = pb.SAFETY_POLICY_RETREAT_BUTTON
    m.conditions.ssm.CopyFrom(
        pb.SsmParams(
            human_speed=1.6,
            reaction_time_s=0.1,
            deceleration=2.0,
            intrusion_distance_m=0.048,
            sensing_uncertainty_m=0.02,
            position_uncertainty_m=0.01,
            min_speed=0.01,
            resume_margin_m=0.05,
            sensing_range_m=2.0,
        )
    )
    m.conditions.robots["r2"].max_tcp_speed = 0.25
    m.conditions.robots["r1"].max_tcp_speed = 1.0
    p = m.conditions.participant
    p.input, p.replay_file = pb.INPUT_SOURCE_REPLAY, "/rec/p01.jsonl"
    p.reaction_time_s, p.peak_hand_speed, p.caution, p.fitts_a_s, p.fitts_b_s = (
        0.4,
        1.0,
        0.5,
        0.1,
        0.2,
    )
    p.pick_dwell_s, p.place_dwell_s, p.place_error_m, p.grip_close_s = 0.3, 0.25, 0.005, 0.15
    p.grip_open_s, p.max_hold_back_s, p.left_handed = 0.1, 10.0, True
    p.profile, p.fitts_c_s_per_m = pb.PARTICIPANT_PROFILE_REAL, 0.8
    p.stop_above, p.collision_reaction_s = False, 0.17
    p.provoke_probability = 0.5
    p.provoke_times_s.extend([3.0, 7.5])
    m.task.started, m.task.finished, m.task.completion_s = True, True, 45.5
    m.task.completion_home_s = 47.25
    m.human.completion_s, m.human.idle_s = 39.25, 1.5
    m.robots["r2"].CopyFrom(
        pb.RobotMetrics(
            completion_s=44.0,
            idle_s=0.5,
            avg_tcp_speed_mps=0.4,
            max_tcp_speed_mps=0.5,
            avg_tcp_speed_over_time_mps=0.2,
            completion_home_s=46.0,
        )
    )
    m.robots["r1"].CopyFrom(
        pb.RobotMetrics(
            completion_s=45.5,
            idle_s=0.0,
            avg_tcp_speed_mps=0.45,
            max_tcp_speed_mps=0.5,
            avg_tcp_speed_over_time_mps=0.3,
            completion_home_s=47.25,
        )
    )
    for rid, stops in (("r1", 2), ("r2", 0)):
        m.robots[rid].ssm.CopyFrom(
            pb.SsmMetrics(
                min_separation_m=0.125,
                reduced_speed_s=12.5,
                protective_stop_count=stops,
                protective_stop_s=1.5 * stops,
            )
        )
    col = m.collisions
    col.human_robot.add(t_s=3.5, robot="r2", hand="right", delay_s=1.5)
    col.human_robot_count, col.total_delay_s = 1, 1.5
    col.near.add(t_s=12.5)
    col.near_count = 1
    m.parts["S1"].CopyFrom(pb.PartMetrics(grabbed_s=1.5, placed_s=4.75))
    m.parts["H1"].CopyFrom(pb.PartMetrics(grabbed_s=0.0, placed_s=1.75))
    m.run.CopyFrom(
        pb.RunMetrics(
            mode=pb.CLOCK_MODE_REALTIME,
            ticks=11364,
            wall_s=10.5,
            realtime_factor=4.5,
            ok=False,
            end_reason="stalled",
            deadline_misses={"ik_cpp": 3, "human_input": 1},
            stall="stalled for 60 s: the human holds H3 since 42.6 s; r1 is home",
        )
    )
    m.recording.lost_messages = 12
    m.recording.loss_spans.add(from_s=1.5, to_s=3.25, messages=12)
    m.access.CopyFrom(metrics.access_metrics({"no_credentials": 2, "wrong_password": 1}))
    return m


def check_field_for_field(msg: Message, data: dict[str, Any]) -> None:
    """`data` has exactly the message's fields, in declaration order, with equal values."""
    fields = msg.DESCRIPTOR.fields
    assert list(data) == [f.name for f in fields]
    for f in fields:
        value, got = getattr(msg, f.name), data[f.name]
        if f.message_type is not None and f.message_type.GetOptions().map_entry:
            assert list(got) == sorted(value)
            for k in value:
                if isinstance(value[k], Message):
                    check_field_for_field(value[k], got[k])
                else:
                    assert got[k] == value[k] and type(got[k]) is int
        elif f.label == FieldDescriptor.LABEL_REPEATED and f.message_type is None:
            assert got == list(value)
        elif f.label == FieldDescriptor.LABEL_REPEATED:
            assert len(got) == len(value)
            for v, g in zip(value, got, strict=True):
                check_field_for_field(v, g)
        elif f.type == FieldDescriptor.TYPE_MESSAGE:
            check_field_for_field(value, got)
        elif f.type == FieldDescriptor.TYPE_ENUM:
            name = f.enum_type.values_by_number[value].name
            assert got is not None and name.endswith(got.upper())
        else:
            assert got == value and type(got) is type(value)


def test_the_json_form_matches_the_message_field_for_field() -> None:
    m = full_metrics()
    data = metrics.to_dict(m)
    check_field_for_field(m, data)
    assert data["conditions"]["safety_policy"] == "retreat_button"
    assert data["run"]["mode"] == "realtime" and data["seed"] == 2**63 + 5  # no strings
    assert list(data["parts"]) == ["H1", "S1"]
    json.dumps(data, allow_nan=False)


def test_unset_optional_fields_messages_and_enums_are_null() -> None:
    m = pb.Metrics(scenario="s")
    m.parts["H1"].grabbed_s = 0.0  # set to zero: not the same as never
    m.robots["r1"].idle_s = 0.0
    m.collisions.human_robot.add(t_s=1.0, robot="r1", hand="left")
    m.run.ticks = 10
    data = metrics.to_dict(m)
    assert data["parts"]["H1"] == {"grabbed_s": 0.0, "placed_s": None}
    assert data["robots"]["r1"]["completion_s"] is None and data["robots"]["r1"]["idle_s"] == 0.0
    assert data["collisions"]["human_robot"][0]["delay_s"] is None
    assert data["task"] is None and data["human"] is None and data["conditions"] is None
    assert data["run"]["mode"] is None and data["run"]["wall_s"] is None
    m.human.idle_s = math.nan
    assert metrics.to_dict(m)["human"] == {"completion_s": None, "idle_s": None}


def test_from_dict_is_the_inverse() -> None:
    m = full_metrics()
    assert metrics.from_dict(metrics.to_dict(m)) == m
    sparse = pb.Metrics(scenario="s")
    sparse.parts["H1"].grabbed_s = 0.0
    back = metrics.from_dict(json.loads(json.dumps(metrics.to_dict(sparse))))
    assert back == sparse and not back.parts["H1"].HasField("placed_s")


@pytest.mark.parametrize("name", ["thesis", "thesis-collisions"])
def test_a_committed_metrics_json_reads_back_unchanged(name: str) -> None:
    data = json.loads((ROOT / "tests" / "golden" / name / "metrics.json").read_text())
    assert metrics.to_dict(metrics.from_dict(data)) == data


@pytest.mark.parametrize(
    ("data", "match"),
    [
        ({"scenario": "s", "colour": "red"}, "colour: no such field"),
        ({"conditions": {"safety_policy": "pray"}}, "unknown SafetyPolicy 'pray'"),
        ({"run": {"mode": 1}}, "run.mode: expected text"),
        ({"seed": "one"}, "^seed: "),
        ({"parts": {"H1": {"placed_s": [1.0]}}}, "^parts.H1.placed_s: "),
    ],
)
def test_from_dict_refuses_what_is_not_in_the_schema(data: dict[str, Any], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        metrics.from_dict(data)


def field_paths(desc: Descriptor, prefix: str = "") -> list[str]:
    """Every field as docs/metrics.md names it: maps as `<id>`, repeated messages as `[]`."""
    out: list[str] = []
    for f in desc.fields:
        path = f"{prefix}{f.name}"
        out.append(path)
        sub = f.message_type
        if sub is not None and sub.GetOptions().map_entry:
            value = sub.fields_by_name["value"]
            if value.message_type is not None:
                out += field_paths(value.message_type, f"{path}.<id>.")
        elif sub is not None:
            inner = f"{path}[]." if f.label == FieldDescriptor.LABEL_REPEATED else f"{path}."
            out += field_paths(sub, inner)
    return out


def test_docs_list_every_field_once() -> None:
    text = (ROOT / "docs" / "metrics.md").read_text()
    rows = re.findall(r"^\| `([^`]+)` \|", text, flags=re.MULTILINE)
    assert rows == field_paths(pb.Metrics.DESCRIPTOR)


def test_refused_links_go_into_metrics_json_and_a_last_line_of_log_txt(tmp_path: Path) -> None:
    (tmp_path / metrics.METRICS_FILE).write_text(json.dumps(metrics.to_dict(full_metrics())))
    (tmp_path / metrics.TEXT_LOG_FILE).write_text("0.00 sec : TASK STARTED\n")
    refused = metrics.access_metrics({"no_credentials": 4, "unknown_user": 2, "wrong_password": 0})
    assert metrics.add_access(tmp_path, refused)
    data = json.loads((tmp_path / metrics.METRICS_FILE).read_text())
    assert data["access"] == {
        "refused_links": 6,
        "no_credentials": 4,
        "unknown_user": 2,
        "wrong_password": 0,
    }
    assert data["recording"]["lost_messages"] == 12  # the rest as it was
    last = (tmp_path / metrics.TEXT_LOG_FILE).read_text().splitlines()[-1]
    assert last.startswith("ACCESS REFUSED: 6 attempt(s)") and "none given 4" in last


def test_no_refused_link_no_line_and_no_metrics_json_no_file(tmp_path: Path) -> None:
    (tmp_path / metrics.TEXT_LOG_FILE).write_text("0.00 sec : TASK STARTED\n")
    assert not metrics.add_access(tmp_path, metrics.access_metrics({"no_credentials": 0}))
    assert not (tmp_path / metrics.METRICS_FILE).exists()
    assert (tmp_path / metrics.TEXT_LOG_FILE).read_text() == "0.00 sec : TASK STARTED\n"
