"""Checks that relate the tables of a scenario to each other.

`check_references` works on the raw TOML data and reads it defensively, so it still runs (and
reports) when some tables have schema errors; values of the wrong type are skipped here because
the schema check already reported them. So is every other check here: one broken table never hides
the problems of the others.
"""

from __future__ import annotations

import itertools
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from hrc.scenario import urdf
from hrc.scenario.enums import InputSource, RobotRole, SafetyPolicy
from hrc.scenario.errors import Problem
from hrc.scenario.graph import Edge, find_cycles
from hrc.scenario.models import DEFAULT_BASE_LINK, DEFAULT_TIP_LINK, HUMAN
from hrc.scenario.paths import installed_root, resolve_dir, resolve_path, resolve_urdf


def part_key(index: int, raw_part: Any) -> str:
    """Parts are named by id in problem keys; by position only when the id is unusable."""
    if isinstance(raw_part, dict) and isinstance(raw_part.get("id"), str) and raw_part["id"]:
        return f"parts.{raw_part['id']}"
    return f"parts[{index}]"


def _names(items: Iterable[str]) -> str:
    return ", ".join(items) if items else "(none)"


# ---------------------------------------------------------------- ids, owners, sequences, graph


def check_references(raw: dict[str, Any]) -> list[Problem]:
    problems: list[Problem] = []
    raw_robots: dict[str, Any] = r if isinstance(r := raw.get("robots"), dict) else {}
    roles: dict[str, RobotRole | None] = {}
    for rid, rrobot in raw_robots.items():
        roles[rid] = RobotRole.parse(rrobot.get("role")) if isinstance(rrobot, dict) else None
        if rid == HUMAN:
            problems.append(
                Problem(
                    "robots.human",
                    "'human' is reserved for the participant; give the robot another id",
                )
            )
    agents = [HUMAN, *[r for r in raw_robots if r != HUMAN]]

    raw_parts: list[Any] = r if isinstance(r := raw.get("parts"), list) else []
    # id -> (key, owner or None, after list); the first part with an id wins for references
    parts: dict[str, tuple[str, str | None, list[str]]] = {}
    seen_at: dict[str, int] = {}
    for i, rpart in enumerate(raw_parts):
        if not isinstance(rpart, dict):
            continue
        key = part_key(i, rpart)
        pid = rpart.get("id") if isinstance(rpart.get("id"), str) else None
        owner = rpart.get("owner") if isinstance(rpart.get("owner"), str) else None
        after_raw = rpart.get("after", [])
        after = [a for a in after_raw if isinstance(a, str)] if isinstance(after_raw, list) else []
        if pid is not None:
            if pid in seen_at:
                problems.append(
                    Problem(
                        key,
                        f"duplicate part id {pid!r}: parts #{seen_at[pid] + 1} "
                        f"and #{i + 1} both use it",
                    )
                )
                continue
            seen_at[pid] = i
            parts[pid] = (key, owner, after)
        # owner
        if owner is not None and owner != HUMAN and owner not in roles:
            problems.append(
                Problem(
                    f"{key}.owner",
                    f"unknown owner {owner!r}: use 'human' or a robot id ({_names(list(roles))})",
                )
            )
        # start: required for human and transport parts, none for screws (they come from the feeder)
        owner_role = roles.get(owner) if owner is not None else None
        has_start = "start" in rpart
        if owner == HUMAN or owner_role == RobotRole.TRANSPORT:
            if not has_start:
                problems.append(
                    Problem(
                        f"{key}.start",
                        f"missing required key: a part owned by {owner} needs a start pose",
                    )
                )
        elif owner_role == RobotRole.SCREWING and has_start:
            problems.append(
                Problem(
                    f"{key}.start",
                    f"a part of screwing robot {owner} has no "
                    "start pose (it comes from the robot's feeder); remove it",
                )
            )

    # after: known ids, not itself, no repeats
    for pid, (key, _owner, after) in parts.items():
        seen: set[str] = set()
        for dep in after:
            if dep == pid:
                problems.append(
                    Problem(
                        f"{key}.after", f"{pid} waits for itself (dependency cycle of one part)"
                    )
                )
            elif dep not in parts:
                problems.append(Problem(f"{key}.after", f"unknown part {dep!r}"))
            elif dep in seen:
                problems.append(Problem(f"{key}.after", f"{dep} is listed twice"))
            seen.add(dep)

    # sequences: known agents, known parts, each part once, in its owner's sequence
    raw_seq: dict[str, Any] = r if isinstance(r := raw.get("sequence"), dict) else {}
    listed_by: dict[str, list[str]] = {}
    clean_seq: dict[str, list[str]] = {}
    for agent, entries in raw_seq.items():
        skey = f"sequence.{agent}"
        if agent not in agents:
            problems.append(
                Problem(
                    skey,
                    f"unknown agent {agent!r}: use 'human' or a robot id ({_names(list(roles))})",
                )
            )
            continue
        if not isinstance(entries, list):
            continue
        order: list[str] = []
        for entry in entries:
            if not isinstance(entry, str):
                continue
            if entry not in parts:
                problems.append(Problem(skey, f"unknown part {entry!r}"))
                continue
            if entry in order:
                problems.append(Problem(skey, f"{entry} is listed twice"))
                continue
            order.append(entry)
            listed_by.setdefault(entry, []).append(agent)
        clean_seq[agent] = order

    for pid, (key, owner, _after) in parts.items():
        if owner is None or (owner != HUMAN and owner not in roles):
            continue  # owner problem already reported
        listers = listed_by.get(pid, [])
        for agent in listers:
            if agent == owner:
                continue
            if len(listers) > 1:
                msg = (
                    f"{pid} is in two sequences ({_names(listers)}); it belongs to {owner}, "
                    f"so only sequence.{owner} may list it"
                )
            else:
                msg = f"{pid} belongs to {owner}; only sequence.{owner} may list it"
            problems.append(Problem(f"sequence.{agent}", msg))
        if owner not in listers:
            problems.append(
                Problem(
                    key,
                    f"{pid} is owned by {owner} but not in sequence.{owner}: "
                    "it would never be done (add it there or remove the part)",
                )
            )

    problems.extend(_deadlocks(list(parts), parts, clean_seq))
    return problems


