"""Experiment ``stimuli``: rendered videos for a perception study, with counterbalanced orders.

``python -m laughlab experiment=stimuli`` renders one MP4 per audio item x
condition, normalises the audio's loudness, and writes what PsychoPy and
jsPsych load directly.  van Duijn (2014, 6.1) asks for exactly such a study:
prerecorded laughter "of different levels of intensity", rated for naturalness,
with a view zoomed in on the face (the video's inset).

Conditions (``harness.preset``)
-------------------------------
``laughlab`` (default): what each part of the pipeline adds.

=============== =====================================================================
smile_only      ``scheduler=none``, chest and belly flat (``body.chest_gain=0``,
                ``body.belly_gain=0``): the idle body with the smile, jaw and eyes
face_breathing  ``scheduler=none``: face plus the chest/belly breathing shapes
laugh_energy    full laughter, clips chosen by the laughing energy (thesis ch. 4)
laugh_concat    full laughter, clips by segment concatenation (Ding et al. 2014, 4.2)
=============== =====================================================================

``riddle``: the smile-vs-laugh design of Ding et al. (2014, 5.2): the agent
Speaks (tells the riddle) or Listens (to the participant's riddle) and Smiles
or Laughs at the answer: SS, SL, LS, LL.  In laughlab terms the response is
the rendering and the role is presentation:

==== ======== ======== ==============================================================
id   role     response rendering
==== ======== ======== ==============================================================
SS   speaking smile    smile_only, the jaw shut, audio muted (the agent smiles silently)
SL   speaking laugh    laugh_energy with the laughter audio
LS   listening smile   as SS
LL   listening laugh   as SL
==== ======== ======== ==============================================================

The role (who tells the riddle) is a column of the order files for the
presentation script, which shows the riddle text; SS and LS (SL and LL) are
rendered alike.  In the paper the listening agent reacted live to the
participant's speech; that is laughlab's live mode (``input=mic
output=vmc``), these videos are its presentation-based variant.  The preset
uses one trial per condition (``design: one_per_condition``): each participant
sees the four conditions once, each with another audio item, as the paper's
participants saw four riddles in four conditions.  The paper also alternated
speaking and listening; a Williams square of four conditions cannot keep
that alternation in every row, so the orders here balance first-order carry-over
instead (see Orders).

Audio items (``harness.corpus``)
--------------------------------
As the harness: synthetic laughter over ``profiles`` x ``seeds`` (each with
its own seed) and/or every audio file of ``folder`` (run with each of
``run_seeds``).  The animation is computed from the item's original audio;
only the audio muxed into the video is normalised.

Loudness (``harness.loudness``)
-------------------------------
Every item's audio is normalised to ``target_lufs`` integrated loudness
(ITU-R BS.1770-4 via pyloudnorm, K-weighting and gating; default -23 LUFS,
EBU R 128) by one gain, before it is muxed (AAC).  If that gain would take the
sample peak above ``max_peak_dbfs`` (default -1 dBFS) the gain is lowered to
meet the peak and a warning is printed; ``audio.csv`` lists each item's
measured loudness before and after, the gain and the peak.  The loudness is of
the mono signal (played as dual mono on headphones it sounds about 3 dB
louder than a stereo programme of the same LUFS; the same for every item).

Outputs
-------
``stimuli/<stimulus_id>.mp4``; ``manifest.csv`` (``stimulus_id``, ``file``,
``sha256``, ``condition``, ``audio_id``, ``duration_s``, ``seed``, ``fps``;
paths relative to the output folder, so the same seed gives the same bytes
wherever it is written); ``audio/<audio_id>.wav`` (normalised, float 32-bit);
``audio.csv``; ``orders/psychopy/participant_NNN.csv`` (a PsychoPy loop's
conditions file: one row per trial, the video in ``file``),
``orders/psychopy_all.csv`` (every participant, ``participant`` column);
``orders/jspsych/participant_NNN.json`` (a jsPsych ``timeline_variables``
array: ``stimulus`` is the one-element list of the video path that the video
plugins take) and ``orders/jspsych_all.json`` (participant -> array).
Keep the folder as it is and put the PsychoPy experiment (or the jsPsych
page) in it: the paths are relative to it.

Resume: each video, once rendered, is journaled in ``stimuli/.rendered.jsonl``
(:class:`Rendered`, keyed by :func:`render_key`).  A run stopped by Ctrl-C or a
file-system fault keeps those videos; the same command renders only the others.

Orders
------
Participant ``p`` (1-based) takes row ``(p - 1) mod R`` of a balanced Latin
square (Williams 1949) of the ``n`` conditions (:func:`williams`): for even
``n`` the standard square (``R = n`` rows: first row 0, 1, n-1, 2, n-2, ...,
each further row adds 1 mod n), in which every condition appears once in
every position and every condition immediately follows every other exactly
once; for odd ``n`` that square plus its rows reversed (``R = 2n``), in which
each ordered pair is adjacent exactly twice.  Use a multiple of ``R``
participants for full balance.

``design: all``: every participant sees every stimulus, in blocks of one
audio item each; the blocks' order rotates by participant (a cyclic Latin
square over the items) and within each block the conditions follow the
participant's Williams row.  ``design: one_per_condition``: one trial per
condition, position ``j`` showing the item ``(p - 1 + j) mod n_items``.
"""
from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import shlex
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from laughlab.core.errors import LaughlabError
from laughlab.core.outfiles import file_sha256 as _sha256   # the manifest's hashes

