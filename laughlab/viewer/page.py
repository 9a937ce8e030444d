"""The viewer's page (``index.html``): served with its files beside it, or written with everything inline.

A page opened as a file (``file://``) may not fetch the files beside it, nor load them as JavaScript modules:
the browser treats each file as a separate origin.  So the page that ``view RUN --out DIR`` writes carries them:

* three.js and its loader and controls as ``data:`` URLs in the page's import map (the add-ons' relative
  imports rewritten to ``three/addons/...``, which the map also resolves); for a VRM avatar
  (``view RUN --character my.vrm``) three-vrm too, as ``three-vrm`` (the name the served page maps to its file);
* the viewer's own module inline;
* ``run.json`` and ``character.glb`` (base64) in ``<script>`` elements the viewer reads instead of fetching.

The audio stays a file beside the page: a media element may play a sibling file of a page opened as a file.
A page that would exceed :data:`INLINE_MAX_BYTES` loads its files instead; opened as a file, it then says in
words how to serve its folder (as it does for any failure to start).
"""
from __future__ import annotations

import base64
import html
import json
import os
import re
from importlib import resources
from pathlib import Path

#: the character and the run's channels inline up to this size (bytes before base64); past it the page
#: loads them from its folder (a long run's character.glb can take hundreds of MB)
INLINE_MAX_BYTES = 64 * 2 ** 20

_ONERROR = "laughlabFail('its script viewer.js could not be loaded')"


def _template(name: str) -> str:
    text = resources.files("laughlab.viewer").joinpath("index.html").read_text(encoding="utf-8")
    return text.replace("<title>laughlab viewer</title>", f"<title>laughlab: {html.escape(name)}</title>")


def vendor_dir() -> Path:
    return Path(str(resources.files("laughlab.viewer").joinpath("vendor")))


def viewer_js() -> bytes:
    return resources.files("laughlab.viewer").joinpath("viewer.js").read_bytes()


def _json_in_html(doc) -> str:
    """JSON that cannot end its script element (every ``<`` escaped)."""
    return json.dumps(doc, separators=(",", ":")).replace("<", "\\u003c")


def served(name: str) -> bytes:
    """The page that loads three.js, the viewer, the run and the character from its folder."""
    imports = {"three": "./vendor/three/build/three.module.min.js", "three/addons/": "./vendor/three/examples/jsm/",
               "three-vrm": "./vendor/three_vrm/three-vrm.module.min.js"}
    text = _template(name).replace(
        "<!--laughlab:importmap-->", f'<script type="importmap">{_json_in_html({"imports": imports})}</script>'
    ).replace("<!--laughlab:viewer-->", f'<script type="module" src="./viewer.js" onerror="{_ONERROR}"></script>')
    return text.encode()


def _module_url(source: str) -> str:
    return "data:text/javascript;base64," + base64.b64encode(source.encode()).decode()


def inline_imports(vrm: bool = False) -> dict[str, str]:
    """The import map that resolves ``three`` and every vendored add-on to a ``data:`` URL; with ``vrm``,
    ``three-vrm`` too (it imports only ``three``)."""
    three = vendor_dir() / "three"
    imports = {"three": _module_url((three / "build" / "three.module.min.js").read_text(encoding="utf-8"))}
    jsm = three / "examples" / "jsm"
    for f in sorted(jsm.rglob("*.js")):
        here = f.parent.relative_to(jsm).as_posix()

        def bare(m: re.Match) -> str:  # a relative import has no base inside a data: URL
            parts = [p for p in f"{here}/{m.group(2)}".split("/") if p not in ("", ".")]
            out: list[str] = []
            for p in parts:
                out.pop() if p == ".." else out.append(p)
            return f"{m.group(1)}three/addons/{'/'.join(out)}{m.group(3)}"

        source = re.sub(r"""(from\s+['"])(\.{1,2}/[^'"]+)(['"])""", bare, f.read_text(encoding="utf-8"))
        imports[f"three/addons/{f.relative_to(jsm).as_posix()}"] = _module_url(source)
    if vrm:
        imports["three-vrm"] = _module_url((vendor_dir() / "three_vrm" / "three-vrm.module.min.js")
                                           .read_text(encoding="utf-8"))
    return imports


def fits_inline(run_json: bytes, glb: bytes) -> bool:
    return len(run_json) + len(glb) <= INLINE_MAX_BYTES


def static(name: str, run_json: bytes, glb: bytes, folder: Path, run_dir: Path, vrm: bool = False) -> bytes:
    """The page with everything but the audio inline (or, past :data:`INLINE_MAX_BYTES`, the served page);
    ``vrm``: the character is a VRM (three-vrm inlined too).

    The message shown if it cannot start names its folder and ``run_dir``: the page finds its own folder where it
    is opened (``location``), and holds only the run's path relative to ``folder``, where it is written. Until
    2026-11-28 it held both as absolute paths: a published page showed the author's folders."""
    if not fits_inline(run_json, glb):
        text = served(name).decode()
    else:
        js = viewer_js().decode()
        if "</script" in js.lower() or "<!--" in js:
            raise ValueError("viewer.js cannot be inlined: it holds '</script' or '<!--'")
        data = (f'<script type="application/json" id="laughlab-run">{_json_in_html(json.loads(run_json))}</script>\n'
                f'<script type="application/octet-stream" id="laughlab-glb">{base64.b64encode(glb).decode()}</script>')
        text = _template(name).replace(
            "<!--laughlab:importmap-->",
            f'<script type="importmap">{_json_in_html({"imports": inline_imports(vrm)})}</script>'
        ).replace("<!--laughlab:viewer-->", f'{data}\n<script type="module" onerror="{_ONERROR}">\n{js}</script>')
    try:
        rel = Path(os.path.relpath(run_dir, folder)).as_posix()
    except ValueError:   # Windows: another drive; the message then says RUN_DIR
        return text.encode()
    return text.replace("<body>", f'<body data-run="{html.escape(rel)}">', 1).encode()
