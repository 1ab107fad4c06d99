"""The rerun view of a trial: recording.rrd always, plus a live native or web viewer on request.

Timelines: ``tick`` (sequence) and ``sim_time`` (duration, seconds); every message is logged at
its own header's tick and sim time. Wall-clock timelines are off, so the same trial gives the
same recording content.

Entities:
- ``robot_<id>/...``: the robot from its URDF (rerun's URDF loader, ``rerun.urdf.UrdfTree``, with
  frame prefix ``<id>/``); ``robot_<id>/base`` places its root link in the world (static);
  ``robot_<id>/joints/<joint>`` holds each joint's transform (parent link -> child link, from our
  FK, ``hrc.urdf_fk``), logged at most ``view_hz`` times per simulated second plus the last state.
- ``world/tcp/<id>``: the TCP point; ``plots/tcp_speed/<id>``: its speed (m/s).
- ``world/parts/<id>``: each part as a box coloured by owner; its transform is logged only when it
  moved (at most ``view_hz``/s, immediately on grab/release/snap/spawn).
- ``world/targets/<id>``: each part's target (static wireframe, owner colour).
- ``world/human/{head,left_hand,right_hand}``: the participant (hands darken with the grip).
- ``plots/hand_distance/<hand>/<robot>``: distance from each hand to each robot's link chain (m).
- ``world/cues/<kind>/<name>`` (cue id ``target:RA1`` -> ``world/cues/target/RA1``): target
  highlights, object outlines, "Waiting.." labels, the continue button; flashing cues blink at
  ``flash_hz`` on the sim timeline as they do for the participant; ``status/cues`` lists the
  active cues.
- ``world/contacts/<kind>/<a>_<b>``: contact markers while a contact lasts.
- ``world/workspace/...``: envelope boxes, continue button, feeders (static).
- ``events``: a text log of every task event (the log.txt line where there is one).

The layout (scene large, from behind the participant; plots and events beside it) is the
blueprint of ``hrc_logger.blueprint``, sent at setup.
"""

from __future__ import annotations

import logging
import math
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import rerun as rr
from rerun.urdf import UrdfTree

from hrc.geometry import vec3_from_pb, yaw_quat_deg
from hrc.scenario import colors
from hrc.scenario.convert import ssm_from_proto
from hrc.scenario.meshes import RERUN_DRAWS
from hrc.scenario.models import DEFAULT_TICK_HZ, HUMAN
from hrc.scenario.urdf import localized_urdf
from hrc.urdf_fk import (
    UrdfError,
    UrdfModel,
    matrix_to_quat_xyzw,
    yaw_transform,
)
from hrc.wire import pb

from hrc_logger.blueprint import blueprint
from hrc_logger.cues import WHITE, CueView, cue_archetype
from hrc_logger.entities import CLEAR, cue_entity, finite, part, rgb, rgba, srgb_to_linear
from hrc_logger.series import PointRow, SeriesBatch, StateStream
from hrc_logger.ssm_zone import Zone
from hrc_logger.textlog import kind_name

log = logging.getLogger(__name__)

HEAD_RADIUS_M = 0.05
HAND_RADIUS_M = 0.03

ROOT_FRAME = "tf#/"  # rerun's implicit frame of the root entity: the world
# Colours come from the one table (hrc.scenario.colors); the participant's parts in their part
# colour, as physics and the participant's page draw them.
HUMAN_PART_RGB = colors.rgb(colors.HUMAN_PART_COLOR)
UNKNOWN_COLOR = colors.UNKNOWN_RGB


@dataclass
class ViewSettings:
    view_hz: float = 30.0  # robot/hand/object updates per simulated second (logging cost)
    flash_hz: float = 2.0  # cue blinking: on for half of each 1/flash_hz period
    tick_hz: float = DEFAULT_TICK_HZ  # replaced by the scenario's / clock's rate when known
    # Time series (joint transforms, plots) are sent in columns, one call per entity, once this
    # many simulated seconds have gathered (None: at the end): a rerun log call per row was
    # most of the logger's CPU time.
    series_flush_s: float | None = None


@dataclass
class RobotView:
    rid: str
    color: tuple[int, int, int]
    base: np.ndarray
    model: UrdfModel | None = None
    q: dict[str, float] = field(default_factory=dict)
    tcp: np.ndarray | None = None
    states: StateStream[pb.RobotState] = field(default_factory=StateStream)
    unknown_joints_warned: bool = False
    # The joint vector (model.joint_vector) of the last logged state; never changed in place
    # (hand-distance rows keep it until sent). None without a model.
    qvec: np.ndarray | None = None
    chain: np.ndarray | None = None  # link origins at qvec, computed when asked (View._chain)


