"""Phase machines of r1 (transport) and r2 (screwing), dwell, dependency waits and idle time."""

from __future__ import annotations

import pytest
from orch_fakes import K, Sim, idle_seconds, load

from hrc.geometry import vec3
from hrc.scenario.conventions import APPROACH_HEIGHT_M
from hrc.wire import pb

PHASES_R1 = ["to_pick", "to_intermediate", "to_place", "returning", "to_home"]


def start(sim: Sim) -> None:
    sim.step()
    sim.grab("H1")
    sim.step()


def robot_log(sim: Sim, robot: str) -> list[str]:
    """Phase names and part events of one robot, in order."""
    out = []
    for e in sim.events:
        if e.robot != robot:
            continue
        if e.kind == K.TASK_EVENT_KIND_ROBOT_PHASE:
            out.append(e.text.split("phase ")[1].split(" ")[0].rstrip("."))
        elif e.kind in (
            K.TASK_EVENT_KIND_PART_GRABBED,
            K.TASK_EVENT_KIND_PART_PLACED,
            K.TASK_EVENT_KIND_ROBOT_WAITING,
            K.TASK_EVENT_KIND_ROBOT_WAIT_OVER,
            K.TASK_EVENT_KIND_ROBOT_FINISHED,
        ):
            out.append(pb.TaskEventKind.Name(e.kind).removeprefix("TASK_EVENT_KIND_").lower())
    return out


def test_transport_robot_phases_commands_and_world_commands() -> None:
    s = load("minimal.toml")
    sim = Sim(s)
    start(sim)
    sim.run_to_end()
    assert robot_log(sim, "r1") == [
        "to_pick",
        "part_grabbed",
        "to_intermediate",
        "to_place",
        "part_placed",
        "robot_finished",  # at its last placement (the thesis's "task FINISHED"), then home
        "returning",
        "to_home",
    ]
    r1 = [c for c in sim.commands if c.robot == "r1"]
    part = s.part("RA1")
    pick, mid, place, back, home = r1
    assert [c.command_id for c in r1] == [1, 2, 3, 4, 5]
    top = part.size[2] / 2
    assert (pick.target.x, pick.target.y, pick.target.z) == pytest.approx(
        (part.start.xyz[0], part.start.xyz[1], part.start.xyz[2] + top)
    )
    assert pick.approach_height == 0.05 and pick.depart_height == 0.0
    assert (mid.target.x, mid.target.y, mid.target.z) == tuple(s.robots["r1"].intermediate)
    assert mid.depart_height == 0.05
    assert (place.target.x, place.target.y, place.target.z) == pytest.approx(
        (part.target.xyz[0], part.target.xyz[1], part.target.xyz[2] + top)
    )
    assert place.approach_height == APPROACH_HEIGHT_M and place.yaw_deg == part.target.yaw
    assert back.depart_height == 0.05
    assert (home.target.x, home.target.y, home.target.z) == tuple(s.robots["r1"].home)
    attach = [w.attach for w in sim.world if w.HasField("attach") and w.attach.holder == "r1"]
    assert [a.object for a in attach] == ["RA1"]
    rel = [w.release for w in sim.world if w.HasField("release") and w.release.object == "RA1"]
    assert len(rel) == 1 and rel[0].snap
    assert (rel[0].pose.position.x, rel[0].pose.position.y, rel[0].pose.position.z) == tuple(
        part.target.xyz
    )
    fin = next(e for e in sim.kinds(K.TASK_EVENT_KIND_ROBOT_FINISHED) if e.robot == "r1")
    assert fin.robot_finished.max_tcp_speed_mps == pytest.approx(0.5)
    assert 0 < fin.robot_finished.avg_tcp_speed_mps <= 0.5
    assert "task FINISHED" in fin.text


