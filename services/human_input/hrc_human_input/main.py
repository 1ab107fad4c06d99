"""Entry point of the human-input service (``hrc-human-input``)."""

from __future__ import annotations

from hrc.service import run_service

from hrc_human_input.service import HumanInputService

SERVICE = HumanInputService


def main(argv: list[str] | None = None) -> int:
    return run_service(SERVICE, argv)


if __name__ == "__main__":
    raise SystemExit(main())
