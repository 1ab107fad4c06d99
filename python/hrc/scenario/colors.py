"""The colours of a scenario's things, defined once: what a colour name means in RGB, the
participant's colour, each part's colour and the furniture's (used by physics's debug view, the
participant client's scene and anything else that draws the world).

A scenario names a colour (``red``) or writes it as ``#rrggbb`` (docs/scenario.md).
"""

from __future__ import annotations

import re

RGB = tuple[int, int, int]

# The names a scenario may use, and what they look like.
NAMED_RGB: dict[str, RGB] = {
    "red": (220, 45, 45),
    "green": (45, 170, 70),
    "blue": (50, 100, 225),
    "yellow": (235, 200, 35),
    "orange": (240, 140, 35),
    "purple": (140, 65, 190),
    "cyan": (40, 200, 210),
    "magenta": (210, 55, 190),
    "white": (240, 240, 240),
    "black": (25, 25, 25),
    "grey": (128, 128, 128),
    "gray": (128, 128, 128),
    "pink": (240, 150, 185),
    "brown": (135, 85, 45),
}
HEX_COLOR = re.compile(r"^#[0-9a-fA-F]{6}$")
UNKNOWN_RGB: RGB = (170, 170, 170)

# The participant's colour in the thesis: the hands, their own outlines and target highlights.
HUMAN_COLOR = "blue"
# The participant's parts (the robots' parts take their robot's colour): orange, so a part
# stands out against the blue hand holding it and the blue cue of its target.
HUMAN_PART_COLOR = "orange"

# The furniture (hrc.scenario.layout), as RGB in [0, 1] with alpha.
BOARD_RGBA = (0.1, 0.45, 0.2, 1.0)
TABLE_RGBA = (0.55, 0.45, 0.35, 1.0)
PICKING_TABLE_RGBA = (0.5, 0.5, 0.55, 1.0)
FEEDER_RGBA = (0.3, 0.3, 0.3, 1.0)
FEEDER_WALL_RGBA = (0.35, 0.35, 0.35, 1.0)
TARGET_MARKER_RGBA = (1.0, 1.0, 1.0, 0.25)


def rgb(name: str, default: RGB = UNKNOWN_RGB) -> RGB:
    """A scenario colour (name or #rrggbb) as RGB 0..255; anything else gives ``default``."""
    n = (name or "").strip().lower()
    if n in NAMED_RGB:
        return NAMED_RGB[n]
    if HEX_COLOR.match(n):
        return int(n[1:3], 16), int(n[3:5], 16), int(n[5:7], 16)
    return default


def hex_color(name: str, default: RGB = UNKNOWN_RGB) -> str:
    """A scenario colour as ``#rrggbb``."""
    r, g, b = rgb(name, default)
    return f"#{r:02x}{g:02x}{b:02x}"


def rgba_hex(rgba: tuple[float, float, float, float]) -> str:
    """An RGBA in [0, 1] as ``#rrggbb`` (alpha dropped)."""
    r, g, b = (max(0, min(255, round(c * 255))) for c in rgba[:3])
    return f"#{r:02x}{g:02x}{b:02x}"


def unit_rgba(name: str, alpha: float = 1.0) -> tuple[float, float, float, float]:
    """A scenario colour as RGBA in [0, 1] (pybullet's form)."""
    r, g, b = rgb(name)
    return r / 255.0, g / 255.0, b / 255.0, alpha


def part_color(owner: str, robot_colors: dict[str, str]) -> str:
    """A part's colour: its robot's colour, or the participant's part colour."""
    return robot_colors.get(owner, HUMAN_PART_COLOR)
