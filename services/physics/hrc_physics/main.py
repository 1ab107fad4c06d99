"""Entry point of the physics service (``hrc-physics``)."""

from __future__ import annotations

from hrc.service import run_service

from hrc_physics.service import PhysicsService

SERVICE = PhysicsService


def main(argv: list[str] | None = None) -> int:
    return run_service(SERVICE, argv)


if __name__ == "__main__":
    raise SystemExit(main())
