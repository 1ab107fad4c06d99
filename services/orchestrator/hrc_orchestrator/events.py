"""Task events and their thesis-style log lines (one line per event;
docs/task-semantics.md#outputs).

Every line starts with the task time: ``"12.345 sec : ..."``. The wall-clock date of the start is
carried only in ``TaskEvent.wall_time`` (never in ``text``), so the text of every event is a pure
function of the scenario and the inputs. The figures of a kind travel in its typed payload
(``TaskEvent.payload``, named after the kind).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from google.protobuf.message import Message

from hrc.scenario.conventions import WAITING_TEXT
from hrc.wire import pb

if TYPE_CHECKING:
    from hrc_orchestrator.ssm import Change

K = pb.TaskEventKind


def fmt_t(t: float) -> str:
    return f"{t:.3f}"


def line(t: float, body: str) -> str:
    return f"{fmt_t(t)} sec : {body}"


def make(
    kind: pb.TaskEventKind.ValueType,
    t: float,
    body: str,
    *,
    agent: str = "",
    part: str = "",
    robot: str = "",
    hand: str = "",
    payload: Message | None = None,
    wall_time: str = "",
) -> pb.TaskEvent:
    ev = pb.TaskEvent(
        kind=kind,
        task_time=t,
        agent=agent,
        part=part,
        robot=robot,
        hand=hand,
        text=line(t, body),
        wall_time=wall_time,
    )
    if payload is not None:
        # The payload field is named after the kind (ROBOT_FINISHED -> robot_finished).
        name = K.Name(kind).removeprefix("TASK_EVENT_KIND_").lower()
        getattr(ev, name).CopyFrom(payload)
    return ev


def task_started(wall_time: str, first_part: str) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_TASK_STARTED,
        0.0,
        f"TASK STARTED (first grab of {first_part})." if first_part else "TASK STARTED.",
        agent="human",
        part=first_part,
        wall_time=wall_time,
    )


def part_grabbed(t: float, agent: str, part: str, hand: str = "") -> pb.TaskEvent:
    who = f"human ({hand} hand)" if agent == "human" else agent
    return make(
        K.TASK_EVENT_KIND_PART_GRABBED,
        t,
        f"{who} grabbed {part}.",
        agent=agent,
        part=part,
        robot="" if agent == "human" else agent,
        hand=hand,
    )


def part_released(
    t: float, part: str, hand: str, distance_m: float, angle_deg: float, why: str
) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_PART_RELEASED,
        t,
        f"human released {part} off target ({why}): {distance_m * 100:.1f} cm, "
        f"{angle_deg:.1f} deg.",
        agent="human",
        part=part,
        hand=hand,
        payload=pb.PartReleased(distance_m=distance_m, angle_deg=angle_deg),
    )


def part_placed(t: float, agent: str, part: str, hand: str = "") -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_PART_PLACED,
        t,
        f"{agent} placed {part}.",
        agent=agent,
        part=part,
        robot="" if agent == "human" else agent,
        hand=hand,
    )


def robot_phase(t: float, robot: str, phase: str, part: str) -> pb.TaskEvent:
    suffix = f" ({part})" if part else ""
    return make(
        K.TASK_EVENT_KIND_ROBOT_PHASE,
        t,
        f"{robot} - phase {phase}{suffix}.",
        agent=robot,
        robot=robot,
        part=part,
    )


def robot_waiting(t: float, robot: str, part: str, waits_for: list[str]) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_ROBOT_WAITING,
        t,
        f"{robot} - {WAITING_TEXT} {part} needs {', '.join(waits_for)} first.",
        agent=robot,
        robot=robot,
        part=part,
    )


def robot_wait_over(t: float, robot: str, part: str, waited_s: float) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_ROBOT_WAIT_OVER,
        t,
        f"{robot} - wait over for {part} after {fmt_t(waited_s)} sec.",
        agent=robot,
        robot=robot,
        part=part,
        payload=pb.RobotWaitOver(waited_s=waited_s),
    )


def robot_finished(
    t: float, robot: str, max_speed: float, avg_speed: float, idle_s: float
) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_ROBOT_FINISHED,
        t,
        f"{robot} - task FINISHED. Max speed reached: {max_speed:.3f} m/s, average "
        f"speed: {avg_speed:.3f} m/s. Waited human for {fmt_t(idle_s)} sec.",
        agent=robot,
        robot=robot,
        payload=pb.RobotFinished(
            max_tcp_speed_mps=max_speed, avg_tcp_speed_mps=avg_speed, idle_s=idle_s
        ),
    )


def robot_unreachable(t: float, robot: str, detail: str) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_ROBOT_UNREACHABLE,
        t,
        f"{robot} - target unreachable: {detail or 'no detail'}.",
        agent=robot,
        robot=robot,
    )


def human_finished(t: float, idle_s: float) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_HUMAN_FINISHED,
        t,
        f"Human - task FINISHED. Idle (hands outside the workspace) {fmt_t(idle_s)} sec.",
        agent="human",
        payload=pb.HumanFinished(idle_s=idle_s),
    )


def human_idle(t: float, begin: bool) -> pb.TaskEvent:
    if begin:
        return make(
            K.TASK_EVENT_KIND_HUMAN_IDLE_BEGIN,
            t,
            "human idle: both hands outside the workspace.",
            agent="human",
        )
    return make(K.TASK_EVENT_KIND_HUMAN_IDLE_END, t, "human back in the workspace.", agent="human")


def stalled(t: float, message: str) -> pb.TaskEvent:
    """`message` is the watchdog's: "stalled for 60 s: r2 waits ..."."""
    return make(K.TASK_EVENT_KIND_STALLED, t, f"TASK STALLED{message.removeprefix('stalled')}.")