#: a muted condition's mouth, shut, by face: the smile face's jaw takes an input range above the MCS' 1, so it never
#: opens (a silent smile's jaw followed the muted laugh: a laughing mouth without a sound, a video producer's review);
#: a face not named here keeps its mouth as it is, said in a note
SHUT_MOUTH = {"smile": ("face.jaw.min_e=1.0", "face.jaw.max_e=2.0")}

MANIFEST_COLUMNS = ("stimulus_id", "file", "sha256", "condition", "audio_id", "duration_s", "seed", "fps")
AUDIO_COLUMNS = ("audio_id", "source", "sample_rate", "duration_s", "loudness_in_lufs", "gain_db",
                 "loudness_out_lufs", "peak_out_dbfs", "limited")


# -- counterbalancing ---------------------------------------------------------------------------------------------

def williams(n: int) -> list[list[int]]:
    """Rows of a balanced Latin square (Williams design) of conditions ``0..n-1``.

    Even ``n``: ``n`` rows, each condition once per position and each ordered
    pair adjacent exactly once.  Odd ``n``: the ``n`` rows of the same
    construction and their reversals (``2n`` rows), each ordered pair adjacent
    exactly twice.
    """
    n = int(n)
    if n < 1:
        raise ValueError(f"a Latin square needs at least one condition (got {n})")
    first, lo, hi = [0], 1, n - 1
    while len(first) < n:
        if len(first) % 2:
            first.append(lo)
            lo += 1
        else:
            first.append(hi)
            hi -= 1
    rows = [[(c + i) % n for c in first] for i in range(n)]
    if n % 2:
        rows += [row[::-1] for row in rows]
    return rows


def _seeds_of(item, run_seeds: list[int]) -> list[int]:
    """The seeds an audio item is rendered with: a synthetic input its own, a recording each run seed."""
    return [item.seed] if item.seed is not None else run_seeds


def design_notes(n_conditions: int, n_items: int, n_participants: int, design: str) -> list[str]:
    """What a design leaves unbalanced, said before the stimuli are rendered (a review: both were accepted without
    a word): participants not a multiple of the Williams square's rows, and ``one_per_condition`` with fewer audio
    items than conditions, where a participant hears one item under several conditions."""
    rows = len(williams(n_conditions))
    out = []
    if n_participants % rows:
        more = n_participants % rows
        which = "row 1 serves" if more == 1 else f"rows 1-{more} serve"
        out.append(f"{n_participants} participants on a Williams square of {rows} rows: {which} one "
                   f"participant more than the others, so the orders are not balanced; "
                   f"{n_participants - more or rows} or {n_participants - more + rows} participants balance them")
    if design == "one_per_condition" and n_items < n_conditions:
        out.append(f"one_per_condition with {n_items} audio item(s) for {n_conditions} conditions: each participant "
                   "hears an item under more than one condition; more recordings (harness.corpus.folder), or "
                   "more seeds (harness.corpus.seeds) or profiles of the synthetic laughter, "
                   "give each condition its own")
    return out


