"""A synthetic trial fed straight into the recorder: log.txt, events.jsonl and recording.rrd."""

from __future__ import annotations

import json
import math
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import rerun as rr
from offline import run_offline
from synthetic import SyntheticTrial

from hrc import scenario as sc
from hrc.paths import project_root
from hrc.urdf_fk import point_polyline_distance, yaw_transform
from hrc.wire import pb

from hrc_logger.records import event_record, metrics_record
from hrc_logger.rrd import summarize


@pytest.fixture(scope="module")
def trial_dir(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, SyntheticTrial]:
    scenario = sc.to_proto(
        sc.load(project_root() / "scenarios" / "thesis.toml", motion_check=False)
    )
    trial = SyntheticTrial(scenario, n_ticks=600)
    out = tmp_path_factory.mktemp("trial")
    run_offline(trial, out)
    return out, trial


def test_log_txt_in_thesis_order(trial_dir: tuple[Path, SyntheticTrial]) -> None:
    out, trial = trial_dir
    settings, *lines = (out / "log.txt").read_text().splitlines()
    # the thesis's settings first: its speeds, anticipation, policy, the participant
    assert settings.startswith("SETTINGS: anticipation on, safety policy retreat, seed 1; ")
    assert "r1 max TCP speed 0.5 m/s, r2 max TCP speed 0.5 m/s;" in settings
    assert "participant P01: scripted, profile baseline, reaction_time_s " in settings
    assert lines[0] == "2024-05-02 14:03:11 - TASK STARTED."
    assert lines[-2].endswith("TASK FINISHED. 2 total collisions.")
    assert lines[-1].endswith(" sec : 1 total near-collisions between the robots.")
    assert sum(" : Collision " in line for line in lines) == trial.expected.collisions == 2
    assert sum(" : Near-collision " in line for line in lines) == trial.expected.near == 1
    assert sum("Continuing after robot-hand collision" in line for line in lines) == 2
    order = [line.split(" sec : ")[1].split(" ")[0] for line in lines[1:]]
    assert order == [
        "Collision",
        "Continuing",
        "Near-collision",
        "Collision",
        "Continuing",
        "r1",
        "r2",
        "Human",
        "TASK",
        "1",
    ]
    times = [float(line.split(" sec : ")[0]) for line in lines[1:]]
    assert times == sorted(times)


def test_events_jsonl_counts(trial_dir: tuple[Path, SyntheticTrial]) -> None:
    out, trial = trial_dir
    records = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    kinds = Counter(r["kind"] for r in records if r["type"] == "event")
    assert kinds == trial.expected.event_kinds
    assert sum(r["type"] == "cue" for r in records) == trial.expected.cue_changes
    metrics = [r for r in records if r["type"] == "metrics"]
    assert len(metrics) == 1 and metrics[0]["final"] is True
    assert metrics[0]["collisions"]["human_robot_count"] == kinds["COLLISION"]
    assert metrics[0]["collisions"]["near_count"] == kinds["NEAR_COLLISION"]
    assert records[-1]["type"] == "run_end" and records[-1]["ok"] is True
    for r in records:
        assert {"type", "tick", "sim_time"} <= set(r)


def test_recording_holds_robots_parts_cues_over_the_trial(
    trial_dir: tuple[Path, SyntheticTrial],
) -> None:
    out, trial = trial_dir
    s = summarize(out / "recording.rrd")
    last = trial.n - 1
    for rid in ("r1", "r2"):
        assert any(e.startswith(f"/robot_{rid}/") and "visual_geometries" in e for e in s), rid
        assert "Transform3D:child_frame" in s[f"/robot_{rid}/base"].components
        for j in ("j1_base_yaw", "j2_shoulder", "j3_elbow", "j4_wrist_pitch", "j5_wrist_roll"):
            joint = s[f"/robot_{rid}/joints/{j}"]
            assert "Transform3D:quaternion" in joint.components
            assert (joint.first_tick, joint.last_tick) == (0, last), (rid, j)
        assert (
            s[f"/plots/tcp_speed/{rid}"].first_tick,
            s[f"/plots/tcp_speed/{rid}"].last_tick,
        ) == (0, last)
        for hand in ("left", "right"):
            assert s[f"/plots/hand_distance/{hand}/{rid}"].last_tick == last
        tcp = s[f"/world/tcp/{rid}"]  # sent in columns, as the joints and plots
        assert {"Points3D:positions", "Points3D:colors"} <= tcp.components, rid
        assert (tcp.first_tick, tcp.last_tick) == (0, last), rid
    for ent in ("head", "left_hand", "right_hand"):
        human = s[f"/world/human/{ent}"]
        assert {"Points3D:positions", "Points3D:radii"} <= human.components, ent
        assert human.last_tick == last, ent
    assert "Points3D:labels" in s["/world/human/left_hand"].components  # the grip, hidden
    for p in trial.sc.parts:
        assert f"/world/targets/{p.id}" in s
        if p.start_given or p.id in trial.expected.parts_moved:
            assert "Transform3D:translation" in s[f"/world/parts/{p.id}"].components, p.id
    for pid in trial.expected.parts_moved:
        assert len(s[f"/world/parts/{pid}"].ticks) > 5, pid  # animated, not just placed
    for cid in trial.expected.cue_ids:
        ent = "/world/cues/" + cid.replace(":", "/")
        assert "Clear:is_recursive" in s[ent].components, cid  # turned off again (or blinking)
    # flashing: the H1 target cue is on for ticks 50..200 (0.6 s at 2 Hz blink) -> shown, hidden,
    # shown...
    assert len(s["/world/cues/target/H1"].ticks) >= 4
    assert sorted(s["/world/contacts/hand_robot/left_r1_link3_forearm"].ticks) == [250, 262]
    assert "/world/contacts/hand_envelope" not in " ".join(s)


