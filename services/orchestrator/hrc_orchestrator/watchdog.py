"""The stall watchdog (docs/task-semantics.md, "The watchdog"): a trial in which nothing
progresses for ``stall_timeout_s`` of simulated time ends, with one message saying who waits on
what.

Progress is a task event of the work itself: a grab, release or placement, a robot's phase, wait
or finish, the task's start and end. A collision and what answers it (halts, retreats, the
continue button, the robots going on, protective stops) is not: those repeat without end when a
hand keeps meeting a robot that retreats and comes back (a livelock, 300 collisions in 1,000
simulated seconds before this rule), and they are counted for the message. Cues follow the
task's state (they change with the events above, or toggle with the collisions) and do not
count either. The message is a pure function of the task's state, so it is the same in every run
of a scenario and seed.

A live participant is a person, not a process: in a live trial, time the task spends waiting on
the person (every robot done, not started, waiting for a part that waits on the person, halted or
stopped by the person's hand, or waiting for the continue button) never ends the trial. The
watchdog announces the wait once (`PARTICIPANT_WAIT`, after ``PARTICIPANT_WAIT_NOTICE_S``) and
only the experimenter ends such a trial; a robot that is stuck still ends it.
"""

from __future__ import annotations

from typing import Protocol

from hrc.wire import pb

from hrc_orchestrator.board import Board
from hrc_orchestrator.exchange import Outputs
from hrc_orchestrator.human import HumanAgent
from hrc_orchestrator.robots import Phase, RobotAgent
from hrc_orchestrator.safety import Safety


class Task(Protocol):
    """What the watchdog reads of the task (hrc_orchestrator.task.Task), and never changes."""

    board: Board
    human: HumanAgent
    agents: dict[str, RobotAgent]
    safety: Safety
    started: bool
    watchdog: Watchdog


K = pb.TaskEventKind
# A collision and its recovery: no progress of the work, however often they repeat.
RECOVERY = frozenset(
    {
        K.TASK_EVENT_KIND_COLLISION,
        K.TASK_EVENT_KIND_COLLISION_END,
        K.TASK_EVENT_KIND_CONTINUED,
        K.TASK_EVENT_KIND_NEAR_COLLISION,
        K.TASK_EVENT_KIND_NEAR_COLLISION_END,
        K.TASK_EVENT_KIND_ROBOT_HALTED,
        K.TASK_EVENT_KIND_RETREAT_REACHED,
        K.TASK_EVENT_KIND_BUTTON_PRESSED,
        K.TASK_EVENT_KIND_PROTECTIVE_STOP,
        K.TASK_EVENT_KIND_PROTECTIVE_RESUME,
    }
)
# Events that do not show the task moving on: hands wandering in and out of the workspace, a
# robot saying it cannot make its move, a wait on a live participant, and the above.
NOT_PROGRESS = RECOVERY | {
    K.TASK_EVENT_KIND_HUMAN_IDLE_BEGIN,
    K.TASK_EVENT_KIND_HUMAN_IDLE_END,
    K.TASK_EVENT_KIND_ROBOT_UNREACHABLE,
    K.TASK_EVENT_KIND_PARTICIPANT_WAIT,
}
# what the stall message counts since the last progress
COUNTED = {
    K.TASK_EVENT_KIND_COLLISION: "human-robot collision",
    K.TASK_EVENT_KIND_NEAR_COLLISION: "near collision",
    K.TASK_EVENT_KIND_PROTECTIVE_STOP: "protective stop",
}
# A live trial announces a wait on the participant after this much quiet (simulated = wall s).
PARTICIPANT_WAIT_NOTICE_S = 10.0


def progressed(out: Outputs) -> bool:
    return any(e.kind not in NOT_PROGRESS for e in out.events)


class Watchdog:
    def __init__(self, timeout_s: float, live: bool = False) -> None:
        self.timeout_s = timeout_s  # <= 0: no watchdog
        self.live = live  # a person takes part: waits on them are not stalls
        self.last_progress = 0.0  # simulated time
        self.message = ""  # set once it fired
        self.announced = ""  # live: the part the announced wait on the participant is for
        self.recoveries: dict[int, int] = {}  # COUNTED event kind -> count since the progress

    def check(self, sim_time: float, out: Outputs) -> bool:
        """True on the ticks the trial has gone `timeout_s` without progress: once, as the
        trial then ends, unless it waits on a live participant (Task._participant_wait)."""
        if self.message:
            return False
        if progressed(out):
            self.last_progress = sim_time
            self.announced = ""
            self.recoveries.clear()
            return False
        for e in out.events:
            if e.kind in COUNTED:
                self.recoveries[e.kind] = self.recoveries.get(e.kind, 0) + 1
        return self.timeout_s > 0 and sim_time - self.last_progress >= self.timeout_s - 1e-9

    def quiet_s(self, sim_time: float) -> float:
        return sim_time - self.last_progress


def _xyz(v: tuple[float, float, float]) -> str:
    return f"({v[0]:.3f}, {v[1]:.3f}, {v[2]:.3f})"


def _move(agent: RobotAgent) -> str:
    """The move the robot was last sent: its id, what it is for and where it goes."""
    sent = agent.sent
    what = agent.phase.value + (
        f" {agent.carrying or agent.part}" if agent.phase != Phase.TO_HOME else ""
    )
    if sent is None or not sent.is_move:
        return f"command #{agent.sent_id} ({what})"
    return f"move #{agent.sent_id} ({what}) to {_xyz(sent.target)}"


