"""No hangs in the task logic: near collisions never deadlock, and the watchdog ends a trial in
which nothing progresses, saying who waits on what."""

from __future__ import annotations

from orch_fakes import K, Sim, load

from hrc.wire import pb

from hrc_orchestrator.robots import Phase
from hrc_orchestrator.task import Task

RR = pb.CONTACT_KIND_ROBOT_ROBOT


def last_cmd(sim: Sim, robot: str) -> pb.RobotCommand:
    return [c for c in sim.commands if c.robot == robot][-1]


def r2_waiting() -> Sim:
    """The human grabbed H1 and stays still holding it: r2 waits with S1 (needs H1)."""
    sim = Sim(load("thesis.toml"))
    sim.run(lambda x: x.task.started, max_s=20)
    assert sim.human is not None
    sim.human.enabled = False
    sim.run(lambda x: x.task.agents["r2"].phase == Phase.WAITING, max_s=30)
    assert sim.task.agents["r1"].phase not in (Phase.WAITING, Phase.FINISHED)
    return sim


def test_near_collision_with_a_waiting_arm_halts_the_waiting_one() -> None:
    sim = r2_waiting()
    sim.contact(RR, True, "r1", "r2")
    sim.step()
    near = sim.kinds(K.TASK_EVENT_KIND_NEAR_COLLISION)
    # r2 sits at its goal (distance 0): the old rule would halt r1, the only arm that can move.
    assert len(near) == 1 and near[0].robot == "r2"
    assert last_cmd(sim, "r1").kind == pb.RobotCommand.KIND_MOVE
    halted = sim.kinds(K.TASK_EVENT_KIND_ROBOT_HALTED)[-1]
    assert halted.robot == "r2" and "only arm that can move" in halted.text
    placed = len(sim.kinds(K.TASK_EVENT_KIND_PART_PLACED))
    sim.run(lambda x: len(x.kinds(K.TASK_EVENT_KIND_PART_PLACED)) > placed, max_s=30)
    assert sim.kinds(K.TASK_EVENT_KIND_PART_PLACED)[-1].robot == "r1"


def test_a_held_arm_goes_on_once_the_other_one_stops_to_wait() -> None:
    sim = Sim(load("thesis.toml"))
    sim.run(lambda x: x.task.started, max_s=20)
    assert sim.human is not None
    sim.human.enabled = False
    # both moving: r1 is farther from its target (picking table) and yields
    sim.run(
        lambda x: (
            all(a.phase not in (Phase.NOT_STARTED, Phase.WAITING) for a in x.task.agents.values())
            and x.t > 0.1
        ),
        max_s=5,
    )
    sim.contact(RR, True, "r1", "r2")
    sim.step()
    first = sim.kinds(K.TASK_EVENT_KIND_NEAR_COLLISION)[0].robot
    assert sim.task.safety.override(first) is not None
    other = "r2" if first == "r1" else "r1"
    # The volumes keep touching; the moving arm reaches a dependency wait (r2 with S1) or goes
    # on; either way the held arm is not held forever.
    sim.run(lambda x: x.task.safety.override(first) is None, max_s=60)
    assert sim.task.agents[other].phase == Phase.WAITING or other == "r1"
    assert last_cmd(sim, first).kind == pb.RobotCommand.KIND_MOVE


def test_watchdog_names_the_waiting_robot_and_what_the_human_holds() -> None:
    sim = r2_waiting()
    # r1 finishes what it can; then nothing moves: r1 waits (RA4 needs H3) or is done.
    stopped_at = None
    out = None
    for _ in range(int(200 / sim.dt)):
        out = sim.step()
        if out.stalled:
            stopped_at = sim.k * sim.dt
            break
    assert out is not None and stopped_at is not None, "the watchdog never fired"
    msg = out.stalled
    assert msg.startswith("stalled for 60 s: ")
    assert "r2 waits at its intermediate pose for S1, which needs H1" in msg
    assert "the human holds H1 since " in msg
    assert "r1 " in msg
    stalled = sim.kinds(K.TASK_EVENT_KIND_STALLED)
    assert len(stalled) == 1 and msg.removeprefix("stalled") in stalled[0].text
    assert sim.task.watchdog.message == msg and not sim.task.finished
    # nothing more after the stall
    assert sim.step().events == [] and not sim.stop


def test_an_unreachable_move_ends_the_trial_at_once_naming_it() -> None:
    # No holding without a way out: the run ends on the tick the arm says so, not a timeout later.
    sim = Sim(load("thesis.toml", scenario={"stall_timeout_s": 5.0}))
    sim.run(lambda x: x.task.started, max_s=20)
    r1 = sim.task.agents["r1"]
    robot = sim.robots["r1"]

    def unreachable(s: Sim) -> None:  # the arm says it cannot make its move
        robot.frozen = True
        robot.status = pb.MOTION_STATUS_UNREACHABLE

    sim.hooks.append(unreachable)
    out = None
    t0 = sim.task.now()
    for _ in range(int(30 / sim.dt)):
        out = sim.step()
        if out.stalled:
            break
    assert out is not None and out.stalled, "the trial never ended"
    assert out.stalled.startswith(f"r1 cannot make its move #{r1.sent_id} (to_pick RA1) to (")
    assert out.stalled.endswith("no way for it to go on, the trial ends at once")
    assert sim.task.now() - t0 < 0.5  # at once, not after the watchdog's 5 s
    stalled = sim.kinds(K.TASK_EVENT_KIND_STALLED)
    assert len(stalled) == 1 and out.stalled in stalled[0].text


