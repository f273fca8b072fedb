"""Colours, sizes and legend entries of the 3D view: one table that the scene, the HTML legend
and the browser tests share.

Colours are RGB in [0, 1]. The arm keeps the URDF's materials (models.urdf.MATERIALS: stem grey,
segment 1 blue, segment 2 green); the marker sleeve is drawn as its black/white checker pattern.
"""

from __future__ import annotations

from dataclasses import dataclass

RGB = tuple[float, float, float]

# The four tip spheres, in drawing order. Hues are >= 30 deg apart from each other and from
# the arm's blue (215 deg) and green (153 deg) so a screenshot can tell them apart.
TIP_KINDS: tuple[str, ...] = ("desired", "commanded", "estimated", "true")


@dataclass(frozen=True)
class TipStyle:
    """How one tip is drawn: colour, sphere radius [m], legend label, opacity [-]."""

    color: RGB
    radius: float
    label: str
    opacity: float = 0.95


TIP_STYLES: dict[str, TipStyle] = {
    "desired": TipStyle((1.00, 0.80, 0.00), 0.0020, "desired tip (trajectory)", 0.6),
    "commanded": TipStyle((0.00, 0.85, 0.95), 0.0015, "commanded tip (model at psi_cmd)"),
    "estimated": TipStyle((0.85, 0.00, 0.85), 0.0015, "vision-estimated tip"),
    "true": TipStyle((0.90, 0.10, 0.10), 0.0015, "true tip (simulated arm)"),
}

TRAIL_OPACITY = 0.9  # [-] of the recent-path lines
GHOST_COLOR: RGB = (0.62, 0.52, 0.95)  # commanded-configuration ghost arm (violet)
GHOST_OPACITY = 0.22  # [-]
GHOST_RADIUS_SCALE = 1.18  # [-] the ghost is a slightly wider shell, so it never z-fights the true arm
MARKER_BLACK: RGB = (0.04, 0.04, 0.04)
MARKER_WHITE: RGB = (0.97, 0.97, 0.97)
ENDOSCOPE_COLOR: RGB = (0.22, 0.22, 0.25)
LEFT_FRUSTUM_COLOR: RGB = (0.85, 0.45, 0.10)  # orange
RIGHT_FRUSTUM_COLOR: RGB = (0.45, 0.25, 0.75)  # purple
GRID_COLOR: RGB = (0.62, 0.64, 0.68)  # 1 cm grid in the incision plane
BACKGROUND_TOP: RGB = (0.97, 0.97, 0.96)
BACKGROUND_BOTTOM: RGB = (0.80, 0.82, 0.85)

# (label, colour) rows of the legend, tips first.
LEGEND: tuple[tuple[str, RGB], ...] = tuple((s.label, s.color) for s in TIP_STYLES.values()) + (
    ("commanded configuration (ghost)", GHOST_COLOR),
    ("arm: segment 1 / segment 2", (0.20, 0.45, 0.85)),
    ("wrist marker (checker sleeve)", MARKER_BLACK),
    ("left camera frustum", LEFT_FRUSTUM_COLOR),
    ("right camera frustum", RIGHT_FRUSTUM_COLOR),
)


# Several arms in one view (viz.arms_scene): each arm has a colour; its tips are drawn in shades
# of it (desired: light, translucent and largest; estimated: the colour; true: dark and smallest).
# The first three hues are >= 30 deg apart from each other and from the segments' blue and green.
ARM_COLORS: tuple[RGB, ...] = (
    (0.95, 0.40, 0.00),  # orange
    (0.80, 0.00, 0.80),  # magenta
    (0.00, 0.75, 0.85),  # cyan
    (0.90, 0.75, 0.00),  # yellow
    (0.85, 0.05, 0.25),  # crimson
    (0.55, 0.30, 0.95),  # violet
    (0.55, 0.80, 0.00),  # lime
    (0.55, 0.35, 0.20),  # brown
)
ARM_TIP_KINDS: tuple[str, ...] = ("desired", "estimated", "true")


def arm_color(index: int) -> RGB:
    """The colour of the scene's arm number ``index`` (0-based; the palette repeats after 8)."""
    return ARM_COLORS[index % len(ARM_COLORS)]


def _mix(rgb: RGB, other: RGB, f: float) -> RGB:
    r, g, b = (float(c + f * (o - c)) for c, o in zip(rgb, other))
    return (r, g, b)


def arm_tip_styles(rgb: RGB) -> dict[str, TipStyle]:
    """The tip styles of an arm drawn in colour ``rgb`` (keys: ARM_TIP_KINDS)."""
    return {
        "desired": TipStyle(_mix(rgb, (1.0, 1.0, 1.0), 0.45), 0.0030, "desired tip", 0.5),
        "estimated": TipStyle(rgb, 0.0022, "vision-estimated tip"),
        "true": TipStyle(_mix(rgb, (0.0, 0.0, 0.0), 0.45), 0.0014, "true tip"),
    }


LegendRow = tuple[str, tuple[RGB, ...]]


def arms_legend(names: list[str]) -> tuple[LegendRow, ...]:
    """Legend of a scene of several arms: per arm its name and its desired, estimated and true
    tips' colours, then the arm, marker and frustum rows of the one-arm legend."""
    rows: list[LegendRow] = []
    for i, name in enumerate(names):
        st = arm_tip_styles(arm_color(i))
        rows.append((f"arm {name}: desired / estimated / true tip", tuple(st[k].color for k in ARM_TIP_KINDS)))
    return (*rows, *((label, (rgb,)) for label, rgb in LEGEND[-4:]))


def hex_color(rgb: RGB) -> int:
    """0xRRGGBB integer of an RGB triple in [0, 1] (Meshcat material colours)."""
    r, g, b = (max(0, min(255, int(round(255 * c)))) for c in rgb)
    return (r << 16) | (g << 8) | b


def css_color(rgb: RGB) -> str:
    """'#rrggbb' of an RGB triple in [0, 1]."""
    return f"#{hex_color(rgb):06x}"
