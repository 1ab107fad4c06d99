"""log.txt lines: one formatter per thesis kind, the orchestrator's text preferred."""

from __future__ import annotations

import pytest

from hrc.wire import pb

from hrc_logger.textlog import LOG_KINDS, ThesisLog, kind_name, run_end_line, wall_clock

K = pb.TaskEventKind


def ev(kind: int, t: float = 12.345, **kw: object) -> pb.TaskEvent:
    return pb.TaskEvent(kind=kind, task_time=t, **kw)  # type: ignore[arg-type]


def test_task_started_uses_the_wall_time_of_the_event() -> None:
    line = ThesisLog().line_for(
        ev(K.TASK_EVENT_KIND_TASK_STARTED, wall_time="2024-05-02T14:03:11+02:00")
    )
    assert line == "2024-05-02 14:03:11 - TASK STARTED."
    assert wall_clock("") == "(no wall time)"
    assert wall_clock("not a date") == "not a date"


def test_collisions_and_near_collisions_are_numbered_in_order() -> None:
    log = ThesisLog()
    assert (
        log.line_for(ev(K.TASK_EVENT_KIND_COLLISION, robot="r1", hand="left"))
        == "12.35 sec : Collision 1 occurred between r1 and left hand."
    )
    assert (
        log.line_for(
            ev(K.TASK_EVENT_KIND_CONTINUED, t=15.0, continued=pb.Continued(number=1, delay_s=2.5))
        )
        == "15.00 sec : Continuing after robot-hand collision 1. Delayed 2.50 sec."
    )
    assert (
        log.line_for(ev(K.TASK_EVENT_KIND_NEAR_COLLISION, t=16.0))
        == "16.00 sec : Near-collision 1 between the robots."
    )
    assert (
        log.line_for(ev(K.TASK_EVENT_KIND_COLLISION, t=20.0, robot="r2", hand="right"))
        == "20.00 sec : Collision 2 occurred between r2 and right hand."
    )
    assert (
        log.line_for(ev(K.TASK_EVENT_KIND_NEAR_COLLISION, t=21.0))
        == "21.00 sec : Near-collision 2 between the robots."
    )
    # the event's own number wins over the count
    assert log.line_for(
        ev(
            K.TASK_EVENT_KIND_COLLISION,
            t=22.0,
            robot="r1",
            hand="left",
            collision=pb.CollisionNumber(number=7),
        )
    ).startswith("22.00 sec : Collision 7 ")
    assert log.line_for(
        ev(K.TASK_EVENT_KIND_NEAR_COLLISION, t=23.0, near_collision=pb.NearCollision(number=9))
    ).startswith("23.00 sec : Near-collision 9 ")
    assert (
        log.line_for(ev(K.TASK_EVENT_KIND_CONTINUED, t=24.0))
        == "24.00 sec : Continuing after robot-hand collision 3. Delayed ? sec."
    )


def test_robot_and_human_finish_carry_speeds_and_waiting_time() -> None:
    log = ThesisLog()
    line = log.line_for(
        ev(
            K.TASK_EVENT_KIND_ROBOT_FINISHED,
            t=61.0,
            robot="r1",
            robot_finished=pb.RobotFinished(
                max_tcp_speed_mps=0.5, avg_tcp_speed_mps=0.2314, idle_s=4.2
            ),
        )
    )
    assert line == (
        "61.00 sec : r1 - task FINISHED. Max speed reached : 0.500 m/s, "
        "average speed : 0.231 m/s. Waited human for 4.20 sec."
    )
    assert (
        log.line_for(
            ev(
                K.TASK_EVENT_KIND_HUMAN_FINISHED,
                t=70.25,
                human_finished=pb.HumanFinished(idle_s=2.1),
            )
        )
        == "70.25 sec : Human - task FINISHED. Idle (hands outside the workspace) for 2.10 sec."
    )
    assert (
        log.line_for(ev(K.TASK_EVENT_KIND_HUMAN_FINISHED, t=70.25))
        == "70.25 sec : Human - task FINISHED."
    )


