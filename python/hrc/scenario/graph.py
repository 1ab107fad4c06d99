"""Cycles in the "must be done before" graph of parts.

Nodes are part ids; an edge u -> v means u must be done before v can be done. Edges come from
`after` (each listed part -> the dependent part) and from sequence order (each part -> the next
part of the same agent's sequence). Any cycle is a deadlock: no part on it can ever be done.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass


@dataclass(frozen=True)
class Edge:
    src: str
    dst: str
    via: str  # "after" or the agent whose sequence orders src before dst


def strongly_connected(nodes: list[str], edges: list[Edge]) -> list[list[str]]:
    """Tarjan's algorithm, iterative (a long sequence must not hit the recursion limit).
    Components come out in a deterministic order for a given node and edge order."""
    succ: dict[str, list[str]] = {n: [] for n in nodes}
    for e in edges:
        succ[e.src].append(e.dst)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    counter = 0
    for root in nodes:
        if root in index:
            continue
        work: list[tuple[str, int]] = [(root, 0)]
        while work:
            node, i = work.pop()
            if i == 0:
                index[node] = low[node] = counter
                counter += 1
                stack.append(node)
                on_stack.add(node)
            recurse = False
            children = succ[node]
            while i < len(children):
                child = children[i]
                i += 1
                if child not in index:
                    work.append((node, i))
                    work.append((child, 0))
                    recurse = True
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            if recurse:
                continue
            if low[node] == index[node]:
                comp: list[str] = []
                while True:
                    top = stack.pop()
                    on_stack.discard(top)
                    comp.append(top)
                    if top == node:
                        break
                out.append(comp)
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
    return out


def find_cycles(nodes: list[str], edges: list[Edge]) -> list[list[Edge]]:
    """One concrete cycle (as its edges, in order) per strongly connected component that has one.
    Self-loops are ignored here (the caller reports a part waiting for itself separately)."""
    order = {n: i for i, n in enumerate(nodes)}
    cycles: list[list[Edge]] = []
    for comp in strongly_connected(nodes, edges):
        if len(comp) < 2:
            continue
        members = set(comp)
        inner = [e for e in edges if e.src in members and e.dst in members and e.src != e.dst]
        start = min(comp, key=order.__getitem__)
        cycles.append(_shortest_cycle_through(start, inner))
    cycles.sort(key=lambda c: order[c[0].src])
    return cycles


def _shortest_cycle_through(start: str, edges: list[Edge]) -> list[Edge]:
    out: dict[str, list[Edge]] = {}
    for e in edges:
        out.setdefault(e.src, []).append(e)
    came_by: dict[str, Edge] = {}
    queue: deque[str] = deque([start])
    seen = {start}
    while queue:
        node = queue.popleft()
        for e in out.get(node, []):
            if e.dst == start:
                path = [e]
                cur = node
                while cur != start:
                    back = came_by[cur]
                    path.append(back)
                    cur = back.src
                return list(reversed(path))
            if e.dst not in seen:
                seen.add(e.dst)
                came_by[e.dst] = e
                queue.append(e.dst)
    raise AssertionError("a strongly connected component always has a cycle through each member")
