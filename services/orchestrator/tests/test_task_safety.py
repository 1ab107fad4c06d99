"""The three human-robot safety policies and robot-robot near-collision yielding."""

from __future__ import annotations

import pytest
from orch_fakes import K, Sim, load

from hrc.geometry import vec3
from hrc.scenario import Ssm
from hrc.scenario.conventions import CONTINUE_BUTTON_CUE
from hrc.wire import pb

from hrc_orchestrator.task import Task

HR = pb.CONTACT_KIND_HAND_ROBOT
RR = pb.CONTACT_KIND_ROBOT_ROBOT


def started(policy: str, **kw: object) -> Sim:
    sim = Sim(load("thesis.toml", conditions={"safety_policy": policy}), **kw)
    sim.run(lambda x: x.task.started and x.t >= 3.0, max_s=20)
    return sim


def last_cmd(sim: Sim, robot: str) -> pb.RobotCommand:
    return [c for c in sim.commands if c.robot == robot][-1]


def target(cmd: pb.RobotCommand) -> tuple[float, float, float]:
    return (cmd.target.x, cmd.target.y, cmd.target.z)


def test_retreat_both_robots_retreat_then_resume_their_targets() -> None:
    sim = started("retreat")
    goals = {rid: a.goal for rid, a in sim.task.agents.items()}
    next_part = sim.task.human.next_part
    sim.contact(HR, True, "right", "r1", "link3")
    out = sim.step()
    t_col = sim.t
    col = [e for e in out.events if e.kind == K.TASK_EVENT_KIND_COLLISION]
    assert len(col) == 1 and col[0].robot == "r1" and col[0].hand == "right"
    assert "Collision 1 occurred between r1" in col[0].text
    for rid in ("r1", "r2"):
        cmd = last_cmd(sim, rid)
        assert cmd.kind == pb.RobotCommand.KIND_MOVE
        assert target(cmd) == tuple(sim.scenario.robots[rid].retreat)
    # During the collision no new object may be grabbed.
    if not sim.task.human.held_part:
        assert sim.grabbable[next_part] is False
    # A second touch during the collision is not counted (one at a time).
    sim.contact(HR, True, "left", "r2", "link2")
    sim.step()
    assert len(sim.kinds(K.TASK_EVENT_KIND_COLLISION)) == 1
    sim.run(lambda x: bool(x.kinds(K.TASK_EVENT_KIND_CONTINUED)), max_s=10)
    reached = sim.kinds(K.TASK_EVENT_KIND_RETREAT_REACHED)
    assert sorted(e.robot for e in reached) == ["r1", "r2"]
    cont = sim.kinds(K.TASK_EVENT_KIND_CONTINUED)[0]
    assert cont.task_time >= max(e.task_time for e in reached)
    delay = cont.continued.delay_s
    assert delay == pytest.approx(cont.task_time - t_col) and delay > 0
    sim.step()
    for rid, goal in goals.items():  # the interrupted targets, or the phase they moved on to
        agent = sim.task.agents[rid]
        assert last_cmd(sim, rid).kind == pb.RobotCommand.KIND_MOVE
        assert target(last_cmd(sim, rid)) == agent.goal.target
        if agent.phase.value != "waiting":
            assert agent.goal == goal or agent.phase.value == "to_place"
    sim.contact(HR, False, "right", "r1", "link3")
    sim.contact(HR, False, "left", "r2", "link2")
    sim.run_to_end()
    rec = sim.task.safety.records
    assert len(rec) == 1 and rec[0].delay_s == pytest.approx(cont.continued.delay_s)
    assert sim.task.safety.total_delay == pytest.approx(cont.continued.delay_s)
    assert sim.kinds(K.TASK_EVENT_KIND_TASK_FINISHED)[0].text.endswith(
        "TASK FINISHED. 1 total collisions."
    )


