"""Keeps pandas out of the logger's process.

pyarrow imports pandas (about 0.2 CPU-s, a tenth of the logger's CPU in a thesis trial) on the
first array rerun builds, only to ask whether it was handed a DataFrame; the logger never hands
it one. With pandas unimportable pyarrow takes it as not installed. Installed by the process's
entry point only (``python -m hrc_logger``), never on import, so that a test process importing
the logger keeps pandas.
"""

from __future__ import annotations

import importlib.machinery
import sys
from collections.abc import Sequence
from types import ModuleType


class _NoPandas:
    """A meta path finder that refuses pandas and its submodules."""

    def find_spec(
        self, name: str, path: Sequence[str] | None = None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if name == "pandas" or name.startswith("pandas."):
            raise ModuleNotFoundError(
                f"{name} is kept out of the logger's process (hrc_logger.nopandas)", name=name
            )
        return None


def block_pandas() -> None:
    """Makes ``import pandas`` fail from now on in this process (if not imported yet)."""
    if "pandas" not in sys.modules and not any(isinstance(f, _NoPandas) for f in sys.meta_path):
        sys.meta_path.insert(0, _NoPandas())
