"""The clock master's side of declared events (TickAck.next_event_tick): an exchange ends at a
declared event, and the ticks of its reaction chain start exchanges of their own
(docs/ARCHITECTURE.md, "Exchange step")."""

from __future__ import annotations

from hrc.bus.clock import REACTION_TICKS, DeclaredEvents


def _spans(events: DeclaredEvents, ticks: int, longest: int) -> list[tuple[int, int]]:
    """(start, span) of the exchanges from tick 0 up to ``ticks``."""
    out, k = [], 0
    while k < ticks:
        n = events.limit(k, longest)
        out.append((k, n))
        k += n
    return out


def test_an_exchange_ends_at_the_event_and_its_reactions_get_one_tick_each() -> None:
    events = DeclaredEvents()
    events.add(40)
    starts = {k: n for k, n in _spans(events, 80, 16)}
    # tick 0 (everyone's first states) is an event too: 1, 2, 3 start exchanges
    assert starts[0] == starts[1] == starts[2] == 1 and 3 in starts
    # no exchange runs past 40 ...
    assert any(k + n == 41 for k, n in starts.items())
    # ... and 41, 42, 43 start exchanges; 41 and 42 are one tick long
    assert all(k in starts for k in range(41, 41 + REACTION_TICKS))
    assert starts[41] == starts[42] == 1
    assert starts[43] > 1


def test_nothing_declared_gives_the_longest_exchanges_and_zero_is_no_event() -> None:
    events = DeclaredEvents()
    events.add(0)
    spans = _spans(events, 100, 8)
    assert [n for _k, n in spans[:REACTION_TICKS]] == [1] * REACTION_TICKS
    assert all(n == 8 for _k, n in spans[REACTION_TICKS:-1])
    events.add(0)  # an ack without an event declares nothing
    assert events.limit(100, 8) == 8


def test_past_events_are_forgotten() -> None:
    events = DeclaredEvents()
    for e in (5, 6, 30):
        events.add(e)
    assert events.limit(20, 8) == 8
    assert events.limit(28, 8) == 3  # ends at 30
    assert events.limit(200, 8) == 8
    assert events.limit(28, 8) == 8  # all forgotten: the clock only goes forward


def test_declared_looks_start_exchanges_on_their_grid_without_a_reaction_chain() -> None:
    events = DeclaredEvents()
    events.set_samples("human_input", 20, 8)
    spans = _spans(events, 60, 32)
    # after tick 0's chain (0, 1, 2, then 3): exchanges start at 20, 28, 36, ..., with no
    # one-tick chain after them
    assert [k for k, _n in spans if k > 3] == [20, 28, 36, 44, 52]
    assert all(n == 8 for k, n in spans if 20 <= k < 52)
    # a later declaration replaces it; none clears it
    events = DeclaredEvents()
    events.set_samples("human_input", 10, 8)
    events.set_samples("human_input", 40)
    assert [k for k, _n in _spans(events, 60, 32) if k > 3] == [35, 40]
    events.set_samples("human_input", 0)
    assert [k for k, _n in _spans(events, 60, 32) if k > 3] == [32]  # (tick 0 is past now)