def participant_trials(conditions: list[str], items: list[str], n_participants: int,
                       design: str = "all") -> list[list[tuple[str, str]]]:
    """Each participant's trials as (condition, audio_id) pairs (see the module doc, Orders)."""
    rows = williams(len(conditions))
    out = []
    for p in range(n_participants):
        order = [conditions[c] for c in rows[p % len(rows)]]
        if design == "all":
            blocks = [items[(p + b) % len(items)] for b in range(len(items))]
            out.append([(c, item) for item in blocks for c in order])
        elif design == "one_per_condition":
            out.append([(c, items[(p + j) % len(items)]) for j, c in enumerate(order)])
        else:
            raise ValueError(f"design must be all or one_per_condition (got {design!r})")
    return out


# -- loudness -----------------------------------------------------------------------------------------------------

def normalise_loudness(samples: np.ndarray, sample_rate: int, target_lufs: float = -23.0,
                       max_peak_dbfs: float = -1.0) -> tuple[np.ndarray, dict]:
    """Scale mono audio to ``target_lufs`` (ITU-R BS.1770-4 integrated loudness, pyloudnorm).

    Returns the scaled samples and ``loudness_in_lufs``, ``gain_db``,
    ``loudness_out_lufs``, ``peak_out_dbfs``, ``limited`` (the gain was
    lowered to keep the peak at ``max_peak_dbfs``).
    """
    import pyloudnorm

    x = np.asarray(samples, dtype=np.float64)
    if len(x) < int(0.4 * sample_rate) + 1:
        raise LaughlabError(f"loudness needs at least 0.4 s of audio (got {len(x) / sample_rate:.2f} s)")
    meter = pyloudnorm.Meter(int(sample_rate))
    before = float(meter.integrated_loudness(x))
    if not math.isfinite(before):
        raise LaughlabError("cannot normalise the loudness of silent audio")
    gain_db = float(target_lufs) - before
    peak = float(np.max(np.abs(x)))
    limited = False
    if peak > 0 and 20 * math.log10(peak) + gain_db > max_peak_dbfs:
        gain_db = max_peak_dbfs - 20 * math.log10(peak)
        limited = True
    y = x * 10 ** (gain_db / 20)
    info = {"loudness_in_lufs": before, "gain_db": gain_db, "loudness_out_lufs": float(meter.integrated_loudness(y)),
            "peak_out_dbfs": 20 * math.log10(max(float(np.max(np.abs(y))), 1e-12)), "limited": limited}
    return y.astype(np.float32), info


# -- the procedure ------------------------------------------------------------------------------------------------

