"""Append-only line files that survive a crash: each line goes to the OS in one write.

The file is opened unbuffered, so a line is handed to the kernel before ``write_line`` returns;
a process killed with SIGKILL afterwards loses nothing already written, and a reader never sees
half a line from an earlier write.
"""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path
from typing import Any


class LineFile:
    """A text file written line by line, each line flushed to the OS at once."""

    def __init__(self, path: Path) -> None:
        self.path = path
        path.parent.mkdir(parents=True, exist_ok=True)
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND, 0o644)
        self._lock = threading.Lock()
        self.lines = 0

    def write_line(self, text: str) -> None:
        if "\n" in text or "\r" in text:
            raise ValueError(f"{self.path.name}: one line expected, got a line break in {text!r}")
        data = (text + "\n").encode("utf-8")
        with self._lock:
            if self._fd < 0:
                raise ValueError(f"{self.path} is closed")
            view = memoryview(data)
            while view:  # os.write may write less than asked (rare on regular files)
                n = os.write(self._fd, view)
                view = view[n:]
            self.lines += 1

    def close(self) -> None:
        with self._lock:
            if self._fd >= 0:
                os.fsync(self._fd)
                os.close(self._fd)
                self._fd = -1

    def __enter__(self) -> LineFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class JsonlFile(LineFile):
    """One JSON object per line (compact, keys in insertion order)."""

    def write(self, obj: dict[str, Any]) -> None:
        self.write_line(json.dumps(obj, separators=(",", ":"), allow_nan=False))
