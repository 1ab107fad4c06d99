"""Whole tasks with fake arms and a fake participant: completion, anticipation cues, the end,
metrics, determinism."""

from __future__ import annotations

import json

import pytest
from orch_fakes import FakeHuman, K, Sim, load

from hrc import metrics as metrics_schema
from hrc.wire import pb

from hrc_orchestrator import metrics


def cue_log(sim_factory) -> list[pb.Cue]:
    """Every cue change of a run (the Sim keeps only the current ones)."""
    changes: list[pb.Cue] = []
    sim = sim_factory()
    while not sim.stop:
        changes.extend(sim.step().cues)
        assert sim.k < 200_000
    return changes


@pytest.mark.parametrize("name,parts", [("minimal.toml", 3), ("thesis.toml", 18)])
def test_whole_task_completes_and_ends_with_a_stop_request(name: str, parts: int) -> None:
    sim = Sim(load(name), human=FakeHuman(grab_delay_s=0.8, place_delay_s=0.6, misses=1))
    sim.run_to_end()
    assert sim.stop == "task finished"
    fin = sim.kinds(K.TASK_EVENT_KIND_TASK_FINISHED)
    assert (
        len(fin) == 1
        and fin[0].text
        == f"{fin[0].text[: fin[0].text.index(' sec')]} sec : TASK FINISHED. 0 total collisions."
    )
    assert len(sim.kinds(K.TASK_EVENT_KIND_PART_PLACED)) == parts
    assert all(sim.task.board.is_done(p.id) for p in sim.scenario.parts)
    assert len(sim.kinds(K.TASK_EVENT_KIND_PART_RELEASED)) == 1  # the one miss
    assert sim.task.completion_s == pytest.approx(fin[0].task_time)
    assert sim.task.completion_s == max(
        [sim.task.human.completion_s] + [a.completion_s for a in sim.task.agents.values()]
    )
    # After the end nothing more is produced.
    out = sim.step()
    assert out.events == [] and out.robot_commands == [] and out.world_commands == []
    assert sim.cues == {}  # every cue was switched off at the end


def test_thesis_cross_waits_accrue_robot_idle_time_with_a_slow_participant() -> None:
    sim = Sim(load("thesis.toml"), human=FakeHuman(grab_delay_s=3.0, place_delay_s=3.0))
    sim.run_to_end()
    waits = sim.kinds(K.TASK_EVENT_KIND_ROBOT_WAITING)
    assert {e.robot for e in waits} == {"r1", "r2"}  # both wait on the participant
    for rid, agent in sim.task.agents.items():
        over = [
            e.robot_wait_over.waited_s
            for e in sim.kinds(K.TASK_EVENT_KIND_ROBOT_WAIT_OVER)
            if e.robot == rid
        ]
        assert agent.idle.total == pytest.approx(sum(over)) and agent.idle.total > 0


def _run(name: str, **conditions: object) -> Sim:
    # The participant is slow enough for r2 to wait for H1 at its intermediate pose.
    sim = Sim(
        load(name, conditions=conditions), human=FakeHuman(grab_delay_s=1.5, place_delay_s=3.0)
    )
    return sim


def test_anticipation_cues_robot_target_in_robot_colour_from_grab_to_placement() -> None:
    changes = cue_log(lambda: _run("minimal.toml", anticipation=True))
    ra1 = [c for c in changes if c.id == "target:RA1"]
    assert [c.on for c in ra1] == [True, False]
    assert ra1[0].color == "yellow" and ra1[0].robot == "r1" and ra1[0].flashing
    s1 = [c for c in changes if c.id == "target:S1"]
    assert [c.on for c in s1] == [True, False] and s1[0].color == "green"
    assert (s1[0].position.x, s1[0].position.y, s1[0].position.z) == (-0.21, -0.02, 0.04)
    waiting = [c for c in changes if c.id == "waiting:r2"]
    assert [c.on for c in waiting] == [True, False] and waiting[0].text == "Waiting.."
    # The on/off instants match the grab and placement events.
    sim = _run("minimal.toml", anticipation=True)
    on_tick = off_tick = -1
    while not sim.stop:
        out = sim.step()
        for c in out.cues:
            if c.id == "target:RA1":
                if c.on:
                    on_tick = sim.k
                    assert any(
                        e.kind == K.TASK_EVENT_KIND_PART_GRABBED and e.part == "RA1"
                        for e in out.events
                    )
                else:
                    off_tick = sim.k
                    assert any(
                        e.kind == K.TASK_EVENT_KIND_PART_PLACED and e.part == "RA1"
                        for e in out.events
                    )
    assert 0 < on_tick < off_tick