def _robot(task: Task, rid: str, agent: RobotAgent) -> str:
    safety = task.safety
    st = agent.state
    if (
        st is not None
        and st.status == pb.MOTION_STATUS_UNREACHABLE
        and st.command_id == agent.sent_id
    ):
        return f"{rid} cannot make its {_move(agent)}: {st.detail or 'unreachable'}"
    if agent.phase == Phase.FINISHED:
        return f"{rid} is home"
    if agent.phase == Phase.NOT_STARTED:
        return f"{rid} has not started"
    if rid in safety.halted:
        rec = safety.halted[rid]
        return f"{rid} is halted: the {rec.hand} hand touches it since {rec.t_s:.1f} s"
    mon = safety.ssm.get(rid)
    if mon is not None and safety.protective_stop(rid):
        return (
            f"{rid} is in protective stop {mon.stops} since {mon.stop_since:.1f} s "
            f"(separation {mon.separation:.3f} m to the {mon.body or 'participant'})"
        )
    for (a, b), held in safety.near_yield.items():
        if held == rid:
            other = b if a == rid else a
            return f"{rid} holds for a near collision with {other}"
    if safety.retreating is not None and rid in safety.retreating.retreat:
        if not safety.retreating.arrived.get(rid, False):
            return f"{rid} moves to its retreat pose ({_move(agent)}, not reached)"
        if safety.button_wanted:
            return f"{rid} waits at its retreat pose for the continue button"
        return f"{rid} waits at its retreat pose for the other robots"
    if agent.phase == Phase.WAITING:
        missing = task.board.missing_deps(agent.carrying)
        return (
            f"{rid} waits at its intermediate pose for {agent.carrying}, which needs "
            f"{', '.join(missing)}"
        )
    if agent.phase == Phase.SCREWING:
        return f"{rid} screws {agent.part}"
    status = (
        pb.MotionStatus.Name(st.status).removeprefix("MOTION_STATUS_").lower()
        if st is not None
        else "no state"
    )
    return f"{rid} has not finished its {_move(agent)} (status {status})"


def _human(task: Task) -> str:
    h = task.human
    if h.done:
        return "the human is done"
    if h.held_part:
        missing = task.board.missing_deps(h.held_part)
        needs = f", which needs {', '.join(missing)}" if missing else ""
        return f"the human holds {h.held_part} since {h.held_since:.1f} s{needs}"
    nxt = h.next_part
    if not task.started:
        return f"the human has not grabbed {nxt}, the first part"
    if h.grabbable(nxt, task.safety.blocks_grab):
        return f"the human has not grabbed {nxt}"
    return f"the human may not grab {nxt} (a collision is open)"


def waits_on_participant(task: Task) -> str:
    """What the participant is expected to do next, when nothing but the participant can move
    the task on (every robot done, not started, waiting for a part, or held by the person's
    hand, zone or button); "" when a robot is stuck on its own."""
    h = task.human
    safety = task.safety
    retreating = safety.retreating
    for rid, agent in task.agents.items():
        st = agent.state
        if (
            st is not None
            and st.status == pb.MOTION_STATUS_UNREACHABLE
            and st.command_id == agent.sent_id
        ):
            return ""
        if agent.phase in (Phase.FINISHED, Phase.NOT_STARTED, Phase.WAITING):
            continue
        if rid in safety.halted or (rid in safety.ssm and safety.protective_stop(rid)):
            continue  # the person's hand holds it
        if (
            retreating is not None
            and rid in retreating.retreat
            and safety.button_wanted
            and retreating.arrived.get(rid, False)
        ):
            continue  # at its retreat pose, for the person's button
        return ""
    if safety.button_wanted:
        return "the continue button"
    if h.done:
        return ""
    return h.held_part or h.next_part


def unreachable(task: Task) -> str:
    """A robot that reports its current move impossible: the trial cannot go on (no holding
    without a way out, docs/task-semantics.md "Interruptions"); "" if none does."""
    for rid, agent in task.agents.items():
        st = agent.state
        if (
            st is not None
            and st.status == pb.MOTION_STATUS_UNREACHABLE
            and st.command_id == agent.sent_id
            and agent.sent_id > 0
        ):
            return (
                f"{rid} cannot make its {_move(agent)}: {st.detail or 'unreachable'}; "
                "no way for it to go on, the trial ends at once"
            )
    return ""


def describe(task: Task, stalled_s: float) -> str:
    """'stalled for 60 s: r2 waits ...; the human holds H3 since 42.6 s; r1 is home'."""
    robots = [_robot(task, rid, a) for rid, a in task.agents.items()]
    # the robots that wait or are stuck come first, then the human (often what they wait for)
    stuck = [r for r in robots if " waits " in r or " cannot " in r]
    rest = [r for r in robots if r not in stuck]
    counts = task.watchdog.recoveries
    meanwhile = ", ".join(
        f"{counts[k]} {name}{'s' if counts[k] > 1 else ''}"
        for k, name in COUNTED.items()
        if counts.get(k)
    )
    # a livelock: the work stands still while the same collision comes back again and again
    how = f" ({meanwhile} meanwhile)" if meanwhile else ""
    return f"stalled for {stalled_s:g} s{how}: " + "; ".join([*stuck, _human(task), *rest])