def test_rate_limit_keeps_the_view_cheap(trial_dir: tuple[Path, SyntheticTrial]) -> None:
    out, trial = trial_dir
    s = summarize(out / "recording.rrd")
    rows = len(s["/robot_r1/joints/j1_base_yaw"].ticks)
    expected = trial.n / (240 / 30)
    assert expected <= rows <= expected + 2  # 30 Hz of sim time plus the final state


def test_record_mapping_is_flat_and_json_safe() -> None:
    ev = pb.TaskEvent(
        kind=pb.TASK_EVENT_KIND_CONTINUED,
        task_time=float("nan"),
        continued=pb.Continued(number=2, delay_s=1.5),
    )
    ev.header.tick, ev.header.sim_time, ev.header.seq = 7, 7 / 240, 3
    r = event_record(ev)
    assert r["kind"] == "CONTINUED" and r["task_time"] is None
    assert r["payload"] == {"number": 2, "delay_s": 1.5}
    assert (r["tick"], r["seq"], r["type"]) == (7, 3, "event")
    json.dumps(r, allow_nan=False)
    assert event_record(pb.TaskEvent(kind=pb.TASK_EVENT_KIND_PART_PLACED))["payload"] == {}
    report = pb.MetricsReport(final=True)
    col = report.metrics.collisions
    col.human_robot.add(t_s=1.0, robot="r1", hand="left", delay_s=2.0)
    col.human_robot_count = 1
    col.near.add(t_s=float("inf"))
    report.header.tick = 9
    rec = metrics_record(report)
    assert (rec["type"], rec["tick"], rec["final"]) == ("metrics", 9, True)
    assert rec["collisions"]["human_robot_count"] == 1 and rec["collisions"]["near"] == [
        {"t_s": None}
    ]
    assert math.isclose(rec["collisions"]["human_robot"][0]["delay_s"], 2.0)
    assert rec["run"] is None and rec["task"] is None  # not set by the sender
    json.dumps(rec, allow_nan=False)


def _scalar_rows(path: Path, entity: str) -> dict[int, float]:
    """tick -> value of a scalar entity's rows in a recording."""
    out: dict[int, float] = {}
    for chunk in rr.chunk.RrdReader(path).stream():
        if chunk.entity_path != entity:
            continue
        batch = chunk.to_record_batch()
        ticks = batch.column("tick").to_pylist()
        values = batch.column("Scalars:scalars").to_pylist()
        for t, v in zip(ticks, values, strict=True):
            out[int(t)] = float(v[0])
    return out


def test_hand_distances_are_to_the_chain_of_the_state_logged_with_them(
    trial_dir: tuple[Path, SyntheticTrial],
) -> None:
    """Hand distances are computed per column when sent, from the joint vector each row kept:
    every row must be the distance to the robot's chain at that row's own state."""
    out, trial = trial_dir
    for rid, r in trial.robots.items():
        model = trial.models[rid]
        base = yaw_transform([r.base.xyz.x, r.base.xyz.y, r.base.xyz.z], r.base.yaw_deg)
        for hand in ("left", "right"):
            rows = _scalar_rows(out / "recording.rrd", f"/plots/hand_distance/{hand}/{rid}")
            assert len(rows) > 50, (rid, hand)
            for k, d in rows.items():
                hs = trial.human_state(k)
                p = (hs.left_hand if hand == "left" else hs.right_hand).position
                chain = model.chain_points(
                    dict(zip(model.movable, trial.q(rid, k), strict=True)), base
                )
                expected = point_polyline_distance(np.array([p.x, p.y, p.z]), chain)
                assert d == pytest.approx(expected, abs=1e-9), (rid, hand, k)
