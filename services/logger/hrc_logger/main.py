"""Entry point of the logger service (``hrc-logger``)."""

from __future__ import annotations

from hrc.service import run_service

from hrc_logger.service import LoggerService

SERVICE = LoggerService


def main(argv: list[str] | None = None) -> int:
    return run_service(SERVICE, argv)


if __name__ == "__main__":
    raise SystemExit(main())