def _write_text(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.part")
    tmp.write_text(text, encoding="utf-8", newline="")
    tmp.replace(path)


def _csv_text(columns, rows) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    w.writerows(rows)
    return buf.getvalue()


SCRATCH = "laughlab-stimuli-"
"""The prefix of the run's scratch folder in its output folder (renders in progress)."""

JOURNAL = ".rendered.jsonl"
"""In ``stimuli/``: one line per video rendered (its id, render key and manifest row), so an interrupted
run resumes; removed when the manifest is written."""


def render_key(overrides: list[str], spec: dict, keep_runs: bool) -> str:
    """What a video is made of: the run's overrides, the video settings, the bytes of the audio muxed in
    (its path is a temporary one: its sha256 instead) and the camera's framing (a video framed before the
    look-ahead framing of 2026-11-27, with a raised hand cut by the top, is rendered again)."""
    from laughlab.render.framing import VERSION

    video = {k: v for k, v in spec.items() if k != "audio_path"}
    doc = {"overrides": list(overrides), "video": video, "audio_sha256": _sha256(Path(spec["audio_path"])),
           "keep_runs": keep_runs, "framing": VERSION}
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()[:16]


class Rendered:
    """The journal of rendered videos (:data:`JOURNAL`); a line cut by a kill is ignored."""

    def __init__(self, path: Path):
        self.path = path
        self._lines: dict[str, dict] = {}
        if path.is_file():
            for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
                try:
                    rec = json.loads(line)
                    self._lines[rec["sid"]] = rec
                except (ValueError, KeyError, TypeError):
                    continue

    def finished(self, sid: str, key: str, video: Path, run_dir: Path | None) -> list | None:
        """The manifest row of ``sid`` if a run of the same ``key`` rendered it and its file is intact."""
        rec = self._lines.get(sid)
        if rec is None or rec.get("key") != key or not video.is_file() or _sha256(video) != rec["row"][2]:
            return None
        if run_dir is not None and not run_dir.is_dir():
            return None
        return list(rec["row"])

    def keep(self, sids: set[str]) -> None:
        """Drop the lines of videos that will be rendered again (and their files)."""
        for sid in [s for s in self._lines if s not in sids]:
            (self.path.parent / f"{sid}.mp4").unlink(missing_ok=True)
            del self._lines[sid]
        if self._lines or self.path.exists():
            self.path.write_text("".join(json.dumps(r, sort_keys=True) + "\n" for r in self._lines.values()),
                                 encoding="utf-8")

    def add(self, sid: str, key: str, row: list) -> None:
        import os

        self._lines[sid] = {"sid": sid, "key": key, "row": row}
        with open(self.path, "a", encoding="utf-8") as f:
            f.write(json.dumps(self._lines[sid], sort_keys=True) + "\n")
            f.flush()
            os.fsync(f.fileno())

    def sids(self) -> list[str]:
        return list(self._lines)

    def videos(self) -> list[Path]:
        return [self.path.parent / f"{sid}.mp4" for sid in self._lines]


def _register_sink() -> None:
    """Make sure the ``video`` sink is registered (before its entry point exists)."""
    from laughlab.core import plugins

    if "video" not in plugins.registry()["sink"]:
        from laughlab_plugins import sink_video

        plugins.pm.register(sink_video, name="laughlab_plugins.sink_video")


def _item_audio(item, base: list[str], seed: int, tmp: Path) -> tuple[np.ndarray, int]:
    """The item's audio as the pipeline reads it: mono float32 samples and the rate."""
    from laughlab.core import pipeline
    from laughlab.io.audio import read_blocks
    from laughlab.core.errors import LaughlabError
    from laughlab.harness.runner import _compose
    from laughlab.io.video import source_audio

    cfg = _compose([*base, *item.overrides, f"seed={seed}"])
    pipe = pipeline.build(cfg)
    try:
        path = source_audio(pipe.source, tmp / item.id)
        if path is None:
            raise LaughlabError(f"input {item.id} has no audio file to put in a video")
        rate = int(pipe.source.sample_rate)
        return np.concatenate(list(read_blocks(path))), rate
    finally:
        pipe.source.close()


def _write_wav(path: Path, samples: np.ndarray, rate: int) -> None:
    from laughlab.io.audio import FloatWavWriter

    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.part")
    with FloatWavWriter(tmp, rate) as f:
        f.write(samples)
    tmp.replace(path)


def _shut_mouth(overrides: list[str], cond: str) -> tuple:
    """The overrides that keep a muted condition's mouth shut under the face ``overrides`` choose (:data:`SHUT_MOUTH`);
    none, and a note, for a face without such settings."""
    from laughlab.harness.runner import _compose

    face = _compose(overrides).face.name
    if face not in SHUT_MOUTH:
        print(f"stimuli: note: face={face} has no setting that keeps a silent smile's mouth shut: {cond}'s mouth "
              "follows the muted laugh", file=sys.stderr)
    return SHUT_MOUTH.get(face, ())


def _render(overrides: list[str], video: dict, run_dir: Path, csv_too: bool = False) -> dict:
    """Run the pipeline with the ``video`` sink (and ``csv``) into ``run_dir``; return the video sink's metrics."""
    from laughlab.core import pipeline
    from laughlab.harness.runner import _compose

    cfg = _compose(overrides)
    OmegaConf.set_struct(cfg, False)
    cfg.output = OmegaConf.create({"csv": {}, "video": video} if csv_too else {"video": video})
    run_dir.mkdir(parents=True, exist_ok=True)
    pipe = pipeline.build(cfg)
    pipeline.execute(pipe, run_dir, OmegaConf.to_container(cfg, resolve=True))
    sink = next(s for s in pipe.sinks if s.name == "video")
    return sink.metrics()


def check(h: dict) -> None:
    """The keys this experiment adds to the harness, checked before anything is written (the command line calls
    it in its preflight; a review found a word for the loudness target failing after Hydra wrote the folder):
    the preset, the design, the participants, the loudness target and peak."""
    import math

    from laughlab.core.errors import LaughlabError

    preset_name = h.get("preset") or "laughlab"
    if preset_name not in (h.get("presets") or {}):
        raise LaughlabError(f"unknown stimuli preset {preset_name!r}; choose one of: {', '.join(h.get('presets') or {})}")
    for key, default in (("target_lufs", -23.0), ("max_peak_dbfs", -1.0)):
        v = (h.get("loudness") or {}).get(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise LaughlabError(f"harness.loudness.{key} must be a number (dB; got {v!r})")
    n = h.get("participants", 0)
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise LaughlabError(f"harness.participants must be a whole number >= 1 (got {n!r})")
    # here, not first in run(): the harness had made the run folder's parent by then (a review: an empty runs/)
    design = h.get("design") or (h["presets"][preset_name] or {}).get("design") or "all"
    if design not in ("all", "one_per_condition"):
        raise LaughlabError(f"harness.design must be all or one_per_condition (got {design!r})")


def run(cfg, out_dir) -> dict:
    """Render every stimulus, write the manifest, the audio and the participants' orders into ``out_dir``."""
    from laughlab.harness.corpus import build_corpus
    from laughlab.harness.experiment import _task_overrides
    from laughlab.harness.runner import check_conditions

    _register_sink()
    out_dir = Path(out_dir)
    h = OmegaConf.to_container(cfg.harness, resolve=True)
    check(h)
    preset_name = h.get("preset") or "laughlab"
    preset = (h.get("presets") or {}).get(preset_name)
    conditions = check_conditions(h.get("conditions") or preset.get("conditions"))
    muted = set(preset.get("muted") or [])
    columns = preset.get("columns") or {}
    design = h.get("design") or preset.get("design") or "all"   # check()ed
    items = build_corpus(h.get("corpus") or {})
    run_seeds = [int(s) for s in h.get("run_seeds") or [0]]
    n_participants = int(h["participants"])   # check()ed
    loud = h.get("loudness") or {}
    target, max_peak = float(loud.get("target_lufs", -23.0)), float(loud.get("max_peak_dbfs", -1.0))   # check()ed
    video = {k: v for k, v in (h.get("video") or {}).items()}
    base = _task_overrides()
    progress = str(cfg.get("progress", "auto")) != "off"
    for line in design_notes(len(conditions), sum(len(_seeds_of(i, run_seeds)) for i in items),
                             n_participants, design):
        print(f"stimuli: note: {line}", file=sys.stderr)

    stim_dir, audio_dir = out_dir / "stimuli", out_dir / "audio"
    stim_dir.mkdir(parents=True, exist_ok=True)
    journal = Rendered(stim_dir / JOURNAL)
    audio_rows, manifest, done = [], [], []
    for stale in out_dir.glob(f"{SCRATCH}*"):   # a killed run's scratch folder (it could not remove it)
        shutil.rmtree(stale, ignore_errors=True)
    work = Path(tempfile.mkdtemp(prefix=SCRATCH, dir=out_dir))
    try:
        # 1. every audio item, normalised once
        audio_files: dict[tuple[str, int], tuple[Path, Path]] = {}
        units = []  # (audio_id, item, seed)
        for item in items:
            seeds = _seeds_of(item, run_seeds)
            for s in seeds:
                audio_id = item.id if len(seeds) == 1 else f"{item.id}-seed{s}"
                samples, rate = _item_audio(item, base, s, work)
                origin = f"synthetic:{item.profile}" if item.seed is not None else Path(item.path).name
                try:
                    norm, info = normalise_loudness(samples, rate, target, max_peak)
                except LaughlabError as exc:   # which recording (a video producer's review: 'silent audio' alone)
                    raise LaughlabError(f"stimulus audio {origin}: {exc}; take it out of the corpus folder") from None
                if info["limited"]:
                    print(f"stimuli: warning: {audio_id} reaches {info['loudness_out_lufs']:.1f} LUFS, not "
                          f"{target:g}: the gain was limited to keep the peak at {max_peak:g} dBFS", file=sys.stderr)
                wav = audio_dir / f"{audio_id}.wav"
                _write_wav(wav, norm, rate)
                done.append(wav)
                silent = work / "silence" / f"{audio_id}.wav"
                if muted:
                    _write_wav(silent, np.zeros_like(norm), rate)
                audio_files[(item.id, s)] = (wav, silent)
                units.append((audio_id, item, s))
                audio_rows.append([audio_id, origin, rate, f"{len(samples) / rate:.6f}",
                                   f"{info['loudness_in_lufs']:.3f}", f"{info['gain_db']:.3f}",
                                   f"{info['loudness_out_lufs']:.3f}", f"{info['peak_out_dbfs']:.3f}",
                                   str(info["limited"]).lower()])
        # 2. every stimulus (those an interrupted run of the same configuration finished are kept)
        total = len(units) * len(conditions)
        keep_runs = bool(h.get("keep_runs"))
        jobs = []
        for cond, cond_overrides in conditions.items():
            if cond in muted:
                cond_overrides = [*cond_overrides, *_shut_mouth([*base, *cond_overrides], cond)]
            for audio_id, item, s in units:
                sid = f"{cond}-{audio_id}"
                wav, silent = audio_files[(item.id, s)]
                spec = {**video, "file": f"{sid}.mp4", "audio": True,
                        "audio_path": str(silent if cond in muted else wav)}
                overrides = [*base, *cond_overrides, *item.overrides, f"seed={s}"]
                key = render_key(overrides, spec, keep_runs)
                row = journal.finished(sid, key, stim_dir / f"{sid}.mp4",
                                       out_dir / "runs" / sid if keep_runs else None)
                jobs.append((sid, cond, audio_id, s, spec, overrides, key, row))
        kept = sum(1 for j in jobs if j[-1] is not None)
        if kept:
            print(f"stimuli: resuming: {kept} of {total} videos were rendered, rendering {total - kept}",
                  file=sys.stderr, flush=True)
        journal.keep({j[0] for j in jobs if j[-1] is not None})
        for k, (sid, cond, audio_id, s, spec, overrides, key, row) in enumerate(jobs, start=1):
            final = stim_dir / f"{sid}.mp4"
            if row is not None:
                manifest.append(row)
                continue
            run_dir = work / "runs" / sid
            if progress:
                print(f"stimuli: [{k}/{total}] {sid}", file=sys.stderr, flush=True)
            metrics = _render(overrides, spec, run_dir, keep_runs)
            (run_dir / f"{sid}.mp4").replace(final)
            done.append(final)
            if keep_runs:
                keep = out_dir / "runs" / sid
                shutil.rmtree(keep, ignore_errors=True)
                keep.parent.mkdir(parents=True, exist_ok=True)
                shutil.move(str(run_dir), keep)
            vfps = float(metrics["video_fps"])
            row = [sid, f"stimuli/{sid}.mp4", _sha256(final), cond, audio_id,
                   f"{metrics['video_frames'] / vfps:.6f}", s, f"{vfps:g}"]
            journal.add(sid, key, row)
            manifest.append(row)
    except BaseException as exc:
        # stopped (Ctrl-C, a full disk): the videos already rendered and journaled stay, so the same command
        # resumes; any other failure (a bad setting) leaves none of the run's files
        from laughlab.core import interrupts

        keep = interrupts.interrupted(exc) or isinstance(exc, OSError)
        kept = set(journal.sids()) if keep else set()
        for f in done:
            if f.parent != stim_dir or f.stem not in kept:
                f.unlink(missing_ok=True)
        if not kept:
            journal.path.unlink(missing_ok=True)
            for f in journal.videos():   # a resumed run's earlier videos: the same rule
                f.unlink(missing_ok=True)
        for d in (stim_dir, audio_dir):
            if d.is_dir() and not any(d.iterdir()):
                d.rmdir()
        raise
    finally:
        shutil.rmtree(work, ignore_errors=True)
    journal.path.unlink(missing_ok=True)   # every video is in the manifest now

    _write_text(out_dir / "manifest.csv", _csv_text(MANIFEST_COLUMNS, manifest))
    _write_text(out_dir / "audio.csv", _csv_text(AUDIO_COLUMNS, audio_rows))
    orders = write_orders(out_dir, manifest, list(conditions), [u[0] for u in units], n_participants, design,
                          columns)
    doc = {"experiment": h.get("name") or "stimuli", "preset": preset_name, "design": design,
           "conditions": conditions, "condition_order": list(conditions),  # the file's keys are sorted
           "muted": sorted(muted), "n_stimuli": len(manifest),
           "audio_items": [u[0] for u in units], "participants": n_participants,
           "latin_square_rows": len(williams(len(conditions))), "loudness_target_lufs": target,
           "orders": [p.relative_to(out_dir).as_posix() for p in orders]}   # the same file on every OS
    character = OmegaConf.select(cfg, "character", default=None)
    doc["character"] = ({"file": Path(str(character)).name, "sha256": _sha256(Path(str(character)).expanduser())}
                        if character else "mannequin")  # which body the participants saw
    _write_text(out_dir / "stimuli.json", json.dumps(doc, indent=2, sort_keys=True) + "\n")
    print(f"stimuli: {len(manifest)} videos -> {out_dir / 'manifest.csv'}; orders for {n_participants} "
          f"participants in {out_dir / 'orders'}; the study page: python -m laughlab study build "
          f"{shlex.quote(str(out_dir))}")
    return doc


def write_orders(out_dir: Path, manifest: list, conditions: list[str], audio_ids: list[str], n_participants: int,
                 design: str, columns: dict | None = None) -> list[Path]:
    """Write the PsychoPy and jsPsych order files; return their paths."""
    columns = columns or {}
    extra = sorted({k for c in columns.values() for k in (c or {})})
    by_key = {(row[3], row[4]): row for row in manifest}
    header = ["participant", "trial", "stimulus_id", "condition", "audio_id", "file", *extra]
    every, js_all, written = [], {}, []
    for p, trials in enumerate(participant_trials(conditions, audio_ids, n_participants, design), start=1):
        rows, js = [], []
        for t, (cond, audio_id) in enumerate(trials, start=1):
            sid, path = by_key[(cond, audio_id)][:2]
            more = [(columns.get(cond) or {}).get(k, "") for k in extra]
            rows.append([p, t, sid, cond, audio_id, path, *more])
            js.append({"participant": p, "trial": t, "stimulus_id": sid, "condition": cond, "audio_id": audio_id,
                       "file": path, "stimulus": [path], **dict(zip(extra, more))})
        every += rows
        js_all[str(p)] = js
        f = out_dir / "orders" / "psychopy" / f"participant_{p:03d}.csv"
        _write_text(f, _csv_text(header, rows))
        g = out_dir / "orders" / "jspsych" / f"participant_{p:03d}.json"
        _write_text(g, json.dumps(js, indent=1) + "\n")
        written += [f, g]
    f = out_dir / "orders" / "psychopy_all.csv"
    _write_text(f, _csv_text(header, every))
    g = out_dir / "orders" / "jspsych_all.json"
    _write_text(g, json.dumps(js_all, indent=1) + "\n")
    return written + [f, g]
