"""Counterbalancing (hrc.study.order): each condition once per position across a full set of
participants; a Williams square balances first-order carry-over."""

from __future__ import annotations

import itertools
from collections import Counter

import pytest

from hrc.study.order import latin_square, orders, rows_needed, williams_square


def positions_balanced(rows: list[list[int]], n: int) -> bool:
    """Each condition equally often at each position."""
    return all(
        len(set(Counter(row[pos] for row in rows).values())) == 1
        and set(row[pos] for row in rows) == set(range(n))
        for pos in range(n)
    )


def carry_over(rows: list[list[int]]) -> Counter[tuple[int, int]]:
    """How often each condition directly follows each other one."""
    return Counter((a, b) for row in rows for a, b in itertools.pairwise(row))


@pytest.mark.parametrize("n", range(1, 9))
def test_every_row_is_an_order_of_all_conditions(n: int) -> None:
    for rows in (latin_square(n), williams_square(n)):
        assert all(sorted(r) == list(range(n)) for r in rows)


@pytest.mark.parametrize("n", range(2, 9))
def test_latin_and_williams_put_each_condition_once_at_each_position(n: int) -> None:
    assert positions_balanced(latin_square(n), n)
    assert positions_balanced(williams_square(n), n)
    for order in ("latin", "williams"):
        full = orders(order, n, rows_needed(order, n))
        assert positions_balanced(full, n), (order, full)


@pytest.mark.parametrize("n", range(2, 9))
def test_williams_balances_first_order_carry_over(n: int) -> None:
    rows = williams_square(n)
    assert len(rows) == (n if n % 2 == 0 else 2 * n)
    pairs = carry_over(rows)
    want = 1 if n % 2 == 0 else 2  # each ordered pair of different conditions, equally often
    assert set(pairs) == {(a, b) for a in range(n) for b in range(n) if a != b}
    assert set(pairs.values()) == {want}, pairs


def test_a_cyclic_latin_square_does_not_balance_carry_over() -> None:
    # the check above can fail: a plain Latin square of 4 has 0 -> 1 three times, 1 -> 0 never
    pairs = carry_over(latin_square(4))
    assert pairs[(0, 1)] == 3 and pairs[(1, 0)] == 0


def test_participants_beyond_a_full_set_start_the_square_again() -> None:
    rows = orders("williams", 4, 10)
    assert rows[4:8] == rows[0:4] and rows[8] == rows[0]
    assert orders("williams", 3, 7)[6] == orders("williams", 3, 1)[0]


def test_random_orders_are_seeded_permutations() -> None:
    a = orders("random", 5, 6, seed=3)
    assert a == orders("random", 5, 6, seed=3)
    assert a != orders("random", 5, 6, seed=4)
    assert all(sorted(r) == list(range(5)) for r in a)
    assert len({tuple(r) for r in a}) > 1


def test_fixed_is_the_file_order_and_an_unknown_order_is_named() -> None:
    assert orders("fixed", 3, 2) == [[0, 1, 2], [0, 1, 2]]
    with pytest.raises(ValueError, match="order: one of williams"):
        orders("balanced", 3, 2)
