"""The experimenter's console of a live trial (hrc.trial.console): its lines and status line, fed
the messages it gets from the bus (the bus itself is exercised by tests/test_live_trial.py)."""

from __future__ import annotations

import io
from typing import Any

from hrc.bus import Keys
from hrc.trial.console import LiveConsole
from hrc.wire import pb

K = pb.TaskEventKind


class Subscriptions:
    """Stands in for the bus: records what the console subscribes to, so the test can deliver."""

    def __init__(self) -> None:
        self.keys = Keys("t1")
        self.handlers: dict[str, Any] = {}

    def subscribe(self, key: str, _msg_type: type, handler: Any) -> None:
        self.handlers[key] = handler


class Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def event(kind: int, t: float = 0.0, **kw: Any) -> pb.TaskEvent:
    return pb.TaskEvent(kind=kind, task_time=t, **kw)


def test_lines_and_status_of_a_live_trial() -> None:
    bus = Subscriptions()
    out = io.StringIO()
    console = LiveConsole(bus, "L03", 3, out)  # type: ignore[arg-type]
    on_event = bus.handlers[bus.keys.task_events()]
    on_clients = bus.handlers[bus.keys.human_clients()]
    on_clients(
        "",
        pb.ParticipantClients(
            clients=[
                pb.ParticipantClient(peer="127.0.0.1:5000", role=pb.CLIENT_ROLE_SPECTATOR),
                pb.ParticipantClient(peer="127.0.0.1:5001", role=pb.CLIENT_ROLE_DRIVER),
            ],
            changes=["VR client 127.0.0.1:5001 connected as the driver"],
        ),
    )
    wait = event(K.TASK_EVENT_KIND_PARTICIPANT_WAIT, part="H1")
    wait.participant_wait.quiet_s = 12.0
    wait.participant_wait.what = "H1"
    on_event("", wait)
    status = console.status()
    assert status.startswith("L03: driver 127.0.0.1:5001, 1 spectator(s) | waiting for the first")
    assert "placed 0/3" in status and "waiting for the participant: H1, 12 s" in status, status
    on_event("", event(K.TASK_EVENT_KIND_TASK_STARTED, part="H1"))
    assert "waiting for the participant" not in console.status()  # the grab ended the wait
    on_event("", event(K.TASK_EVENT_KIND_PART_PLACED, 3.0, part="H1", agent="human"))
    on_event("", event(K.TASK_EVENT_KIND_COLLISION, 4.0, robot="r1", hand="right"))
    assert "collisions 1 (open)" in console.status()
    on_event("", event(K.TASK_EVENT_KIND_COLLISION_END, 4.5, robot="r1", hand="right"))
    on_event("", event(K.TASK_EVENT_KIND_PART_PLACED, 6.0, part="RA1", agent="r1"))
    console.update()
    text = out.getvalue()
    for line in (
        "VR client 127.0.0.1:5001 connected as the driver",
        "waiting for the participant: H1",
        "task started: H1",
        "H1 placed by the participant (1/3)",
        "collision 1: r1 and the right hand",
        "RA1 placed by r1 (2/3)",
        "status: L03: driver",  # not a terminal: the status line as a line of its own
    ):
        assert line in text, (line, text)
    assert "\r" not in text
    status = console.status()
    assert "running" in status and "placed 2/3" in status and "collisions 1 |" not in status
    on_event("", event(K.TASK_EVENT_KIND_TASK_FINISHED, 9.5))
    console.close("stopped by orchestrator: task finished")
    assert "task finished at 9.5 s, 1 collisions" in out.getvalue()
    assert out.getvalue().rstrip().endswith("run ended: stopped by orchestrator: task finished")


def test_on_a_terminal_the_status_line_is_rewritten_in_place() -> None:
    bus = Subscriptions()
    out = Tty()
    console = LiveConsole(bus, "P01", 1, out)  # type: ignore[arg-type]
    console.update()
    console.update()  # nothing changed: nothing written
    first = out.getvalue()
    assert first.startswith("\r\x1b[KP01: no driver") and first.count("\r") == 1, repr(first)
    bus.handlers[bus.keys.task_events()]("", event(K.TASK_EVENT_KIND_TASK_STARTED, part="H1"))
    console.update()
    rest = out.getvalue()[len(first) :]
    # the event line goes above the status line, which is written again
    assert rest.startswith("\r\x1b[K[task "), repr(rest)
    assert "task started: H1\n\r\x1b[KP01:" in rest, repr(rest)
    console.close("stopped by experimenter: interrupted (Ctrl-C)")
    tail = out.getvalue()[len(first) + len(rest) :]
    assert tail == "\nrun ended: stopped by experimenter: interrupted (Ctrl-C)\n", repr(tail)
