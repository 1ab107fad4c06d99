"""Load a scenario file and check all of it: `load` and `validate`."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from hrc.scenario.checks import (
    check_files,
    check_references,
    check_robots,
    check_workspace,
    part_key,
)
from hrc.scenario.errors import Problem, ScenarioError
from hrc.scenario.models import Scenario
from hrc.scenario.motion_check import check_motion
from hrc.scenario.paths import find_project_root


def load(
    path: str | Path,
    project_root: Path | None = None,
    *,
    motion_check: bool = True,
) -> Scenario:
    """Parse, build and check a scenario file; raise ScenarioError listing every problem.

    Relative paths resolve against the file's folder, then `project_root` (default: $HRC_ROOT,
    else the nearest folder above the file that holds `scenarios/`). The motion check plans every
    robot move with the IK service's code (`hrc.scenario.motion_check`); `motion_check=False`
    skips it.
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
    problems = _check_raw(raw, folder, root)
    if problems:
        raise ScenarioError(problems, path)
    scenario = Scenario.model_validate(raw)
    scenario._source_path = path.resolve()
    scenario._source_text = text
    scenario._project_root = root
    if motion_check:
        problems = check_motion(scenario)
        if problems:
            raise ScenarioError(problems, path)
    return scenario


def loads(
    text: str,
    folder: Path | None = None,
    project_root: Path | None = None,
    *,
    motion_check: bool = False,
) -> Scenario:
    """Like `load`, from text (tests, tools); relative paths resolve against `folder`, then root.
    No motion check unless asked."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError([Problem("toml", f"not valid TOML: {exc}")]) from exc
    problems = _check_raw(raw, folder, project_root)
    if problems:
        raise ScenarioError(problems)
    scenario = Scenario.model_validate(raw)
    scenario._source_text = text
    scenario._project_root = project_root
    if motion_check:
        problems = check_motion(scenario)
        if problems:
            raise ScenarioError(problems)
    return scenario


def validate(scenario: Scenario, motion_check: bool = False) -> list[Problem]:
    """Every problem of an already built scenario (e.g. one changed in code, or received over the
    bus). The motion check runs only when asked, and only on a scenario without other problems."""
    raw = scenario.model_dump(mode="python", exclude_none=True)
    folder = scenario.source_path.parent if scenario.source_path else None
    problems = _check_raw(raw, folder, scenario.project_root)
    if motion_check and not problems:
        problems = check_motion(scenario)
    return problems


# ---------------------------------------------------------------- internals


def _check_raw(raw: dict[str, Any], folder: Path | None, root: Path | None) -> list[Problem]:
    problems: list[Problem] = []
    try:
        Scenario.model_validate(raw)
    except ValidationError as exc:
        problems.extend(_schema_problems(exc, raw))

    problems.extend(check_references(raw))
    problems.extend(check_robots(raw))
    problems.extend(check_workspace(raw))
    problems.extend(check_files(raw, folder, root))
    # The motion check needs the whole scenario built: it runs after these pass (load, validate).
    return _dedupe(problems)


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
            chars = (
                "'_', '-' and '.'"
                if "." in str(err.get("ctx", {}).get("pattern", ""))
                else "'_' and '-'"
            )
            message = (
                f"{err['input']!r} is not allowed here: use letters, digits, {chars}, "
                "starting with a letter or digit"
            )
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
                out = part_key(
                    part, node[part] if isinstance(node, list) and part < len(node) else None
                )
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