def test_without_anticipation_only_the_participants_own_cues() -> None:
    changes = cue_log(lambda: _run("minimal.toml", anticipation=False))
    ids = {c.id for c in changes}
    assert ids == {"outline:H1", "target:H1"}
    assert all(c.color == "blue" for c in changes)


METRIC_FIELDS = [
    "scenario",
    "participant",
    "conditions",
    "seed",
    "task.completion_s",
    "task.completion_home_s",
    "human.completion_s",
    "human.idle_s",
    "collisions.human_robot",
    "collisions.human_robot_count",
    "collisions.total_delay_s",
    "collisions.near",
    "collisions.near_count",
    "run.mode",
    "run.ticks",
    "run.wall_s",
    "run.realtime_factor",
]


def dig(d: dict, path: str):
    for key in path.split("."):
        d = d[key]
    return d


def test_metrics_have_every_field_and_match_the_events() -> None:
    sim = Sim(
        load("thesis.toml", conditions={"safety_policy": "retreat"}),
        human=FakeHuman(grab_delay_s=1.0, place_delay_s=1.0),
        hands_in_envelope=False,
    )
    sim.run(lambda x: x.task.started and x.t >= 4.0)
    sim.contact(pb.CONTACT_KIND_HAND_ROBOT, True, "right", "r2", "tool")
    sim.step()
    sim.contact(pb.CONTACT_KIND_HAND_ROBOT, False, "right", "r2", "tool")
    sim.contact(pb.CONTACT_KIND_ROBOT_ROBOT, True, "r1", "r2")
    sim.step()
    sim.contact(pb.CONTACT_KIND_ROBOT_ROBOT, False, "r1", "r2")
    sim.run_to_end()
    end = pb.RunEnd(
        ok=True,
        reason="stopped: task finished",
        ticks=sim.k,
        sim_time=sim.k * sim.dt,
        wall_s=2.0,
        mode=pb.CLOCK_MODE_LOCKSTEP,
        realtime_factor=sim.k * sim.dt / 2,
    )
    msg = metrics.build(sim.task, 7, metrics.run_metrics(end))
    data = metrics_schema.to_dict(msg)
    json.dumps(data, allow_nan=False)  # serialisable
    for path in METRIC_FIELDS:
        dig(data, path)
    assert data["seed"] == 7 and data["run"]["mode"] == "lockstep"
    cond = data["conditions"]
    assert cond["anticipation"] is True and cond["safety_policy"] == "retreat"
    assert cond["robots"] == {"r1": {"max_tcp_speed": 0.5}, "r2": {"max_tcp_speed": 0.5}}
    assert cond["participant"]["input"] == "scripted" and cond["participant"]["caution"] == 0.5
    assert cond["ssm"] is None
    assert data["task"]["completion_s"] == pytest.approx(sim.task.completion_s)
    assert data["task"]["completion_home_s"] == pytest.approx(sim.task.completion_home_s)
    assert data["human"]["idle_s"] == pytest.approx(data["human"]["completion_s"])  # never in
    for rid in ("r1", "r2"):
        r = data["robots"][rid]
        assert set(r) == {
            "completion_s",
            "idle_s",
            "avg_tcp_speed_mps",
            "max_tcp_speed_mps",
            "avg_tcp_speed_over_time_mps",
            "completion_home_s",
            "ssm",
        }
        assert r["ssm"] is None  # only under safety_policy = "ssm"
        assert 0 < r["avg_tcp_speed_mps"] <= r["max_tcp_speed_mps"] <= 0.5 + 1e-9
        assert 0 < r["avg_tcp_speed_over_time_mps"] < r["avg_tcp_speed_mps"]
        assert r["completion_s"] <= data["task"]["completion_s"]
        assert r["completion_home_s"] <= data["task"]["completion_home_s"]
    col = data["collisions"]
    assert col["human_robot_count"] == 1 and col["near_count"] == 1
    rec = col["human_robot"][0]
    assert rec["robot"] == "r2" and rec["hand"] == "right" and rec["delay_s"] > 0
    assert col["total_delay_s"] == pytest.approx(rec["delay_s"])
    assert set(data["parts"]) == {p.id for p in sim.scenario.parts}
    for pid, p in data["parts"].items():
        assert 0 <= p["grabbed_s"] <= p["placed_s"], pid
    assert msg.seed == 7 and msg.run.ticks == sim.k and msg.run.ok
    assert data["run"]["end_reason"] == "stopped: task finished"
    assert data["task"]["started"] is True and data["task"]["finished"] is True
    report = metrics.report(msg, final=True)
    assert report.final and report.metrics.collisions.human_robot[0].robot == "r2"