def _deadlocks(
    order: list[str],
    parts: dict[str, tuple[str, str | None, list[str]]],
    sequences: dict[str, list[str]],
) -> list[Problem]:
    edges: list[Edge] = []
    for pid, (_key, _owner, after) in parts.items():
        for dep in dict.fromkeys(after):
            if dep in parts and dep != pid:
                edges.append(Edge(dep, pid, "after"))
    for agent, seq in sequences.items():
        for a, b in itertools.pairwise(seq):
            edges.append(Edge(a, b, agent))
    problems: list[Problem] = []
    for cycle in find_cycles(order, edges):
        steps = []
        for e in cycle:
            why = f"{e.dst}.after" if e.via == "after" else f"sequence.{e.via}"
            steps.append(f"{e.src} before {e.dst} ({why})")
        names = _names([e.src for e in cycle])
        only_after = all(e.via == "after" for e in cycle)
        what = "dependency cycle" if only_after else "deadlock through sequence order and after"
        first_after = next(e for e in cycle if e.via == "after")
        key = parts[first_after.dst][0] + ".after"
        problems.append(
            Problem(key, f"{what}: {'; '.join(steps)}; so none of {names} can ever be done")
        )
    return problems


# ---------------------------------------------------------------- per-table rules (raw, defensive)


def _table(value: Any) -> dict[str, Any]:
    return value if isinstance(value, dict) else {}


def _vec3(value: Any) -> list[float] | None:
    if (
        isinstance(value, list)
        and len(value) == 3
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
    ):
        return [float(v) for v in value]
    return None


def check_robots(raw: dict[str, Any]) -> list[Problem]:
    """Keys that depend on a robot's role."""
    problems: list[Problem] = []
    for rid, robot in _table(raw.get("robots")).items():
        robot = _table(robot)
        role = RobotRole.parse(robot.get("role"))
        key = f"robots.{rid}"
        if role == RobotRole.SCREWING and "feeder" not in robot:
            problems.append(
                Problem(
                    f"{key}.feeder",
                    "missing required key: a screwing robot "
                    "takes its screws from a feeder position",
                )
            )
        if role == RobotRole.TRANSPORT:
            for name in ("feeder", "screw_time_s"):
                if name in robot:
                    problems.append(
                        Problem(
                            f"{key}.{name}",
                            f"only screwing robots have {name}; {rid} is a transport robot",
                        )
                    )
    return problems


