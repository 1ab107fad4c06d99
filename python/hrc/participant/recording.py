"""The participant's recording (docs/replay-format.md): a header line, then one hand sample a
line. Read with every problem named by its line, written flushed line by line. `hrc fit` reads
it; human_input records and replays it."""

from __future__ import annotations

import datetime as dt
import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from hrc.participant.sample import Sample, parse_sample

log = logging.getLogger(__name__)

FORMAT = "hrc-human-input"
VERSION = 1


class ReplayError(ValueError):
    """A recording that cannot be played; ``problems`` lists every one, each naming its line."""

    def __init__(self, path: str, problems: list[str]) -> None:
        self.path = path
        self.problems = problems
        shown = "\n".join(f"  {p}" for p in problems[:200])
        more = f"\n  ... and {len(problems) - 200} more" if len(problems) > 200 else ""
        super().__init__(f"replay file {path}: {len(problems)} problem(s):\n{shown}{more}")


@dataclass
class Recording:
    header: dict[str, Any]
    samples: list[Sample] = field(default_factory=list)


def parse_recording(lines: list[str], path: str = "<recording>") -> Recording:
    """Checks every line; raises ReplayError with all problems, each as ``line N: ...``."""
    problems: list[str] = []
    header: dict[str, Any] = {}
    samples: list[Sample] = []
    numbered = [(i + 1, ln) for i, ln in enumerate(lines) if ln.strip()]
    if not numbered:
        raise ReplayError(path, ["the file is empty (expected a header line, then samples)"])
    first_no, first = numbered[0]
    try:
        obj = json.loads(first)
    except json.JSONDecodeError as exc:
        problems.append(
            f"line {first_no}: header is not valid JSON: {exc.msg} (column {exc.colno})"
        )
    else:
        if not isinstance(obj, dict):
            problems.append(f"line {first_no}: header must be a JSON object")
        else:
            header = obj
            if obj.get("format") != FORMAT:
                problems.append(
                    f"line {first_no}: header format must be {FORMAT!r}, got {obj.get('format')!r}"
                )
            if obj.get("version") != VERSION:
                problems.append(
                    f"line {first_no}: header version must be {VERSION}, got {obj.get('version')!r}"
                )
    last_t: float | None = None
    last_no = 0
    for no, text in numbered[1:]:
        try:
            obj = json.loads(text)
        except json.JSONDecodeError as exc:
            problems.append(f"line {no}: not valid JSON: {exc.msg} (column {exc.colno})")
            continue
        sample, errs = parse_sample(obj, require_t=True)
        problems.extend(f"line {no}: {e}" for e in errs)
        if sample is None:
            continue
        if last_t is not None and sample.t <= last_t:
            problems.append(
                f"line {no}: t = {sample.t:g} is not after t = {last_t:g} of line "
                f"{last_no} (times must increase)"
            )
            continue
        last_t, last_no = sample.t, no
        samples.append(sample)
    if not problems and not samples:
        problems.append(f"line {first_no}: the header is not followed by any sample")
    if problems:
        raise ReplayError(path, problems)
    return Recording(header, samples)


def load_recording(path: str | Path) -> Recording:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ReplayError(str(p), [f"cannot read the file: {exc.strerror or exc}"]) from exc
    except UnicodeDecodeError as exc:
        raise ReplayError(str(p), [f"the file is not UTF-8 text: {exc}"]) from exc
    return parse_recording(text.splitlines(), str(p))


class Recorder:
    """Writes a header and then one sample per line, flushed, so a crash keeps what was written."""

    def __init__(self, path: str | Path, metadata: dict[str, Any] | None = None) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file: IO[str] | None = open(self.path, "w", encoding="utf-8")
        self._last_t: float | None = None
        self.count = 0
        header = {
            "format": FORMAT,
            "version": VERSION,
            "created": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        }
        header.update(metadata or {})
        self._write(header)

    def _write(self, obj: dict[str, Any]) -> None:
        assert self._file is not None, "recorder is closed"
        # json writes floats with repr(): they read back bit-identical.
        self._file.write(json.dumps(obj, separators=(",", ":"), allow_nan=False) + "\n")
        self._file.flush()

    def write(self, sample: Sample) -> None:
        if self._last_t is not None and sample.t <= self._last_t:
            log.warning("not recording a sample at t = %g: not after %g", sample.t, self._last_t)
            return
        self._write(sample.to_json())
        self._last_t = sample.t
        self.count += 1

    def close(self) -> None:
        if self._file is not None:
            file, self._file = self._file, None
            try:
                file.close()
            except OSError as exc:  # a write already failed (and ended the run): say, go on
                log.warning("closing the recording %s: %s", self.path, exc)

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
