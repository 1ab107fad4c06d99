"""The three input sources behind one interface: ``sample(t)`` -> the participant at sim time t."""

from __future__ import annotations

from typing import Protocol

from hrc.geometry import Pose, look_quat
from hrc.scenario import InputSource

from hrc_human_input.replay import Replayer
from hrc_human_input.sample import Sample
from hrc_human_input.scripted import HEAD_POS, REST, ScriptedParticipant
from hrc_human_input.task_view import TaskView
from hrc_human_input.vr_bridge import VrBridge


def rest_sample(t: float = 0.0) -> Sample:
    """Standing at the table, hands down, grips open."""
    return Sample(t, Pose(HEAD_POS, look_quat(HEAD_POS, (0.0, 0.0, 0.0))), Pose(REST["left"]),
                  Pose(REST["right"]), 0.0, 0.0)


class Source(Protocol):
    name: InputSource

    def sample(self, t: float) -> Sample: ...


class ScriptedSource:
    name = InputSource.SCRIPTED

    def __init__(self, participant: ScriptedParticipant, view: TaskView) -> None:
        self.participant = participant
        self.view = view

    def sample(self, t: float) -> Sample:
        return self.participant.step(t, self.view)


class ReplaySource:
    name = InputSource.REPLAY

    def __init__(self, replayer: Replayer) -> None:
        self.replayer = replayer

    def sample(self, t: float) -> Sample:
        return self.replayer.sample_at(t)


class VrSource:
    """The latest sample the bridge accepted, stamped with the tick's time (the rest pose until
    a client sends one; the last one when the client goes away)."""

    name = InputSource.VR

    def __init__(self, bridge: VrBridge) -> None:
        self.bridge = bridge

    def sample(self, t: float) -> Sample:
        latest = self.bridge.latest()
        return rest_sample(t) if latest is None else latest.at(t)
