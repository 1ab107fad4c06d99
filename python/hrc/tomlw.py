"""A small TOML writer for scenario and study files (tomllib only reads; no writer is pinned).

Handles what a scenario holds: tables, arrays of tables, inline tables of plain values, lists,
strings, booleans, integers and floats. `dumps` checks its own output reads back equal.
"""

from __future__ import annotations

import json
import math
import re
import tomllib
from typing import Any

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(key: str) -> str:
    return key if _BARE_KEY.match(key) else json.dumps(key)


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"cannot write {value} to TOML")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)  # a JSON string is a TOML basic string
    if isinstance(value, list):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot write a {type(value).__name__} to TOML")


def _is_section(value: Any) -> bool:
    """A table that holds tables (written as [a.b]); plain ones are written inline."""
    return isinstance(value, dict) and any(
        isinstance(v, dict) or _is_table_array(v) for v in value.values()
    )


def _is_table_array(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _table(prefix: str, table: dict[str, Any], out: list[str]) -> None:
    plain = {
        k: v
        for k, v in table.items()
        if not _is_section(v)
        and not _is_table_array(v)
        and not (prefix == "" and isinstance(v, dict))
    }
    for k, v in plain.items():
        out.append(f"{_key(k)} = {_value(v)}")
    for k, v in table.items():
        name = f"{prefix}.{_key(k)}" if prefix else _key(k)
        if k in plain:
            continue
        if _is_table_array(v):
            for item in v:
                out.append("")
                out.append(f"[[{name}]]")
                _table(name, item, out)
        else:
            has_plain = any(not _is_section(x) and not _is_table_array(x) for x in v.values())
            if has_plain or not v:  # a table holding only tables needs no header of its own
                out.append("")
                out.append(f"[{name}]")
            _table(name, v, out)


def dumps(doc: dict[str, Any]) -> str:
    """TOML text for ``doc``; raises ValueError if it would not read back equal."""
    out: list[str] = []
    _table("", doc, out)
    text = "\n".join(out).lstrip("\n") + "\n"
    if tomllib.loads(text) != doc:
        raise ValueError("TOML writer: the text does not read back as the same document")
    return text
