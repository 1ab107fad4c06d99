"""What the bridge streams to its clients (docs/client-protocol.md): the world as the session has
it, mirrored from the bus in the tick thread, and handed to the bridge's event loop as immutable
snapshots; per client, a frame carries only what changed since the last frame sent to it.

The tick thread only builds a snapshot (small dict copies) and hands it over; JSON and sending
happen in the bridge's loop.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

from hrc.participant.sample import Sample
from hrc.scenario.convert import ssm_from_proto
from hrc.ssm import Zone
from hrc.wire import pb

from hrc_human_input.scene import cue_def, r4, scene_cue_json, v3

# The task events a participant perceives, forwarded as `event` messages.
PERCEIVABLE = frozenset(
    {
        pb.TASK_EVENT_KIND_PART_PLACED,
        pb.TASK_EVENT_KIND_PART_RELEASED,
        pb.TASK_EVENT_KIND_COLLISION,
        pb.TASK_EVENT_KIND_COLLISION_END,
        pb.TASK_EVENT_KIND_CONTINUED,
        pb.TASK_EVENT_KIND_BUTTON_PRESSED,
        pb.TASK_EVENT_KIND_ROBOT_WAITING,
        pb.TASK_EVENT_KIND_ROBOT_WAIT_OVER,
        pb.TASK_EVENT_KIND_TASK_STARTED,
        pb.TASK_EVENT_KIND_TASK_FINISHED,
        pb.TASK_EVENT_KIND_ROBOT_FINISHED,
        pb.TASK_EVENT_KIND_HUMAN_FINISHED,
        pb.TASK_EVENT_KIND_STALLED,
        pb.TASK_EVENT_KIND_PARTICIPANT_WAIT,
    }
)
EVENT_PREFIX = "TASK_EVENT_KIND_"
STATUS_PREFIX = "MOTION_STATUS_"


def event_kind(kind: pb.TaskEventKind.ValueType) -> str:
    """The protocol's name of a task event kind: the enum name, lower case, without prefix."""
    return pb.TaskEventKind.Name(kind).removeprefix(EVENT_PREFIX).lower()


def motion_status(status: pb.MotionStatus.ValueType) -> str:
    return pb.MotionStatus.Name(status).removeprefix(STATUS_PREFIX).lower()


class RunState:
    WAITING = "waiting_first_grab"
    RUNNING = "running"
    FINISHED = "finished"  # the task finished
    STOPPED = "stopped"  # the experimenter ended the trial before the task finished
    FAILED = "failed"


RobotEntry = tuple[tuple[float, ...], tuple[float, ...], str, int]  # q, tcp, status, command
ObjectEntry = tuple[tuple[float, ...], tuple[float, ...], str, bool, bool]  # p, q, holder, ...
ZoneEntry = tuple[float, str]  # radius (m, to the centimetre), state
ZONE_RESOLUTION_M = 0.01  # a zone is sent again when its radius changes by this


def ssm_zones(msg: pb.Scenario) -> dict[str, Zone]:
    """Per robot, its protective zone under safety_policy = "ssm"; none under another policy."""
    if msg.conditions.safety_policy != pb.SAFETY_POLICY_SSM:
        return {}
    return {r.id: Zone(ssm_from_proto(r.ssm)) for r in msg.robots}


@dataclass(frozen=True)
class Snapshot:
    """The world at one tick, as the clients get it. Never mutated once handed over."""

    version: int
    tick: int
    t: float
    task_t: float | None
    robots: dict[str, RobotEntry]
    objects: dict[str, ObjectEntry]
    cues: dict[str, bool]
    cue_defs: dict[str, str]  # cue id -> JSON of its live definition, where not the scene's
    hands: dict[str, Any]
    run: str
    zones: dict[str, ZoneEntry] = field(default_factory=dict)