def participant_wait(t: float, what: str, quiet_s: float) -> pb.TaskEvent:
    """A live trial waits on the person (not a stall): what they are expected to do next."""
    part = what if what != "the continue button" else ""
    return make(
        K.TASK_EVENT_KIND_PARTICIPANT_WAIT,
        t,
        f"waiting for the participant: {what} (nothing else moved for {quiet_s:.0f} s)",
        agent="human",
        part=part,
        payload=pb.ParticipantWait(quiet_s=quiet_s, what=what),
    )


def task_finished(t: float, collisions: int, near: int) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_TASK_FINISHED,
        t,
        f"TASK FINISHED. {collisions} total collisions.",
        payload=pb.TaskFinished(human_robot_collisions=collisions, near_collisions=near),
    )


def collision(t: float, n: int, robot: str, hand: str, link: str) -> pb.TaskEvent:
    where = f" ({link})" if link else ""
    return make(
        K.TASK_EVENT_KIND_COLLISION,
        t,
        f"Collision {n} occurred between {robot}{where} and {hand} hand.",
        agent="human",
        robot=robot,
        hand=hand,
        payload=pb.CollisionNumber(number=n),
    )


def collision_end(t: float, n: int, robot: str, hand: str) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_COLLISION_END,
        t,
        f"Collision {n}: the hand left {robot}.",
        agent="human",
        robot=robot,
        hand=hand,
        payload=pb.CollisionNumber(number=n),
    )


def retreat_reached(t: float, robot: str, n: int) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_RETREAT_REACHED,
        t,
        f"{robot} reached its retreat pose (collision {n}).",
        agent=robot,
        robot=robot,
        payload=pb.CollisionNumber(number=n),
    )


def robot_halted(t: float, robot: str, why: str) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_ROBOT_HALTED, t, f"{robot} halted: {why}.", agent=robot, robot=robot
    )


def button_pressed(t: float, hand: str) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_BUTTON_PRESSED,
        t,
        f"Continue button pressed ({hand} hand).",
        agent="human",
        hand=hand,
    )


def continued(t: float, n: int, delay_s: float, robot: str = "") -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_CONTINUED,
        t,
        f"Continuing after robot-hand collision {n}. Delayed {fmt_t(delay_s)} sec.",
        robot=robot,
        payload=pb.Continued(number=n, delay_s=delay_s),
    )


def near_collision(
    t: float, n: int, a: str, b: str, halted: str, d_a: float, d_b: float
) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_NEAR_COLLISION,
        t,
        f"Near-collision {n} between the robots ({a}, {b}); {halted} halts.",
        robot=halted,
        payload=pb.NearCollision(
            number=n, robot_a=a, distance_a_m=d_a, robot_b=b, distance_b_m=d_b
        ),
    )


def near_collision_end(t: float, n: int, halted: str) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_NEAR_COLLISION_END,
        t,
        f"Near-collision {n} over; {halted} continues.",
        robot=halted,
        payload=pb.CollisionNumber(number=n),
    )


def protective_stop(t: float, robot: str, change: Change) -> pb.TaskEvent:
    who = f", {change.body}" if change.body in ("left", "right") else ""
    closest = f"{change.body} hand" if who else change.body or "participant"
    return make(
        K.TASK_EVENT_KIND_PROTECTIVE_STOP,
        t,
        f"{robot} PROTECTIVE STOP {change.number}: separation {change.separation_m:.3f} m "
        f"({closest}), protective distance {change.protective_distance_m:.3f} m.",
        agent=robot,
        robot=robot,
        hand=change.body if who else "",
        payload=pb.ProtectiveStop(
            number=change.number,
            separation_m=round(change.separation_m, 6),
            protective_distance_m=round(change.protective_distance_m, 6),
            body=change.body,
        ),
    )


def protective_resume(t: float, robot: str, change: Change) -> pb.TaskEvent:
    return make(
        K.TASK_EVENT_KIND_PROTECTIVE_RESUME,
        t,
        f"{robot} resumes after protective stop {change.number} "
        f"(stopped {fmt_t(change.stopped_s)} sec, separation {change.separation_m:.3f} m).",
        agent=robot,
        robot=robot,
        payload=pb.ProtectiveResume(
            number=change.number,
            separation_m=round(change.separation_m, 6),
            stopped_s=round(change.stopped_s, 6),
        ),
    )