@dataclass
class ObjectView:
    oid: str
    size: tuple[float, float, float]
    color: tuple[int, int, int]
    shown: bool = False
    pose: tuple[float, ...] = ()  # last logged (x, y, z, qx, qy, qz, qw); () before the first
    next_due: int = 0
    held_by: str = ""
    placed: bool = False


def open_recording(
    path: Path,
    recording_id: str,
    *,
    viewer: bool = False,
    web: bool = False,
    viewer_port: int = 9876,
    web_port: int = 9090,
    grpc_port: int = 9877,
) -> rr.RecordingStream:
    """A recording that always writes ``path``; ``viewer`` also streams to a spawned native viewer,
    ``web`` also hosts a gRPC server plus the web viewer (http://127.0.0.1:<web_port>)."""
    rec = rr.RecordingStream("hrc-cosim", recording_id=recording_id)
    rec.set_log_time_enabled(False)  # no wall-clock timeline: same trial, same content
    rec.set_log_tick_enabled(False)
    sinks: list[Any] = [rr.FileSink(str(path))]
    if viewer:
        exe = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
        rr.spawn(port=viewer_port, connect=False, executable_path=exe)
        sinks.append(rr.GrpcSink(f"rerun+http://127.0.0.1:{viewer_port}/proxy"))
        log.info("native viewer spawned on port %d", viewer_port)
    server = None
    if web:
        server = rr.GrpcServerSink(bind_ip="127.0.0.1", port=grpc_port)
        sinks.append(server)
    rec.set_sinks(*sinks)
    if server is not None:
        rr.serve_web_viewer(web_port=web_port, open_browser=False, connect_to=server.uri)
        log.info("web viewer: http://127.0.0.1:%d (data from %s)", web_port, server.uri)
    return rec


