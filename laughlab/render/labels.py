"""Text labels that never overprint: placing them and checking a finished figure.

:func:`place_label` puts a label at the first of several candidate spots where, on the
rendered figure, it stays inside its axes and clear of the labels already placed and of
the given lines; when no spot is free it places nothing (the figure must then identify the
thing another way, e.g. a colour key).  :func:`overlapping_texts` lists every pair of
visible texts of a figure whose boxes overlap, and :func:`colorbars_without_direction`
every colour bar whose label does not say which way is better, :func:`lines_told_apart_by_hue`
every pair of named lines only their hue tells apart, and :func:`texts_cut_off` every text the
figure's edge cuts (tests use them all on every figure laughlab draws); :func:`print_sizes` gives each
text's size in points once the figure is printed at a given width (a column's 3.5 in).

Positions are measured with the figure's own renderer (``fig.canvas.get_renderer()``),
after the layout engine has run, so the check sees what the PNG shows.  Labels placed
here are left out of the layout (``set_in_layout(False)``): adding one does not move the
axes it was measured against.
"""
from __future__ import annotations

from itertools import combinations
from typing import Iterable, Sequence

import numpy as np
from matplotlib.text import Text
from matplotlib.transforms import Bbox

#: padding around a label's box when testing it against others and against lines (pixels)
PAD_PX = 1.5


def layout_now(fig):
    """Run the figure's layout engine and return its renderer (positions are final after this)."""
    engine = fig.get_layout_engine()
    if engine is not None:
        engine.execute(fig)
    return fig.canvas.get_renderer()


def _padded(bb: Bbox, pad: float) -> Bbox:
    return Bbox.from_extents(bb.x0 - pad, bb.y0 - pad, bb.x1 + pad, bb.y1 + pad)


def line_crosses(bb: Bbox, xy: np.ndarray) -> bool:
    """Whether the polyline ``xy`` (display pixels, shape (n, 2)) enters the box ``bb``."""
    if len(xy) == 0:
        return False
    x, y = xy[:, 0], xy[:, 1]
    if len(xy) == 1:
        return bool(bb.x0 <= x[0] <= bb.x1 and bb.y0 <= y[0] <= bb.y1)
    xa, xb, ya, yb = x[:-1], x[1:], y[:-1], y[1:]
    near = (np.maximum(xa, xb) >= bb.x0) & (np.minimum(xa, xb) <= bb.x1)
    if not near.any():
        return False
    xa, xb, ya, yb = xa[near], xb[near], ya[near], yb[near]
    # clip each segment to the box's x range, then test its y range there against the box's
    dx = np.where(xb != xa, xb - xa, 1.0)
    ta = np.clip((bb.x0 - xa) / dx, 0, 1)
    tb = np.clip((bb.x1 - xa) / dx, 0, 1)
    lo_t, hi_t = np.minimum(ta, tb), np.maximum(ta, tb)
    y_lo_t, y_hi_t = ya + lo_t * (yb - ya), ya + hi_t * (yb - ya)
    vertical = xb == xa
    y_lo_t = np.where(vertical, ya, y_lo_t)
    y_hi_t = np.where(vertical, yb, y_hi_t)
    return bool(np.any((np.maximum(y_lo_t, y_hi_t) >= bb.y0) & (np.minimum(y_lo_t, y_hi_t) <= bb.y1)))


def line_pixels(line) -> np.ndarray:
    """A Line2D's vertices in display pixels."""
    return line.get_transform().transform(np.asarray(line.get_xydata(), float))


def place_label(ax, renderer, text: str, spots: Sequence[dict], taken: list, lines: Iterable = (),
                inside: Bbox | None = None, avoid: Sequence[Bbox] = (), **kw) -> Text | None:
    """Add ``text`` to ``ax`` at the first free spot; None (and nothing added) if none is free.

    Parameters
    ----------
    ax : Axes
    renderer : the figure's renderer (:func:`layout_now`)
    text : str
    spots : sequence of dict
        Candidate keyword sets for ``ax.text`` (``x``, ``y`` and e.g. ``ha``, ``va``,
        ``rotation``), tried in order.
    taken : list of Bbox
        Boxes (display pixels) already occupied; the placed label's box is appended.
    lines : iterable of (n, 2) arrays
        Polylines in display pixels the label must not touch.
    inside : Bbox, optional
        The label must lie inside this box (display pixels) as well as inside the axes.
    avoid : sequence of Bbox
        Further boxes (display pixels) the label must not overlap, e.g. other shapes.
    **kw
        Further ``ax.text`` keywords (font size, colour, ...).
    """
    axes_box = ax.get_window_extent(renderer)
    lines = list(lines)
    for spot in spots:
        spot = dict(spot)
        t = ax.text(spot.pop("x"), spot.pop("y"), text, **{**kw, **spot})
        t.set_in_layout(False)
        bb = t.get_window_extent(renderer)
        ok = (axes_box.x0 <= bb.x0 and bb.x1 <= axes_box.x1 and axes_box.y0 <= bb.y0 and bb.y1 <= axes_box.y1)
        if ok and inside is not None:
            ok = inside.x0 <= bb.x0 and bb.x1 <= inside.x1 and inside.y0 <= bb.y0 and bb.y1 <= inside.y1
        padded = _padded(bb, PAD_PX)
        if ok:
            ok = (not any(padded.overlaps(o) for o in taken) and not any(bb.overlaps(o) for o in avoid)
                  and not any(line_crosses(padded, xy) for xy in lines))
        if ok:
            taken.append(bb)
            return t
        t.remove()
    return None


