"""Closest-point queries that ask pybullet for no more than the answer needs.

A query's cost grows with the pairs of colliders its distance threshold reaches: between the two
UR5e arms (mesh hulls) 140 us at 1 cm, 960 us at 3.5 m (2026-12-01, one core); a hand against one
UR5e 3 us when nothing is within the threshold, 30 us at 2 m. Every pair nearer than a threshold
is among that query's points, so the first of growing thresholds that gives any point gives the
same nearest points as one query at the largest, and the near, cheap ones usually answer.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pybullet as p

GROWTH = 4.0  # each threshold this many times the one before (the last one: the limit)

Point = tuple[Any, ...]  # one of pybullet's closest points (pt[8]: the distance)


def thresholds(start: float, limit: float) -> Iterator[float]:
    """start, GROWTH * start, ... (each below ``limit``), then ``limit``."""
    t = start
    while 0.0 < t < limit:
        yield t
        t *= GROWTH
    yield limit


def nearest(
    client: int,
    a: int,
    b: int,
    limit: float,
    start: float,
) -> list[Point]:
    """The points of ``getClosestPoints(a, b, t)`` for the smallest t of :func:`thresholds`
    that gives any: they hold the pair nearest of all, as one query at ``limit`` would (empty:
    none nearer than ``limit``)."""
    for t in thresholds(start, limit):
        pts = p.getClosestPoints(a, b, t, physicsClientId=client)
        if pts:
            return pts
    return []
