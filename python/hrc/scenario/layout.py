"""The static furniture of a scenario, derived from its poses (pure data): physics builds its
world from it and the participant client draws it (hrc_human_input's scene).

Conventions (docs/scenario.md, docs/ARCHITECTURE.md "Task conventions"):
- the board's top surface is z = 0; the board is flush with the table top around it, so parts
  that start in front of the board (the participant's parts) also rest at z = size / 2;
- each robot whose parts have start poses gets a picking table under them (their footprints plus
  a margin), its top at the lowest part bottom;
- each robot with a feeder gets a feeder pedestal whose top is where a screw spawned at the
  feeder point (the screw's centre) rests, and a low wall on the participant's side (-y);
- a floor 0.75 m below the board catches anything dropped off the tables.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hrc.geometry import Vec3
from hrc.scenario.colors import (
    BOARD_RGBA,
    FEEDER_RGBA,
    FEEDER_WALL_RGBA,
    PICKING_TABLE_RGBA,
    TABLE_RGBA,
    TARGET_MARKER_RGBA,
)
from hrc.scenario.models import HUMAN, Scenario

BOARD_SIZE: Vec3 = (0.60, 0.40, 0.02)
TABLE_THICKNESS = 0.04
TABLE_MARGIN = 0.08  # around the board and the participant's parts
PICKING_MARGIN = 0.05
FEEDER_HALF = 0.04  # pedestal 8 x 8 cm
FEEDER_WALL_HEIGHT = 0.03  # above the feeder surface
FEEDER_WALL_GAP = 0.05  # from the feeder point towards the participant
FLOOR_Z = -0.75
DEFAULT_SCREW_HEIGHT = 0.02
BUTTON_RADIUS = 0.04
BUTTON_HEIGHT = 0.02


@dataclass(frozen=True)
class StaticBox:
    """A fixed box: ``collides`` boxes carry parts, the others are markers (visual only)."""

    name: str
    center: Vec3
    half: Vec3
    yaw_deg: float = 0.0
    collides: bool = True
    rgba: tuple[float, float, float, float] = (0.6, 0.5, 0.4, 1.0)


def _footprint(xy: tuple[float, float], size: list[float], yaw_deg: float) -> tuple[float, ...]:
    """Axis-aligned xy bounds (x0, y0, x1, y1) of a box of ``size`` turned by ``yaw_deg``."""
    c, s = abs(math.cos(math.radians(yaw_deg))), abs(math.sin(math.radians(yaw_deg)))
    hx = 0.5 * (size[0] * c + size[1] * s)
    hy = 0.5 * (size[0] * s + size[1] * c)
    return (xy[0] - hx, xy[1] - hy, xy[0] + hx, xy[1] + hy)


def _union(bounds: list[tuple[float, ...]]) -> tuple[float, float, float, float]:
    return (
        min(b[0] for b in bounds),
        min(b[1] for b in bounds),
        max(b[2] for b in bounds),
        max(b[3] for b in bounds),
    )


def _slab(
    name: str,
    bounds: tuple[float, ...],
    top: float,
    margin: float,
    rgba: tuple[float, float, float, float],
) -> StaticBox:
    x0, y0, x1, y1 = bounds[0] - margin, bounds[1] - margin, bounds[2] + margin, bounds[3] + margin
    return StaticBox(
        name,
        (0.5 * (x0 + x1), 0.5 * (y0 + y1), top - 0.5 * TABLE_THICKNESS),
        (0.5 * (x1 - x0), 0.5 * (y1 - y0), 0.5 * TABLE_THICKNESS),
        rgba=rgba,
    )


def furniture(scenario: Scenario) -> list[StaticBox]:
    """Board, table, picking tables, feeders with their walls, target markers."""
    boxes: list[StaticBox] = []
    bx, by, bz = BOARD_SIZE
    board = (-bx / 2, -by / 2, bx / 2, by / 2)
    boxes.append(StaticBox("board", (0.0, 0.0, -bz / 2), (bx / 2, by / 2, bz / 2), rgba=BOARD_RGBA))
    # The table carries the board and the participant's parts.
    human = [
        _footprint((p.start.xyz[0], p.start.xyz[1]), p.size, p.start.yaw)
        for p in scenario.parts
        if p.owner == HUMAN and p.start is not None
    ]
    boxes.append(_slab("table", _union([board, *human]), 0.0, TABLE_MARGIN, TABLE_RGBA))

    for rid, robot in scenario.robots.items():
        own = [(p, p.start) for p in scenario.parts if p.owner == rid and p.start is not None]
        if own:
            bounds = _union(
                [_footprint((s.xyz[0], s.xyz[1]), p.size, s.yaw) for p, s in own if s is not None]
            )
            top = min(s.xyz[2] - p.size[2] / 2 for p, s in own if s is not None)
            boxes.append(
                _slab(f"{rid}_picking_table", bounds, top, PICKING_MARGIN, PICKING_TABLE_RGBA)
            )
        if robot.feeder is not None:
            fx, fy, fz = robot.feeder
            heights = [p.size[2] for p in scenario.parts if p.owner == rid and p.start is None]
            top = fz - 0.5 * (max(heights) if heights else DEFAULT_SCREW_HEIGHT)
            bottom = min(-TABLE_THICKNESS, top - TABLE_THICKNESS)
            boxes.append(
                StaticBox(
                    f"{rid}_feeder",
                    (fx, fy, 0.5 * (top + bottom)),
                    (FEEDER_HALF, FEEDER_HALF, 0.5 * (top - bottom)),
                    rgba=FEEDER_RGBA,
                )
            )
            wall_top = top + FEEDER_WALL_HEIGHT
            boxes.append(
                StaticBox(
                    f"{rid}_feeder_wall",
                    (fx, fy - FEEDER_WALL_GAP, 0.5 * (wall_top + bottom)),
                    (1.5 * FEEDER_HALF, 0.005, 0.5 * (wall_top - bottom)),
                    rgba=FEEDER_WALL_RGBA,
                )
            )

    for p in scenario.parts:
        t = p.target
        boxes.append(
            StaticBox(
                f"target:{p.id}",
                (t.xyz[0], t.xyz[1], t.xyz[2]),
                (p.size[0] / 2, p.size[1] / 2, p.size[2] / 2),
                t.yaw,
                collides=False,
                rgba=TARGET_MARKER_RGBA,
            )
        )
    return boxes