def test_robots_keep_what_they_hold_during_a_retreat() -> None:
    sim = started("retreat")
    sim.run(lambda x: x.task.agents["r1"].carrying != "", max_s=10)
    n_world = len(sim.world)
    sim.contact(HR, True, "right", "r1")
    sim.step()
    sim.run(lambda x: bool(x.kinds(K.TASK_EVENT_KIND_CONTINUED)), max_s=10)
    new = [w for w in sim.world[n_world:] if w.HasField("release") and w.release.object == "RA2"]
    assert new == [] and sim.task.agents["r1"].carrying


def test_retreat_button_waits_for_the_button() -> None:
    sim = started("retreat_button")
    sim.contact(HR, True, "left", "r2", "tool")
    sim.step()
    assert sim.cues[CONTINUE_BUTTON_CUE].kind == pb.CUE_KIND_CONTINUE_BUTTON
    assert sim.cues[CONTINUE_BUTTON_CUE].flashing
    sim.run(lambda x: len(x.kinds(K.TASK_EVENT_KIND_RETREAT_REACHED)) == 2, max_s=10)
    sim.contact(HR, False, "left", "r2", "tool")
    sim.run(lambda x: x.t >= 15.0)  # a long time at the retreat poses: nobody resumes
    assert sim.kinds(K.TASK_EVENT_KIND_CONTINUED) == []
    for rid in ("r1", "r2"):
        assert target(last_cmd(sim, rid)) == tuple(sim.scenario.robots[rid].retreat)
    assert "continue_button" in sim.cues
    sim.contact(pb.CONTACT_KIND_HAND_BUTTON, True, "right", "continue_button")
    sim.step()
    assert sim.has(K.TASK_EVENT_KIND_BUTTON_PRESSED, hand="right")
    cont = sim.kinds(K.TASK_EVENT_KIND_CONTINUED)
    assert len(cont) == 1 and cont[0].continued.delay_s > 11.9
    assert "continue_button" not in sim.cues
    sim.step()
    assert {target(last_cmd(sim, r)) for r in ("r1", "r2")} != {
        tuple(sim.scenario.robots[r].retreat) for r in ("r1", "r2")
    }
    sim.run_to_end()


def test_button_before_the_robots_arrive_is_kept_until_they_do() -> None:
    sim = started("retreat_button")
    sim.contact(HR, True, "left", "r1")
    sim.step()
    sim.contact(pb.CONTACT_KIND_HAND_BUTTON, True, "right", "continue_button")
    sim.step()
    assert sim.kinds(K.TASK_EVENT_KIND_CONTINUED) == []
    sim.run(lambda x: bool(x.kinds(K.TASK_EVENT_KIND_CONTINUED)), max_s=10)
    cont = sim.kinds(K.TASK_EVENT_KIND_CONTINUED)[0]
    assert cont.task_time >= max(e.task_time for e in sim.kinds(K.TASK_EVENT_KIND_RETREAT_REACHED))


def test_stop_colliding_only_the_touched_robot_holds() -> None:
    sim = started("stop_colliding")
    sim.contact(HR, True, "right", "r1", "link4")
    sim.step()
    t_col = sim.t
    assert last_cmd(sim, "r1").kind == pb.RobotCommand.KIND_HOLD
    assert sim.has(K.TASK_EVENT_KIND_ROBOT_HALTED, robot="r1")
    r2_cmd = last_cmd(sim, "r2")
    assert r2_cmd.kind == pb.RobotCommand.KIND_MOVE
    assert target(r2_cmd) != tuple(sim.scenario.robots["r2"].retreat)
    r1_tcp = sim.robots["r1"].tcp
    r2_tcp = sim.robots["r2"].tcp
    n_r2 = len([c for c in sim.commands if c.robot == "r2"])
    sim.run(lambda x: x.t >= t_col + 4.0)
    assert sim.robots["r1"].tcp == r1_tcp  # held
    assert sim.robots["r2"].tcp != r2_tcp  # carried on
    assert len([c for c in sim.commands if c.robot == "r2"]) > n_r2  # and changed phases
    assert sim.kinds(K.TASK_EVENT_KIND_CONTINUED) == []
    sim.contact(HR, False, "right", "r1", "link4")
    sim.step()
    assert sim.has(K.TASK_EVENT_KIND_COLLISION_END, robot="r1")
    cont = sim.kinds(K.TASK_EVENT_KIND_CONTINUED)
    assert len(cont) == 1 and cont[0].continued.delay_s == pytest.approx(sim.t - t_col)
    assert last_cmd(sim, "r1").kind == pb.RobotCommand.KIND_MOVE
    sim.run_to_end()
    assert sim.task.safety.records[0].delay_s == pytest.approx(cont[0].continued.delay_s)


