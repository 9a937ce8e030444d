"""``python -m laughlab report RUN_DIR [--out DIR]``: the command line of :mod:`laughlab.harness.report`."""
from __future__ import annotations

import shlex
from pathlib import Path

from laughlab.core.errors import LaughlabError, one_line_parser, os_error_line
from laughlab.render.layout import COLUMN_HEIGHT_IN


def main(args: list[str]) -> None:
    """Write the Markdown report with figures of a run or sweep folder."""
    from laughlab.harness.report import write_report
    from laughlab.harness.sweep_plan import partial_warning

    parser = one_line_parser(prog="python -m laughlab report",
                             description="Write a Markdown report with figures (README.md) from a run or sweep "
                                         "folder, into RUN_DIR/report/ or --out DIR.")
    parser.add_argument("run_dir", help="an experiment's run folder (results.json) or a multirun sweep folder")
    parser.add_argument("--out", help="report folder (default: RUN_DIR/report; the committed reports: "
                                      "--out reports/<experiment>)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace a report of another experiment in --out (one of the same is always replaced)")
    parser.add_argument("--metrics", help="a sweep's table and figures also show these metrics (NAME,NAME; "
                                          "besides the key ones and every metric a plugin registered)")
    parser.add_argument("--panels", help="the figures show only these metrics, in this order (NAME,NAME: an "
                                         "experiment's metrics.png and timing.png, a sweep's heatmaps and line plots), "
                                         "e.g. the ones a paper discusses: a column holds about 10 panels; the tables "
                                         "keep every metric")
    parser.add_argument("--width", choices=("page", "column"), default="page",
                        help="the figures drawn for a page (default) or 3.5 in wide for one column of a "
                             "two-column paper, no text under 7 pt (metrics.png and timing.png; a sweep's heatmaps "
                             "and line plots)")
    ns = parser.parse_args(args)
    command = "python -m laughlab report " + shlex.join(args)
    try:
        path = write_report(ns.run_dir, ns.out, command, overwrite=ns.overwrite,
                            metrics=_names(ns.metrics), width=ns.width, panels=_names(ns.panels) or None)
    except OSError as exc:
        raise LaughlabError(os_error_line(exc, ns.out or Path(ns.run_dir) / "report")
                            + "; no report was written") from None
    print(f"laughlab: report written: {path}")
    tall = _taller_than_a_column(path.parent / "figures") if ns.width == "column" else []
    if tall:
        print(f"laughlab: {', '.join(tall)} {'is' if len(tall) == 1 else 'are'} taller than a column (about "
              f"{COLUMN_HEIGHT_IN:g} in): --panels NAME,NAME draws only the metrics you discuss")
    partial_warning(Path(ns.run_dir))   # a half-finished sweep: its report says PARTIAL, and one line here


def _names(text: str | None) -> list[str]:
    """``NAME,NAME`` as a list, each name once."""
    return list(dict.fromkeys(m.strip() for m in (text or "").split(",") if m.strip()))


def _taller_than_a_column(figures: Path) -> list[str]:
    """``NAME.png (H in tall)`` for each of a report's figures of metrics (``--panels``') drawn for a column that is
    taller than a column."""
    from PIL import Image

    out = []
    for png in sorted(p for p in figures.glob("*.png") if p.name in ("metrics.png", "timing.png")
                      or p.name.startswith(("heatmap_", "line_"))):
        with Image.open(png) as im:
            dpi = (im.info.get("dpi") or (100, 100))[1]
            tall = im.size[1] / dpi
        if tall > COLUMN_HEIGHT_IN:
            out.append(f"{png.name} ({tall:.1f} in tall)")
    return out
