"""The thesis board laid out for an arm (`hrc robot add --board`): both robots of a template
scenario (scenarios/thesis.toml by default) replaced by the arm, then its bases and waiting poses
moved, in small steps, until the project's own checks pass: the scenario checks and the motion
check, which plans every move of the task with the IK service's code (`hrc validate`).

The search, in order (the first layout without a problem is taken):
- the bases where the template has them, then moved back from the board 0.1 m at a time;
- for each base, every robot pose the motion check names (`robots.<id>.home`, `intermediate`,
  `retreat`, `feeder`) moved, one at a time, by the first of POSE_MOVES that clears that pose's
  problems without adding any elsewhere: up, then outward (away from the board's middle, as a
  UR must retreat beside its own axis), then back, then combinations.
The parts' positions, the task and everything else stay the template's.
"""

from __future__ import annotations

import copy
import math
import tomllib
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hrc.scenario import ScenarioError
from hrc.scenario.loader import loads
from hrc.tomlw import dumps

POSES = ("home", "intermediate", "retreat", "feeder")
BASE_BACK_M = (0.0, 0.1, 0.2, 0.3)
# (outward, back, up) in metres: outward = away from the board's middle along x, back = away
# from the board along the base's side (+y for the thesis's robots), up = +z
POSE_MOVES: tuple[tuple[float, float, float], ...] = (
    (0.0, 0.0, 0.1),
    (0.0, 0.0, 0.2),
    (0.1, 0.0, 0.0),
    (0.2, 0.0, 0.0),
    (0.0, 0.1, 0.0),
    (0.1, 0.0, 0.1),
    (0.2, 0.0, 0.1),
    (0.0, 0.1, 0.1),
    (0.1, 0.1, 0.1),
    (0.3, 0.0, 0.0),
    (0.2, 0.1, 0.2),
    (-0.1, 0.0, 0.1),
)


class BoardError(ValueError):
    """No layout passed: the message names what the last one still failed."""


@dataclass
class Layout:
    text: str  # the scenario, TOML
    changes: list[str] = field(default_factory=list)  # what moved, for a person
    tried: int = 0  # layouts checked


def _problems(raw: dict[str, Any], folder: Path, root: Path | None) -> list[Any]:
    try:
        loads(dumps(raw), folder, root, motion_check=True)
    except ScenarioError as exc:
        return list(exc.problems)
    return []


def _moved(
    xyz: Sequence[float], move: tuple[float, float, float], base_xy: Sequence[float]
) -> list[float]:
    out_x = math.copysign(1.0, base_xy[0]) if base_xy[0] else 1.0
    back_y = math.copysign(1.0, base_xy[1]) if base_xy[1] else 1.0
    return [
        round(xyz[0] + out_x * move[0], 4),
        round(xyz[1] + back_y * move[1], 4),
        round(xyz[2] + move[2], 4),
    ]


def layout(
    template: Path,
    robot: Mapping[str, Any],
    folder: Path,
    root: Path | None = None,
    name: str = "",
    written_urdf: str = "",
) -> Layout:
    """The template with each robot's description keys replaced by `robot` (urdf, base_link,
    tip_link, tcp, ...), laid out as the module says. `folder`: where the scenario will be
    written (its relative paths resolve there); `written_urdf`: the robot's `urdf` as the
    written scenario names it (beside it, say), the checks having used `robot`'s."""
    raw = tomllib.loads(template.read_text(encoding="utf-8"))
    for r in raw.get("robots", {}).values():
        for k in ("urdf", "base_link", "tip_link", "tcp", "gripper", "packages"):
            r.pop(k, None)
        r.update(copy.deepcopy(dict(robot)))
    if name:
        raw.setdefault("scenario", {})["name"] = name
    tried = 0
    last: list[Any] = []
    for back in BASE_BACK_M:
        cand = copy.deepcopy(raw)
        changes: list[str] = []
        for rid, r in cand["robots"].items():
            if back:
                bx, by = r["base"]["xyz"][:2]
                r["base"]["xyz"] = _moved(r["base"]["xyz"], (0.0, back, 0.0), (bx, by))
                changes.append(f"robots.{rid}.base moved back {back:.1f} m: {r['base']['xyz']}")
        problems = _problems(cand, folder, root)
        tried += 1
        for key in _pose_keys(problems):
            _, rid, pose = key.split(".")
            r = cand["robots"][rid]
            original = list(r[pose])
            before = Counter(p.key for p in problems)
            for move in POSE_MOVES:
                r[pose] = _moved(original, move, r["base"]["xyz"])
                trial = _problems(cand, folder, root)
                tried += 1
                now = Counter(p.key for p in trial)
                cleared = key not in now
                worse = any(now[k] > before.get(k, 0) for k in now)
                if cleared and not worse:
                    problems = trial
                    changes.append(f"robots.{rid}.{pose} moved: {original} -> {r[pose]}")
                    break
            else:
                r[pose] = original
        if not problems:
            if written_urdf:
                for r in cand["robots"].values():
                    r["urdf"] = written_urdf
            return Layout(dumps(cand), changes, tried)
        last = problems
    keys = Counter(p.key for p in last)
    raise BoardError(
        f"no layout of {template.name} passed the checks in {tried} tries; the last still "
        "failed: "
        + "; ".join(f"{k} ({n} moves)" for k, n in keys.items())
        + (f"; first: {last[0]}" if last else "")
    )


def _pose_keys(problems: Sequence[Any]) -> list[str]:
    seen: dict[str, None] = {}
    for p in problems:
        parts = p.key.split(".")
        if len(parts) == 3 and parts[0] == "robots" and parts[2] in POSES:
            seen[p.key] = None
    return list(seen)