def test_task_finished_counts_collisions_when_the_event_does_not() -> None:
    log = ThesisLog()
    log.line_for(ev(K.TASK_EVENT_KIND_COLLISION, robot="r1", hand="left"))
    assert (
        log.line_for(ev(K.TASK_EVENT_KIND_TASK_FINISHED, t=75.4))
        == "75.40 sec : TASK FINISHED. 1 total collisions."
    )
    assert (
        log.line_for(
            ev(
                K.TASK_EVENT_KIND_TASK_FINISHED,
                t=75.4,
                task_finished=pb.TaskFinished(human_robot_collisions=3),
            )
        )
        == "75.40 sec : TASK FINISHED. 3 total collisions."
    )


def test_the_orchestrators_text_is_used_as_one_line() -> None:
    log = ThesisLog()
    line = log.line_for(
        ev(
            K.TASK_EVENT_KIND_ROBOT_FINISHED,
            robot="r1",
            text="5 sec : Robot1 - task FINISHED.\nRobot1 - waited human for 2 sec.\n",
        )
    )
    assert line == "5 sec : Robot1 - task FINISHED. Robot1 - waited human for 2 sec."


@pytest.mark.parametrize(
    "kind",
    [
        K.TASK_EVENT_KIND_PART_PLACED,
        K.TASK_EVENT_KIND_ROBOT_PHASE,
        K.TASK_EVENT_KIND_COLLISION_END,
        K.TASK_EVENT_KIND_HUMAN_IDLE_BEGIN,
    ],
)
def test_kinds_outside_the_thesis_log_give_no_line(kind: int) -> None:
    assert ThesisLog().line_for(ev(kind, text="something")) is None
    assert kind not in LOG_KINDS


def test_every_thesis_kind_has_a_fallback_line() -> None:
    for kind in LOG_KINDS:
        line = ThesisLog().line_for(ev(kind))
        assert line and "\n" not in line, kind_name(kind)


def test_kind_names() -> None:
    assert kind_name(K.TASK_EVENT_KIND_NEAR_COLLISION) == "NEAR_COLLISION"
    assert kind_name(999) == "KIND_999"


def test_closing_line_only_when_the_task_did_not_finish() -> None:
    ok = pb.RunEnd(ok=True, reason="stopped by orchestrator: task finished")
    assert run_end_line(ok, "", True, 10.0) is None
    assert (
        run_end_line(pb.RunEnd(ok=True, reason="ticks"), "", False, 3.0)
        == "3.00 sec : RUN ENDED before the task finished (ticks)."
    )
    bad = pb.RunEnd(
        ok=False, reason="participant 'ik_cpp' missed the barrier", failed_participant="ik_cpp"
    )
    assert (
        run_end_line(bad, "", False, 4.0)
        == "4.00 sec : RUN ENDED WITH AN ERROR (service 'ik_cpp'): "
        "participant 'ik_cpp' missed the barrier"
    )
    assert (
        run_end_line(None, "terminated by SIGTERM", False, 1.0)
        == "1.00 sec : RUN ENDED WITH AN ERROR: terminated by SIGTERM"
    )


def test_start_line_keeps_the_date_even_when_the_orchestrator_sends_text() -> None:
    line = ThesisLog().line_for(
        ev(
            K.TASK_EVENT_KIND_TASK_STARTED,
            t=0.0,
            wall_time="2024-05-02T14:03:11Z",
            text="0.000 sec : TASK STARTED (first grab of H1).",
        )
    )
    assert line == "2024-05-02 14:03:11 - TASK STARTED."
    assert (
        ThesisLog().line_for(ev(K.TASK_EVENT_KIND_TASK_STARTED, text="x TASK STARTED."))
        == "x TASK STARTED."
    )
