"""``python -m laughlab report RUN_DIR [--out DIR]``: the command line of :mod:`laughlab.harness.report`."""
from __future__ import annotations

import shlex
from pathlib import Path

from laughlab.core.errors import LaughlabError, one_line_parser, os_error_line


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
    parser.add_argument("--width", choices=("page", "column"), default="page",
                        help="the figures drawn for a page (default) or 3.5 in wide for one column of a "
                             "two-column paper, no text under 7 pt (metrics.png and timing.png; a sweep's heatmaps "
                             "and line plots)")
    ns = parser.parse_args(args)
    command = "python -m laughlab report " + shlex.join(args)
    try:
        path = write_report(ns.run_dir, ns.out, command, overwrite=ns.overwrite,
                            metrics=[m.strip() for m in (ns.metrics or "").split(",") if m.strip()], width=ns.width)
    except OSError as exc:
        raise LaughlabError(os_error_line(exc, ns.out or Path(ns.run_dir) / "report")
                            + "; no report was written") from None
    print(f"report written: {path}")
    partial_warning(Path(ns.run_dir))   # a half-finished sweep: its report says PARTIAL, and one line here