class View:
    """Turns the session's messages into rerun entities (see the module docstring)."""

    def __init__(self, rec: rr.RecordingStream, settings: ViewSettings | None = None) -> None:
        self.rec = rec
        self.s = settings or ViewSettings()
        self.every = max(1, round(self.s.tick_hz / self.s.view_hz))
        self.robots: dict[str, RobotView] = {}
        self.objects: dict[str, ObjectView] = {}
        self.parts: dict[str, pb.PartConfig] = {}
        self.owner_color: dict[str, tuple[int, int, int]] = {HUMAN: HUMAN_PART_RGB}
        self.cues: dict[str, CueView] = {}
        self.hands: dict[str, np.ndarray] = {}
        self.human: StateStream[pb.HumanState] = StateStream()
        self.clock: tuple[int, float] | None = None  # the latest clock tick (tick, sim time)
        self.button: npt.NDArray[np.float64] = np.zeros(3)
        self._flash_phase: int | None = None
        self.zones: dict[str, Zone] = {}  # ssm only: the protective zone per robot
        self._log_calls = 0
        self._time_sent = False  # rerun has been told batch.now (set_time before a log call)
        self.batch = SeriesBatch(rec, self.s.series_flush_s)

    # ------------------------------------------------------------------ helpers
    def _log(self, entity: str, *archetypes: Any, static: bool = False) -> None:
        if not (static or self._time_sent):
            self.rec.set_time("tick", sequence=self.batch.now[0])
            self.rec.set_time("sim_time", duration=self.batch.now[1])
            self._time_sent = True
        self.rec.log(entity, *archetypes, static=static)
        self._log_calls += 1

    @property
    def logged(self) -> int:
        """Rerun log calls and rows sent in columns, for the service's summary."""
        return self._log_calls + self.batch.rows

    def _time(self, tick: int, sim_time: float) -> None:
        """The time of what follows; rerun is told only before a log call (rows in columns
        carry their own times), as set_time costs more than most rows."""
        now = (int(tick), float(sim_time))
        if now != self.batch.now:
            self.batch.now = now
            self._time_sent = False

    def _distance_row(self, entity: str, rv: RobotView, hand: np.ndarray) -> None:
        """A hand's distance to a robot's link chain (the TCP without a URDF) at the current
        time, computed for a whole column when sent."""
        if rv.model is not None and rv.qvec is not None:
            self.batch.chain_distance(entity, rv.model, rv.base, rv.qvec, hand)
        elif rv.tcp is not None:
            self.batch.polyline_distance(entity, rv.tcp[None, :], hand)

    def _chain(self, rv: RobotView) -> np.ndarray | None:
        """The robot's link origins at its last logged state (None without a URDF)."""
        if rv.chain is None and rv.model is not None and rv.qvec is not None:
            rv.chain = rv.model.chain_points_columns(rv.qvec[None, :], rv.base)[0]
        return rv.chain

    def flush_series(self) -> None:
        """Sends every gathered time-series row (one call per entity)."""
        self.batch.flush()

    def set_tick_hz(self, hz: float) -> None:
        if hz > 0 and math.isfinite(hz):
            self.s.tick_hz = hz
            self.every = max(1, round(hz / self.s.view_hz))

    # ------------------------------------------------------------------ static scene
    def setup(self, scenario: pb.Scenario | None) -> None:
        """Static content from the scenario; robots from their URDFs."""
        self._log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)  # z up for the whole scene
        self.rec.send_blueprint(blueprint())  # the scene large, seen from behind the participant
        if scenario is None:
            return
        if scenario.info.tick_hz > 0:
            self.set_tick_hz(scenario.info.tick_hz)
        for r in scenario.robots:
            self.owner_color[r.id] = rgb(r.color)
        for r in scenario.robots:
            self._setup_robot(r)
            if scenario.conditions.safety_policy == pb.SAFETY_POLICY_SSM:
                self.zones[r.id] = Zone(ssm_from_proto(r.ssm))
        for p in scenario.parts:
            self.parts[p.id] = p
            color = self.owner_color.get(p.owner, UNKNOWN_COLOR)
            size = (p.size.x, p.size.y, p.size.z)
            self.objects[p.id] = ObjectView(p.id, size, color)
            self._log(
                f"world/targets/{part(p.id)}",
                rr.Boxes3D(
                    half_sizes=[[s / 2 for s in size]],
                    centers=[vec3_from_pb(p.target.xyz)],
                    quaternions=[yaw_quat_deg(p.target.yaw_deg)],
                    colors=[rgba(color, 110)],
                    fill_mode="majorwireframe",
                    labels=[f"{p.id} target"],
                    show_labels=False,
                ),
                static=True,
            )
        for i, b in enumerate(scenario.workspace.envelope):
            lo, hi = np.array(vec3_from_pb(b.min)), np.array(vec3_from_pb(b.max))
            self._log(
                f"world/workspace/envelope_{i}",
                rr.Boxes3D(
                    half_sizes=[(hi - lo) / 2],
                    centers=[(hi + lo) / 2],
                    colors=[(150, 150, 150, 60)],
                    fill_mode="majorwireframe",
                ),
                static=True,
            )
        self.button = np.array(vec3_from_pb(scenario.workspace.continue_button))
        self._log(
            "world/workspace/continue_button",
            rr.Points3D(
                [self.button], radii=[0.015], colors=[(120, 120, 120)], labels=["continue button"]
            ),
            static=True,
        )
        for r in scenario.robots:
            if r.role == pb.ROBOT_ROLE_SCREWING:
                self._log(
                    f"world/workspace/feeder_{part(r.id)}",
                    rr.Points3D(
                        [vec3_from_pb(r.feeder)],
                        radii=[0.02],
                        colors=[rgb(r.color)],
                        labels=[f"{r.id} feeder"],
                    ),
                    static=True,
                )
        for rid, rv in self.robots.items():
            self._log(
                f"plots/tcp_speed/{part(rid)}",
                rr.SeriesLines(colors=[rv.color], names=[f"{rid} TCP speed"]),
                static=True,
            )

    def _setup_robot(self, r: pb.RobotConfig) -> None:
        base = yaw_transform(vec3_from_pb(r.base.xyz), r.base.yaw_deg)
        rv = RobotView(r.id, rgb(r.color), base)
        self.robots[r.id] = rv
        ent = f"robot_{part(r.id)}"
        try:
            rv.model = UrdfModel.from_file(r.urdf_path)
            # rerun's importer resolves package:// only through ROS's variables: it gets a copy
            # with absolute mesh paths, every visual in the robot's colour unless told not to
            # (written linear: the importer reads a URDF colour as linear and shows it as sRGB)
            tint = None if r.own_colors else [srgb_to_linear(c / 255.0) for c in rv.color]
            # (and visual meshes outside the formats rerun documents converted to GLB)
            shown = localized_urdf(
                Path(r.urdf_path), [Path(d) for d in r.package_dirs], None, tint, RERUN_DRAWS
            )
            tree = UrdfTree.from_file_path(
                shown,
                ent,
                frame_prefix=f"{r.id}/",
                static_transform_entity_path=f"{ent}/tf_static",
            )
            # Geometry only: every joint transform comes from us (fixed ones static, the others
            # per state), so no child frame has two sources. Visuals only: the collision shapes
            # (a maker's plain meshes) would be drawn over them, white, and double the file.
            chunks = tree.stream(include_joint_transforms=False)
            rr.send_chunks(
                (c for c in chunks if "/collision_geometries/" not in c.entity_path),
                recording=self.rec,
            )
        except (UrdfError, OSError, ValueError, RuntimeError) as exc:
            log.warning("robot %s: no URDF view (%s); showing its TCP only", r.id, exc)
            rv.model = None
            return
        q = rv.base[:3, :3]
        self._log(
            f"{ent}/base",
            rr.Transform3D(
                translation=rv.base[:3, 3],
                quaternion=rr.Quaternion(xyzw=matrix_to_quat_xyzw(q)),
                parent_frame=ROOT_FRAME,
                child_frame=f"{r.id}/{rv.model.root}",
            ),
            static=True,
        )
        for j in rv.model.joints:
            if j.kind == "fixed":
                self._log_fixed_joint(rv, j.name, j.local(0.0))
        rv.qvec = rv.model.joint_vector({})

    def _log_fixed_joint(self, rv: RobotView, name: str, t: np.ndarray) -> None:
        assert rv.model is not None
        j = rv.model.by_name[name]
        self._log(
            f"robot_{part(rv.rid)}/joints/{part(name)}",
            rr.Transform3D(
                translation=t[:3, 3],
                quaternion=rr.Quaternion(xyzw=matrix_to_quat_xyzw(t[:3, :3])),
                parent_frame=f"{rv.rid}/{j.parent}",
                child_frame=f"{rv.rid}/{j.child}",
            ),
            static=True,
        )

    # ------------------------------------------------------------------ robots
    def robot_state(self, st: pb.RobotState) -> None:
        rv = self.robots.get(st.robot)
        if rv is None:  # a robot the scenario did not announce: TCP only
            rv = self.robots[st.robot] = RobotView(st.robot, UNKNOWN_COLOR, np.eye(4))
        # Only the states the rate limit lets through are looked into (a state per tick per arm
        # would otherwise cost more than logging them).
        if rv.states.offer(st, self.every):
            self._log_robot(rv, st)

    def _absorb(self, rv: RobotView, st: pb.RobotState) -> None:
        """The joints and TCP of a state about to be logged."""
        if st.joint_names and len(st.joint_names) == len(st.joint_positions):
            q = dict(zip(st.joint_names, st.joint_positions, strict=True))
        elif rv.model is not None and len(st.joint_positions) == len(rv.model.movable):
            q = dict(zip(rv.model.movable, st.joint_positions, strict=True))
        else:
            q = {}
        if finite(q.values()):
            rv.q.update(q)
        p = st.tcp.position
        if finite((p.x, p.y, p.z)):
            rv.tcp = np.array([p.x, p.y, p.z])

    def _log_robot(self, rv: RobotView, st: pb.RobotState) -> None:
        self._absorb(rv, st)
        self._time(st.header.tick, st.header.sim_time)
        rv.states.logged(st)
        if rv.model is not None:
            unknown = [n for n in rv.q if n not in rv.model.by_name]
            if unknown and not rv.unknown_joints_warned:
                rv.unknown_joints_warned = True
                log.warning(
                    "robot %s: joints not in its URDF ignored: %s", rv.rid, ", ".join(unknown)
                )
            rv.qvec = rv.model.joint_vector(rv.q)
            rv.chain = None
            self.batch.joints(f"robot_{part(rv.rid)}/joints", rv.rid, rv.model, rv.qvec)
        if rv.tcp is not None:
            self.batch.point(f"world/tcp/{part(rv.rid)}", PointRow(rv.tcp, 0.01, rv.color))
        if math.isfinite(st.tcp_speed):
            self.batch.row(f"plots/tcp_speed/{part(rv.rid)}", st.tcp_speed)
        zone = self.zones.get(rv.rid)
        if zone is not None:
            zone.observe(st)
            self._log_zone(rv, zone)

    def _log_zone(self, rv: RobotView, zone: Zone) -> None:
        chain = self._chain(rv)
        centers = chain if chain is not None else rv.tcp[None] if rv.tcp is not None else None
        if centers is not None and finite(np.ravel(centers)):
            self._log(f"world/ssm_zone/{part(rv.rid)}", zone.archetype(np.asarray(centers)))

    # ------------------------------------------------------------------ human
    def human_state(self, hs: pb.HumanState) -> None:
        if self.human.offer(hs, self.every):
            self._log_human(hs)

    def _log_human(self, hs: pb.HumanState) -> None:
        for hand, pose in (("left", hs.left_hand), ("right", hs.right_hand)):
            p = pose.position
            if finite((p.x, p.y, p.z)):
                self.hands[hand] = np.array([p.x, p.y, p.z])
        self._time(hs.header.tick, hs.header.sim_time)
        self.human.logged(hs)
        h = hs.head.position
        if finite((h.x, h.y, h.z)):
            # smaller than life: seen from behind, a life-size head hides the board
            self.batch.point(
                "world/human/head",
                PointRow(np.array([h.x, h.y, h.z]), HEAD_RADIUS_M, (230, 190, 160)),
            )
        for hand, grip in (("left", hs.left_grip), ("right", hs.right_grip)):
            pos = self.hands.get(hand)
            if pos is None:
                continue
            g = min(1.0, max(0.0, grip if math.isfinite(grip) else 0.0))
            color = (int(240 - 90 * g), int(200 - 110 * g), int(170 - 110 * g))
            self.batch.point(
                f"world/human/{hand}_hand",
                PointRow(pos, HAND_RADIUS_M, color, f"{hand} {g:.1f}"),
                show_labels=False,  # the grip shows as the colour; labels crowd the board
            )
            for rid, rv in self.robots.items():
                self._distance_row(f"plots/hand_distance/{hand}/{part(rid)}", rv, pos)

    # ------------------------------------------------------------------ objects
    def world_objects(self, wo: pb.WorldObjects) -> None:
        tick = wo.header.tick
        forced = {e.object for e in wo.events}
        timed = False
        for o in wo.objects:
            ov = self.objects.get(o.id)
            if ov is None:
                ov = self.objects[o.id] = ObjectView(o.id, (0.03, 0.03, 0.03), UNKNOWN_COLOR)
            p, q = o.pose.position, o.pose.orientation
            pose = (p.x, p.y, p.z, q.x, q.y, q.z, q.w)
            if not finite(pose):
                continue
            changed_state = o.held_by != ov.held_by or o.placed != ov.placed
            if ov.shown and not changed_state:
                # Plain floats: most objects of most messages have not moved (numpy's
                # per-call cost was most of the logger's time here).
                x, y, z, qx, qy, qz, qw = ov.pose
                dx, dy, dz = pose[0] - x, pose[1] - y, pose[2] - z
                moved = (
                    math.sqrt(dx * dx + dy * dy + dz * dz) > 5e-4
                    or abs(pose[3] * qx + pose[4] * qy + pose[5] * qz + pose[6] * qw) < 0.99999
                )
                if not moved:
                    continue
                if o.id not in forced and tick < ov.next_due:
                    continue  # a moving object: at most view_hz updates per simulated second
            pos, quat = np.array(pose[:3]), np.array(pose[3:])
            if not timed:
                self._time(tick, wo.header.sim_time)
                timed = True
            ent = f"world/parts/{part(o.id)}"
            if not ov.shown or changed_state:
                label = (
                    o.id
                    + (f" ({o.held_by})" if o.held_by else "")
                    + (" placed" if o.placed else "")
                )
                self._log(
                    ent,
                    rr.Boxes3D(
                        half_sizes=[[s / 2 for s in ov.size]],
                        colors=[rgba(ov.color, 255 if o.placed else 200)],
                        fill_mode="solid",
                        labels=[label],
                        show_labels=not o.placed,  # the board fills up: only loose parts named
                    ),
                )
                ov.shown = True
            self.batch.pose(ent, pos, quat)
            ov.pose = pose
            ov.held_by, ov.placed = o.held_by, o.placed
            ov.next_due = tick + self.every

    # ------------------------------------------------------------------ contacts
    def world_contacts(self, wc: pb.WorldContacts) -> None:
        self._time(wc.header.tick, wc.header.sim_time)
        for c in wc.contacts:
            if c.kind == pb.CONTACT_KIND_HAND_ENVELOPE:
                continue  # not a place in space; human idle shows in the events
            kind = pb.ContactKind.Name(c.kind).removeprefix("CONTACT_KIND_").lower()
            name = "_".join(part(x) for x in (c.a, c.b, c.link) if x)
            ent = f"world/contacts/{kind}/{name}"
            if c.begin and finite(vec3_from_pb(c.point)):
                color = (255, 40, 40) if c.kind == pb.CONTACT_KIND_HAND_ROBOT else (255, 150, 0)
                self._log(
                    ent,
                    rr.Points3D(
                        [vec3_from_pb(c.point)],
                        radii=[0.025],
                        colors=[color],
                        labels=[f"{c.a}-{c.b}"],
                    ),
                )
            elif not c.begin:
                self._log(ent, CLEAR)

    # ------------------------------------------------------------------ cues
    def indicators(self, ind: pb.Indicators) -> None:
        self._time(ind.header.tick, ind.header.sim_time)
        for c in ind.cues:
            ent = cue_entity(c.id)
            if c.on:
                cv = self.cues[c.id] = CueView(pb.Cue())
                cv.cue.CopyFrom(c)
                self._show_cue(ent, cv)
                cv.visible = True
            else:
                self.cues.pop(c.id, None)
                self._log(ent, CLEAR)
        self._log(
            "status/cues",
            rr.TextDocument(
                "\n".join(f"- {cid}" for cid in sorted(self.cues)) or "(no cue active)"
            ),
        )

    def _show_cue(self, ent: str, cv: CueView) -> None:
        c = cv.cue
        ov = self.objects.get(c.part) if c.kind == pb.CUE_KIND_OUTLINE else None
        shown_for = ov.pose if ov is not None else ()
        if cv.shown is None or cv.shown_for != shown_for:
            rv = self.robots.get(c.robot)
            seen = (ov.size, ov.pose) if ov is not None and ov.pose else None
            cv.shown = cue_archetype(
                c,
                self.parts.get(c.part),
                seen,
                self.owner_color.get(c.robot, WHITE),
                rv.base if rv is not None else None,
                self.button,
            )
            cv.shown_for = shown_for
        self._log(ent, cv.shown)

    def tick(self, k: int, sim_time: float) -> None:
        """Blinks the flashing cues on the sim timeline (on for the first half of each period)."""
        self.clock = (k, sim_time)
        phase = math.floor(sim_time * self.s.flash_hz * 2.0)
        if phase == self._flash_phase:
            return
        self._flash_phase = phase
        on = phase % 2 == 0
        timed = False
        for cid, cv in self.cues.items():
            if not cv.cue.flashing or cv.visible == on:
                continue
            if not timed:
                self._time(k, sim_time)
                timed = True
            ent = cue_entity(cid)
            if on:
                self._show_cue(ent, cv)
            else:
                self._log(ent, CLEAR)
            cv.visible = on

    # ------------------------------------------------------------------ events
    def event(self, ev: pb.TaskEvent, line: str | None) -> None:
        self._time(ev.header.tick, ev.header.sim_time)
        name = kind_name(ev.kind)
        text = line or " ".join(
            x for x in (name, ev.agent, ev.robot, ev.part, ev.hand, ev.text) if x
        )
        level = (
            "WARN"
            if ev.kind
            in (
                pb.TASK_EVENT_KIND_COLLISION,
                pb.TASK_EVENT_KIND_NEAR_COLLISION,
                pb.TASK_EVENT_KIND_ROBOT_UNREACHABLE,
                pb.TASK_EVENT_KIND_PROTECTIVE_STOP,
            )
            else "INFO"
        )
        self._log("events", rr.TextLog(text, level=level))
        zone = self.zones.get(ev.robot)
        if zone is not None and zone.event(ev) and ev.robot in self.robots:
            self._log_zone(self.robots[ev.robot], zone)  # a stopped arm sends no new state

    # ------------------------------------------------------------------ end
    def close(self) -> None:
        """Logs the last states that the rate limit held back, and the held states once more at
        the last clock tick (states come on change), so every timeline reaches the end."""
        for rv in self.robots.values():
            for st in rv.states.closing(self.clock):
                self._log_robot(rv, st)
        for hs in self.human.closing(self.clock):
            self._log_human(hs)
        self.flush_series()
        self.rec.flush()
        self.rec.disconnect()  # closes the file sink (writes the rrd footer)