@dataclass
class WorldMirror:
    """The tick thread's copy of what clients see, updated by the bus handlers."""

    joint_order: dict[str, list[str]]  # robot -> the scene's joint names
    scene_cues: dict[str, str]  # cue id -> JSON of the scene's definition
    zones: dict[str, Zone] = field(default_factory=dict)  # ssm only: per robot
    robots: dict[str, RobotEntry] = field(default_factory=dict)
    objects: dict[str, ObjectEntry] = field(default_factory=dict)
    cues: dict[str, bool] = field(default_factory=dict)
    cue_defs: dict[str, str] = field(default_factory=dict)
    events: list[str] = field(default_factory=list)  # JSON, since the last snapshot
    run: str = RunState.WAITING
    run_reason: str = ""
    task_start: float | None = None
    version: int = 0
    last_tick: int = 0
    last_t: float = 0.0
    # physics's first world/objects (tick 0: every object) has arrived; in realtime a step may
    # come before it, and a client's first frame must hold the whole world
    world_seen: bool = False

    # ------------------------------------------------------------------ bus handlers
    def on_objects(self, msg: pb.WorldObjects) -> None:
        self.world_seen = True
        for o in msg.objects:
            p, q = o.pose.position, o.pose.orientation
            self.objects[o.id] = (
                (r4(p.x), r4(p.y), r4(p.z)),
                (r4(q.x), r4(q.y), r4(q.z), r4(q.w)),
                o.held_by,
                o.placed,
                o.grabbable,
            )

    def on_robot_state(self, msg: pb.RobotState) -> None:
        order = self.joint_order.get(msg.robot) or list(msg.joint_names)
        by_name = dict(zip(msg.joint_names, msg.joint_positions, strict=False))
        if all(n in by_name for n in order):
            q = tuple(r4(by_name[n]) for n in order)
        else:  # names the scene does not know: as sent
            q = tuple(r4(x) for x in msg.joint_positions)
        p = msg.tcp.position
        self.robots[msg.robot] = (
            q,
            (r4(p.x), r4(p.y), r4(p.z)),
            motion_status(msg.status),
            int(msg.command_id),
        )
        zone = self.zones.get(msg.robot)
        if zone is not None:
            zone.observe(msg)

    def zone_entries(self) -> dict[str, ZoneEntry]:
        return {
            rid: (round(z.radius / ZONE_RESOLUTION_M) * ZONE_RESOLUTION_M, z.state)
            for rid, z in self.zones.items()
        }

    def on_indicators(self, msg: pb.Indicators) -> None:
        for cue in msg.cues:
            self.cues[cue.id] = cue.on
            if cue.on:
                live = scene_cue_json(cue_def(cue))
                if live != self.scene_cues.get(cue.id):
                    self.cue_defs[cue.id] = live
                else:
                    self.cue_defs.pop(cue.id, None)

    def on_task_event(self, msg: pb.TaskEvent) -> None:
        t = msg.header.sim_time
        zone = self.zones.get(msg.robot)
        if zone is not None:
            zone.event(msg)
        if msg.kind == pb.TASK_EVENT_KIND_TASK_STARTED and self.task_start is None:
            self.task_start = t - msg.task_time
        if msg.kind in PERCEIVABLE:
            event = {
                "type": "event",
                "tick": msg.header.tick,
                "t_s": r4(t),
                "task_t_s": r4(msg.task_time) if self.task_start is not None else None,
                "kind": event_kind(msg.kind),
                "part": msg.part,
                "robot": msg.robot or (msg.agent if msg.agent != "human" else ""),
                "hand": msg.hand,
                "text": msg.text,
            }
            if msg.kind == pb.TASK_EVENT_KIND_PARTICIPANT_WAIT:
                event["quiet_s"] = r4(msg.participant_wait.quiet_s)
                event["part"] = msg.participant_wait.what
            self.events.append(json.dumps(event, separators=(",", ":")))
        # the run message follows the event that changed it
        if msg.kind == pb.TASK_EVENT_KIND_TASK_STARTED:
            self.set_run(RunState.RUNNING)
        elif msg.kind == pb.TASK_EVENT_KIND_TASK_FINISHED:
            self.set_run(RunState.FINISHED, msg.text)
        elif msg.kind == pb.TASK_EVENT_KIND_STALLED:
            self.set_run(RunState.FAILED, msg.text)

    def set_run(self, state: str, reason: str = "") -> None:
        if state == self.run:
            return
        self.run, self.run_reason = state, reason
        self.events.append(
            json.dumps({"type": "run", "state": state, "reason": reason}, separators=(",", ":"))
        )

    # ------------------------------------------------------------------ hand-over
    def snapshot(self, tick: int, t: float, sample: Sample | None) -> tuple[Snapshot, list[str]]:
        """The state at the end of ``tick`` and the events since the last snapshot."""
        self.version += 1
        self.last_tick, self.last_t = tick, t
        events, self.events = self.events, []
        task_t = None if self.task_start is None else r4(t - self.task_start)
        snap = Snapshot(
            self.version,
            tick,
            r4(t),
            task_t,
            dict(self.robots),
            dict(self.objects),
            dict(self.cues),
            dict(self.cue_defs),
            hands_json(sample),
            self.run,
            self.zone_entries(),
        )
        return snap, events


