"""Where the test command's time goes: every test's time from the JUnit XML files that
scripts/test-all.sh writes (build/test-logs/pytest-*.xml), summed by test file.

    .venv/bin/python scripts/slow_tests.py [--top N] [XML ...]

Prints, per phase (one XML file each), its tests' total time (in the parallel phase the sum
of both workers' time, about twice its wall time) and the files that take most of it, with
their share and their slowest test. A test's time is its setup, call and teardown.
"""

from __future__ import annotations

import argparse
import sys
import xml.etree.ElementTree as ET
from collections import defaultdict
from datetime import datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LOGS = ROOT / "build" / "test-logs"


class Unreadable(Exception):
    """A file that is not JUnit XML."""


def by_file(xml: Path) -> dict[str, list[tuple[float, str]]]:
    """Test file -> [(seconds, test name)] from one JUnit XML file."""
    out: dict[str, list[tuple[float, str]]] = defaultdict(list)
    try:
        root = ET.parse(xml).getroot()
    except ET.ParseError as exc:
        raise Unreadable(f"{xml}: not XML ({exc})") from None
    for case in root.iter("testcase"):
        # classname: the dotted module path (tests.test_fuzz), then a class if any
        out[source_file(case.get("classname", "?"))].append(
            (float(case.get("time", "0")), case.get("name", "?"))
        )
    return out


def source_file(classname: str) -> str:
    parts = classname.split(".")
    for n in range(len(parts), 0, -1):
        path = "/".join(parts[:n]) + ".py"
        if (ROOT / path).is_file():
            return path
    return classname


def report(xml: Path, top: int) -> str:
    files = by_file(xml)
    total = sum(t for cases in files.values() for t, _ in cases)
    written = datetime.fromtimestamp(xml.stat().st_mtime).strftime("%Y-%m-%d %H:%M")
    count = sum(map(len, files.values()))
    lines = [f"{xml.name} (written {written}): {count} tests, {total:.0f} s in all"]
    ranked = sorted(files.items(), key=lambda kv: -sum(t for t, _ in kv[1]))
    for name, cases in ranked[:top]:
        spent = sum(t for t, _ in cases)
        slowest = max(cases)
        lines.append(
            f"  {spent:7.1f} s {spent / total if total else 0:6.1%}  {len(cases):3d} tests  {name}"
            f"  (slowest {slowest[0]:.1f} s: {slowest[1]})"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "xml", nargs="*", type=Path, help="JUnit XML files (default: the last run's)"
    )
    parser.add_argument("--top", type=int, default=25, help="files shown per phase (default 25)")
    args = parser.parse_args(argv)
    paths = args.xml or sorted(LOGS.glob("pytest*.xml"))
    if not paths:
        print(f"no JUnit XML in {LOGS}: run scripts/test-all.sh first", file=sys.stderr)
        return 1
    for path in paths:
        if not path.is_file():
            print(f"{path}: no such file", file=sys.stderr)
            return 1
        try:
            print(report(path, args.top))
        except Unreadable as exc:
            print(exc, file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
