"""Entity paths and colours of the rerun view (hrc_logger.view), shared by its parts."""

from __future__ import annotations

import math
import re
from typing import Any

import rerun as rr

from hrc.scenario import colors

rgb = colors.rgb
_ENTITY_SAFE = re.compile(r"[^A-Za-z0-9_\-]")
CLEAR = rr.Clear(recursive=False)  # one archetype for every clear (building one costs ~0.2 ms)


def rgba(c: tuple[int, int, int], a: int) -> tuple[int, int, int, int]:
    return c[0], c[1], c[2], a


def srgb_to_linear(c: float) -> float:
    """An sRGB channel (0..1) as linear light."""
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def part(name: str) -> str:
    """One entity-path segment (ids are already [A-Za-z0-9_-], but cue ids carry ':')."""
    return _ENTITY_SAFE.sub("_", name) or "_"


def cue_entity(cue_id: str) -> str:
    return "world/cues/" + "/".join(part(p) for p in cue_id.split(":"))


def finite(values: Any) -> bool:
    return all(math.isfinite(x) for x in values)