def hands_json(s: Sample | None) -> dict[str, Any]:
    if s is None:
        return {}

    def pose(p: Any, grip: float | None = None) -> dict[str, Any]:
        out: dict[str, Any] = {"p": v3(p.position), "q": v3(p.orientation)}
        if grip is not None:
            out["grip"] = r4(grip)
        return out

    return {
        "left": pose(s.left, s.left_grip),
        "right": pose(s.right, s.right_grip),
        "head": pose(s.head),
    }


@dataclass
class ClientView:
    """What one client was last sent, for its deltas."""

    robots: dict[str, RobotEntry] = field(default_factory=dict)
    objects: dict[str, ObjectEntry] = field(default_factory=dict)
    cues: dict[str, bool] = field(default_factory=dict)
    cue_defs: dict[str, str] = field(default_factory=dict)
    zones: dict[str, ZoneEntry] = field(default_factory=dict)
    seq: int = 0
    version: int = 0


def frame_json(view: ClientView, snap: Snapshot, dropped: int) -> str:
    """The next frame for one client (only what changed for it), and remembers it as sent."""
    robots = {
        rid: {"q": list(e[0]), "tcp": list(e[1]), "status": e[2], "command": e[3]}
        for rid, e in snap.robots.items()
        if view.robots.get(rid) != e
    }
    objects = {
        oid: {"p": list(e[0]), "q": list(e[1]), "holder": e[2], "placed": e[3], "grabbable": e[4]}
        for oid, e in snap.objects.items()
        if view.objects.get(oid) != e
    }
    cues = {cid: on for cid, on in snap.cues.items() if view.cues.get(cid) != on}
    defs = {cid: d for cid, d in snap.cue_defs.items() if view.cue_defs.get(cid) != d}
    zones = {
        rid: {"radius": r4(e[0]), "state": e[1]}
        for rid, e in snap.zones.items()
        if view.zones.get(rid) != e
    }
    view.seq += 1
    view.version = snap.version
    view.robots, view.objects, view.cues, view.cue_defs = (
        snap.robots,
        snap.objects,
        snap.cues,
        snap.cue_defs,
    )
    view.zones = snap.zones
    frame: dict[str, Any] = {
        "type": "frame",
        "seq": view.seq,
        "tick": snap.tick,
        "t_s": snap.t,
        "task_t_s": snap.task_t,
        "robots": robots,
        "objects": objects,
        "cues": cues,
        "hands": snap.hands,
        "run": snap.run,
        "dropped": dropped,
    }
    if zones:  # ssm only, on change
        frame["zones"] = zones
    head = json.dumps(frame, separators=(",", ":"))
    if not defs:
        return head
    # The live definitions are JSON already: spliced in, not parsed and dumped again.
    body = ",".join(f"{json.dumps(cid)}:{d}" for cid, d in sorted(defs.items()))
    return head[:-1] + ',"cue_defs":{' + body + "}}"
