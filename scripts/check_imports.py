#!/usr/bin/env python3
"""The house rules of the Python imports (run by scripts/lint.sh):

1. the library stands below every service: no module of `python/hrc` imports a service's package
   (`hrc_physics`, `hrc_orchestrator`, `hrc_human_input`, `hrc_logger`), and no service imports
   another service;
2. no import cycle among the modules of the library or of any one service, nor among the
   rooms of the library (its subpackages and top-level modules: `hrc.study`, `hrc.session`,
   `hrc.bus`, `hrc.geometry`, ...), where a room's imports are those of all its modules.

Every import counts, also one inside a function (a cycle hidden in a function is still a
cycle; it only moves the error to run time). `from pkg import name` depends on `pkg.name` when
that is a module, else on `pkg` itself; `import a.b.c` depends on `a.b.c`. Imports under
`if TYPE_CHECKING:` count too.

    scripts/check_imports.py [ROOT]   exit 1 with each finding named, 0 when the house is in order
"""

from __future__ import annotations

import ast
import itertools
import sys
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LIBRARY = "hrc"
# package name -> folder that holds it (set by main: the library and every service's package)
PACKAGES: dict[str, Path] = {}


def find_packages(root: Path) -> dict[str, Path]:
    return {
        LIBRARY: root / "python" / LIBRARY,
        **{p.name: p for p in sorted((root / "services").glob("*/hrc_*")) if p.is_dir()},
    }


def module_name(package: str, path: Path) -> str:
    rel = path.relative_to(PACKAGES[package]).with_suffix("")
    parts = [package, *rel.parts]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    found = {}
    for package, folder in PACKAGES.items():
        for path in sorted(folder.rglob("*.py")):
            if "tests" in path.relative_to(folder).parts:
                continue
            found[module_name(package, path)] = path
    return found


def imports(name: str, path: Path, known: set[str]) -> Iterator[tuple[str, int]]:
    """(module imported, line) for each import of the module `name` at `path`."""
    tree = ast.parse(path.read_text(), str(path))
    is_package = path.name == "__init__.py"
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                if not is_package:
                    base = base[:-1]
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                yield (sub if sub in known else target), node.lineno


def top(module: str) -> str:
    return module.split(".", 1)[0]


def graph(root: Path) -> tuple[dict[str, dict[str, str]], list[str]]:
    """The import graph among our modules (edges to the first line that imports) and the
    imports across the layers that rule 1 forbids."""
    found = modules()
    known = set(found)
    edges: dict[str, dict[str, str]] = {m: {} for m in found}
    wrong = []
    for name, path in found.items():
        for target, line in imports(name, path, known):
            if top(target) not in PACKAGES:
                continue
            where = f"{path.relative_to(root)}:{line}"
            if top(target) != top(name) and top(target) != LIBRARY:
                below = "the library" if top(name) == LIBRARY else f"service {top(name)}"
                finding = f"{where}: {below} imports {top(target)} (a service's package)"
                if finding not in wrong:
                    wrong.append(finding)
                continue
            # an import of a module imports its packages too; a module's own package is no cycle
            while target not in known and "." in target:
                target = target.rsplit(".", 1)[0]
            if target in known and target != name and not name.startswith(target + "."):
                edges[name].setdefault(target, f"line {line}")
    return edges, wrong


def room(module: str) -> str:
    """The library's room that holds `module`: hrc.study.sweep -> hrc.study."""
    return ".".join(module.split(".")[:2])


def rooms(edges: dict[str, dict[str, str]]) -> dict[str, dict[str, str]]:
    """The import graph among the library's rooms (a room's edges: its modules' imports)."""
    out: dict[str, dict[str, str]] = {}
    for v, targets in edges.items():
        if top(v) != LIBRARY or v == LIBRARY:
            continue
        out.setdefault(room(v), {})
        for w, line in targets.items():
            if top(w) == LIBRARY and w != LIBRARY and room(w) != room(v):
                out[room(v)].setdefault(room(w), f"{v} {line}")
                out.setdefault(room(w), {})
    return out


def cycles(edges: dict[str, dict[str, str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), each as one cycle."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = 0

    def visit(v: str) -> None:
        nonlocal counter
        index[v] = low[v] = counter
        counter += 1
        stack.append(v)
        on_stack.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    sys.setrecursionlimit(10000)
    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def one_cycle(component: list[str], edges: dict[str, dict[str, str]]) -> str:
    """A shortest loop through the component's first module, with the line of each import."""
    members = set(component)
    start = component[0]
    paths = {start: [start]}
    frontier = [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(edges[v]):
                if w == start:
                    loop = paths[v] + [start]
                    return (
                        " -> ".join(f"{a} ({edges[a][b]})" for a, b in itertools.pairwise(loop))
                        + f" -> {start}"
                    )
                if w in members and w not in paths:
                    paths[w] = paths[v] + [w]
                    nxt.append(w)
        frontier = nxt
    return ", ".join(component)


def main(argv: list[str]) -> int:
    root = Path(argv[0]).resolve() if argv else ROOT
    PACKAGES.clear()
    PACKAGES.update(find_packages(root))
    if not PACKAGES[LIBRARY].is_dir():
        print(f"imports: {root} holds no python/{LIBRARY} (give the project's root)")
        return 2
    edges, wrong = graph(root)
    found = cycles(edges)
    among_rooms = rooms(edges)
    found_rooms = cycles(among_rooms)
    for line in wrong:
        print(f"layer: {line}")
    for component in found:
        print(f"cycle among {len(component)} modules: {one_cycle(component, edges)}")
    for component in found_rooms:
        print(
            f"cycle among {len(component)} rooms of the library: "
            f"{one_cycle(component, among_rooms)}"
        )
    found += found_rooms
    n = sum(len(e) for e in edges.values())
    if wrong or found:
        print(
            f"imports: {len(wrong)} across the layers, {len(found)} cycle(s) "
            f"({len(edges)} modules, {n} imports)"
        )
        return 1
    print(f"imports: the library below every service, no cycle ({len(edges)} modules, {n} imports)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
