"""What the rerun view logs when: the rate limit of robot and hand states (StateStream), and the
time series gathered and sent in columns, one call per entity (Series, SeriesBatch): a rerun log
call per row was most of the logger's CPU time."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import numpy as np
import numpy.typing as npt
import rerun as rr

from hrc.urdf_fk import (
    Joint,
    UrdfModel,
    point_polyline_distance,
    polyline_distances,
)
from hrc.wire import pb

from hrc_logger.entities import part

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


class SeriesBatch:
    """Every series' rows not yet sent, at the time ``now`` (set by the view); sent together
    once ``flush_s`` simulated seconds have gathered (None: only when flushed)."""

    def __init__(self, rec: rr.RecordingStream, flush_s: float | None) -> None:
        self.rec = rec
        self.flush_s = flush_s
        self.now = (0, 0.0)
        self.rows = 0  # entity rows gathered so far (sent or not), for the service's summary
        self._series: dict[str, Series] = {}
        self._since = 0.0  # sim time of the oldest unsent row
        self._pending = 0

    def row(self, entity: str, value: float) -> None:
        """A scalar's row."""
        self._append(self._get(entity, Series), value)

    def joints(self, key: str, rid: str, model: UrdfModel, qvec: np.ndarray) -> None:
        """A robot's joint positions; each movable joint's transforms are computed for a whole
        column at once when sent (Joint.local_columns)."""
        series = self._series.get(key)
        if series is None:
            joints = [
                JointEntity(
                    f"{key}/{part(j.name)}", j, (f"{rid}/{j.parent}", f"{rid}/{j.child}"), i
                )
                for i, j in enumerate(model.joints)
                if j.kind != "fixed"
            ]
            series = self._series[key] = Series(joints=joints)
        assert series.joints is not None
        self._append(series, qvec, len(series.joints))

    def chain_distance(
        self, entity: str, model: UrdfModel, base: np.ndarray, qvec: np.ndarray, hand: np.ndarray
    ) -> None:
        """A hand's distance to a robot's link chain (segments through its link origins),
        computed for a whole column when sent."""
        self._append(self._get(entity, lambda: Series(chain=(model, base))), (hand, qvec))

    def polyline_distance(self, entity: str, points: np.ndarray, hand: np.ndarray) -> None:
        """A hand's distance to a polyline (a robot's TCP without a URDF)."""
        self._append(self._get(entity, lambda: Series(polyline=True)), (hand, points))

    def point(self, entity: str, row: PointRow, show_labels: bool | None = None) -> None:
        """A point entity's row (one point): a rerun log call per point was most of the
        logger's CPU after the plots went to columns."""
        self._append(self._get(entity, lambda: Series(points=True, show_labels=show_labels)), row)

    def pose(self, entity: str, translation: Any, xyzw: Any) -> None:
        """A part's pose."""
        self._append(self._get(entity, lambda: Series(pose=True)), (translation, xyzw))

    def flush(self) -> None:
        """Sends every gathered row (one call per entity)."""
        for entity, series in self._series.items():
            series.send(self.rec, entity)
        self._pending = 0

    def _get(self, entity: str, make: Callable[[], Series]) -> Series:
        series = self._series.get(entity)
        if series is None:
            series = self._series[entity] = make()
        return series

    def _append(self, series: Series, value: Any, rows: int = 1) -> None:
        """``rows``: the entity rows this value makes (a robot's joint vector: one per joint)."""
        if not self._pending:
            self._since = self.now[1]
        self._pending += rows
        series.ticks.append(self.now[0])
        series.times.append(self.now[1])
        series.values.append(value)
        self.rows += rows
        if self.flush_s is not None and self.now[1] - self._since >= self.flush_s:
            self.flush()
