"""Problems found in a scenario, and the error that carries all of them."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a scenario.

    key: dotted path of what is wrong, e.g. "robots.r1.max_tcp_speed" or "parts.H3.after"
    (parts are named by id, not by index). message: what is wrong, for a person.
    """

    key: str
    message: str

    def __str__(self) -> str:
        return f"{self.key}: {self.message}"


class ScenarioError(Exception):
    """A scenario that cannot be used. `problems` lists every problem found, in file order."""

    def __init__(self, problems: list[Problem], source: str | Path | None = None) -> None:
        self.problems = list(problems)
        self.source = str(source) if source is not None else "<scenario>"
        super().__init__(str(self))

    def lines(self) -> list[str]:
        return [f"{self.source}: {problem.key}: {problem.message}" for problem in self.problems]

    def __str__(self) -> str:
        return "\n".join(self.lines())