def test_a_hand_that_keeps_meeting_a_robot_is_a_stall_not_progress() -> None:
    """A livelock seen in a simulated study: the hand rests where r1 comes back to after each
    retreat, so collision, retreat, continue repeat without end (300 times in 1,000 simulated
    s) while no part moves on. The collisions are not progress: the trial ends as stalled,
    the message counting them."""
    sim = Sim(load("thesis.toml", scenario={"stall_timeout_s": 10.0}))
    sim.run(lambda x: x.task.started, max_s=20)
    assert sim.human is not None
    sim.human.enabled = False  # holds H1 and stays still
    sim.run(lambda x: x.task.agents["r1"].carrying != "", max_s=30)
    touching = {"on": False, "since": 0.0}

    def bump(s: Sim) -> None:
        # the hand meets r1 once it has gone on after the last collision, for 0.2 s each time
        going_on = s.task.safety.retreating is None and s.task.safety.can_move("r1")
        if not touching["on"] and going_on and s.t - touching["since"] > 0.5:
            s.contact(pb.CONTACT_KIND_HAND_ROBOT, True, "right", "r1", "link5_flange")
            touching.update(on=True, since=s.t)
        elif touching["on"] and s.t - touching["since"] > 0.2:
            s.contact(pb.CONTACT_KIND_HAND_ROBOT, False, "right", "r1", "link5_flange")
            touching.update(on=False, since=s.t)

    sim.hooks.append(bump)
    out = None
    for _ in range(int(120 / sim.dt)):
        out = sim.step()
        if out.stalled:
            break
    collisions = sim.kinds(K.TASK_EVENT_KIND_COLLISION)
    assert out is not None and out.stalled, f"no stall after {len(collisions)} collisions"
    assert len(collisions) >= 3  # the collisions went on: they alone did not keep it alive
    assert out.stalled.startswith("stalled for 10 s (")
    counted = int(out.stalled.split("(", 1)[1].split(" human-robot collision")[0])
    assert 3 <= counted <= len(collisions), out.stalled
    assert "the human holds H1 since " in out.stalled


def test_watchdog_off_and_progress_resets_it() -> None:
    task = Task(load("thesis.toml"), stall_timeout_s=0)
    assert task.watchdog.timeout_s == 0
    sim = Sim(load("thesis.toml", scenario={"stall_timeout_s": 2.0}))
    sim.run_to_end()  # a normal trial never goes 2 s without an event or a cue change
    assert not sim.kinds(K.TASK_EVENT_KIND_STALLED) and sim.stop == "task finished"


# ---------------------------------------------------------------- a live participant


def live_thesis(**scenario: object) -> Sim:
    return Sim(load("thesis.toml", participant={"input": "vr"}, scenario=scenario))


def test_a_live_participant_who_never_grabs_is_waited_for_not_stalled() -> None:
    sim = live_thesis(stall_timeout_s=5.0)
    sim.human = None  # nobody grabs anything
    for _ in range(int(30 / sim.dt)):
        assert not sim.step().stalled
    waits = sim.kinds(K.TASK_EVENT_KIND_PARTICIPANT_WAIT)
    # announced once, after 5 s (the notice comes at the watchdog's timeout when it is shorter)
    assert len(waits) == 1, [e.text for e in waits]
    assert waits[0].part == "H1" and waits[0].participant_wait.what == "H1"
    assert "waiting for the participant: H1" in waits[0].text
    assert waits[0].participant_wait.quiet_s >= 5.0 - 1e-6
    assert not sim.task.watchdog.message and not sim.kinds(K.TASK_EVENT_KIND_STALLED)


def test_a_live_pause_mid_task_is_announced_again_after_progress() -> None:
    sim = live_thesis()
    sim.run(lambda x: x.task.started, max_s=20)
    assert sim.human is not None
    sim.human.enabled = False  # holds H1 and stays still: the robots end up waiting on it
    for _ in range(int(150 / sim.dt)):
        assert not sim.step().stalled
    waits = sim.kinds(K.TASK_EVENT_KIND_PARTICIPANT_WAIT)
    assert len(waits) == 1 and waits[0].participant_wait.what == "H1", [e.text for e in waits]
    assert not sim.kinds(K.TASK_EVENT_KIND_STALLED)


def test_a_robot_stuck_on_its_own_still_ends_a_live_trial() -> None:
    sim = live_thesis(stall_timeout_s=5.0)
    sim.run(lambda x: x.task.started, max_s=20)
    robot = sim.robots["r1"]

    def unreachable(s: Sim) -> None:
        robot.frozen = True
        robot.status = pb.MOTION_STATUS_UNREACHABLE

    sim.hooks.append(unreachable)
    out = None
    for _ in range(int(30 / sim.dt)):
        out = sim.step()
        if out.stalled:
            break
    assert out is not None and out.stalled.startswith("r1 cannot make its move"), "no end"
