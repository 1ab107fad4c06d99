"""Start, human gating, placement judgement, target cues and human idle time."""

from __future__ import annotations

import pytest
from orch_fakes import K, Sim, load

from hrc.geometry import add, vec3
from hrc.wire import pb


def grabbable_cmds(out: pb.WorldCommand | list) -> dict[str, bool]:
    return {
        w.set_grabbable.object: w.set_grabbable.grabbable
        for w in out
        if w.HasField("set_grabbable")
    }


def test_nothing_moves_before_the_first_grab_then_the_task_starts_at_zero() -> None:
    sim = Sim(load("thesis.toml"), human=None)
    first = sim.step()
    # Only H1 is grabbable; every other part with a start pose is explicitly not.
    g = grabbable_cmds(first.world_commands)
    assert g["H1"] is True
    assert all(not v for k, v in g.items() if k != "H1") and "RA1" in g and "H2" in g
    assert "outline:H1" in sim.cues and sim.cues["outline:H1"].color == "blue"
    for _ in range(100):
        sim.step()
    assert sim.commands == [] and sim.events == [] and sim.t == 0.0
    sim.grab("H2")  # not the first object: ignored, no start
    sim.step()
    assert sim.events == []
    k_start = sim.k
    sim.grab("H1", "left")
    out = sim.step()
    kinds = [e.kind for e in out.events]
    assert kinds[0] == K.TASK_EVENT_KIND_TASK_STARTED
    started = out.events[0]
    assert started.task_time == 0.0 and started.wall_time == sim.wall
    assert sim.wall not in started.text  # the date stays out of the deterministic text
    assert sim.task.start_sim_time == pytest.approx(k_start * sim.dt)
    assert any(
        e.kind == K.TASK_EVENT_KIND_PART_GRABBED and e.part == "H1" and e.hand == "left"
        for e in out.events
    )
    assert {c.robot for c in out.robot_commands} == {"r1", "r2"}
    assert "outline:H1" not in sim.cues  # held: no outline
    assert "target:H1" in sim.cues  # H1 has no `after`: placeable at once


def start(sim: Sim, part: str = "H1") -> None:
    sim.step()
    sim.grab(part)
    sim.step()


def test_release_within_tolerance_snaps_onto_the_target() -> None:
    s = load("thesis.toml")
    sim = Sim(s, human=None)
    start(sim)
    target = vec3(s.part("H1").target.xyz)
    sim.release("H1", add(target, (0.012, -0.01, 0.0)), yaw_deg=15.0)  # 1.56 cm, 15 deg
    out = sim.step()
    snap = [w.release for w in out.world_commands if w.HasField("release")]
    assert len(snap) == 1 and snap[0].object == "H1" and snap[0].snap
    assert (snap[0].pose.position.x, snap[0].pose.position.y, snap[0].pose.position.z) == target
    assert any(e.kind == K.TASK_EVENT_KIND_PART_PLACED and e.part == "H1" for e in out.events)
    g = grabbable_cmds(out.world_commands)
    assert g == {"H1": False, "H2": True}  # the next one becomes grabbable
    assert "outline:H2" in sim.cues and "target:H1" not in sim.cues
    assert sim.task.board.placed_s["H1"] == pytest.approx(sim.dt)


@pytest.mark.parametrize("offset,yaw_deg", [((0.03, 0.0, 0.0), 0.0), ((0.0, 0.0, 0.0), 25.0)])
def test_release_outside_tolerance_is_a_miss_and_can_be_grabbed_again(offset, yaw_deg) -> None:
    s = load("thesis.toml")
    sim = Sim(s, human=None)
    start(sim)
    sim.release("H1", add(vec3(s.part("H1").target.xyz), offset), yaw_deg=yaw_deg)
    out = sim.step()
    assert not any(w.HasField("release") for w in out.world_commands)
    missed = [e for e in out.events if e.kind == K.TASK_EVENT_KIND_PART_RELEASED]
    assert len(missed) == 1 and missed[0].part == "H1"
    assert "H1" not in sim.task.board.placed_s
    assert sim.grabbable["H1"] is True and "outline:H1" in sim.cues
    sim.grab("H1")
    sim.step()
    sim.release("H1", vec3(s.part("H1").target.xyz))
    out = sim.step()
    assert any(e.kind == K.TASK_EVENT_KIND_PART_PLACED for e in out.events)
    assert sim.task.board.grabbed_s["H1"] == 0.0  # metrics keep the first grab


def test_target_cue_and_placement_wait_for_after_parts() -> None:
    s = load("thesis.toml")
    sim = Sim(s, human=None)
    start(sim)
    sim.release("H1", vec3(s.part("H1").target.xyz))
    sim.step()
    sim.grab("H2")  # H2 needs RA2 (placed by r1 after a few seconds)
    sim.step()
    assert "target:H2" not in sim.cues
    sim.release("H2", vec3(s.part("H2").target.xyz))
    out = sim.step()
    released = [e for e in out.events if e.kind == K.TASK_EVENT_KIND_PART_RELEASED]
    assert released and "RA2" in released[0].text
    sim.grab("H2")
    sim.step()
    sim.run(lambda x: x.task.board.is_done("RA2"), max_s=30)
    sim.step()
    assert "target:H2" in sim.cues
    sim.release("H2", vec3(s.part("H2").target.xyz))
    out = sim.step()
    assert any(e.kind == K.TASK_EVENT_KIND_PART_PLACED and e.part == "H2" for e in out.events)


def test_human_idle_is_time_with_no_hand_in_any_envelope_box() -> None:
    s = load("minimal.toml")
    sim = Sim(s, human=None, hands_in_envelope=False)
    start(sim)  # no hand inside: idle from t = 0
    assert sim.has(K.TASK_EVENT_KIND_HUMAN_IDLE_BEGIN, task_time=0.0)
    sim.run(lambda x: x.t >= 2.0)
    sim.contact(pb.CONTACT_KIND_HAND_ENVELOPE, True, "left", "1")
    sim.step()
    t_in = sim.t
    sim.run(lambda x: x.t >= 3.0)
    sim.contact(pb.CONTACT_KIND_HAND_ENVELOPE, True, "right", "0")
    sim.contact(pb.CONTACT_KIND_HAND_ENVELOPE, False, "left", "1")  # the right hand is still in
    sim.step()
    sim.run(lambda x: x.t >= 4.0)
    sim.contact(pb.CONTACT_KIND_HAND_ENVELOPE, False, "right", "0")
    sim.step()
    t_out = sim.t
    sim.run(lambda x: x.t >= 4.5)
    sim.release("H1", vec3(s.part("H1").target.xyz))
    sim.step()
    t_done = sim.t
    expected = t_in + (t_done - t_out)
    assert sim.task.human.completion_s == pytest.approx(t_done)
    assert sim.task.human.idle.total == pytest.approx(expected)
    assert expected == pytest.approx(2.5, abs=0.01)
    assert len(sim.kinds(K.TASK_EVENT_KIND_HUMAN_IDLE_BEGIN)) == 2
    assert len(sim.kinds(K.TASK_EVENT_KIND_HUMAN_IDLE_END)) == 1
    finished = sim.kinds(K.TASK_EVENT_KIND_HUMAN_FINISHED)[0]
    assert finished.human_finished.idle_s == pytest.approx(expected)