def test_no_new_grab_during_a_collision_but_the_held_part_can_be_placed() -> None:
    s = load("thesis.toml", conditions={"safety_policy": "stop_colliding"})
    sim = Sim(s, human=None)
    sim.step()
    sim.grab("H1")
    sim.step()
    sim.contact(HR, True, "left", "r2")
    out = sim.step()
    assert not any(
        w.HasField("set_grabbable")
        and not w.set_grabbable.grabbable
        and w.set_grabbable.object == "H1"
        for w in out.world_commands
    )
    sim.release("H1", vec3(s.part("H1").target.xyz))
    out = sim.step()
    assert any(e.kind == K.TASK_EVENT_KIND_PART_PLACED and e.part == "H1" for e in out.events)
    assert sim.grabbable.get("H2") is False and "outline:H2" not in sim.cues
    sim.contact(HR, False, "left", "r2")
    sim.step()
    assert sim.grabbable["H2"] is True and "outline:H2" in sim.cues


def test_missed_release_during_collision_cannot_be_regrabbed_until_it_ends() -> None:
    s = load("thesis.toml", conditions={"safety_policy": "retreat"})
    sim = Sim(s, human=None)
    sim.step()
    sim.grab("H1")
    sim.step()
    sim.contact(HR, True, "left", "r2")
    sim.step()
    sim.release("H1", (0.3, -0.3, 0.02))
    sim.step()
    assert sim.grabbable["H1"] is False
    sim.contact(HR, False, "left", "r2")
    sim.run(lambda x: bool(x.kinds(K.TASK_EVENT_KIND_CONTINUED)), max_s=10)
    sim.step()
    assert sim.grabbable["H1"] is True


def set_tcp(sim: Sim, robot: str, pos: tuple[float, float, float]) -> None:
    for st in sim.states:
        if st.robot == robot:
            st.tcp.position.x, st.tcp.position.y, st.tcp.position.z = pos


def test_near_collision_the_robot_farther_from_its_target_halts() -> None:
    sim = started("retreat")
    goals = {rid: a.goal.target for rid, a in sim.task.agents.items()}
    set_tcp(sim, "r1", (goals["r1"][0] + 0.3, goals["r1"][1], goals["r1"][2]))
    set_tcp(sim, "r2", (goals["r2"][0] + 0.1, goals["r2"][1], goals["r2"][2]))
    sim.contact(RR, True, "r2", "r1")
    sim.step()
    near = sim.kinds(K.TASK_EVENT_KIND_NEAR_COLLISION)
    assert len(near) == 1 and near[0].robot == "r1" and "r1 halts" in near[0].text
    assert last_cmd(sim, "r1").kind == pb.RobotCommand.KIND_HOLD
    assert last_cmd(sim, "r2").kind == pb.RobotCommand.KIND_MOVE
    sim.run(lambda x: x.t >= 6.0)
    assert last_cmd(sim, "r1").kind == pb.RobotCommand.KIND_HOLD
    sim.contact(RR, False, "r2", "r1")
    sim.step()
    assert sim.has(K.TASK_EVENT_KIND_NEAR_COLLISION_END, robot="r1")
    assert last_cmd(sim, "r1").kind == pb.RobotCommand.KIND_MOVE
    sim.run_to_end()
    assert [round(t, 6) for t in sim.task.safety.near_times] == [round(near[0].task_time, 6)]
    assert sim.task.safety.records == []  # near collisions are not human-robot collisions


