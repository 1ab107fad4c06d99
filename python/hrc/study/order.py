"""Condition orders for participants who do every condition (within-subject): counterbalancing.

    orders("williams", n_conditions=4, n_people=8)  # -> 8 lists of condition indices

- ``latin``: a cyclic Latin square: across n participants each condition is once at each
  position.
- ``williams``: a balanced Latin square (Williams 1949): each condition also follows every other
  condition equally often (first-order carry-over balanced). n rows for an even number of
  conditions, 2n (each row and its reverse) for an odd one.
- ``random``: a seeded random permutation per participant.
- ``fixed``: the study file's order for everybody.

Participant k (0-based, in the study file's order) takes row k modulo the square's rows: a full
set of participants is a multiple of `rows_needed`.
"""

from __future__ import annotations

import numpy as np

ORDERS = ("williams", "latin", "random", "fixed")


def latin_square(n: int) -> list[list[int]]:
    return [[(row + j) % n for j in range(n)] for row in range(n)]


def williams_square(n: int) -> list[list[int]]:
    """Rows of a balanced Latin square: the first is 0, 1, n-1, 2, n-2, ...; the others add the
    row number (mod n). An odd n needs each row reversed as well."""
    first = [0] + [(-(j // 2) if j % 2 == 0 else (j + 1) // 2) % n for j in range(1, n)]
    rows = [[(c + r) % n for c in first] for r in range(n)]
    if n % 2 == 1:
        rows += [list(reversed(row)) for row in rows]
    return rows


def rows_needed(order: str, n: int) -> int:
    """Participants in a full set: each row of the square once."""
    if order == "latin":
        return n
    if order == "williams":
        return n if n % 2 == 0 else 2 * n
    return 1


def orders(order: str, n_conditions: int, n_people: int, seed: int = 0) -> list[list[int]]:
    """The order of the condition indices for each of `n_people` participants."""
    if order not in ORDERS:
        raise ValueError(f"order: one of {', '.join(ORDERS)} (got {order!r})")
    n = n_conditions
    if n == 0:
        return [[] for _ in range(n_people)]
    if order == "fixed":
        return [list(range(n)) for _ in range(n_people)]
    if order == "random":
        return [
            [int(i) for i in np.random.default_rng([seed, k]).permutation(n)]
            for k in range(n_people)
        ]
    square = latin_square(n) if order == "latin" else williams_square(n)
    return [list(square[k % len(square)]) for k in range(n_people)]
