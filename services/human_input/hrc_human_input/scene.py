"""The `scene` a participant client draws (docs/client-protocol.md), built once from the wire
scenario: furniture from :mod:`hrc.scenario.layout`, colours from :mod:`hrc.scenario.colors`,
cue ids from :mod:`hrc.scenario.conventions` — the same facts physics and the task use.

Also which files the bridge may serve under ``/robots/``: the scenario's URDFs and the mesh
files next to them, nothing else.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hrc import scenario as sc
from hrc.scenario import urdf
from hrc.scenario.colors import HUMAN_COLOR, hex_color, part_color, rgba_hex
from hrc.scenario.conventions import (
    CONTINUE_BUTTON_CUE,
    WAITING_HEIGHT_M,
    WAITING_TEXT,
    outline_cue_id,
    target_cue_id,
    waiting_cue_id,
)
from hrc.scenario.layout import BOARD_SIZE, FLOOR_Z, furniture
from hrc.ssm import ZONE_ALPHA, ZONE_COLORS
from hrc.wire import pb

PROTOCOL_VERSION = 1
DEFAULT_FRAME_RATE_HZ = 90.0
# Files a URDF may reference (meshes, their textures) that the bridge serves from its folder.
MESH_SUFFIXES = (".stl", ".dae", ".obj", ".mtl", ".glb", ".gltf", ".bin", ".png", ".jpg", ".jpeg")
URDF_URL_PREFIX = "/robots/"


def r4(x: float) -> float:
    """Positions, quaternions and joints go out with 4 decimals (0.1 mm, 0.1 mrad): the
    display needs no more, and it halves the frames."""
    return round(float(x), 4)


def v3(xs: Any) -> list[float]:
    return [r4(x) for x in xs]


def joint_names(path: Path) -> list[str]:
    """The movable joints of a URDF in file order (the order of ``RobotState.joint_names`` for
    the shipped arms; frames reorder by name anyway)."""
    try:
        info = urdf.read_urdf(path)
    except urdf.UrdfError:
        return []
    return [j.name for j in info.joints if j.kind in urdf.MOVABLE and j.name]


@dataclass
class RobotFiles:
    """What ``GET /robots/<name>`` may return: name -> file."""

    urdfs: dict[str, Path] = field(default_factory=dict)
    folders: list[Path] = field(default_factory=list)
    # package://NAME/x is asked for as NAME/x: served when it resolves (around a URDF or in a
    # robot's packages folders) to a mesh one of the URDFs names
    packages: list[Path] = field(default_factory=list)
    meshes: set[Path] = field(default_factory=set)

    def add(self, rid: str, path: Path, packages: Sequence[Path] = ()) -> str:
        """Registers a robot's URDF (and the meshes it names); returns its URL."""
        for d in packages:
            if d not in self.packages:
                self.packages.append(d)
        try:
            info = urdf.read_urdf(path)
            for m in info.meshes:
                found = urdf.resolve(m, path.parent, packages)
                if found is not None:
                    self.meshes.add(found)
        except urdf.UrdfError:
            pass  # the URDF itself then fails to load in the page, which says so
        for name, known in self.urdfs.items():
            if known == path:
                return URDF_URL_PREFIX + name
        name = path.name if path.name not in self.urdfs else f"{rid}-{path.name}"
        self.urdfs[name] = path
        if path.parent not in self.folders:
            self.folders.append(path.parent)
        return URDF_URL_PREFIX + name

    def lookup(self, rel: str) -> Path | None:
        """The file for ``/robots/<rel>``: a URDF of the scenario, or a mesh file inside one of
        their folders (``package://pkg/meshes/x.stl`` is asked for as ``pkg/meshes/x.stl`` or
        ``meshes/x.stl``). None for anything else, and for any path leaving those folders."""
        if rel in self.urdfs:
            return self.urdfs[rel]
        if "\\" in rel or "\x00" in rel or not rel.lower().endswith(MESH_SUFFIXES):
            return None
        for folder in self.folders:
            base = folder.resolve()
            parts = [p for p in rel.split("/") if p]
            if any(p in (".", "..") for p in parts):
                return None
            for skip in (0, 1):  # with and without a package name in front
                cand = base.joinpath(*parts[skip:]).resolve() if parts[skip:] else None
                if cand is not None and cand.is_relative_to(base) and cand.is_file():
                    return cand
        for folder in self.folders:
            found = urdf.resolve(urdf.PACKAGE + rel, folder, self.packages)
            if found is not None and found in self.meshes:
                return found
        return None


def _box(center: Any, half: Any) -> dict[str, Any]:
    return {"center": v3(center), "size": v3(2 * h for h in half)}