def check_workspace(raw: dict[str, Any]) -> list[Problem]:
    problems: list[Problem] = []
    workspace = _table(raw.get("workspace"))
    envelope = workspace.get("envelope")
    for i, box in enumerate(envelope if isinstance(envelope, list) else []):
        lo, hi = _vec3(_table(box).get("min")), _vec3(_table(box).get("max"))
        if lo is None or hi is None:
            continue  # the schema check reports it
        bad = [
            f"{axis}: {a:g} >= {b:g}" for axis, a, b in zip("xyz", lo, hi, strict=True) if a >= b
        ]
        if bad:
            problems.append(
                Problem(
                    f"workspace.envelope[{i}]",
                    f"min must be below max on every axis ({', '.join(bad)})",
                )
            )
    policy = SafetyPolicy.parse(_table(raw.get("conditions")).get("safety_policy"))
    if (
        policy == SafetyPolicy.RETREAT_BUTTON
        and "workspace" in raw
        and "continue_button" not in workspace
    ):
        problems.append(
            Problem(
                "workspace.continue_button",
                "missing required key: safety_policy = 'retreat_button' needs a continue button",
            )
        )
    return problems


def check_files(raw: dict[str, Any], folder: Path | None, root: Path | None) -> list[Problem]:
    """URDFs and the replay file must exist (file's folder first, then the project root)."""

    def missing(written: str) -> str:
        bases = [str(b) for b in (folder, root, installed_root()) if b is not None]
        if Path(written).is_absolute() or not bases:
            return f"file not found: {written}"
        return f"file not found: {written} (looked in {' and '.join(dict.fromkeys(bases))})"

    problems: list[Problem] = []
    for rid, robot in _table(raw.get("robots")).items():
        problems += _check_robot_files(rid, _table(robot), folder, root, missing)
    participant = _table(raw.get("participant"))
    if InputSource.parse(participant.get("input")) == InputSource.REPLAY:
        replay = participant.get("replay_file")
        if replay is None:
            problems.append(
                Problem(
                    "participant.replay_file",
                    "missing required key: input = 'replay' needs a replay_file",
                )
            )
        elif isinstance(replay, str) and resolve_path(replay, folder, root) is None:
            problems.append(Problem("participant.replay_file", missing(replay)))
    return problems


def _check_robot_files(
    rid: str,
    robot: dict[str, Any],
    folder: Path | None,
    root: Path | None,
    missing: Callable[[str], str],
) -> list[Problem]:
    """The robot's URDF, its `packages` folders, its chain and the meshes it names."""
    key = f"robots.{rid}"
    problems: list[Problem] = []
    packages: list[Path] = []
    written_packages = robot.get("packages")
    for i, d in enumerate(written_packages if isinstance(written_packages, list) else []):
        found = resolve_dir(d, folder, root) if isinstance(d, str) and d else None
        if isinstance(d, str) and d and found is None:
            problems.append(Problem(f"{key}.packages[{i}]", f"no such folder: {d}"))
        elif found is not None:
            packages.append(found)
    written = robot.get("urdf")
    if not isinstance(written, str) or not written:
        return problems  # the schema check names it
    path = resolve_urdf(written, folder, root, packages)
    if path is None:
        package = written.startswith(urdf.PACKAGE)
        why = _not_found(written, None, packages) if package else missing(written)
        return [*problems, Problem(f"{key}.urdf", why)]
    try:
        info = urdf.read_urdf(path)
    except urdf.UrdfError as exc:
        return [*problems, Problem(f"{key}.urdf", str(exc))]
    links = {}
    before = len(problems)
    for name, default in (("base_link", DEFAULT_BASE_LINK), ("tip_link", DEFAULT_TIP_LINK)):
        value = robot.get(name, default)
        if not isinstance(value, str):
            return problems  # the schema check names it
        links[name] = value
        if value not in info.links:
            problems.append(
                Problem(
                    f"{key}.{name}",
                    f"{path.name} has no link named {value!r}"
                    + ("" if name in robot else f" (the default {name})")
                    + f"; its links: {', '.join(info.links)}",
                )
            )
    if len(problems) > before:
        return problems  # no chain to speak of
    joints = info.chain(links["base_link"], links["tip_link"])
    if joints is None:
        problems.append(
            Problem(
                f"{key}.tip_link",
                f"{links['tip_link']!r} is not below {links['base_link']!r} in {path.name}: "
                f"no chain of joints leads from one to the other; links below "
                f"{links['base_link']!r}: {', '.join(info.below(links['base_link'])) or '(none)'}",
            )
        )
    elif not any(j.kind in urdf.MOVABLE for j in joints):
        problems.append(
            Problem(
                f"{key}.tip_link",
                f"the chain {links['base_link']} -> {links['tip_link']} in {path.name} has no "
                "movable joint",
            )
        )
    else:
        odd = [f"{j.name} ({j.kind})" for j in joints if j.kind not in (*urdf.MOVABLE, "fixed")]
        if odd:
            problems.append(
                Problem(
                    f"{key}.tip_link",
                    f"the chain has joints a serial arm cannot have: {', '.join(odd)}",
                )
            )
    problems += _check_gripper(key, robot.get("gripper"), info, joints or [])
    problems += _check_gripper_urdf(key, robot, path, folder, root, packages, missing)
    lost = urdf.missing_meshes(info, packages)
    if lost:  # all of them at once: a description is fixed in one go, not one run per mesh
        first = _not_found(lost[0], path.parent, packages)
        more = (
            f"; {len(lost) - 1} more of its {len(info.meshes)} meshes not found: "
            + ", ".join(lost[1:])
            if len(lost) > 1
            else ""
        )
        problems.append(Problem(f"{key}.urdf", f"{path.name}: mesh {first}{more}"))
    return problems


