"""The unrolled sleeve at 1:1 for printing (``wristmark marker print``).

The sleeve's surface unrolled: x = r a [m] (angle a from x_wm towards y_wm, 0 at the left edge,
one circumference 2 pi r wide), z up (distal edge at the top). Seen from outside with the distal
end up the angle grows to the right, so the print, wrapped printed side out with its top edge
distal and its left edge at x_wm, is the sleeve of the marker file. Dark areas are rectangles:
the checker patches (|z| < row_height) and every listed patch (split where it wraps past 2 pi).

``sleeve_rects`` gives them in metres; ``write_svg`` writes them directly (units mm, width and
height in mm: exact physical size) with the sleeve's outline, a 10 mm scale bar and a label;
``write_pdf`` draws the same page with matplotlib at its exact size (points = mm / 25.4 * 72).
"""

from __future__ import annotations

import math
from pathlib import Path

from wristmark.models.marker import MarkerModel

Rect = tuple[float, float, float, float]  # x0, z0, width, height [m]
MARGIN = 0.005  # page margin around the sleeve [m]
FOOTER = 0.012  # space below the sleeve for the scale bar and the label [m]
MIN_WIDTH = 0.075  # least page width, for the label [m]
BAR = 0.010  # scale bar length [m]


def sleeve_rects(marker: MarkerModel) -> list[Rect]:
    """Dark rectangles (x0, z0, width, height) [m] of the unrolled sleeve, x in [0, 2 pi r)."""
    r, beta, h = marker.radius, marker.beta, marker.row_height
    out: list[Rect] = []
    for k in range(marker.columns):
        z0 = 0.0 if k % 2 == 0 else -h  # upper-row patch black for even k, lower row the opposite
        out.append((r * k * beta, z0, r * beta, h))
    two_pi = 2.0 * math.pi
    for a0, a1, z0, z1 in marker.patches:
        s = a0 % two_pi
        e = s + (a1 - a0)
        for lo, hi in ((s, min(e, two_pi)), (0.0, e - two_pi)):
            if hi > lo:
                out.append((r * lo, z0, r * (hi - lo), z1 - z0))
    return out


def page_size(marker: MarkerModel) -> tuple[float, float]:
    """Page width and height [m]: the circumference and z extent plus margins and the footer."""
    z_lo, z_hi = marker.z_extent
    return max(2.0 * math.pi * marker.radius + 2 * MARGIN, MIN_WIDTH), (z_hi - z_lo) + 2 * MARGIN + FOOTER


def _label(marker: MarkerModel, name: str) -> tuple[str, str]:
    return (f"{name}: r = {1e3 * marker.radius:.2f} mm, circumference {2e3 * math.pi * marker.radius:.2f} mm",
            "print at 100 %; wrap printed side out, top edge distal, left edge at x_wm")


def write_svg(marker: MarkerModel, path: Path, name: str) -> None:
    """The page as SVG in millimetres (module doc)."""
    W, H = (1e3 * v for v in page_size(marker))
    z_hi = marker.z_extent[1]
    m = 1e3 * MARGIN

    def y(z: float) -> float:  # page y (down) of sleeve height z
        return m + 1e3 * (z_hi - z)

    circ = 2e3 * math.pi * marker.radius
    z_lo = marker.z_extent[0]
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W:.4f}mm" height="{H:.4f}mm" '
             f'viewBox="0 0 {W:.4f} {H:.4f}">',
             f'<rect class="outline" x="{m:.4f}" y="{y(z_hi):.4f}" width="{circ:.4f}" '
             f'height="{1e3 * (z_hi - z_lo):.4f}" fill="white" stroke="#999999" stroke-width="0.05"/>']
    for x0, z0, w, h in sleeve_rects(marker):
        parts.append(f'<rect class="dark" x="{m + 1e3 * x0:.4f}" y="{y(z0 + h):.4f}" width="{1e3 * w:.4f}" '
                     f'height="{1e3 * h:.4f}" fill="black"/>')
    yb = y(z_lo) + 3.0
    parts.append(f'<rect class="scalebar" x="{m:.4f}" y="{yb:.4f}" width="{1e3 * BAR:.4f}" height="0.4" fill="black"/>')
    parts.append(f'<text x="{m:.4f}" y="{yb + 3.0:.4f}" font-size="2" font-family="sans-serif">10 mm</text>')
    for k, line in enumerate(_label(marker, name)):
        parts.append(f'<text x="{m:.4f}" y="{yb + 6.0 + 2.2 * k:.4f}" font-size="1.6" font-family="sans-serif">'
                     f'{line}</text>')
    parts.append("</svg>")
    path.write_text("\n".join(parts) + "\n")


def write_pdf(marker: MarkerModel, path: Path, name: str) -> None:
    """The page as PDF at its exact physical size (matplotlib; module doc)."""
    from matplotlib.figure import Figure  # no pyplot: the process's matplotlib backend is left alone
    from matplotlib.patches import Rectangle

    W, H = page_size(marker)
    z_lo, z_hi = marker.z_extent
    inch = 0.0254
    fig = Figure(figsize=(W / inch, H / inch))
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(-MARGIN, W - MARGIN)
    ax.set_ylim(z_hi + MARGIN - H, z_hi + MARGIN)  # 1:1: one metre of page per metre of sleeve
    ax.set_axis_off()
    circ = 2.0 * math.pi * marker.radius
    ax.add_patch(Rectangle((0.0, z_lo), circ, z_hi - z_lo, facecolor="white", edgecolor="#999999", linewidth=0.15))
    for x0, z0, w, h in sleeve_rects(marker):
        ax.add_patch(Rectangle((x0, z0), w, h, facecolor="black", edgecolor="none", linewidth=0))
    yb = z_lo - 0.0034
    ax.add_patch(Rectangle((0.0, yb), BAR, 0.0004, facecolor="black", edgecolor="none"))
    ax.text(0.0, yb - 0.0025, "10 mm", fontsize=5.5, family="sans-serif")
    for k, line in enumerate(_label(marker, name)):
        ax.text(0.0, yb - 0.0055 - 0.0022 * k, line, fontsize=4.5, family="sans-serif")
    fig.savefig(str(path), format="pdf")
