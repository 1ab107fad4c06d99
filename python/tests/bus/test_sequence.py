"""Sequence numbers: a gap or a step back is reported and counted, per (key, sender)."""

from __future__ import annotations

import logging

import pytest

from hrc.bus.sequence import SeqChecker


def test_consecutive_numbers_are_fine() -> None:
    s = SeqChecker()
    for i in range(1, 6):
        assert s.check("k", "a", i) is None
    assert (s.gaps, s.lost, s.messages) == (0, 0, 5)


def test_a_gap_is_reported_as_an_error_and_counted(caplog: pytest.LogCaptureFixture) -> None:
    s = SeqChecker()
    s.check("hrc/x/task/events", "orchestrator", 1)
    with caplog.at_level(logging.ERROR):
        p = s.check("hrc/x/task/events", "orchestrator", 4)
    assert p is not None and p.missing == 2
    assert (s.gaps, s.lost) == (1, 2)
    assert (
        "sequence gap on hrc/x/task/events from 'orchestrator': expected seq 2, got 4"
        in caplog.text
    )
    assert s.check("hrc/x/task/events", "orchestrator", 5) is None  # continues from the new number


def test_a_first_message_after_1_means_the_start_was_missed() -> None:
    s = SeqChecker()
    assert s.check("k", "a", 3) is not None
    assert s.lost == 2


def test_duplicates_and_steps_back_are_counted_but_lose_nothing() -> None:
    s = SeqChecker()
    s.check("k", "a", 1)
    s.check("k", "a", 2)
    p = s.check("k", "a", 2)
    assert p is not None and p.missing == 0 and "out of order" in p.describe()
    assert (s.gaps, s.lost) == (1, 0)
    assert s.check("k", "a", 3) is None


def test_keys_and_senders_are_independent() -> None:
    s = SeqChecker()
    assert s.check("k1", "a", 1) is None
    assert s.check("k2", "a", 1) is None
    assert s.check("k1", "b", 1) is None
    assert s.check("k1", "a", 2) is None
    assert s.gaps == 0


def test_loss_spans_follow_the_clock_and_seldom_keys_count_towards_them() -> None:
    s = SeqChecker()
    for tick, seq in ((0, 1), (1, 2), (2, 3), (50, 51), (51, 52), (90, 54)):
        s.check("clock", "physics", seq, tick)  # two outages: ticks 2..50 and 51..90
    s.check("objects", "physics", 1, 0)
    s.check("objects", "physics", 9, 60)  # last seen at 0: overlaps the first outage
    s.check("state", "ik", 1, 95)
    s.check("state", "ik", 4, 140)  # no clock gap there: a span of its own
    spans = [(sp.from_tick, sp.to_tick, sp.messages) for sp in s.loss_spans("clock")]
    assert spans == [(2, 50, 47 + 7), (51, 90, 1), (95, 140, 2)]
    assert s.lost == 47 + 1 + 7 + 2
    # without a timeline, overlapping gaps merge
    merged = [(sp.from_tick, sp.to_tick, sp.messages) for sp in s.loss_spans()]
    assert merged == [(0, 90, 47 + 1 + 7), (95, 140, 2)]
