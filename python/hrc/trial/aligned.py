"""Whether a trial gave what one-tick exchanges give (docs/ARCHITECTURE.md, "Exchange step"):
the same events and cues at the same ticks, the same metrics and log lines, but for what the
exchange rules leave unaligned on purpose and the wall clock.

Left out (documented there as not aligned): the participant's idle time (a hand crossing the
workspace's edge inside an exchange is seen at its end: the idle events, the idle figure of
``HUMAN_FINISHED`` and of the metrics, the log lines that say it). A move refused as
unreachable ends the trial, and a part coming to rest after a missed placement is an object
event, which keeps its tick: neither is left out. Used by ``hrc bench aligned`` and the tests
that compare a trial with its one-tick twin.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

WALL_FIELDS = frozenset({"wall_time", "wall_s", "realtime_factor"})
IDLE_EVENTS = frozenset({"HUMAN_IDLE_BEGIN", "HUMAN_IDLE_END"})


@dataclass
class Difference:
    """Where a trial and its one-tick twin differ: ``where`` names the file and the record."""

    where: str
    got: Any
    want: Any

    def __str__(self) -> str:
        return f"{self.where}: {json.dumps(self.got)} != {json.dumps(self.want)}"


@dataclass
class Comparison:
    """What was compared (events and cues, metrics, log lines) and the differences found."""

    records: int
    differences: list[Difference] = field(default_factory=list)

    @property
    def aligned(self) -> bool:
        return not self.differences


def without_wall(obj: Any) -> Any:
    """``obj`` without its wall-clock fields (WALL_FIELDS) at any depth."""
    if isinstance(obj, dict):
        return {k: without_wall(v) for k, v in obj.items() if k not in WALL_FIELDS}
    if isinstance(obj, list):
        return [without_wall(v) for v in obj]
    return obj


def _without_idle_metrics(metrics: dict[str, Any]) -> dict[str, Any]:
    """The metrics but the participant's idle time (the robots' is aligned)."""
    human = {k: v for k, v in metrics.get("human", {}).items() if k != "idle_s"}
    return {**metrics, "human": human}


def records(folder: Path) -> list[dict[str, Any]]:
    """The trial's events.jsonl as compared: wall-clock fields and what is not aligned on
    purpose left out (the module's docstring); ``seq`` too, as it counts what was left out."""
    out = []
    for line in (folder / "events.jsonl").read_text().splitlines():
        r = without_wall(json.loads(line))
        kind = r.get("kind")
        if kind in IDLE_EVENTS:
            continue
        r.pop("seq", None)
        if kind == "HUMAN_FINISHED":  # its text and payload say the idle time
            r.pop("text", None)
            r.pop("payload", None)
        if r.get("type") == "metrics":
            r = _without_idle_metrics(r)
        out.append(r)
    return out


def flat(obj: Any, prefix: str = "") -> dict[str, Any]:
    """Nested dicts and lists as {".a.b[0]": value}."""
    if isinstance(obj, dict):
        return {k: v for key, val in obj.items() for k, v in flat(val, f"{prefix}.{key}").items()}
    if isinstance(obj, list):
        return {k: v for i, val in enumerate(obj) for k, v in flat(val, f"{prefix}[{i}]").items()}
    return {prefix: obj}


def _metrics(folder: Path) -> dict[str, Any]:
    metrics = without_wall(json.loads((folder / "metrics.json").read_text()))
    return flat(_without_idle_metrics(metrics))


def _log(folder: Path) -> list[tuple[int, str]]:
    """(line number, line) of the log's lines that are compared."""
    return [
        (n, line)
        for n, line in enumerate((folder / "log.txt").read_text().splitlines(), 1)
        if "idle" not in line.lower() and not line.endswith(" - TASK STARTED.")  # (its date)
    ]


def _sequence(
    file: str, item: str, got: list[tuple[int, Any]], want: list[tuple[int, Any]]
) -> list[Difference]:
    """Two numbered sequences of a file, item by item, then their lengths."""
    bad = [
        Difference(f"{file} {item} {n}", a, b)
        for (n, a), (_, b) in zip(got, want, strict=False)
        if a != b
    ]
    if len(got) != len(want):
        bad.append(Difference(f"{file} length", len(got), len(want)))
    return bad


def compare(got: Path, want: Path, limit: int = 5) -> Comparison:
    """Trial folder ``got`` against ``want`` (its one-tick twin): at most ``limit`` differences
    of each file."""
    ev_got, ev_want = (list(enumerate(records(f), 1)) for f in (got, want))
    found = _sequence("events.jsonl", "record", ev_got, ev_want)[:limit]
    m_got, m_want = _metrics(got), _metrics(want)
    keys = sorted(k for k in m_got.keys() | m_want.keys() if m_got.get(k) != m_want.get(k))
    found += [Difference(f"metrics.json {k}", m_got.get(k), m_want.get(k)) for k in keys[:limit]]
    found += _sequence("log.txt", "line", _log(got), _log(want))[:limit]
    return Comparison(len(ev_want), found)