def build_scene(msg: pb.Scenario, files: RobotFiles) -> dict[str, Any]:
    """The `scene` message (without per-client fields)."""
    s = sc.from_proto(msg)
    robot_colors = {rid: r.color_or_default for rid, r in s.robots.items()}
    boxes = furniture(s)
    board = next(b for b in boxes if b.name == "board")
    tables: list[dict[str, Any]] = []
    for b in boxes:
        if b.name == "board" or not b.collides:
            continue
        tid = "human" if b.name == "table" else b.name.removesuffix("_picking_table")
        tables.append({"id": tid, **_box(b.center, b.half), "color": rgba_hex(b.rgba)})
    parts = []
    for p in s.parts:
        parts.append(
            {
                "id": p.id,
                "owner": p.owner,
                "kind": p.kind,
                "size": v3(p.size),
                "color": hex_color(part_color(p.owner, robot_colors)),
                "start": None
                if p.start is None
                else {"xyz": v3(p.start.xyz), "yaw_deg": r4(p.start.yaw)},
                "target": {"xyz": v3(p.target.xyz), "yaw_deg": r4(p.target.yaw)},
                "after": list(p.after),
            }
        )
    robots = []
    for rid, r in s.robots.items():
        urdf_file = s.urdf_path(rid) or Path(r.urdf)
        robots.append(
            {
                "id": rid,
                "role": r.role.value,
                "color": hex_color(robot_colors[rid]),
                "urdf_url": files.add(rid, urdf_file, [Path(d) for d in r.packages]),
                "tint": r.tint,
                "base": {"xyz": v3(r.base.xyz), "yaw_deg": r4(r.base.yaw)},
                "joint_names": joint_names(urdf_file),
                "home": v3(r.home),
                "feeder": None if r.feeder is None else v3(r.feeder),
            }
        )
    button = s.workspace.continue_button
    scene: dict[str, Any] = {
        "type": "scene",
        "protocol": PROTOCOL_VERSION,
        "scenario": s.scenario.name,
        "tick_hz": s.scenario.tick_hz,
        "participant": s.participant.name,
        "anticipation": s.conditions.anticipation,
        "safety_policy": s.conditions.safety_policy.value,
        "board": {
            "size": v3(BOARD_SIZE),
            "center": v3(board.center),
            "color": rgba_hex(board.rgba),
        },
        "tables": tables,
        "floor_z": FLOOR_Z,
        "parts": parts,
        "robots": robots,
        "envelope": [{"min": v3(b.min), "max": v3(b.max)} for b in s.workspace.envelope],
        "continue_button": None if button is None else v3(button),
        "hand_color": hex_color(HUMAN_COLOR),
        "cues": scene_cues(s, robot_colors),
        "frame_rate_hz": DEFAULT_FRAME_RATE_HZ,
    }
    if s.conditions.safety_policy == sc.SafetyPolicy.SSM:
        scene["ssm_zone"] = ssm_zone_style()
    return scene


def ssm_zone_style() -> dict[str, Any]:
    """How the page draws the protective zones: the logger view's colours and opacity."""
    return {
        "colors": {state: "#{:02x}{:02x}{:02x}".format(*c) for state, c in ZONE_COLORS.items()},
        "opacity": r4(ZONE_ALPHA / 255),
    }


def scene_cues(s: sc.Scenario, robot_colors: dict[str, str]) -> list[dict[str, Any]]:
    """Every cue the task may light, with its colour and place (the orchestrator's rules:
    docs/task-semantics.md); frames then carry only which are on."""
    human = hex_color(HUMAN_COLOR)
    cues: list[dict[str, Any]] = []
    for p in s.parts:
        color = human if p.owner == sc.HUMAN else hex_color(robot_colors.get(p.owner, ""))
        cues.append(
            _cue(
                target_cue_id(p.id),
                "target",
                p.id,
                "" if p.owner == sc.HUMAN else p.owner,
                color,
                p.target.xyz,
            )
        )
        if p.owner == sc.HUMAN and p.start is not None:
            cues.append(_cue(outline_cue_id(p.id), "outline", p.id, "", human, p.start.xyz))
    for rid, r in s.robots.items():
        above = [r.base.xyz[0], r.base.xyz[1], r.base.xyz[2] + WAITING_HEIGHT_M]
        cues.append(
            _cue(
                waiting_cue_id(rid),
                "waiting",
                "",
                rid,
                hex_color(robot_colors[rid]),
                above,
                WAITING_TEXT,
            )
        )
    button = s.workspace.continue_button
    if button is not None:
        cues.append(_cue(CONTINUE_BUTTON_CUE, "button", "", "", hex_color("red"), button))
    return cues


def scene_cue_json(cue: dict[str, Any]) -> str:
    """A cue definition as frames compare it (compact JSON)."""
    return json.dumps(cue, separators=(",", ":"))


def _cue(
    cid: str, kind: str, part: str, robot: str, color: str, pos: Any, text: str = ""
) -> dict[str, Any]:
    return {
        "id": cid,
        "kind": kind,
        "part": part,
        "robot": robot,
        "color": color,
        "position": v3(pos),
        "text": text,
    }


CUE_KINDS = {
    pb.CUE_KIND_OUTLINE: "outline",
    pb.CUE_KIND_TARGET: "target",
    pb.CUE_KIND_WAITING: "waiting",
    pb.CUE_KIND_CONTINUE_BUTTON: "button",
}


def cue_def(cue: pb.Cue) -> dict[str, Any]:
    """A cue as the orchestrator sent it, in the scene's form (frames carry a cue's definition
    when it differs from the scene's: e.g. an outline follows its part)."""
    return _cue(
        cue.id,
        CUE_KINDS.get(cue.kind, "other"),
        cue.part,
        cue.robot,
        hex_color(cue.color, (255, 60, 60)) if cue.color else hex_color("red"),
        [cue.position.x, cue.position.y, cue.position.z],
        cue.text,
    )
