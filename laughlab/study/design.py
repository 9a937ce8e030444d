"""The design of a study: who sees which stimulus in which trial, and what is asked after it.

A design is built from the folder ``experiment=stimuli`` wrote (``stimuli.json``, ``manifest.csv``,
``orders/jspsych/participant_NNN.json``) and a preset of rating questions
(``laughlab/study/presets/<stimuli preset>.yaml``, or ``--questions FILE``).  It is one JSON
document (``design.json`` in the study folder, ``window.STUDY`` in ``design.js``) that the page
runs, the server checks every post against and the analysis reads its exclusion rules from.

Participant ``p`` (1 .. ``participants``) takes the order file of the stimuli run, i.e. row
``(p - 1) mod R`` of its balanced Latin square (``order_row``).  Attention items sit in
``attention.count`` trials spread evenly over each participant's trials (trial
``floor((k + 0.5) * n / count) + 1`` for k = 0 ..); the audio-check word is the participant's in
turn (``words[(p - 1) mod len(words)]``).
"""
from __future__ import annotations

import csv
import hashlib
import json
import re
from importlib import resources
from pathlib import Path

from laughlab.core.errors import LaughlabError, read_json_object
from laughlab.study.exclusions import DEFAULT_RULES

SCALES = ("likert", "slider")
#: the kinds of rows a study stores (``kind`` column)
KINDS = ("rating", "attention", "audio_check")


