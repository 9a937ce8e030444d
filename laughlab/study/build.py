"""``python -m laughlab study build STIMULI_RUN_DIR``: a self-contained study folder.

What the folder holds (it runs offline, from ``study serve`` or any static host):

=====================  ==========================================================================
``index.html``         the page: consent, instructions, the audio check, the participant's trials
                       (video, then the rating questions), attention items, the end page
``study.js``,          the jsPsych timeline (``laughlab/study/page/``) and its style
``study.css``
``design.js``,         the design (``laughlab.study.design``): every participant's trials, the
``design.json``        questions, the checks; the same document twice (the page reads the ``.js``, whose audio-check
                       words are hashes: ``laughlab.study.design.page_design``;
                       so it also runs from ``file://``)
``stimuli/*.mp4``      the videos, checked against the manifest's sha256
``audio_check/*.wav``  the words of the audio check, loudness-normalised like the stimuli
``vendor/jspsych/``    jsPsych and its plugins from the npm registry (``laughlab.study.vendor``)
=====================  ==========================================================================

The folder is written whole or not at all (built beside it, then moved in).  ``--overwrite``
replaces only these entries of an earlier study folder; a folder holding a database of people's
answers (any name), or a folder that is not a study, is never replaced.
"""
from __future__ import annotations

import json
import shutil
import sys
from importlib import resources
from pathlib import Path

import numpy as np

from laughlab.core.errors import LaughlabError
from laughlab.study import design as D
from laughlab.study import vendor

PAGE_FILES = ("index.html", "study.js", "study.css")
DB_NAME = "responses.sqlite"
#: what ``build`` writes at the top of the study folder (``--overwrite`` replaces these and nothing else)
OWN = (*PAGE_FILES, "design.js", "design.json", "stimuli", "audio_check", "vendor")


def check_out(out: Path, overwrite: bool) -> None:
    """Refuse a study folder that may not be (re)built: one that holds people's answers, or, without
    ``overwrite``, anything; with it, anything but an earlier study."""
    from laughlab.study.db import participants_kind

    if not out.exists():
        return
    if not out.is_dir():
        raise LaughlabError(f"{out} exists and is not a folder; choose another --out")
    held = sorted(p.name for p in out.iterdir())
    for name in held:
        f = out / name
        try:
            with open(f, "rb") as fh:
                sqlite = fh.read(16) == b"SQLite format 3\x00"
        except OSError:   # a folder, or unreadable
            sqlite = False
        # a database of people's answers is never replaced; one without any answer (the page served and opened,
        # nobody answered: a review found it blocked the rebuild) goes with the study's other files
        if sqlite and participants_kind(f) != "simulated" and _answered(f):
            raise LaughlabError(f"{out} holds a study's response database with answers ({name}); build the study "
                                "into another folder")
    if held and not overwrite:
        raise LaughlabError(f"{out} exists and is not empty; choose another --out or add --overwrite")
    if held and "design.json" not in held:
        raise LaughlabError(f"{out} is not a study folder (no design.json); --overwrite replaces only an earlier "
                            "study: choose an empty or new --out")


def _answered(db: Path) -> bool:
    """Does the study database ``db`` hold an answer?  (Unreadable: assume it does.)"""
    import sqlite3

    from laughlab.study.db import participants_stored

    try:
        return bool(participants_stored(db))
    except sqlite3.DatabaseError:
        return True


def default_out(run_dir: Path) -> Path:
    run_dir = Path(run_dir).resolve()
    return run_dir.with_name(run_dir.name + "-study")


def _word_audio(word: str) -> Path:
    """The KTuberling recording of an English ``word`` (Debian ktuberling-data), fetched if missing."""
    from laughlab.corpora import fetch as F

    iid = f"ktuberling/en-{word}"
    lock = F.load_lock()
    entry = lock["files"].get(iid)
    if entry is None:
        words = sorted(i.split("/en-", 1)[1] for i in lock["files"] if i.startswith("ktuberling/en-"))
        raise LaughlabError(f"no recording of {word!r} for the audio check; give a file "
                            f"({{file: my.wav, answer: {word}}}) or choose one of: {', '.join(words)}")
    path = F.file_path(iid, entry)
    if not (path.is_file() and F.sha256(path.read_bytes()) == entry["sha256"]):
        F.fetch(["ktuberling-data"], progress=lambda m: print(f"study: {m}", file=sys.stderr, flush=True))
    return path


