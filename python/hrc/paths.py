"""Where things are: the project root and the built binaries (overridable by environment)."""

from __future__ import annotations

import os
from pathlib import Path


def project_root() -> Path:
    """The repository root (``HRC_ROOT`` overrides): the folder holding ``scenarios/``."""
    env = os.environ.get("HRC_ROOT")
    if env:
        return Path(env).resolve()
    return Path(__file__).resolve().parents[2]


def build_dir() -> Path:
    return Path(os.environ.get("HRC_BUILD_DIR", project_root() / "build")).resolve()


def ik_binary() -> Path:
    """The C++ IK service, where the service table says it is built."""
    from hrc.service_table import service

    binary = service("ik_cpp").binary
    assert binary is not None  # a C++ service
    return build_dir() / binary


def bus_probe_binary() -> Path:
    env = os.environ.get("HRC_BUS_PROBE_BIN")
    return Path(env) if env else build_dir() / "ik_cpp" / "hrc-bus-probe"


def ik_bench_binary() -> Path:
    """The IK solver benchmark (``HRC_IK_BENCH_BIN`` overrides); built next to ``hrc-ik``."""
    env = os.environ.get("HRC_IK_BENCH_BIN")
    return Path(env) if env else build_dir() / "ik_cpp" / "hrc-ik-bench"
