"""What laughlab assumes of the operating system (a Windows/macOS portability review, 2026-11-29).

Windows opens text files in the locale's code page (cp1252), not UTF-8: a report's README with its arrows, a Hydra
file holding a non-ASCII path, ended in UnicodeEncodeError/UnicodeDecodeError there.  Every text file laughlab
reads or writes names its encoding; a run and its report under a locale that is not UTF-8 (ASCII here, as strict
as cp1252 is for these characters) work.
"""
from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: receivers whose ``.open(...)`` is not a file's (plugins' and sources' own open methods)
NOT_FILES = ("os",)


def _text_opens_without_encoding(tree: ast.AST) -> list[int]:
    """Lines of ``open(...)``, ``X.open("w")``, ``read_text()`` and ``write_text(...)`` in text mode with no
    ``encoding=``."""
    out = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call) or any(k.arg == "encoding" for k in node.keywords):
            continue
        fn = node.func
        name = fn.attr if isinstance(fn, ast.Attribute) else fn.id if isinstance(fn, ast.Name) else None
        if name in ("read_text", "write_text"):
            out.append(node.lineno)
        elif name == "open":
            args = node.args
            if isinstance(fn, ast.Name):
                mode = args[1] if len(args) > 1 else next((k.value for k in node.keywords if k.arg == "mode"), None)
                devnull = args and isinstance(args[0], ast.Attribute) and args[0].attr == "devnull"
                if not devnull and (mode is None or isinstance(mode, ast.Constant) and "b" not in mode.value):
                    out.append(node.lineno)
            elif not (isinstance(fn.value, ast.Name) and fn.value.id in NOT_FILES) and args \
                    and isinstance(args[0], ast.Constant) and isinstance(args[0].value, str) \
                    and set(args[0].value) <= set("rwax+t"):   # path.open("w"): a file in text mode
                out.append(node.lineno)
    return out


def test_every_text_file_laughlab_opens_names_its_encoding():
    found = []
    for folder in ("laughlab", "plugins", "experiments"):
        for f in sorted((ROOT / folder).rglob("*.py")):
            for line in _text_opens_without_encoding(ast.parse(f.read_text(encoding="utf-8"))):
                found.append(f"{f.relative_to(ROOT)}:{line}")
    assert found == [], "text files opened in the locale's encoding (cp1252 on Windows): " + ", ".join(found)


def test_the_scan_finds_what_it_looks_for():
    src = ('open(p)\nopen(p, "w")\nopen(p, "rb")\nopen(p, "w", encoding="utf-8")\np.read_text()\n'
           'p.write_text(s)\np.write_text(s, encoding="utf-8")\npath.open("a")\nsink.open(run)\nos.open(p, 1)\n'
           'open(os.devnull, "w")\n')
    assert _text_opens_without_encoding(ast.parse(src)) == [1, 2, 5, 6, 8]


def test_a_run_and_its_report_under_a_locale_that_is_not_utf8(tmp_path):
    """The smoke experiment and its report with Python's UTF-8 mode off and the C locale: open()'s default is ASCII,
    which refuses the report's arrows as cp1252 would refuse other characters (the report's README raised
    UnicodeEncodeError: '\\u2191')."""
    env = {**os.environ, "LC_ALL": "C", "LANG": "C", "PYTHONCOERCECLOCALE": "0", "PYTHONUTF8": "0"}
    py = [sys.executable, "-X", "utf8=0", "-m", "laughlab"]
    check = subprocess.run([sys.executable, "-X", "utf8=0", "-c", "import locale; print(locale.getencoding())"],
                           env=env, capture_output=True, text=True)
    assert check.stdout.strip() in ("ANSI_X3.4-1968", "ascii", "US-ASCII"), check.stdout
    run = subprocess.run([*py, "experiment=smoke", "harness.corpus.seeds=1", f"hydra.run.dir={tmp_path / 'run'}",
                          "progress=off"], env=env, capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert run.returncode == 0, run.stderr
    rep = subprocess.run([*py, "report", str(tmp_path / "run"), "--out", str(tmp_path / "rep")], env=env,
                         capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert rep.returncode == 0, rep.stderr
    assert "\u2191" in (tmp_path / "rep" / "README.md").read_text(encoding="utf-8")


def test_the_browser_is_found_where_each_os_puts_it(tmp_path, monkeypatch):
    """Chromium was looked for only under Debian's names on the PATH; Chrome or Edge where macOS and Windows install
    them, or LAUGHLAB_CHROMIUM, serve too."""
    import pytest

    from laughlab.core.errors import LaughlabError
    from laughlab.viewer import browser

    fake = tmp_path / "chrome.exe"
    fake.write_text("", encoding="utf-8")
    monkeypatch.setattr(browser.shutil, "which", lambda name: None)
    monkeypatch.setattr(browser, "INSTALLED", ("/nowhere/Chromium", str(fake)))
    monkeypatch.delenv("LAUGHLAB_CHROMIUM", raising=False)
    assert browser.chromium() == str(fake)
    monkeypatch.setattr(browser, "INSTALLED", ())
    with pytest.raises(LaughlabError, match="set LAUGHLAB_CHROMIUM"):
        browser.chromium()
    monkeypatch.setenv("LAUGHLAB_CHROMIUM", str(fake))
    assert browser.chromium() == str(fake)
    monkeypatch.setenv("LAUGHLAB_CHROMIUM", str(tmp_path / "missing"))
    with pytest.raises(LaughlabError, match="is not a file"):
        browser.chromium()
