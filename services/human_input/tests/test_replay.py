"""The replay format: line-numbered errors, interpolation, record -> replay round trip."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from hrc.geometry import Pose, quat_norm, quat_yaw_rad, yaw_quat_rad
from hrc.participant.recording import (
    FORMAT,
    VERSION,
    Recorder,
    ReplayError,
    load_recording,
    parse_recording,
)
from hrc.participant.sample import Sample, interpolate, parse_sample

from hrc_human_input.replay import Replayer

HEADER = json.dumps({"format": FORMAT, "version": VERSION, "scenario": "x"})


def sample_json(t: float, x: float = 0.0, grip: float = 0.0) -> dict:
    pose = {"position": [x, -0.5, 0.1], "orientation": [0, 0, 0, 1]}
    return {
        "t": t,
        "head": pose,
        "left": pose,
        "right": pose,
        "left_grip": grip,
        "right_grip": grip,
    }


def lines(*objs: object) -> list[str]:
    return [o if isinstance(o, str) else json.dumps(o) for o in objs]


def test_good_file_parses() -> None:
    rec = parse_recording(lines(HEADER, sample_json(0.0), sample_json(0.1, 0.2, 1.0)))
    assert rec.header["scenario"] == "x"
    assert [s.t for s in rec.samples] == [0.0, 0.1]
    assert rec.samples[1].right.position == (0.2, -0.5, 0.1)
    assert rec.samples[1].right_grip == 1.0


def test_every_error_is_reported_with_its_line_number() -> None:
    bad_grip = sample_json(0.2)
    bad_grip["left_grip"] = 1.5
    bad_quat = sample_json(0.3)
    bad_quat["head"] = {"position": [0, 0, 0], "orientation": [0, 0, 0, 0]}
    missing = sample_json(0.4)
    del missing["right"]
    extra = sample_json(0.5)
    extra["speed"] = 3
    nan = sample_json(0.6)
    nan["left"] = {"position": [float("nan"), 0, 0], "orientation": [0, 0, 0, 1]}
    text = lines(
        HEADER,
        sample_json(0.0),
        "{not json",
        "",
        bad_grip,
        bad_quat,
        missing,
        extra,
        sample_json(0.1),
        nan,
        sample_json(0.7),
    )
    with pytest.raises(ReplayError) as err:
        parse_recording(text, "rec.jsonl")
    problems = err.value.problems
    print("\n".join(problems))
    joined = "\n".join(problems)
    assert "line 3: not valid JSON" in joined
    assert "line 5: left_grip must be a number in [0, 1], got 1.5" in joined
    assert "line 6: head.orientation has zero length" in joined
    assert "line 7: right is missing" in joined
    assert "line 8: unknown key 'speed'" in joined
    assert not any(p.startswith("line 9") or p.startswith("line 11") for p in problems)
    assert "line 10: left.position[0] must be a finite number" in joined
    assert len(problems) == 6
    assert "rec.jsonl" in str(err.value)


def test_time_must_increase_and_header_is_checked() -> None:
    with pytest.raises(ReplayError) as err:
        parse_recording(
            lines(
                {"format": "other", "version": 2},
                sample_json(0.5),
                sample_json(0.5),
                sample_json(0.2),
            )
        )
    joined = "\n".join(err.value.problems)
    assert "line 1: header format must be 'hrc-human-input'" in joined
    assert "line 1: header version must be 1, got 2" in joined
    assert "line 3: t = 0.5 is not after t = 0.5 of line 2" in joined
    assert "line 4: t = 0.2 is not after t = 0.5 of line 2" in joined


def test_empty_and_header_only_files(tmp_path: Path) -> None:
    with pytest.raises(ReplayError, match="empty"):
        parse_recording([])
    with pytest.raises(ReplayError, match="not followed by any sample"):
        parse_recording([HEADER])
    with pytest.raises(ReplayError, match="cannot read"):
        load_recording(tmp_path / "missing.jsonl")


def test_interpolation_lerps_positions_and_grips_and_slerps_orientations() -> None:
    a = Sample(1.0, Pose((0, 0, 0), yaw_quat_rad(0.0)), Pose((0, 0, 0)), Pose((0, 0, 0)), 0.0, 0.0)
    b = Sample(
        2.0, Pose((1, 2, 3), yaw_quat_rad(math.pi / 2)), Pose((1, 0, 0)), Pose((0, 1, 0)), 1.0, 0.5
    )
    m = interpolate(a, b, 1.25)
    assert m.head.position == pytest.approx((0.25, 0.5, 0.75))
    assert quat_yaw_rad(m.head.orientation) == pytest.approx(math.pi / 8)
    assert quat_norm(m.head.orientation) == pytest.approx(1.0)
    assert m.left_grip == pytest.approx(0.25) and m.right_grip == pytest.approx(0.125)
    rp = Replayer(parse_recording(lines(HEADER, a.to_json(), b.to_json())))
    assert rp.sample_at(1.5).right.position == pytest.approx((0, 0.5, 0))
    assert rp.sample_at(0.0).head.position == (0, 0, 0)  # before: first holds
    assert rp.sample_at(9.0).head.position == (1, 2, 3)  # after: last holds
    assert rp.sample_at(9.0).t == 9.0


def test_slerp_takes_the_short_way() -> None:
    a = Sample(0.0, Pose((0, 0, 0), yaw_quat_rad(math.radians(170))))
    b = Sample(1.0, Pose((0, 0, 0), tuple(-c for c in yaw_quat_rad(math.radians(-170)))))
    m = interpolate(a, b, 0.5)
    assert abs(math.degrees(quat_yaw_rad(m.head.orientation))) == pytest.approx(180.0, abs=1e-6)


def test_record_then_replay_is_bit_identical(tmp_path: Path) -> None:
    path = tmp_path / "rec.jsonl"
    samples = []
    for k in range(50):
        t = k / 240.0
        q = yaw_quat_rad(0.1 * k)
        samples.append(
            Sample(
                t,
                Pose((0.1 * k / 3, -0.5, 0.2), q),
                Pose((k / 7, 0.0, 0.1), q),
                Pose((0.3, k / 11, 0.1)),
                (k % 10) / 9,
                1.0 / 3.0,
            )
        )
    with Recorder(path, {"scenario": "demo", "seed": 3}) as rec:
        for s in samples:
            rec.write(s)
        rec.write(samples[10])  # time going backwards is never written
    loaded = load_recording(path)
    assert loaded.header["scenario"] == "demo" and loaded.header["version"] == VERSION
    assert loaded.samples == samples
    rp = Replayer(loaded)
    for s in samples:
        assert rp.sample_at(s.t) == s


def test_recorder_flushes_each_line(tmp_path: Path) -> None:
    path = tmp_path / "rec.jsonl"
    rec = Recorder(path)
    rec.write(Sample(0.0))
    assert len(path.read_text().splitlines()) == 2  # readable before close
    rec.close()


def test_parse_sample_without_time_for_the_bridge() -> None:
    obj = sample_json(0.0)
    del obj["t"]
    s, errs = parse_sample(obj, require_t=False)
    assert s is not None and not errs
    s, errs = parse_sample(obj, require_t=True)
    assert s is None and errs == ["t is missing"]
    s, errs = parse_sample([1, 2], require_t=False)
    assert s is None and "JSON object" in errs[0]
