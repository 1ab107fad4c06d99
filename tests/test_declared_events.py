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
        events.planned(k, n)
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
    for e, who in ((5, "ik_cpp"), (6, "orchestrator"), (30, "human_input")):
        events.add(e, who)
    events.planned(0, 7)  # over 5 and 6: reached
    assert events.limit(7, 8) == 1 and events.limit(8, 8) == 1  # 6's chain
    assert events.limit(20, 8) == 8
    assert events.limit(28, 8) == 3  # ends at 30
    events.planned(28, 3)
    assert events.limit(200, 8) == 8
    assert events.limit(28, 8) == 8  # all forgotten: the clock only goes forward


def test_a_participants_next_ack_replaces_its_declaration() -> None:
    """An arm slowed by a speed scale declares its motion's end later at each ack: only the
    latest counts, so the earlier ones end no exchange and start no reaction chain."""
    events = DeclaredEvents()
    events.planned(0, 1)
    k = 3  # (after tick 0's chain)
    for _ in range(20):  # the end stays 10 ticks ahead of every ack
        events.add(k + 10, "ik_cpp")
        n = events.limit(k, 8)
        assert n == 8, k
        events.planned(k, n)
        k += n
    # another participant's declaration stands beside it; a 0 clears only the sender's own
    events.add(k + 4, "orchestrator")
    events.add(0, "ik_cpp")
    assert events.limit(k, 8) == 5
    events.add(0, "orchestrator")
    assert events.limit(k, 8) == 8
    # one reached: its chain follows, whatever comes after
    events.add(k + 2, "ik_cpp")
    assert events.limit(k, 8) == 3
    events.planned(k, 3)
    events.add(k + 40, "ik_cpp")
    assert [events.limit(t, 8) for t in (k + 3, k + 4)] == [1, 1]
    assert events.limit(k + 5, 8) == 8


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
