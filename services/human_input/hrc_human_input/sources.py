"""The three input sources behind one interface: ``sample(t)`` -> the participant at sim time t;
``register_inputs`` subscribes to what the source perceives of the task (the scripted
participant only); ``summary()`` is its end-of-run log line."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

from hrc.bus import Keys
from hrc.geometry import Pose, look_quat
from hrc.participant.sample import Sample
from hrc.scenario import InputSource
from hrc.scenario.conventions import GRIP_CLOSED
from hrc.service import Inputs
from hrc.wire import pb

from hrc_human_input.replay import Replayer
from hrc_human_input.scripted import HEAD_POS, REST, ScriptedParticipant
from hrc_human_input.stream import RunState, WorldMirror
from hrc_human_input.task_view import TaskView
from hrc_human_input.vr_options import DRIVER

if TYPE_CHECKING:  # the bridge's server is imported only for a live participant
    from hrc.bus.bus import Publisher

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

    def next_event_s(self, t: float) -> float | None:
        """After the sample of time ``t``: a time before which no grip crosses GRIP_CLOSED
        (no grab or release can begin) as far as the source knows; None if it knows of none."""

    def next_decision_s(self, t: float) -> float | None:
        """After the sample of time ``t``: the earliest time a timer of the source may make it
        decide from its inputs (they must then be those of one-tick exchanges); None: none."""

    def next_sample_s(self, t: float) -> tuple[float, int] | None:
        """After the sample of time ``t``: the next time the source looks at its inputs to
        decide (an exchange starts at the first tick at or after it, no reaction chain follows)
        and every how many ticks it goes on looking (0: once); None: none."""

    def hand_speed_bound(self) -> float:
        """m/s no point of a hand exceeds (HumanState.hand_speed_bound); 0: unknown."""

    def published(self, tick: int, t: float, sample: Sample) -> None:
        """The tick's sample is on the bus (the bridge streams the world from here)."""

    def exchange_opened(self, t: float) -> None:
        """An exchange opens at time ``t``: the inputs now held are of the ticks before it."""

    def ended(self, ok: bool, reason: str) -> None:
        """The run is over."""


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

    def next_event_s(self, t: float) -> float | None:
        times = [
            x
            for h in self.participant.hands.values()
            if (x := h.grip_crossing_not_before(t, GRIP_CLOSED)) is not None
        ]
        return min(times) if times else None

    def next_decision_s(self, t: float) -> float | None:
        return self.participant.next_timer_s(self.view)

    def next_sample_s(self, t: float) -> tuple[float, int] | None:
        return self.participant.next_look_s()

    def hand_speed_bound(self) -> float:
        return self.participant.hand_speed_bound()

    def exchange_opened(self, t: float) -> None:
        self.view.exchange_t = t

    def summary(self) -> str | None:
        sp = self.participant
        return (
            f"scripted participant: phase {sp.phase.value}, {len(sp.reaches())} reaches, "
            f"{len(sp.hold_backs)} hold-backs"
        )

    def published(self, tick: int, t: float, sample: Sample) -> None:
        pass

    def ended(self, ok: bool, reason: str) -> None:
        pass


class ReplaySource:
    name = InputSource.REPLAY

    def __init__(self, replayer: Replayer) -> None:
        self.replayer = replayer

    def sample(self, t: float) -> Sample:
        return self.replayer.sample_at(t)

    def register_inputs(self, inputs: Inputs, keys: Keys) -> None:
        pass  # a recording perceives nothing

    def next_event_s(self, t: float) -> float | None:
        return self.replayer.grip_crossing_after(t, GRIP_CLOSED)

    def next_decision_s(self, t: float) -> float | None:
        return None

    def hand_speed_bound(self) -> float:
        return self.replayer.hand_speed_bound()

    def summary(self) -> str | None:
        return None

    def next_sample_s(self, t: float) -> tuple[float, int] | None:
        return None

    def exchange_opened(self, t: float) -> None:
        """Nothing: its samples do not depend on when inputs came."""

    def published(self, tick: int, t: float, sample: Sample) -> None:
        pass

    def ended(self, ok: bool, reason: str) -> None:
        pass


class VrSource:
    """The latest sample the bridge accepted, stamped with the tick's time (the rest pose until
    a client sends one; the last one when the client goes away). It also mirrors what a
    participant perceives of the world and hands it to the bridge after every tick."""

    name = InputSource.VR

    def __init__(
        self, bridge: VrBridge, mirror: WorldMirror, clients_pub: Publisher[Any] | None = None
    ) -> None:
        self.bridge = bridge
        self.mirror = mirror
        self.clients_pub = clients_pub  # human/clients: the experimenter's console

    def sample(self, t: float) -> Sample:
        latest = self.bridge.take()
        return rest_sample(t) if latest is None else latest.at(t)

    def next_event_s(self, t: float) -> float | None:
        return None  # a live person: unknown (realtime exchanges span a headset frame at most)

    def next_decision_s(self, t: float) -> float | None:
        return None

    def hand_speed_bound(self) -> float:
        return 0.0  # unknown

    def register_inputs(self, inputs: Inputs, keys: Keys) -> None:
        m = self.mirror
        inputs.input(keys.world_objects(), pb.WorldObjects, lambda _k, msg: m.on_objects(msg))
        inputs.input(keys.robot_states(), pb.RobotState, lambda _k, msg: m.on_robot_state(msg))
        inputs.input(keys.task_indicators(), pb.Indicators, lambda _k, msg: m.on_indicators(msg))
        inputs.input(keys.task_events(), pb.TaskEvent, lambda _k, msg: m.on_task_event(msg))

    def next_sample_s(self, t: float) -> tuple[float, int] | None:
        return None

    def exchange_opened(self, t: float) -> None:
        """Nothing: its samples do not depend on when inputs came."""

    def published(self, tick: int, t: float, sample: Sample) -> None:
        if self.mirror.world_seen:  # until then the frame would show an empty world
            self.bridge.publish(*self.mirror.snapshot(tick, t, sample))
        pub = self.clients_pub
        presence = self.bridge.presence() if pub is not None else None
        if pub is not None and presence is not None:
            clients, changes = presence
            role = {DRIVER: pb.CLIENT_ROLE_DRIVER}
            msg = pb.ParticipantClients(
                clients=[
                    pb.ParticipantClient(peer=peer, role=role.get(r, pb.CLIENT_ROLE_SPECTATOR))
                    for peer, r in clients
                ],
                changes=changes,
            )
            pub.put(msg, tick, t)

    def ended(self, ok: bool, reason: str) -> None:
        m = self.mirror
        if ok and m.run != RunState.FINISHED:  # stopped before the task finished: the experimenter
            m.set_run(RunState.STOPPED, reason)
        elif not ok:
            m.set_run(RunState.FAILED, reason)
        snap, events = m.snapshot(m.last_tick, m.last_t, self.bridge.latest())
        self.bridge.publish(snap, events)
        self.bridge.flush()

    def summary(self) -> str | None:
        st = self.bridge.stats
        return (
            f"VR bridge: {st.clients} clients, {st.accepted} samples accepted, "
            f"{st.rejected} rejected; {st.frames_sent} frames sent, {st.frames_dropped} "
            f"dropped, {st.bytes_sent} bytes, {st.too_slow} disconnected as too slow"
        )
