"""The size the run's figures are drawn at (``output.plots.width``): a page's width or one column's.

``page`` (the default) draws each figure as it always was: 7-8 in wide, for the full text width of a paper
(``figure*``) or a screen; its text is 5.5-10 pt at that size.  ``column`` draws it 3.5 in wide, the column of
a two-column IEEE or ACM paper, with every text at 7 pt or more at that size (8 pt where it fits): panels
stacked instead of side by side, fewer ticks, shorter titles and labels, a legend in fewer columns, the
filmstrip in rows of :attr:`Layout.strip_cols` figures.  A figure function takes ``layout="page"`` or
``"column"`` (or a :class:`Layout`); its page bytes are those of before the setting existed.
"""
from __future__ import annotations

import functools
import textwrap
from contextlib import contextmanager
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Layout:
    """Sizes (points at the size drawn) and shape of the run's figures for one width."""

    name: str
    #: the figures' width (in); None: each figure's own page width
    width_in: float | None = None
    #: matplotlib settings while a figure is drawn (tick labels, axis labels); empty: matplotlib's own
    rc: dict = field(default_factory=dict)
    title: float = 9.0          # a figure's title
    panel_title: float = 8.0    # a panel's title
    legend: float = 7.0         # the legend under Figs. 3.1 and 3.2
    key: float = 6.5            # the legend and clip key under Figs. 4.1 and 4.2
    key_cols: int = 7           # at most this many columns in that legend
    block_label: float = 5.5    # a clip's name on its block
    side_label: float = 8.0     # Fig. 4.1's right axis label; Fig. 4.2's 'no laughing energy' line
    side_ticks: float = 7.0     # Fig. 4.1's right axis' tick labels
    caption: float = 5.5        # the filmstrip's captions
    frame_title: float = 7.0    # the filmstrip's times
    strip_title: float = 8.0    # the filmstrip's title
    strip_cols: int = 0         # filmstrip figures per row (0: all in one row)

    @property
    def column(self) -> bool:
        return self.name == "column"


PAGE = Layout("page")
#: 3.5 in wide; no text under 7 pt; ticks and axis labels 8 pt (the x ticks' labels 3 pt under their ticks: at 2 pt
#: the y axis' "0" and the x axis' "0.0" touched at a panel's corner, Fig. 4.2 of extractor=pressure, 2026-11-29)
COLUMN = Layout("column", 3.5, rc={"font.size": 8.0, "axes.labelsize": 8.0, "xtick.labelsize": 8.0,
                                   "ytick.labelsize": 8.0, "legend.fontsize": 7.0, "xtick.major.size": 2.5,
                                   "ytick.major.size": 2.5, "xtick.major.pad": 3.0, "ytick.major.pad": 2.0,
                                   "axes.labelpad": 2.0, "axes.titlepad": 3.0},
                title=8.0, panel_title=8.0, legend=7.5, key=7.0, key_cols=2, block_label=7.0, side_label=8.0,
                side_ticks=8.0, caption=7.0, frame_title=7.5, strip_title=8.0, strip_cols=4)
LAYOUTS = {"page": PAGE, "column": COLUMN}
#: the smallest text the column layout allows, in points at its printed width (IEEE and ACM ask for 8-9 pt)
COLUMN_MIN_PT = 7.0
#: the height of a two-column paper's column (in): a figure drawn for a column and taller does not fit one
COLUMN_HEIGHT_IN = 9.5


def layout_of(layout: str | Layout) -> Layout:
    """The :class:`Layout` named ``layout`` (``page`` or ``column``), or ``layout`` itself."""
    if isinstance(layout, Layout):
        return layout
    if layout not in LAYOUTS:
        raise ValueError(f"width must be one of {', '.join(LAYOUTS)} (got {layout!r})")
    return LAYOUTS[layout]


@contextmanager
def drawing(layout: Layout):
    """matplotlib's settings for a figure drawn in ``layout`` (nothing changed for ``page``)."""
    if not layout.rc:
        yield
        return
    import matplotlib

    with matplotlib.rc_context(layout.rc):
        yield


def in_layout(draw):
    """Decorate a figure function: its ``layout`` keyword (``"page"``, ``"column"`` or a :class:`Layout`) reaches
    it as a :class:`Layout`, and it draws and saves under :func:`drawing`."""
    @functools.wraps(draw)
    def wrapper(*args, layout: str | Layout = "page", **kwargs):
        chosen = layout_of(layout)
        with drawing(chosen):
            return draw(*args, layout=chosen, **kwargs)
    return wrapper


def titled(title: str, note: str) -> str:
    """A figure title with a note on what part of the run it shows (e.g. the first 60 s of a long one)."""
    if not note:
        return title
    return f"{title}\n{note}" if len(title) + len(note) > 90 else f"{title}; {note}"


def wrapped(text: str, width_in: float, fontsize: float) -> str:
    """``text`` wrapped to lines that fit ``width_in`` at ``fontsize`` (DejaVu Sans: about 0.55 em a character
    on average, taken as 0.6 to be safe); its own line breaks are kept."""
    chars = max(10, int(width_in * 72 / (0.6 * fontsize)))
    return "\n".join(w for para in text.split("\n") for w in (textwrap.wrap(para, chars) or [""]))


def thin_ticks(*axes, x: int = 4, y: int = 4) -> None:
    """At most about ``x`` and ``y`` tick labels on each axis (a column's panels are 1.5-3 in wide)."""
    from matplotlib.ticker import MaxNLocator

    for ax in axes:
        if x:
            ax.xaxis.set_major_locator(MaxNLocator(x, steps=[1, 2, 2.5, 5, 10]))
        if y:
            ax.yaxis.set_major_locator(MaxNLocator(y, steps=[1, 2, 2.5, 5, 10]))
