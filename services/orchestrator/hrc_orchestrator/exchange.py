"""One tick's exchange of the task: the messages it received (Inputs) and what it sends back
(Outputs)."""

from __future__ import annotations

from dataclasses import dataclass, field

from hrc.wire import pb


@dataclass
class Inputs:
    """The messages received for one tick, in delivery order."""

    robot_states: list[pb.RobotState] = field(default_factory=list)
    objects: list[pb.WorldObjects] = field(default_factory=list)
    contacts: list[pb.WorldContacts] = field(default_factory=list)
    separations: list[pb.Separations] = field(default_factory=list)  # ssm only


@dataclass
class Outputs:
    robot_commands: list[pb.RobotCommand] = field(default_factory=list)  # only new ones
    world_commands: list[pb.WorldCommand] = field(default_factory=list)
    events: list[pb.TaskEvent] = field(default_factory=list)
    cues: list[pb.Cue] = field(default_factory=list)  # on/off changes
    stop: str = ""  # non-empty once: the task finished, end the run
    stalled: str = ""  # non-empty once: the watchdog fired, end the run with this message
