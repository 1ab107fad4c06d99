"""The three input sources behind one interface: ``sample(t)`` -> the participant at sim time t;
``register_inputs`` subscribes to what the source perceives of the task (the scripted
participant only); ``summary()`` is its end-of-run log line."""

from __future__ import annotations

from typing import Protocol

from hrc.bus import Keys
from hrc.geometry import Pose, look_quat
from hrc.scenario import InputSource
from hrc.service import Inputs
from hrc.wire import pb

from hrc_human_input.replay import Replayer
from hrc_human_input.sample import Sample
from hrc_human_input.scripted import HEAD_POS, REST, ScriptedParticipant
from hrc_human_input.task_view import TaskView
from hrc_human_input.vr_bridge import VrBridge


def rest_sample(t: float = 0.0) -> Sample:
    """Standing at the table, hands down, grips open."""
    return Sample(
        t,
        Pose(HEAD_POS, look_quat(HEAD_POS, (0.0, 0.0, 0.0))),
        Pose(REST["left"]),
        Pose(REST["right"]),
        0.0,
        0.0,
    )


class Source(Protocol):
    name: InputSource

    def sample(self, t: float) -> Sample: ...

    def register_inputs(self, inputs: Inputs, keys: Keys) -> None: ...

    def summary(self) -> str | None: ...


class ScriptedSource:
    name = InputSource.SCRIPTED

    def __init__(self, participant: ScriptedParticipant, view: TaskView) -> None:
        self.participant = participant
        self.view = view

    def sample(self, t: float) -> Sample:
        return self.participant.step(t, self.view)

    def register_inputs(self, inputs: Inputs, keys: Keys) -> None:
        view = self.view
        inputs.input(keys.world_objects(), pb.WorldObjects, lambda _k, m: view.on_objects(m))
        inputs.input(keys.world_contacts(), pb.WorldContacts, lambda _k, m: view.on_contacts(m))
        inputs.input(keys.robot_states(), pb.RobotState, lambda _k, m: view.on_robot_state(m))
        inputs.input(keys.task_indicators(), pb.Indicators, lambda _k, m: view.on_indicators(m))
        inputs.input(keys.task_events(), pb.TaskEvent, lambda _k, m: view.on_task_event(m))

    def summary(self) -> str | None:
        sp = self.participant
        return (
            f"scripted participant: phase {sp.phase.value}, {len(sp.reaches())} reaches, "
            f"{len(sp.hold_backs)} hold-backs"
        )


class ReplaySource:
    name = InputSource.REPLAY

    def __init__(self, replayer: Replayer) -> None:
        self.replayer = replayer

    def sample(self, t: float) -> Sample:
        return self.replayer.sample_at(t)

    def register_inputs(self, inputs: Inputs, keys: Keys) -> None:
        pass  # a recording perceives nothing

    def summary(self) -> str | None:
        return None


class VrSource:
    """The latest sample the bridge accepted, stamped with the tick's time (the rest pose until
    a client sends one; the last one when the client goes away)."""

    name = InputSource.VR

    def __init__(self, bridge: VrBridge) -> None:
        self.bridge = bridge

    def sample(self, t: float) -> Sample:
        latest = self.bridge.latest()
        return rest_sample(t) if latest is None else latest.at(t)

    def register_inputs(self, inputs: Inputs, keys: Keys) -> None:
        pass  # the person in the headset sees the view, not the bus

    def summary(self) -> str | None:
        st = self.bridge.stats
        return (
            f"VR bridge: {st.clients} clients, {st.accepted} samples accepted, "
            f"{st.rejected} rejected"
        )