def test_near_collision_tie_halts_r2() -> None:
    sim = started("retreat")
    for rid, agent in sim.task.agents.items():
        set_tcp(sim, rid, agent.goal.target)  # both exactly at their targets: a tie
    sim.contact(RR, True, "r1", "r2")
    sim.step()
    near = sim.kinds(K.TASK_EVENT_KIND_NEAR_COLLISION)
    assert len(near) == 1 and near[0].robot == "r2"
    assert near[0].near_collision.distance_a_m == near[0].near_collision.distance_b_m == 0.0
    assert last_cmd(sim, "r2").kind == pb.RobotCommand.KIND_HOLD


def test_ssm_a_stopped_arm_hands_its_near_collision_hold_over_when_its_stop_goes_out() -> None:
    """Under ssm an arm in a protective stop cannot move, so a near-collision hold passes to its
    partner (Safety.swap_stuck_yields). That happens on the tick the stop goes out to the arm (the
    tick before the next scan, as every scan's decision), not on the scan that decided it: a
    command sent on a scan's tick lies inside an exchange, and reached the IK service later than
    with one-tick exchanges (dense-4x4 under ssm, 2026-12-02: 36 events moved)."""
    sim = started("ssm")
    sim.contact(RR, True, "r2", "r1")
    sim.step()
    near = sim.kinds(K.TASK_EVENT_KIND_NEAR_COLLISION)
    assert len(near) == 1
    held = near[0].robot
    mover = "r1" if held == "r2" else "r2"
    assert last_cmd(sim, held).kind == pb.RobotCommand.KIND_HOLD
    scan = sim.task.safety.ssm[mover].scan
    stop_at = hold_at = -1
    sim.separation(mover, 0.05)  # a hand 5 cm from the moving arm: stopped at its next scan
    for _ in range(4 * scan):
        k = sim.k
        n_cmds = len(sim.commands)
        sim.step()
        if stop_at < 0 and sim.has(K.TASK_EVENT_KIND_PROTECTIVE_STOP, robot=mover):
            stop_at = k
        new = [c for c in sim.commands[n_cmds:] if c.robot == held]
        if hold_at < 0 and any(c.kind == pb.RobotCommand.KIND_MOVE for c in new):
            hold_at = k
            assert any(
                c.robot == mover
                and c.kind == pb.RobotCommand.KIND_SPEED_SCALE
                and c.speed_scale == 0.0
                for c in sim.commands[n_cmds:]
            ), "the hold passes over with the stop going out"
            break
    assert stop_at >= 0 and stop_at % scan == 0, (stop_at, scan)
    assert hold_at == stop_at + scan - 1, (stop_at, hold_at)  # not at the scan itself
    assert any(
        "is the only arm that can move: it goes on" in e.text
        for e in sim.kinds(K.TASK_EVENT_KIND_ROBOT_HALTED)
    )


def test_contacts_before_the_start_are_not_collisions() -> None:
    sim = Sim(load("thesis.toml"), human=None)
    sim.step()
    sim.contact(HR, True, "right", "r1")
    sim.contact(RR, True, "r1", "r2")
    sim.step()
    assert sim.events == [] and sim.commands == []


@pytest.mark.parametrize("r2_period_s", [0.03, 0.05])
def test_ssm_declares_every_robots_next_scan(r2_period_s: float) -> None:
    """The scans the orchestrator declares (TickAck.next_sample_tick, sample_period_ticks) are
    each robot's: the first coming one, and how far the one after it is, whoever's it is. With
    r1 every 7 ticks and r2 every 12, a declared first scan alone let the exchange that began
    there run past the other robot's next one."""
    s = load("thesis.toml", conditions={"safety_policy": "ssm"})
    s.robots["r2"].ssm = Ssm(scan_period_s=r2_period_s)
    task = Task(s)
    periods = {rid: mon.scan for rid, mon in task.safety.ssm.items()}
    assert periods["r1"] == 7 and periods["r2"] == round(r2_period_s * 240)
    scans = sorted({k for p in periods.values() for k in range(p, 200, p)})
    for last in range(0, 150):
        task.tick = last  # the last tick stepped
        first, gap = task.next_scan_tick()
        coming = [k for k in scans if k > last]
        assert first == coming[0], last
        assert first + gap == coming[1], last  # the exchange from `first` ends before the next
        if r2_period_s == 0.03:
            assert gap == 7  # one period for all: the grid of every scan
