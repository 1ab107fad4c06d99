"""Files a reader never sees half written (metrics.json, logger_stats.json)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any


def write_json_atomic(path: Path, data: Any) -> None:
    """``data`` as indented JSON, written as :func:`write_text_atomic` writes."""
    write_text_atomic(path, json.dumps(data, indent=2) + "\n")


def write_text_atomic(path: Path, text: str) -> None:
    """``text`` through a temporary file renamed over ``path``: a crash never leaves half a
    file, and a full disk (OSError, raised again) leaves no temporary one."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError:
        tmp.unlink(missing_ok=True)
        raise
