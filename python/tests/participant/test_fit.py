"""hrc fit's measuring: moves found in a sampled hand path are the model's moves (their whole
time and path, though their slow ends fall under the onset speed), and bad input is named."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hrc.participant.fit import FitError, fit_measures, measure_trial, segment_moves
from hrc.participant.hand import Hand, Move
from hrc.participant.motor import MotorParams


def _sampled(moves: list[Move], motor: MotorParams, hz: float = 240.0) -> tuple:
    hand = Hand("right", (0.0, 0.0, 0.1), 0.0, motor, np.random.default_rng(2))
    hand.do(*moves)
    ts, pos, t = [], [], 0.0
    hand.advance(t)
    while hand.busy or t < 0.2:
        ts.append(t)
        pos.append(hand.pos)
        t += 1.0 / hz
        hand.advance(t)
    for _ in range(48):  # still for a while at the end
        ts.append(t)
        pos.append(hand.pos)
        t += 1.0 / hz
    return np.array(ts), np.array(pos, dtype=float), hand.segments


def test_moves_are_found_whole_under_the_onset_threshold() -> None:
    motor = MotorParams(fitts_a_s=0.2, fitts_b_s=0.1, peak_hand_speed=3.0)
    plan = [Move((0.3, 0.0, 0.1), None, 0.06), Move((0.3, 0.2, 0.1), None, 0.02)]
    ts, pos, segments = _sampled(plan, motor)
    found = segment_moves(ts, pos)
    assert len(found) == len(segments) == 2
    for mv, seg in zip(found, segments, strict=True):
        assert mv.mt == pytest.approx(seg.mt, rel=0.02)
        assert mv.path_m == pytest.approx(seg.distance, rel=0.02)
        assert mv.t_on == pytest.approx(seg.t0, abs=0.01)


def test_without_the_correction_moves_would_look_short() -> None:
    """The check above would pass with a crude threshold only if moves were long: a slow
    move spends a large share of its time under the onset speed."""
    motor = MotorParams(fitts_a_s=0.8, fitts_b_s=0.0, peak_hand_speed=3.0)
    ts, pos, segments = _sampled([Move((0.05, 0.0, 0.1), None, 0.06)], motor)
    (mv,) = segment_moves(ts, pos)
    raw = mv.mt  # corrected
    assert raw == pytest.approx(segments[0].mt, rel=0.03)
    moving = np.linalg.norm(np.diff(pos, axis=0), axis=1) * 240.0 > 0.03
    assert moving.sum() / 240.0 < 0.8 * segments[0].mt  # what a bare threshold would say


def test_a_folder_without_a_recording_or_moves_is_named(tmp_path: Path) -> None:
    with pytest.raises(FitError, match=r"no participant-input\.jsonl"):
        measure_trial(tmp_path)
    with pytest.raises(FitError, match="no hand movement"):
        fit_measures([])


def test_a_client_slower_than_the_ticks_gives_the_same_moves() -> None:
    """A live client sends the hand at, say, 60 Hz; the recording repeats each pose until the
    next: the moves found are those of the 240 Hz path."""
    motor = MotorParams(fitts_a_s=0.2, fitts_b_s=0.1, peak_hand_speed=3.0)
    ts, pos, segments = _sampled([Move((0.3, 0.0, 0.1), None, 0.06)], motor)
    held = pos.copy()
    for k in range(len(held)):
        held[k] = pos[k - k % 4]  # each pose held for 4 ticks
    (mv,) = segment_moves(ts, held)
    assert mv.mt == pytest.approx(segments[0].mt, rel=0.05)
    assert mv.path_m == pytest.approx(segments[0].distance, rel=0.03)