def test_metrics_of_an_unfinished_task_leave_never_unset() -> None:
    sim = Sim(load("minimal.toml"), human=None)
    for _ in range(10):
        sim.step()
    msg = metrics.build(sim.task, 1)
    assert not msg.task.HasField("completion_s") and not msg.parts["RA1"].HasField("placed_s")
    assert not msg.HasField("run")
    data = metrics_schema.to_dict(msg)
    assert data["task"] == {
        "started": False,
        "finished": False,
        "completion_s": None,
        "completion_home_s": None,
    }
    assert data["parts"]["H1"]["grabbed_s"] is None and data["run"] is None


def test_a_run_that_broke_off_says_what_is_unknown() -> None:
    sim = Sim(load("minimal.toml"), human=None)
    sim.step()
    data = metrics_schema.to_dict(
        metrics.build(sim.task, 1, metrics.broken_off_run(sim.task.tick, "terminated by SIGTERM"))
    )
    assert data["run"] == {
        "mode": None,
        "ticks": sim.task.tick,
        "wall_s": None,
        "realtime_factor": None,
        "ok": False,
        "end_reason": "terminated by SIGTERM",
        "deadline_misses": {},
        "stall": None,
    }


def _trace(policy: str) -> tuple[list[bytes], list[bytes], dict]:
    sim = Sim(
        load("thesis.toml", conditions={"safety_policy": policy}),
        human=FakeHuman(grab_delay_s=0.7, place_delay_s=0.9, misses=2),
    )
    cues: list[bytes] = []

    def provoke(x: Sim) -> None:
        if x.task.started and abs(x.t - 5.0) < x.dt / 2:
            x.contact(pb.CONTACT_KIND_HAND_ROBOT, True, "left", "r1", "link2")
        if x.task.started and abs(x.t - 5.5) < x.dt / 2:
            x.contact(pb.CONTACT_KIND_HAND_ROBOT, False, "left", "r1", "link2")
            x.contact(pb.CONTACT_KIND_HAND_BUTTON, True, "left", "continue_button")

    sim.hooks.append(provoke)
    while not sim.stop:
        cues.extend(c.SerializeToString(deterministic=True) for c in sim.step().cues)
        assert sim.k < 100_000
    events = [e.SerializeToString(deterministic=True) for e in sim.events]
    events += [c.SerializeToString(deterministic=True) for c in sim.commands]
    events += [w.SerializeToString(deterministic=True) for w in sim.world]
    return events, cues, metrics_schema.to_dict(metrics.build(sim.task, 1))


@pytest.mark.parametrize("policy", ["retreat", "retreat_button", "stop_colliding"])
def test_same_inputs_give_identical_outputs(policy: str) -> None:
    a, b = _trace(policy), _trace(policy)
    assert a[0] == b[0] and a[1] == b[1] and a[2] == b[2]
    assert a[2]["collisions"]["human_robot_count"] == 1