def test_screwing_robot_spawns_at_the_feeder_and_dwells_at_least_screw_time() -> None:
    s = load("minimal.toml")
    sim = Sim(s)
    start(sim)
    sim.run_to_end()
    assert robot_log(sim, "r2") == [
        "to_feeder",
        "part_grabbed",
        "to_intermediate",
        "to_place",
        "part_placed",
        "robot_finished",
        "screwing",
        "returning",
        "to_home",
    ]
    world = [w for w in sim.world if not w.HasField("set_grabbable")]
    i_spawn = next(i for i, w in enumerate(world) if w.HasField("spawn"))
    spawn = world[i_spawn].spawn
    assert spawn.object == "S1" and spawn.kind == "screw" and spawn.owner == "r2"
    assert (spawn.pose.position.x, spawn.pose.position.y, spawn.pose.position.z) == tuple(
        s.robots["r2"].feeder
    )
    assert world[i_spawn + 1].attach.object == "S1" and world[i_spawn + 1].attach.holder == "r2"
    to_feeder = next(c for c in sim.commands if c.robot == "r2")
    assert to_feeder.target.z == pytest.approx(s.robots["r2"].feeder[2] + 0.01)
    placed = next(
        e for e in sim.events if e.kind == K.TASK_EVENT_KIND_PART_PLACED and e.part == "S1"
    )
    returning = next(
        e
        for e in sim.events
        if e.kind == K.TASK_EVENT_KIND_ROBOT_PHASE and e.robot == "r2" and "returning" in e.text
    )
    dwell = returning.task_time - placed.task_time
    screw = s.robots["r2"].screw_time_or_default
    assert screw - 1e-9 <= dwell < screw + 2 * sim.dt


def test_dependency_wait_accrues_idle_time_and_shows_waiting_cue() -> None:
    s = load("minimal.toml")  # S1 waits for H1
    sim = Sim(s, human=None)
    start(sim)
    sim.run(lambda x: x.task.agents["r2"].phase.value == "waiting", max_s=10)
    t_wait = sim.t
    assert sim.has(K.TASK_EVENT_KIND_ROBOT_WAITING, robot="r2", part="S1")
    sim.step()
    cue = sim.cues["waiting:r2"]
    assert cue.text == "Waiting.." and cue.color == "green" and cue.kind == pb.CUE_KIND_WAITING
    sim.run(lambda x: x.t >= 6.0)
    sim.release("H1", vec3(s.part("H1").target.xyz))
    sim.step()
    t_done = sim.t
    over = sim.kinds(K.TASK_EVENT_KIND_ROBOT_WAIT_OVER)
    assert len(over) == 1 and over[0].robot == "r2"
    assert over[0].robot_wait_over.waited_s == pytest.approx(t_done - t_wait)
    assert t_done - t_wait > 3.0
    assert "waiting:r2" not in sim.cues
    sim.run_to_end()
    assert sim.task.agents["r2"].idle.total == pytest.approx(t_done - t_wait)
    assert idle_seconds(sim.events, "r2") == pytest.approx(t_done - t_wait)
    assert sim.task.agents["r1"].idle.total == 0.0
    fin = next(e for e in sim.kinds(K.TASK_EVENT_KIND_ROBOT_FINISHED) if e.robot == "r2")
    assert fin.robot_finished.idle_s == pytest.approx(t_done - t_wait)


def test_robot_waits_only_at_the_intermediate_pose_holding_its_part() -> None:
    s = load("minimal.toml")
    sim = Sim(s, human=None)
    start(sim)
    sim.run(lambda x: x.task.agents["r2"].phase.value == "waiting", max_s=10)
    agent = sim.task.agents["r2"]
    assert agent.carrying == "S1"
    assert sim.robots["r2"].tcp == pytest.approx(tuple(s.robots["r2"].intermediate))
    n = len([c for c in sim.commands if c.robot == "r2"])
    sim.run(lambda x: x.t >= 4.0)
    assert len([c for c in sim.commands if c.robot == "r2"]) == n  # none while it waits


def test_unreachable_target_is_reported_once() -> None:
    sim = Sim(load("minimal.toml"))
    start(sim)

    def refuse(x: Sim) -> None:
        for st in x.states:
            if st.robot == "r1":
                st.status = pb.MOTION_STATUS_UNREACHABLE
                st.detail = "out of the workspace"

    sim.hooks.append(refuse)
    for _ in range(20):
        sim.step()
    bad = sim.kinds(K.TASK_EVENT_KIND_ROBOT_UNREACHABLE)
    assert len(bad) == 1 and bad[0].robot == "r1" and "out of the workspace" in bad[0].text
    assert sim.task.agents["r1"].phase.value == "to_pick"  # it does not chase the target
