"""``python -m laughlab view RUN_DIR [--port N] [--out DIR] [--character PATH]``: the run in a browser."""
from __future__ import annotations

import shlex

from laughlab.core.errors import LaughlabError, one_line_parser, port_number


def main(args: list[str]) -> None:
    """``python -m laughlab view RUN_DIR [--port N] [--out DIR] [--character PATH]``: the run on the character
    (or the user's avatar) in a browser."""

    from laughlab.viewer import server as V

    parser = one_line_parser(prog="python -m laughlab view",
                                     description="Play a run's character in 3D in a browser, in sync with its "
                                                 "audio, the MCS and laughing energy scrolling below.")
    parser.add_argument("run_dir", help="a run directory (motion.bvh, channels.csv, events.csv)")
    parser.add_argument("--port", type=port_number, default=V.DEFAULT_PORT,
                        help="port on 127.0.0.1 (a free one if taken)")
    parser.add_argument("--out", help="write the page and its files into this new folder instead of serving; "
                                         "its index.html opens from the disk or on any web server")
    parser.add_argument("--character", help="show the run on this avatar (VRM 0.x/1.0, or a humanoid glTF/GLB; "
                                            "docs/avatars.md) instead of the mannequin")
    parser.add_argument("--overwrite", action="store_true",
                        help="with --out: replace an earlier viewer page in that folder (never other files)")
    ns = parser.parse_args(args)
    if ns.overwrite and not ns.out:
        raise LaughlabError("view: --overwrite goes with --out FOLDER (see --help)")
    if ns.out:
        out, opens = V.write(ns.run_dir, ns.out, ns.character, overwrite=ns.overwrite)
        serve = f"python -m http.server -d {shlex.quote(str(out))}"
        print(f"laughlab: viewer of {ns.run_dir} written to {out}/: open {shlex.quote(str(out / 'index.html'))} in a browser, or put "
              f"the folder on any web server (e.g. {serve})" if opens else
              f"laughlab: viewer of {ns.run_dir} written to {out}/: too large to open as a file; serve the folder "
              f"(e.g. {serve}) and open http://127.0.0.1:8000/")
        return
    httpd = V.server(ns.run_dir, ns.port, ns.character)
    taken = f"port {ns.port} is taken; " if httpd.server_address[1] != ns.port and ns.port != 0 else ""
    print(f"laughlab: {taken}viewing {ns.run_dir} at http://127.0.0.1:{httpd.server_address[1]}/ (Ctrl-C to stop)",
          flush=True)
    V.serve_until_interrupted(httpd)
