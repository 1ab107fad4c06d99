"""The rerun view of a trial: recording.rrd always, plus a live native or web viewer on request.

Timelines: ``tick`` (sequence) and ``sim_time`` (duration, seconds); every message is logged at
its own header's tick and sim time. Wall-clock timelines are off, so the same trial gives the
same recording content.

Entities:
- ``robot_<id>/...``: the robot from its URDF (rerun's URDF loader, ``rerun.urdf.UrdfTree``, with
  frame prefix ``<id>/``); ``robot_<id>/base`` places its root link in the world (static);
  ``robot_<id>/joints/<joint>`` holds each joint's transform (parent link -> child link, from our
  own FK, ``urdf_fk``), logged at most ``view_hz`` times per simulated second plus the last state.
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
import re
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Generic, TypeVar

import numpy as np
import numpy.typing as npt
import rerun as rr
from rerun.urdf import UrdfTree

from hrc.geometry import to_array, vec3_from_array, vec3_from_pb, yaw_quat_deg
from hrc.scenario import colors
from hrc.scenario.conventions import WAITING_HEIGHT_M, WAITING_TEXT
from hrc.scenario.convert import ssm_from_proto
from hrc.scenario.models import DEFAULT_TICK_HZ, HUMAN
from hrc.scenario.urdf import localized_urdf
from hrc.wire import pb

from hrc_logger.blueprint import blueprint
from hrc_logger.ssm_zone import Zone
from hrc_logger.textlog import kind_name
from hrc_logger.urdf_fk import (
    Joint,
    UrdfError,
    UrdfModel,
    matrix_to_quat_xyzw,
    point_polyline_distance,
    polyline_distances,
    yaw_transform,
)

log = logging.getLogger(__name__)

HEAD_RADIUS_M = 0.05
HAND_RADIUS_M = 0.03

ROOT_FRAME = "tf#/"  # rerun's implicit frame of the root entity: the world
# Colours come from the one table (hrc.scenario.colors); the participant's parts in their part
# colour, as physics and the participant's page draw them.
HUMAN_PART_RGB = colors.rgb(colors.HUMAN_PART_COLOR)
UNKNOWN_COLOR = colors.UNKNOWN_RGB
rgb = colors.rgb
_ENTITY_SAFE = re.compile(r"[^A-Za-z0-9_\-]")
CLEAR = rr.Clear(recursive=False)  # one archetype for every clear (building one costs ~0.2 ms)


def rgba(c: tuple[int, int, int], a: int) -> tuple[int, int, int, int]:
    return c[0], c[1], c[2], a


def srgb_to_linear(c: float) -> float:
    """An sRGB channel (0..1) as linear light."""
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def part(name: str) -> str:
    """One entity-path segment (ids are already [A-Za-z0-9_-], but cue ids carry ':')."""
    return _ENTITY_SAFE.sub("_", name) or "_"


def cue_entity(cue_id: str) -> str:
    return "world/cues/" + "/".join(part(p) for p in cue_id.split(":"))


def finite(values: Any) -> bool:
    return all(math.isfinite(x) for x in values)


@dataclass
class ViewSettings:
    view_hz: float = 30.0  # robot/hand/object updates per simulated second (logging cost)
    flash_hz: float = 2.0  # cue blinking: on for half of each 1/flash_hz period
    tick_hz: float = DEFAULT_TICK_HZ  # replaced by the scenario's / clock's rate when known
    # Time series (joint transforms, plots) are sent in columns, one call per entity, once this
    # many simulated seconds have gathered (None: at the end): a rerun log call per row was
    # most of the logger's CPU time.
    series_flush_s: float | None = None


S = TypeVar("S", pb.RobotState, pb.HumanState)


class StateStream(Generic[S]):
    """One robot's (or the hands') states for the view: at most one logged per ``every`` ticks;
    the last one held back is logged at the end, and, since states come on change, the last one
    seen is logged once more at the final clock tick so the timeline reaches it."""

    def __init__(self) -> None:
        self.next_due = 0
        self.pending: S | None = None  # held back by the rate limit
        self.last: S | None = None  # in force until the next one
        self.logged_tick = -1

    def offer(self, msg: S, every: int) -> bool:
        """Takes a new state; True if it is to be logged now."""
        self.last = msg
        tick = msg.header.tick
        if tick < self.next_due:
            self.pending = msg
            return False
        self.next_due = tick + every
        self.pending = None
        return True

    def logged(self, msg: S) -> None:
        self.logged_tick = msg.header.tick

    def closing(self, clock: tuple[int, float] | None) -> list[S]:
        """What is still to be logged at the end, in order."""
        out: list[S] = []
        if self.pending is not None:
            out.append(self.pending)
            self.logged_tick = self.pending.header.tick
            self.pending = None
        if clock is not None and self.last is not None and self.logged_tick < clock[0]:
            held = type(self.last)()
            held.CopyFrom(self.last)
            held.header.tick, held.header.sim_time = clock
            out.append(held)
        return out


@dataclass(frozen=True)
class PointRow:
    """One point of a point entity (the TCP, the head, a hand) at one time."""

    position: npt.NDArray[np.float64]
    radius: float
    color: tuple[int, int, int]
    label: str | None = None


@dataclass(frozen=True)
class JointEntity:
    """A movable joint's entity in a robot's joint series; ``index``: its position in the
    model's joint vector (``UrdfModel.joint_vector``)."""

    entity: str
    joint: Joint
    frames: tuple[str, str]  # (parent, child) frame of its transform
    index: int


