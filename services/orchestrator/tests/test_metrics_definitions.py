"""The metric definitions of docs/metrics.md: the thesis's average TCP speed (moving ticks, up to
the last placement) beside the average over time, completion at the last placement vs at home,
and the trial's conditions."""

from __future__ import annotations

import pytest
from orch_fakes import K, Sim, load

from hrc import metrics as metrics_schema
from hrc.geometry import vec3
from hrc.wire import pb

from hrc_orchestrator import metrics
from hrc_orchestrator.robots import MOVING_SPEED_MPS, SpeedStats


def test_a_speed_trace_with_waits_gives_the_thesis_average() -> None:
    stats = SpeedStats()
    # moving at 0.5, a wait (standing still, and a creep below the threshold), moving at 0.25,
    # then, after the last placement, the trip home at 0.5 and standing at home
    before_done = [0.5, 0.5, 0.0, 0.0, 0.0, MOVING_SPEED_MPS / 2, 0.0, 0.25, 0.25, 0.0]
    after_done = [0.5, 0.5, 0.5, 0.0]
    for v in before_done:
        stats.sample(v, until_done=True)
    for v in after_done:
        stats.sample(v, until_done=False)
    assert stats.avg_moving == pytest.approx((0.5 + 0.5 + 0.25 + 0.25) / 4)
    trace = before_done + after_done
    assert stats.avg_over_time == pytest.approx(sum(trace) / len(trace))
    assert stats.max == 0.5
    assert SpeedStats().avg_moving == 0.0 and SpeedStats().avg_over_time == 0.0


def dependency_wait_trial() -> Sim:
    """minimal.toml, r2 held at its intermediate pose ~4 s waiting for H1 (the fake arms move
    at exactly max_tcp_speed, so every moving tick but a motion's last is at 0.5 m/s)."""
    s = load("minimal.toml")
    sim = Sim(s, human=None)
    sim.step()
    sim.grab("H1")
    sim.step()
    sim.run(lambda x: x.t >= 6.0)
    sim.release("H1", vec3(s.part("H1").target.xyz))
    sim.run_to_end()
    return sim


def test_thesis_average_excludes_waits_and_the_trip_home() -> None:
    sim = dependency_wait_trial()
    m = metrics.build(sim.task, seed=1)
    r2 = m.robots["r2"]
    assert r2.idle_s > 3.0
    # moving ticks only: close to the cap (a motion's last tick covers less than a full step)
    assert 0.45 < r2.avg_tcp_speed_mps <= 0.5
    # every tick up to home: the wait pulls it far down
    assert r2.avg_tcp_speed_over_time_mps < 0.6 * r2.avg_tcp_speed_mps
    assert r2.max_tcp_speed_mps == pytest.approx(0.5)
    fin = next(e for e in sim.kinds(K.TASK_EVENT_KIND_ROBOT_FINISHED) if e.robot == "r2")
    assert fin.robot_finished.avg_tcp_speed_mps == pytest.approx(r2.avg_tcp_speed_mps, abs=1e-6)


def test_completion_at_the_last_placement_and_at_home() -> None:
    sim = dependency_wait_trial()
    m = metrics.build(sim.task, seed=1)
    for rid, last in (("r1", "RA1"), ("r2", "S1")):
        r = m.robots[rid]
        assert r.completion_s == m.parts[last].placed_s
        assert r.completion_home_s > r.completion_s + 0.1  # the trip home takes a while
        fin = next(e for e in sim.kinds(K.TASK_EVENT_KIND_ROBOT_FINISHED) if e.robot == rid)
        assert fin.task_time == pytest.approx(r.completion_s, abs=1e-6)
    last_done = max(m.human.completion_s, *(r.completion_s for r in m.robots.values()))
    assert m.task.finished
    assert m.task.completion_s == pytest.approx(last_done)
    last_home = max(r.completion_home_s for r in m.robots.values())
    assert m.task.completion_home_s == pytest.approx(last_home)
    (done,) = sim.kinds(K.TASK_EVENT_KIND_TASK_FINISHED)
    assert done.task_time == pytest.approx(m.task.completion_s, abs=1e-6)
    assert "TASK FINISHED" in done.text


def test_before_the_end_completion_times_are_unset() -> None:
    s = load("minimal.toml")
    sim = Sim(s, human=None)
    sim.step()
    sim.grab("H1")
    sim.run(lambda x: x.t >= 3.0)
    m = metrics.build(sim.task, seed=1)
    assert not m.task.finished
    assert not m.task.HasField("completion_s") and not m.task.HasField("completion_home_s")
    assert not m.robots["r2"].HasField("completion_s")


def test_conditions_record_every_factor_a_study_varies() -> None:
    s = load(
        "minimal.toml",
        conditions={"anticipation": False, "safety_policy": "stop_colliding"},
        participant={"name": "P07", "caution": 0.9, "provoke_collisions": 0.25},
    )
    s.robots["r1"].max_tcp_speed = 0.25
    c = metrics_schema.to_dict(pb.Metrics(conditions=metrics_schema.conditions(s)))["conditions"]
    assert c["anticipation"] is False and c["safety_policy"] == "stop_colliding"
    assert c["robots"] == {"r1": {"max_tcp_speed": 0.25}, "r2": {"max_tcp_speed": 0.5}}
    p = c["participant"]
    assert p["input"] == "scripted" and p["replay_file"] is None
    assert p["caution"] == 0.9 and p["reaction_time_s"] == 0.4  # default filled in
    assert p["provoke_probability"] == 0.25 and p["provoke_times_s"] == []
    line = metrics_schema.settings_line("P07", 3, metrics_schema.conditions(s))
    assert line.startswith("SETTINGS: anticipation off, safety policy stop_colliding, seed 3;")
    assert "r1 max TCP speed 0.25 m/s, r2 max TCP speed 0.5 m/s" in line
    assert (
        "participant P07: scripted, profile baseline, reaction_time_s 0.4," in line
        and "caution 0.9" in line
    )


def test_conditions_of_a_replayed_participant_leave_the_scripted_parameters_out() -> None:
    s = load("minimal.toml", participant={"input": "replay", "replay_file": "/tmp/r.jsonl"})
    p = metrics_schema.to_dict(pb.Metrics(conditions=metrics_schema.conditions(s)))["conditions"][
        "participant"
    ]
    assert p["input"] == "replay" and p["replay_file"] == "/tmp/r.jsonl"
    assert p["caution"] is None and p["reaction_time_s"] is None
