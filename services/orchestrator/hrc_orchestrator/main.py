"""Entry point of the orchestrator service (``hrc-orchestrator``)."""

from __future__ import annotations

from hrc.service import run_service
from hrc_orchestrator.service import OrchestratorService


def main(argv: list[str] | None = None) -> int:
    return run_service(OrchestratorService, argv)


if __name__ == "__main__":
    raise SystemExit(main())