def audio_check_files(words: list, target_lufs: float, out: Path, base: Path) -> list[dict]:
    """Write each audio-check word as ``audio_check/word_N.wav`` (16-bit, normalised); their entries."""
    import soundfile as sf

    from laughlab_experiments.stimuli import normalise_loudness

    entries = []
    for k, w in enumerate(words, start=1):
        if isinstance(w, dict):
            if not w.get("file") or not w.get("answer"):
                raise LaughlabError("an audio_check word given as a mapping needs file and answer")
            src, answer = (base / Path(str(w["file"])).expanduser()), str(w["answer"])
            if not src.is_file():
                raise LaughlabError(f"no audio-check recording at {src}")
        else:
            src, answer = _word_audio(str(w)), str(w)
        try:
            x, rate = sf.read(str(src), dtype="float64", always_2d=True)
        except Exception as exc:  # noqa: BLE001 - an unreadable recording: one line
            raise LaughlabError(f"cannot read the audio-check recording {src}: {exc}") from None
        y, _ = normalise_loudness(x.mean(axis=1), rate, target_lufs)
        pad = np.zeros(int(0.3 * rate), dtype=np.float32)  # a breath of silence either side: no clipped onset
        name = f"audio_check/word_{k}.wav"
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        sf.write(str(out / name), np.concatenate([pad, y, pad]), rate, subtype="PCM_16")
        entries.append({"file": name, "answer": answer.strip().lower()})
    return entries


def build(run_dir, out=None, questions: str | None = None, overwrite: bool = False) -> Path:
    """Build the study folder of a stimuli run into ``out``; its path."""
    run_dir = Path(run_dir).expanduser()
    info, manifest, _ = D.read_stimuli(run_dir)
    preset_name = questions or info.get("preset") or "laughlab"
    if questions is None and preset_name not in D.preset_names():
        preset_name = "laughlab"
    preset = D.load_preset(preset_name)
    out = Path(out).expanduser() if out else default_out(run_dir)
    check_out(out, overwrite)
    from laughlab.core.outfiles import file_sha256   # as the stimuli manifest hashes

    mods = vendor.install()
    tmp = out.with_name(f".{out.name}.part")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    try:
        for m in manifest:
            src = run_dir / m["file"]
            if not src.is_file() or file_sha256(src) != m["sha256"]:
                raise LaughlabError(f"{src} is missing or differs from the manifest's sha256; render the "
                                    "stimuli again")
            (tmp / m["file"]).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, tmp / m["file"])
        words = audio_check_files(preset["audio_check"]["words"], float(info.get("loudness_target_lufs", -23.0)),
                                  tmp, Path(questions).expanduser().parent if questions and
                                  Path(questions).suffix in (".yaml", ".yml") else Path.cwd())
        doc = D.make_design(run_dir, preset, Path(preset_name).stem, words)
        doc["jspsych"] = {"version": vendor.JSPSYCH, "plugins": vendor.PLUGINS}
        text = json.dumps(doc, indent=1, sort_keys=True)
        (tmp / "design.json").write_text(text + "\n", encoding="utf-8")
        (tmp / "design.js").write_text(f"window.STUDY = {json.dumps(D.page_design(doc), indent=1, sort_keys=True)};\n",
                                       encoding="utf-8")
        page = resources.files("laughlab.study").joinpath("page")
        for name in PAGE_FILES:
            (tmp / name).write_bytes(page.joinpath(name).read_bytes())
        vendor.copy_into(tmp / "vendor" / "jspsych", mods)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    check_out(out, overwrite)   # again: vendoring and copying took a while
    if not out.exists():
        tmp.rename(out)
        return out
    from laughlab.core.outfiles import remove

    for name in OWN:   # an earlier study: its own entries only; the user's files, reports, databases stay
        remove(out / name)
        if (tmp / name).exists():
            (tmp / name).rename(out / name)
    shutil.rmtree(tmp, ignore_errors=True)
    return out