@dataclass
class Series:
    """One entity's rows not yet sent, at (tick, sim time): scalars, a robot's joint transforms
    (``joints``: values are joint vectors, sent as one entity per movable joint), part poses
    (``pose``: values are (translation, xyzw)), points (``points``: values are PointRows) or a
    hand's distance to a robot (``chain``: values are (hand position, the robot's joint vector);
    ``polyline``: values are (hand position, points)), computed for the whole column when
    sent."""

    ticks: list[int] = field(default_factory=list)
    times: list[float] = field(default_factory=list)
    values: list[Any] = field(default_factory=list)  # see the class docstring
    joints: list[JointEntity] | None = None
    pose: bool = False  # a Transform3D without frames (a part's pose in the world)
    points: bool = False
    show_labels: bool | None = None  # points: whether the viewer shows their labels
    chain: tuple[UrdfModel, np.ndarray] | None = None  # (model, base) of the robot
    polyline: bool = False

    def send(self, rec: rr.RecordingStream, entity: str) -> None:
        if not self.ticks:
            return
        n = len(self.ticks)
        # nanoseconds rounded as set_time rounds a float duration
        nanos = np.round(np.asarray(self.times, dtype=np.float64) * 1e9).astype(np.int64)
        indexes = [
            rr.TimeColumn("tick", sequence=np.asarray(self.ticks, dtype=np.int64)),
            rr.TimeColumn("sim_time", duration=nanos.astype("timedelta64[ns]")),
        ]
        columns: Any
        if self.joints is not None:
            qs = np.asarray(self.values, dtype=np.float64)
            for je in self.joints:
                translations, quats = je.joint.local_columns(qs[:, je.index])
                columns = rr.Transform3D.columns(
                    translation=translations,
                    quaternion=quats,
                    parent_frame=[je.frames[0]] * n,
                    child_frame=[je.frames[1]] * n,
                )
                rr.send_columns(je.entity, indexes=indexes, columns=columns, recording=rec)
            self.ticks, self.times, self.values = [], [], []
            return
        if self.points:
            rows: list[PointRow] = self.values
            labels = [r.label or "" for r in rows] if rows[0].label is not None else None
            columns = rr.Points3D.columns(
                positions=np.asarray([r.position for r in rows], dtype=np.float32),
                radii=np.asarray([r.radius for r in rows], dtype=np.float32),
                colors=np.asarray([r.color for r in rows], dtype=np.uint8),
                labels=labels,
                show_labels=None if self.show_labels is None else [self.show_labels] * n,
            )
        elif self.chain is not None:
            model, base = self.chain
            hands = np.asarray([v[0] for v in self.values], dtype=np.float64)
            chains = model.chain_points_columns(np.asarray([v[1] for v in self.values]), base)
            columns = rr.Scalars.columns(scalars=polyline_distances(hands, chains))
        elif self.polyline:
            columns = rr.Scalars.columns(
                scalars=np.asarray([point_polyline_distance(p, pts) for p, pts in self.values])
            )
        elif self.pose:
            columns = rr.Transform3D.columns(
                translation=np.asarray([v[0] for v in self.values], dtype=np.float64),
                quaternion=np.asarray([v[1] for v in self.values], dtype=np.float64),
            )
        else:
            columns = rr.Scalars.columns(scalars=np.asarray(self.values, dtype=np.float64))
        rr.send_columns(entity, indexes=indexes, columns=columns, recording=rec)
        self.ticks, self.times, self.values = [], [], []


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