def drawn_texts(fig) -> list[tuple[Text, Bbox]]:
    """Every non-empty text the figure draws, with its box in display pixels.

    The figure is drawn once (without rasterising: ``draw_without_rendering``) with
    :meth:`Text.draw` watched, so the list holds exactly what the PNG shows: titles, tick labels
    in view, axis labels, legend entries, annotations; not the texts of hidden axes or of axes
    turned off.
    """
    drawn = []
    original = Text.draw

    def watched(self, renderer):
        original(self, renderer)
        if self.get_visible() and self.get_text().strip():
            drawn.append((self, self.get_window_extent(renderer)))

    Text.draw = watched
    try:
        fig.draw_without_rendering()
    finally:
        Text.draw = original
    return [(t, bb) for t, bb in drawn if bb.width > 0 and bb.height > 0]


def overlapping_texts(fig, drawn: list | None = None, tolerance_px: float = 0.5) -> list[tuple[str, str]]:
    """Pairs of drawn texts of ``fig`` whose boxes overlap by more than ``tolerance_px`` each way.

    ``drawn``: the figure's :func:`drawn_texts` if already at hand (else the figure is drawn).
    """
    boxes = [(t.get_text(), bb) for t, bb in (drawn if drawn is not None else drawn_texts(fig))]
    bad = []
    for (sa, a), (sb, b) in combinations(boxes, 2):
        w = min(a.x1, b.x1) - max(a.x0, b.x0)
        h = min(a.y1, b.y1) - max(a.y0, b.y0)
        if w > tolerance_px and h > tolerance_px:
            bad.append((sa, sb))
    return bad


def texts_cut_off(fig, drawn: list | None = None, tolerance_px: float = 1.0) -> list[str]:
    """The drawn texts of ``fig`` that reach past the figure's edge by more than ``tolerance_px`` (the PNG and
    the PDF cut them)."""
    w, h = fig.bbox.width, fig.bbox.height
    return [t.get_text() for t, bb in (drawn if drawn is not None else drawn_texts(fig))
            if bb.x0 < -tolerance_px or bb.y0 < -tolerance_px or bb.x1 > w + tolerance_px or bb.y1 > h + tolerance_px]


def colorbars(fig) -> list:
    """The colour bars of a figure (``Colorbar`` objects)."""
    return [ax._colorbar for ax in fig.axes if getattr(ax, "_colorbar", None) is not None]


def colorbars_without_direction(fig) -> list[str]:
    """The labels of the colour bars that do not say which way is better (every bar should)."""
    out = []
    for cb in colorbars(fig):
        label = cb.ax.get_ylabel() if cb.orientation == "vertical" else cb.ax.get_xlabel()
        if "better" not in label.lower():
            out.append(label)
    return out


#: lightness (CIE L*, 0-100) two named lines of one axes differ by at least, when style does not tell them apart
MIN_LIGHTNESS_STEP = 15.0


def _lightness(color) -> float:
    """CIE L* of a colour (sRGB), what a greyscale print keeps of it."""
    from matplotlib.colors import to_rgb

    c = np.asarray(to_rgb(color))
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    y = float(lin @ (0.2126, 0.7152, 0.0722))
    return 116 * y ** (1 / 3) - 16 if y > 0.008856 else 903.3 * y


def lines_told_apart_by_hue(fig) -> list[tuple[str, str]]:
    """Pairs of named lines (legend entries) on one axes, or on axes sharing a spot (twins), that differ
    only in hue: the same line style and marker and lightness within :data:`MIN_LIGHTNESS_STEP`.

    Such lines merge in a greyscale print and, for red against green, for the 1 in 12 men with a red-green
    colour vision deficiency."""
    groups: dict = {}
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        # a position is its (sub)figure's: the same spot in two sub-figures is two panels, not twins
        key = (id(ax.get_figure(root=False)), *np.round(ax.get_position().bounds, 3))
        groups.setdefault(key, []).extend(
            ln for ln in ax.get_lines() if ln.get_visible() and not ln.get_label().startswith("_"))
    bad = []
    for lines in groups.values():
        for a, b in combinations(lines, 2):
            if (a.get_linestyle(), a.get_marker()) != (b.get_linestyle(), b.get_marker()):
                continue
            if abs(_lightness(a.get_color()) - _lightness(b.get_color())) < MIN_LIGHTNESS_STEP:
                bad.append((a.get_label(), b.get_label()))
    return bad


def print_sizes(fig, width_in: float, drawn: list | None = None) -> list[tuple[str, float]]:
    """Each drawn text of ``fig`` with its size (points) once the figure is printed ``width_in`` wide: its font
    size times the figure's scale (``width_in`` over the figure's own width), smallest first."""
    scale = width_in / fig.get_size_inches()[0]
    sizes = [(t.get_text(), t.get_fontsize() * scale) for t, _ in (drawn if drawn is not None else drawn_texts(fig))]
    return sorted(sizes, key=lambda s: s[1])
