"""Entry point of the orchestrator service (``hrc-orchestrator``)."""

from __future__ import annotations

from hrc.service import run_service

from hrc_orchestrator.service import OrchestratorService

SERVICE = OrchestratorService


def main(argv: list[str] | None = None) -> int:
    return run_service(SERVICE, argv)


if __name__ == "__main__":
    raise SystemExit(main())