def _check_gripper_urdf(
    key: str,
    robot: dict[str, Any],
    arm: Path,
    folder: Path | None,
    root: Path | None,
    packages: list[Path],
    missing: Callable[[str], str],
) -> list[Problem]:
    """An attached gripper (`gripper_urdf`): its description found and read, its meshes there,
    and attachable (one tree, no link or joint named like the arm's)."""
    written = robot.get("gripper_urdf")
    tip = robot.get("tip_link", DEFAULT_TIP_LINK)
    if not isinstance(written, str) or not written or not isinstance(tip, str):
        return []  # none, or the schema check names it
    wanted = "robots/gripper.urdf" if written == urdf.GENERIC_GRIPPER else written
    path = resolve_urdf(wanted, folder, root, packages)
    gkey = f"{key}.gripper_urdf"
    if path is None:
        package = wanted.startswith(urdf.PACKAGE)
        return [Problem(gkey, _not_found(wanted, None, packages) if package else missing(wanted))]
    try:
        info = urdf.read_urdf(path)
        lost = urdf.missing_meshes(info, packages)
        if lost:
            return [
                Problem(gkey, f"{path.name}: mesh {_not_found(lost[0], path.parent, packages)}")
            ]
        urdf.with_gripper(arm, tip, path, packages)
    except (urdf.UrdfError, ET.ParseError, OSError) as exc:
        return [Problem(gkey, str(exc))]
    return []


def _not_found(written: str, folder: Path | None, packages: list[Path]) -> str:
    tried = [str(c) for c in urdf.candidates(written, folder, packages)]
    hint = ""
    if written.startswith(urdf.PACKAGE):
        name, _, rest = written[len(urdf.PACKAGE) :].partition("/")
        holding = [d / name for d in packages if (d / name).is_dir()]
        hint = (
            f"; {holding[0]} is in packages but has no {rest}"
            if holding
            else f"; add the folder that holds {name}/ to packages"
        )
    elif written.startswith(urdf.FILE) or Path(written).is_absolute():
        hint = "; an absolute path of the machine it was made on: make it package:// or relative"
    return f"{written} not found (tried {', '.join(tried) or 'nothing'}){hint}"


def _check_gripper(
    key: str, gripper: Any, info: urdf.UrdfInfo, chain: list[urdf.UrdfJoint]
) -> list[Problem]:
    """The fingers are movable joints of the URDF outside the chain, open and closed within
    their limits."""
    if not isinstance(gripper, dict) or not isinstance(gripper.get("joints"), list):
        return []  # none, or the schema check names it
    problems: list[Problem] = []
    by_name = {j.name: j for j in info.joints}
    in_chain = {j.name for j in chain}
    movable = [j.name for j in info.joints if j.kind in urdf.LIMITED]
    for name in gripper["joints"]:
        joint = by_name.get(name) if isinstance(name, str) else None
        if joint is None or joint.kind not in urdf.LIMITED:
            problems.append(
                Problem(
                    f"{key}.gripper.joints",
                    f"{info.path.name} has no revolute or prismatic joint named {name!r}; "
                    f"its movable joints: {', '.join(movable) or '(none)'}",
                )
            )
        elif name in in_chain:
            problems.append(
                Problem(f"{key}.gripper.joints", f"{name!r} is a joint of the arm's chain")
            )
        else:
            for end in ("open", "closed"):
                v = gripper.get(end)
                lo, hi = joint.lower, joint.upper
                known = isinstance(v, int | float) and lo is not None and hi is not None
                if known and not lo - 1e-9 <= v <= hi + 1e-9:  # type: ignore[operator]
                    problems.append(
                        Problem(
                            f"{key}.gripper.{end}",
                            f"{v} is outside {name}'s limits [{lo}, {hi}]",
                        )
                    )
    return problems
