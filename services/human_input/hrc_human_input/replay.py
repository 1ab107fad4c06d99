"""The replay format (docs/replay-format.md): reading with line-numbered errors, playing back on
simulation time, and recording whatever a source relayed."""

from __future__ import annotations

import bisect
import datetime as dt
import itertools
import json
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from hrc.geometry import Quat, distance, quat_norm
from hrc.scenario.conventions import HAND_RADIUS_M, HANDS

from hrc_human_input.sample import Sample, interpolate, parse_sample

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


def _turn_rad(a: Quat, b: Quat) -> float:
    """The angle between two orientations (pi if one is degenerate)."""
    na, nb = quat_norm(a), quat_norm(b)
    if na <= 0 or nb <= 0:
        return math.pi
    dot = abs(sum(x * y for x, y in zip(a, b, strict=True))) / (na * nb)
    return 2.0 * math.acos(min(1.0, dot))


class Replayer:
    """Plays a recording on simulation time: the sample at t, interpolated between neighbours;
    before the first sample the first one holds, after the last the last one holds."""

    def __init__(self, recording: Recording) -> None:
        if not recording.samples:
            raise ValueError("a recording without samples cannot be played")
        self.samples = recording.samples
        self._times = [s.t for s in self.samples]

    @property
    def duration(self) -> float:
        return self._times[-1]

    def grip_crossing_after(self, t: float, threshold: float) -> float | None:
        """The first time after ``t`` a grip crosses ``threshold`` as played (grips are
        interpolated linearly between samples); None if none does."""
        i = max(0, bisect.bisect_right(self._times, t) - 1)
        for a, b in itertools.pairwise(self.samples[i:]):
            for ga, gb in ((a.left_grip, b.left_grip), (a.right_grip, b.right_grip)):
                if (ga < threshold) != (gb < threshold):
                    u = (threshold - ga) / (gb - ga)
                    at = a.t + u * (b.t - a.t)
                    if at > t:
                        return at
        return None

    def hand_speed_bound(self) -> float:
        """m/s no point of a hand exceeds in this recording: between two samples a hand moves
        and turns at a constant rate (interpolate), a point at most |v| + w * HAND_RADIUS_M."""
        bound = 0.0
        for a, b in itertools.pairwise(self.samples):
            span = b.t - a.t
            if span <= 0:
                continue
            for name in HANDS:
                pa, pb_ = a.hand(name), b.hand(name)
                turn = _turn_rad(pa.orientation, pb_.orientation)
                move = distance(pa.position, pb_.position) + turn * HAND_RADIUS_M
                bound = max(bound, move / span)
        return bound

    def sample_at(self, t: float) -> Sample:
        i = bisect.bisect_left(self._times, t)
        if i < len(self._times) and self._times[i] == t:
            return self.samples[i]  # exact hit: bit-identical to what was recorded
        if i == 0:
            return self.samples[0].at(t)
        if i >= len(self._times):
            return self.samples[-1].at(t)
        return interpolate(self.samples[i - 1], self.samples[i], t)


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
