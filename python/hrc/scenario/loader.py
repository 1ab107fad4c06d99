"""Load a scenario file and check all of it: `load` and `validate`."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from hrc.scenario.checks import (
    check_files,
    check_references,
    check_robots,
    check_workspace,
    part_key,
)
from hrc.scenario.errors import Problem, ScenarioError
from hrc.scenario.models import Part, Robot, Scenario
from hrc.scenario.paths import find_project_root, resolve_path
from hrc.scenario.reach import PybulletReachChecker, ReachChecker, reach_items


class _Default:
    """Marker: "use the standard reach checker" (None means: skip the reach check)."""


DEFAULT_REACH = _Default()


def load(
    path: str | Path,
    project_root: Path | None = None,
    *,
    reach_checker: ReachChecker | None | _Default = DEFAULT_REACH,
) -> Scenario:
    """Parse, build and check a scenario file; raise ScenarioError listing every problem.

    Relative paths resolve against the file's folder, then `project_root` (default: $HRC_ROOT,
    else the nearest folder above the file that holds `scenarios/`). The reach check uses
    `PybulletReachChecker` unless another checker is given; `reach_checker=None` skips it.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError([Problem("file", f"cannot read: {exc.strerror or exc}")], path) from exc
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError([Problem("toml", f"not valid TOML: {exc}")], path) from exc

    folder = path.resolve().parent
    root = project_root.resolve() if project_root is not None else find_project_root(folder)
    problems = _check_raw(raw, folder, root, reach_checker)
    if problems:
        raise ScenarioError(problems, path)
    scenario = Scenario.model_validate(raw)
    scenario._source_path = path.resolve()
    scenario._source_text = text
    scenario._project_root = root
    return scenario


def loads(
    text: str,
    folder: Path | None = None,
    project_root: Path | None = None,
    *,
    reach_checker: ReachChecker | None = None,
) -> Scenario:
    """Like `load`, from text (tests, tools); relative paths resolve against `folder`, then root.
    No reach check unless a checker is given."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError([Problem("toml", f"not valid TOML: {exc}")]) from exc
    problems = _check_raw(raw, folder, project_root, reach_checker)
    if problems:
        raise ScenarioError(problems)
    scenario = Scenario.model_validate(raw)
    scenario._source_text = text
    scenario._project_root = project_root
    return scenario


def validate(
    scenario: Scenario,
    reach_checker: ReachChecker | None | _Default = None,
) -> list[Problem]:
    """Every problem of an already built scenario (e.g. one changed in code, or received over the
    bus). `reach_checker=None` (default) skips the reach check; pass `DEFAULT_REACH` or a checker."""
    raw = scenario.model_dump(mode="python", exclude_none=True)
    folder = scenario.source_path.parent if scenario.source_path else None
    return _check_raw(raw, folder, scenario.project_root, reach_checker)


# ---------------------------------------------------------------- internals


def _check_raw(
    raw: dict[str, Any],
    folder: Path | None,
    root: Path | None,
    reach_checker: ReachChecker | None | _Default,
) -> list[Problem]:
    problems: list[Problem] = []
    try:
        Scenario.model_validate(raw)
    except ValidationError as exc:
        problems.extend(_schema_problems(exc, raw))

    problems.extend(check_references(raw))
    problems.extend(check_robots(raw))
    problems.extend(check_workspace(raw))
    problems.extend(check_files(raw, folder, root))

    # The reach check needs typed robots and parts: it takes every one that builds on its own,
    # so a schema error elsewhere does not hide an unreachable target.
    robots = _robots(raw)
    if reach_checker is not None and robots:
        checker = PybulletReachChecker() if isinstance(reach_checker, _Default) else reach_checker
        try:
            problems.extend(_check_reach(robots, _parts(raw), checker, folder, root))
        finally:
            if isinstance(reach_checker, _Default):
                checker.close()  # type: ignore[union-attr]
    return _dedupe(problems)


def _check_reach(
    robots: dict[str, Robot],
    parts: list[Part],
    checker: ReachChecker,
    folder: Path | None,
    root: Path | None,
) -> list[Problem]:
    problems: list[Problem] = []
    for rid, robot in robots.items():
        urdf = resolve_path(robot.urdf, folder, root)
        if urdf is None:
            continue  # already reported by check_files
        items = reach_items(robot, parts)
        for result in checker.check(robot, urdf, items):
            if result.reachable:
                continue
            item = result.item
            where = "[" + ", ".join(f"{v:.3f}" for v in item.position) + "]"
            note = f" ({item.note})" if item.note else ""
            problems.append(Problem(item.key, f"robot {rid} cannot reach {where}{note} with the "
                                    f"tool pointing down: {result.detail}"))
    return problems


def _build(model: type[BaseModel], value: Any) -> Any:
    if value is None:
        return None
    try:
        return model.model_validate(value)
    except ValidationError:
        return None  # reported by the schema check


def _robots(raw: dict[str, Any]) -> dict[str, Robot]:
    out: dict[str, Robot] = {}
    raw_robots = raw.get("robots")
    if not isinstance(raw_robots, dict):
        return out
    for rid, value in raw_robots.items():
        robot = _build(Robot, value)
        if robot is not None:
            robot._id = rid
            out[rid] = robot
    return out


def _parts(raw: dict[str, Any]) -> list[Part]:
    raw_parts = raw.get("parts")
    if not isinstance(raw_parts, list):
        return []
    built = [_build(Part, value) for value in raw_parts]
    return [p for p in built if p is not None]


_MESSAGES = {
    "missing": "missing required key",
    "extra_forbidden": "unknown key",
}


def _schema_problems(exc: ValidationError, raw: dict[str, Any]) -> list[Problem]:
    problems: list[Problem] = []
    for err in exc.errors(include_url=False):
        loc = list(err["loc"])
        key = _loc_key(loc, raw)
        kind = err["type"]
        if kind in _MESSAGES:
            message = _MESSAGES[kind]
        elif kind == "string_pattern_mismatch":
            chars = ("'_', '-' and '.'" if "." in str(err.get("ctx", {}).get("pattern", ""))
                     else "'_' and '-'")
            message = (f"{err['input']!r} is not allowed here: use letters, digits, {chars}, "
                       "starting with a letter or digit")
        else:
            message = err["msg"].removeprefix("Value error, ")
            message = message.replace("Input should be", "should be")
            if kind not in ("value_error",) and "input" in err:
                message += f" (got {_show(err['input'])})"
        if loc and loc[-1] == "[key]":
            message = f"invalid id: {message}"
        problems.append(Problem(key, message))
    return problems


def _loc_key(loc: list[Any], raw: dict[str, Any]) -> str:
    out = ""
    node: Any = raw
    for i, part in enumerate(loc):
        if part == "[key]":
            break
        if isinstance(part, int):
            if i == 1 and loc[0] == "parts":
                out = part_key(part, node[part] if isinstance(node, list) and part < len(node)
                               else None)
            else:
                out += f"[{part}]"
        else:
            out = f"{out}.{part}" if out else str(part)
        try:
            node = node[part]
        except (KeyError, IndexError, TypeError):
            node = None
    return out


def _show(value: Any) -> str:
    text = repr(value)
    if isinstance(value, dict):
        text = "a table"
    elif isinstance(value, list) and len(text) > 40:
        text = f"a list of {len(value)}"
    return text if len(text) <= 60 else text[:57] + "..."


def _dedupe(problems: list[Problem]) -> list[Problem]:
    return list(dict.fromkeys(problems))