def _yaml(path) -> dict:
    from omegaconf import OmegaConf

    try:
        doc = OmegaConf.to_container(OmegaConf.load(path), resolve=True)
    except Exception as exc:  # noqa: BLE001 - a YAML error in the user's file: one line
        mark = getattr(exc, "problem_mark", None)   # the parser's line and cause (a review got only its context)
        why = (f"line {mark.line + 1}, column {mark.column + 1}: {exc.problem}" if mark is not None and
               getattr(exc, "problem", None) else str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
        raise LaughlabError(f"cannot read {path}: {why}") from None
    if not isinstance(doc, dict):
        raise LaughlabError(f"{path} must hold a mapping of study settings")
    return doc


def preset_names() -> list[str]:
    return sorted(p.name[:-5] for p in resources.files("laughlab.study").joinpath("presets").iterdir()
                  if p.name.endswith(".yaml"))


def load_preset(name_or_path: str) -> dict:
    """A preset by name (``laughlab``, ``riddle``) or a YAML file, its ``base`` merged in, checked."""
    path = Path(name_or_path).expanduser()
    if name_or_path in preset_names():
        doc = _yaml(resources.files("laughlab.study").joinpath("presets", f"{name_or_path}.yaml"))
    elif path.suffix in (".yaml", ".yml") or path.is_file():
        if not path.is_file():
            raise LaughlabError(f"no questions file at {path}")
        doc = _yaml(path)
    else:
        raise LaughlabError(f"unknown study preset {name_or_path!r}; choose one of: {', '.join(preset_names())} "
                            "or give a YAML file")
    base = doc.pop("base", None)
    if base:
        doc = {**load_preset(base), **doc}
    return check_preset(doc)


def check_preset(doc: dict) -> dict:
    """The preset with its defaults filled in; a one-line error for anything a page cannot run."""
    def need(cond, msg):
        if not cond:
            raise LaughlabError(f"study preset: {msg}")

    known = {"title", "scale", "points", "slider", "questions", "consent", "instructions", "end", "audio_check",
             "attention", "completion_url", "decline_url", "screened_out_url", "exclusions"}
    unknown = sorted(set(doc) - known)
    need(not unknown, f"unknown key(s) {', '.join(unknown)}; valid: {', '.join(sorted(known))}")
    doc = dict(doc)
    doc.setdefault("title", "A laughing character")
    need(doc.get("scale", "likert") in SCALES, f"scale must be one of {', '.join(SCALES)}")
    doc["scale"] = doc.get("scale", "likert")
    points = doc.setdefault("points", 7)
    need(isinstance(points, int) and 2 <= points <= 11, f"points must be a whole number 2..11 (got {points!r})")
    slider = {"min": 0, "max": 100, "step": 1, **(doc.get("slider") or {})}
    need(all(isinstance(slider[k], (int, float)) for k in ("min", "max", "step")) and slider["min"] < slider["max"]
         and slider["step"] > 0, "slider needs numbers min < max and step > 0")
    doc["slider"] = slider
    qs = doc.get("questions") or []
    need(isinstance(qs, list) and qs, "questions must be a non-empty list")
    ids = set()
    for q in qs:
        need(isinstance(q, dict) and isinstance(q.get("id"), str) and q["id"].isidentifier(),
             f"every question needs an id made of letters, digits and _ (got {q!r})")
        need(q["id"] not in ids and q["id"] not in KINDS, f"question id {q['id']!r} is used twice or reserved")
        ids.add(q["id"])
        need(isinstance(q.get("prompt"), str) and q["prompt"], f"question {q['id']} needs a prompt")
        labels = q.setdefault("labels", ["", ""])
        need(isinstance(labels, list) and len(labels) == 2, f"question {q['id']}: labels are the two ends [low, high]")
    ac = {"words": ["hat"], "attempts": 3, "on_fail": "end", **(doc.get("audio_check") or {})}
    need(isinstance(ac["words"], list) and ac["words"], "audio_check.words must be a non-empty list")
    need(isinstance(ac["attempts"], int) and ac["attempts"] >= 1, "audio_check.attempts must be >= 1")
    need(ac["on_fail"] in ("end", "continue"), f"audio_check.on_fail must be end or continue (got {ac['on_fail']!r})")
    doc["audio_check"] = ac
    att = {"count": 0, "value": 1, "prompt": "Please choose {value} here.", **(doc.get("attention") or {})}
    need(isinstance(att["count"], int) and att["count"] >= 0, "attention.count must be a whole number >= 0")
    lo, hi = (1, points) if doc["scale"] == "likert" else (slider["min"], slider["max"])
    need(isinstance(att["value"], (int, float)) and lo <= att["value"] <= hi,
         f"attention.value must lie on the scale, {lo}..{hi}")
    doc["attention"] = att
    doc["exclusions"] = {**DEFAULT_RULES, **(doc.get("exclusions") or {})}
    doc.setdefault("consent", "<p>Do you agree to take part?</p>")
    ins = doc.setdefault("instructions", [])
    doc["instructions"] = [ins] if isinstance(ins, str) else list(ins)
    doc.setdefault("end", "<p>Thank you.</p>")
    doc.setdefault("completion_url", None)
    doc.setdefault("decline_url", None)
    doc.setdefault("screened_out_url", None)
    return doc


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def read_stimuli(run_dir: Path) -> tuple[dict, list[dict], dict[int, list[dict]]]:
    """``stimuli.json``, the manifest rows and each participant's trials from an ``experiment=stimuli`` folder."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():   # a missing folder "had no stimuli.json, ..." (a new-user review)
        raise LaughlabError(f"{run_dir} {'is not a folder' if run_dir.exists() else 'not found'}: give the "
                            "hydra.run.dir of an experiment=stimuli run")
    need = [n for n in ("stimuli.json", "manifest.csv", "orders/jspsych_all.json") if not (run_dir / n).is_file()]
    if need:
        raise LaughlabError(f"{run_dir} is not a finished experiment=stimuli folder: it has no {', '.join(need)}")
    again = "; render the stimuli again (python -m laughlab experiment=stimuli)"
    info = read_json(run_dir / "stimuli.json", again)
    manifest = read_csv(run_dir / "manifest.csv")
    orders_file = run_dir / "orders" / "jspsych_all.json"
    try:
        orders = {int(p): list(trials) for p, trials in read_json(orders_file, again).items()}
        for trials in orders.values():
            for t in trials:
                for key in ("trial", "stimulus_id", "condition", "audio_id", "file"):
                    t[key]   # noqa: B018 (each trial names these: make_design reads them)
    except (KeyError, TypeError, ValueError) as exc:
        raise LaughlabError(f"{orders_file} is damaged ({type(exc).__name__}: {exc}){again}") from None
    return info, manifest, orders


def read_json(path: Path, fix: str) -> dict:
    """A JSON object laughlab wrote (``stimuli.json``, ``design.json``, ``report.json``...); a damaged one is one
    line naming it, ending with ``fix`` (a review: tracebacks)."""
    return read_json_object(path, fix)


def attention_trials(n_trials: int, count: int) -> list[int]:
    """The (1-based) trials that carry an attention item: ``count`` of them spread evenly."""
    count = min(count, n_trials)
    return sorted({int((k + 0.5) * n_trials / count) + 1 for k in range(count)}) if count else []


def make_design(run_dir: Path, preset: dict, preset_name: str, audio_files: list[dict]) -> dict:
    """The study's design document (see the module doc); ``audio_files`` are the built audio-check words."""
    info, manifest, orders = read_stimuli(run_dir)
    rows = int(info.get("latin_square_rows") or len(info.get("conditions") or {}) or 1)
    durations = {m["stimulus_id"]: float(m["duration_s"]) for m in manifest}
    participants = {}
    for p, trials in sorted(orders.items()):
        att = attention_trials(len(trials), preset["attention"]["count"])
        participants[str(p)] = {
            "order_row": (p - 1) % rows,
            "audio_check": (p - 1) % len(audio_files),
            "trials": [{"trial": t["trial"], "stimulus": t["stimulus_id"], "condition": t["condition"],
                        "audio_id": t["audio_id"], "file": t["file"], "attention": t["trial"] in att,
                        **{k: v for k, v in t.items() if k not in ("participant", "trial", "stimulus_id", "condition",
                                                                    "audio_id", "file", "stimulus")}}
                       for t in trials]}
    n = max(len(p["trials"]) for p in participants.values())
    seconds = sum(durations.values()) / max(len(durations), 1)
    minutes = max(1, round(n * (seconds + 8 * len(preset["questions"]) / 2 + 2) / 60 + 2))
    slider = preset["scale"] == "slider"   # {scale} and {keys}: the texts fit a slider too (an accessibility review)
    lo, hi = (preset["slider"]["min"], preset["slider"]["max"]) if slider else (1, preset["points"])
    fill = {"minutes": minutes, "n_questions": len(preset["questions"]), "points": preset["points"],
            "value": preset["attention"]["value"],
            "scale": f"a slider from {lo} to {hi}" if slider else f"a scale from 1 to {hi}",
            "keys": ("Move each slider with the mouse or the arrow keys, then press Enter" if slider else
                     f"Choose with the mouse, or press the keys 1 to {hi} and then Enter")}
    text = {k: preset[k].format(**fill) for k in ("consent", "end")}
    doc = {
        "format": 1,
        "title": preset["title"], "preset": preset_name, "stimuli_preset": info.get("preset"),
        "design": info.get("design"),
        # the preset's order (stimuli.json's keys are sorted; an older one has no condition_order)
        "conditions": list(info.get("condition_order") or info.get("conditions") or {}),
        "muted": info.get("muted") or [],
        "scale": preset["scale"], "points": preset["points"], "slider": preset["slider"],
        "questions": preset["questions"],
        "attention": {**preset["attention"], "prompt": preset["attention"]["prompt"].format(**fill)},
        "audio_check": {"attempts": preset["audio_check"]["attempts"], "files": audio_files},
        "audio_check_on_fail": preset["audio_check"]["on_fail"],   # not in the id: the answers are the same kind
        "consent": text["consent"], "end": text["end"],
        "instructions": [s.format(**fill) for s in preset["instructions"]],
        "completion_url": preset["completion_url"], "decline_url": preset["decline_url"],
        "screened_out_url": preset["screened_out_url"],
        "exclusions": preset["exclusions"],
        "latin_square_rows": rows, "minutes": minutes,
        "stimuli": {m["stimulus_id"]: {"file": m["file"], "condition": m["condition"], "audio_id": m["audio_id"],
                                       "duration_s": float(m["duration_s"]), "sha256": m["sha256"]}
                    for m in manifest},
        "participants": participants,
    }
    doc["id"] = design_id(doc)
    return doc


def design_id(doc: dict) -> str:
    """A short hash of what a response is checked against (trials, questions, scale, checks) and of what the
    participants saw: each stimulus' sha256 (since 2026-11-29; a user-study review served and analysed a database of
    answers to the mannequin's videos as the answers to the same design on an avatar, whose ids were the same)."""
    keep = {k: doc[k] for k in ("participants", "questions", "scale", "points", "slider", "attention", "audio_check")}
    keep["stimuli"] = {sid: s.get("sha256") for sid, s in (doc.get("stimuli") or {}).items()}
    return hashlib.sha256(json.dumps(keep, sort_keys=True).encode()).hexdigest()[:16]


def extends(new: dict, old: dict) -> bool:
    """Whether ``new`` is ``old`` built for more participants: the same questions, scale, checks and stimulus files,
    and every participant of ``old`` with the same trials (a study-pilot review: a study rebuilt for more
    participants refused its database, stranding everyone already assigned)."""
    same = ("questions", "scale", "points", "slider", "attention", "audio_check")
    shas = lambda d: {sid: s.get("sha256") for sid, s in (d.get("stimuli") or {}).items()}   # noqa: E731
    before, after = old.get("participants") or {}, new.get("participants") or {}
    return all(new.get(k) == old.get(k) for k in same) and shas(new) == shas(old) and len(after) > len(before) \
        and all(after.get(p) == entry for p, entry in before.items())


def load_design(study_dir: Path) -> dict:
    path = Path(study_dir) / "design.json"
    if not Path(study_dir).exists():   # a review: "is not a study folder" of a path that is not there at all
        raise LaughlabError(f"study folder not found: {study_dir}")
    if not path.is_file():
        raise LaughlabError(f"{study_dir} is not a study folder (no design.json): build one with "
                            "python -m laughlab study build STIMULI_RUN_DIR")
    return read_json(path, "; build the study again (python -m laughlab study build STIMULI_RUN_DIR)")


def scale_range(design: dict) -> tuple[float, float]:
    """The lowest and highest answer of a rating."""
    if design["scale"] == "likert":
        return 1.0, float(design["points"])
    return float(design["slider"]["min"]), float(design["slider"]["max"])


def identical_conditions(design: dict | None) -> list[tuple[str, str]]:
    """Pairs of conditions whose videos are the same files (sha256) for every audio item: the riddle preset's
    SS and LS (SL and LL) differ only in the role, which the page does not present, so a difference between
    them can only be noise and is not tested (``study analyze``, ``study power``)."""
    by = {}
    for s in (design or {}).get("stimuli", {}).values():
        by.setdefault(s["condition"], {})[s["audio_id"]] = s.get("sha256")
    conds = [c for c in (design or {}).get("conditions", []) if c in by]
    return [(a, b) for i, a in enumerate(conds) for b in conds[i + 1:]
            if by[a] == by[b] and None not in by[a].values()]


def normalise_word(s: str) -> str:
    """What the audio check compares: lower case, letters only (the page does the same)."""
    return re.sub(r"[^a-z\u00c0-\u024f]", "", s.lower())


def word_check(word: str) -> str:
    """The audio-check word as the page holds it: FNV-1a (32 bits, over the characters of
    :func:`normalise_word`) in hex.  The page compares a participant's word by this hash, so the words are not
    in its source for anyone to read (a review); ``design.json``, which the server keeps to itself, has them."""
    h = 0x811C9DC5
    for c in normalise_word(word):
        h = ((h ^ ord(c)) * 0x01000193) & 0xFFFFFFFF
    return f"{h:08x}"


def page_design(doc: dict) -> dict:
    """The design the page reads (``design.js``): ``doc`` with each audio-check word's ``answer`` replaced by its
    :func:`word_check`."""
    check = dict(doc["audio_check"])
    check["files"] = [{k: v for k, v in f.items() if k != "answer"} | {"check": word_check(f["answer"])}
                      for f in check["files"]]
    return {**doc, "audio_check": check}
