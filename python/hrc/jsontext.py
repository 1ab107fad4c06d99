"""JSON text from the outside (a browser page, a tool): parsed within limits, so that hostile
input gets a clear error instead of exhausting the parser."""

from __future__ import annotations

import json
from typing import Any

MAX_DEPTH = 16  # what the pages send nests 4 deep at most


class JsonTooDeep(ValueError):
    """Nesting beyond MAX_DEPTH: refused before parsing."""


def depth(text: str) -> int:
    """How deep brackets nest in a JSON text (strings skipped), without parsing it: the parser
    recursing into 30,000 levels raises RecursionError instead of answering."""
    if text.count("[") + text.count("{") <= MAX_DEPTH:
        return MAX_DEPTH  # cannot be deeper: no scan for every ordinary message
    level = deepest = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            level += 1
            deepest = max(deepest, level)
        elif ch in "]}":
            level -= 1
    return deepest


def loads(text: str) -> Any:
    """``json.loads`` that refuses nesting deeper than MAX_DEPTH (JsonTooDeep, a ValueError)."""
    if depth(text) > MAX_DEPTH:
        raise JsonTooDeep(f"JSON nested deeper than {MAX_DEPTH} levels: refused")
    return json.loads(text)