@dataclass
class CueView:
    cue: pb.Cue
    visible: bool = False
    # The archetype last shown and what it was built from (an outline: its part's pose): a
    # flashing cue is shown again every second, and building an archetype costs ~1 ms.
    shown: Any = None
    shown_for: tuple[float, ...] | None = None


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
        self.logged = 0  # rerun log calls (and rows sent in columns), for the service's summary
        self._now = (0, 0.0)  # the time set by _time
        self._time_sent = False  # rerun has been told _now (set_time before a log call)
        self._series: dict[str, Series] = {}
        self._series_since = 0.0  # sim time of the oldest unsent row
        self._pending_rows = 0

    # ------------------------------------------------------------------ helpers
    def _log(self, entity: str, *archetypes: Any, static: bool = False) -> None:
        if not (static or self._time_sent):
            self.rec.set_time("tick", sequence=self._now[0])
            self.rec.set_time("sim_time", duration=self._now[1])
            self._time_sent = True
        self.rec.log(entity, *archetypes, static=static)
        self.logged += 1

    def _time(self, tick: int, sim_time: float) -> None:
        """The time of what follows; rerun is told only before a log call (rows in columns
        carry their own times), as set_time costs more than most rows."""
        now = (int(tick), float(sim_time))
        if now != self._now:
            self._now = now
            self._time_sent = False

    def _row(self, entity: str, value: float) -> None:
        """A scalar's row at the current time, sent later in columns (flush_series)."""
        series = self._series.get(entity)
        if series is None:
            series = self._series[entity] = Series()
        self._append(series, value)

    def _joints_row(self, rv: RobotView, model: UrdfModel, qvec: np.ndarray) -> None:
        """A robot's joint positions at the current time; each movable joint's transforms are
        computed for a whole column at once when sent (Joint.local_columns)."""
        key = f"robot_{part(rv.rid)}/joints"
        series = self._series.get(key)
        if series is None:
            joints = [
                JointEntity(
                    f"{key}/{part(j.name)}", j, (f"{rv.rid}/{j.parent}", f"{rv.rid}/{j.child}"), i
                )
                for i, j in enumerate(model.joints)
                if j.kind != "fixed"
            ]
            series = self._series[key] = Series(joints=joints)
        assert series.joints is not None
        self._append(series, qvec, len(series.joints))

    def _distance_row(self, entity: str, rv: RobotView, hand: np.ndarray) -> None:
        """A hand's distance to a robot's link chain (segments through its link origins; the
        TCP without a URDF) at the current time, computed for a whole column when sent."""
        series = self._series.get(entity)
        if rv.model is not None and rv.qvec is not None:
            if series is None:
                series = self._series[entity] = Series(chain=(rv.model, rv.base))
            self._append(series, (hand, rv.qvec))
        elif rv.tcp is not None:
            if series is None:
                series = self._series[entity] = Series(polyline=True)
            self._append(series, (hand, rv.tcp[None, :]))

    def _chain(self, rv: RobotView) -> np.ndarray | None:
        """The robot's link origins at its last logged state (None without a URDF)."""
        if rv.chain is None and rv.model is not None and rv.qvec is not None:
            rv.chain = rv.model.chain_points_columns(rv.qvec[None, :], rv.base)[0]
        return rv.chain

    def _point(self, entity: str, row: PointRow, show_labels: bool | None = None) -> None:
        """A point entity's row (one point) at the current time, sent later in columns: a
        rerun log call per point was most of the logger's CPU after the plots went to columns."""
        series = self._series.get(entity)
        if series is None:
            series = self._series[entity] = Series(points=True, show_labels=show_labels)
        self._append(series, row)

    def _pose(self, entity: str, translation: Any, xyzw: Any) -> None:
        """A part's pose at the current time, sent later in columns."""
        series = self._series.get(entity)
        if series is None:
            series = self._series[entity] = Series(pose=True)
        self._append(series, (translation, xyzw))

    def _append(self, series: Series, value: Any, rows: int = 1) -> None:
        """``rows``: the entity rows this value makes (a robot's joint vector: one per joint)."""
        if not self._pending_rows:
            self._series_since = self._now[1]
        self._pending_rows += rows
        series.ticks.append(self._now[0])
        series.times.append(self._now[1])
        series.values.append(value)
        self.logged += rows
        every = self.s.series_flush_s
        if every is not None and self._now[1] - self._series_since >= every:
            self.flush_series()

    def flush_series(self) -> None:
        """Sends every gathered time-series row (one call per entity)."""
        for entity, series in self._series.items():
            series.send(self.rec, entity)
        self._pending_rows = 0

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
            shown = localized_urdf(Path(r.urdf_path), [Path(d) for d in r.package_dirs], None, tint)
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
            self._joints_row(rv, rv.model, rv.qvec)
        if rv.tcp is not None:
            self._point(f"world/tcp/{part(rv.rid)}", PointRow(rv.tcp, 0.01, rv.color))
        if math.isfinite(st.tcp_speed):
            self._row(f"plots/tcp_speed/{part(rv.rid)}", st.tcp_speed)
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
            self._point(
                "world/human/head",
                PointRow(np.array([h.x, h.y, h.z]), HEAD_RADIUS_M, (230, 190, 160)),
            )
        for hand, grip in (("left", hs.left_grip), ("right", hs.right_grip)):
            pos = self.hands.get(hand)
            if pos is None:
                continue
            g = min(1.0, max(0.0, grip if math.isfinite(grip) else 0.0))
            color = (int(240 - 90 * g), int(200 - 110 * g), int(170 - 110 * g))
            self._point(
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
            self._pose(ent, pos, quat)
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
            cv.shown, cv.shown_for = self._cue_archetype(c), shown_for
        self._log(ent, cv.shown)

    def _cue_archetype(self, c: pb.Cue) -> Any:
        """What shows the cue, from the cue, the scenario and (an outline) its part's pose."""
        color = rgb(c.color, self.owner_color.get(c.robot, (255, 255, 255)))
        pos = vec3_from_pb(c.position)
        given = any(abs(v) > 1e-12 for v in pos) and finite(pos)
        p = self.parts.get(c.part)
        if c.kind == pb.CUE_KIND_TARGET and p is not None:
            size = np.array([p.size.x, p.size.y, p.size.z]) * 1.15
            return rr.Boxes3D(
                half_sizes=[size / 2],
                centers=[vec3_from_pb(p.target.xyz)],
                quaternions=[yaw_quat_deg(p.target.yaw_deg)],
                colors=[rgba(color, 170)],
                fill_mode="solid",
                labels=[c.text or f"{c.part}"],
                show_labels=False,  # the part it is for carries the name
            )
        elif c.kind == pb.CUE_KIND_OUTLINE and (
            (c.part in self.objects and self.objects[c.part].pose)
            or (p is not None and p.start_given)
        ):
            ov = self.objects.get(c.part)
            if ov is not None and ov.pose:  # seen on world/objects
                size = np.array(ov.size)
                center, quat = np.array(ov.pose[:3]), np.array(ov.pose[3:])
            else:  # not seen on world/objects yet: where the scenario puts it
                assert p is not None
                size = np.array([p.size.x, p.size.y, p.size.z])
                center = to_array(vec3_from_pb(p.start.xyz))
                quat = to_array(yaw_quat_deg(p.start.yaw_deg))
            return rr.Boxes3D(
                half_sizes=[size * 1.3 / 2],
                centers=[center],
                quaternions=[quat],
                colors=[rgba(color, 255)],
                fill_mode="majorwireframe",
            )
        elif c.kind == pb.CUE_KIND_WAITING:
            rv = self.robots.get(c.robot)
            if not given and rv is not None:
                pos = vec3_from_array(rv.base[:3, 3] + np.array([0.0, 0.0, WAITING_HEIGHT_M]))
            return rr.Points3D(
                [pos],
                radii=[0.02],
                colors=[color],
                labels=[c.text or WAITING_TEXT],
                show_labels=True,
            )
        elif c.kind == pb.CUE_KIND_CONTINUE_BUTTON:
            where = pos if given else list(self.button)
            return rr.Points3D(
                [where],
                radii=[0.03],
                colors=[rgb(c.color, (255, 60, 60))],
                labels=[c.text or "Continue"],
                show_labels=True,
            )
        else:
            return rr.Points3D([pos], radii=[0.02], colors=[color], labels=[c.text or c.id])

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
