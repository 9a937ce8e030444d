"""Scenes of real audio with ground truth: real laughs spliced between speech and other sounds, over room noise.

A scene is a timeline of events on a bed of background noise:

- ``speech``: a turn of 2-8 s, utterances of one voice joined by 0.05-0.4 s pauses;
- ``laugh``: one annotated laugh recording (its bouts and calls become the truth);
- ``other``: a cough, sneeze, scream, breath, clap, singing, music or noise clip;
- pauses of 0.3-2 s between events.

The truth rows are the laughs' ``bout`` and ``call`` rows and one row per other
event (kind ``speech``, ``cough``, ``music``, ...; bout -1), so a reader of the
truth can tell what a false alarm answered.

Every event is scaled to a foreground level drawn around -26 dBFS (+/- 6 dB);
the bed is pink noise (a room's hum and hiss) mixed with a looped ``noise`` or
``music`` clip, set ``snr_db`` below the foreground's speech level.  All audio is
resampled to ``SAMPLE_RATE`` (44.1 kHz).  The same seed gives the same bytes.
"""
from __future__ import annotations

import csv
import hashlib
import json
import math
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from laughlab.core.errors import LaughlabError
from laughlab.corpora import annotations as ann_mod
from laughlab.corpora.fetch import load_lock, require

SAMPLE_RATE = 44100
OTHER_KINDS = ("cough", "sneeze", "scream", "breath", "clap", "singing", "music", "noise", "vocal")
#: the human sounds that are neither laughter nor speech (``vocal``: cries, moans, grunts, shouts, "hmm", "ow")
HUMAN_KINDS = ("cough", "sneeze", "scream", "breath", "vocal")
BED_KINDS = ("noise", "music")
FG_DBFS = -26.0


@lru_cache(maxsize=4096)
def load(path: str, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """A file as float64 mono at ``sample_rate`` (polyphase resampling, scipy)."""
    import soundfile as sf
    from scipy.signal import resample_poly

    x, sr = sf.read(path, dtype="float64", always_2d=True)
    x = x.mean(axis=1)
    if sr != sample_rate:
        g = math.gcd(int(sr), int(sample_rate))
        x = resample_poly(x, sample_rate // g, int(sr) // g)
    x.setflags(write=False)
    return x


def _rms_active(x: np.ndarray) -> float:
    """RMS over the loudest half of 20 ms frames (the level of the sound, not of its pauses)."""
    n = max(1, int(0.02 * SAMPLE_RATE))
    m = len(x) // n
    if m == 0:
        return float(np.sqrt(np.mean(x * x) + 1e-20))
    e = np.sort((x[: m * n].reshape(m, n) ** 2).mean(axis=1))[::-1]
    return float(np.sqrt(e[: max(1, m // 2)].mean() + 1e-20))


def pink_noise(rng: np.random.Generator, n: int) -> np.ndarray:
    """Pink (1/f power) noise of unit RMS, by shaping white noise's spectrum."""
    w = rng.standard_normal(n)
    spec = np.fft.rfft(w)
    f = np.arange(len(spec), dtype=float)
    f[0] = 1.0
    x = np.fft.irfft(spec / np.sqrt(f), n)
    return x / (np.sqrt(np.mean(x * x)) + 1e-20)


@dataclass
class Pool:
    """The files of one split, by kind, with the laughs' annotations."""

    by_kind: dict
    annotations: dict
    voices: dict

    @classmethod
    def of_split(cls, split: str) -> "Pool":
        """The fetched files of ``split`` (``train``, ``test`` or ``all``); laughs need an annotation."""
        files = require(split=None if split == "all" else split)
        lock = load_lock()["files"]
        by_kind, anns, voices = {}, {}, {}
        for iid, path in files.items():
            e = lock[iid]
            if e["kind"] == "laugh":
                a = ann_mod.bundled(iid, e["duration_s"])
                if a is None or not a.bouts:
                    continue
                anns[iid] = a
            by_kind.setdefault(e["kind"], []).append((iid, str(path)))
            if e["kind"] == "speech":
                voices.setdefault(_voice(iid), []).append((iid, str(path)))
        return cls(by_kind, anns, voices)


def _voice(iid: str) -> str:
    """The voice of a speech item: its folder (hedgewars voice pack, language, kajongg speaker)."""
    src, name = iid.split("/", 1)
    return f"{src}/{name.split('-')[0]}" if src in ("hedgewars", "ktuberling", "kajongg") else src


def _place(out: np.ndarray, x: np.ndarray, at: int) -> None:
    n = min(len(x), len(out) - at)
    if n > 0:
        out[at:at + n] += x[:n]


def speech_turn(rng: np.random.Generator, pool: Pool, max_s: float) -> np.ndarray:
    """2-8 s (at most ``max_s``) of one voice: its utterances joined by short pauses."""
    voice = sorted(pool.voices)[rng.integers(len(pool.voices))]
    utts = pool.voices[voice]
    target = min(max_s, rng.uniform(2.0, 8.0))
    parts, n = [], 0
    while n < target * SAMPLE_RATE:
        _, path = utts[rng.integers(len(utts))]
        x = load(path)
        x = x / (_rms_active(x) + 1e-12)
        gap = np.zeros(int(rng.uniform(0.05, 0.4) * SAMPLE_RATE))
        parts += [x, gap]
        n += len(x) + len(gap)
    return np.concatenate(parts)


def _event(kind: str, at: int, x: np.ndarray, n: int) -> dict:
    """A truth row for a non-laughter event (kind ``speech``, ``cough``, ``music``, ...)."""
    return {"kind": kind, "bout": -1, "onset_s": at / SAMPLE_RATE, "offset_s": min(at + len(x), n) / SAMPLE_RATE,
            "intensity": 0.0}


def build_scene(rng: np.random.Generator, pool: Pool, duration_s: float, snr_db: float | None,
                laugh_share: float = 0.3, other_share: float = 0.2) -> tuple[np.ndarray, list[dict]]:
    """One scene (see the module docstring): (audio at 44.1 kHz, truth rows)."""
    n = int(duration_s * SAMPLE_RATE)
    fg = np.zeros(n)
    rows: list[dict] = []
    t = int(rng.uniform(0.3, 1.5) * SAMPLE_RATE)
    others = [k for k in OTHER_KINDS if pool.by_kind.get(k)]
    laughs = sorted(pool.annotations)
    bout = 0
    while t < n - SAMPLE_RATE:
        u = rng.random()
        level = 10 ** ((FG_DBFS + rng.uniform(-6.0, 6.0)) / 20.0)
        if u < laugh_share and laughs:
            iid = laughs[rng.integers(len(laughs))]
            path = dict(pool.by_kind["laugh"])[iid]
            x = load(path)
            if t + len(x) > n:
                break
            x = x * (level / (_rms_active(x) + 1e-12))
            _place(fg, x, t)
            for r in pool.annotations[iid].truth_rows(t / SAMPLE_RATE):
                r["bout"] += bout
                rows.append(r)
            bout += len(pool.annotations[iid].bouts)
        elif u < laugh_share + other_share and others:
            kind = others[rng.integers(len(others))]
            _, path = pool.by_kind[kind][rng.integers(len(pool.by_kind[kind]))]
            x = load(path)[: int(rng.uniform(1.0, 6.0) * SAMPLE_RATE)]
            x = x * (level / (_rms_active(x) + 1e-12))
            _place(fg, x, t)
            rows.append(_event(kind, t, x, n))
        elif pool.voices:
            x = speech_turn(rng, pool, (n - t) / SAMPLE_RATE) * level
            _place(fg, x, t)
            rows.append(_event("speech", t, x, n))
        else:
            x = np.zeros(SAMPLE_RATE)
        t += len(x) + int(rng.uniform(0.3, 2.0) * SAMPLE_RATE)
    if snr_db is not None:
        bed = pink_noise(rng, n)
        beds = [k for k in BED_KINDS if pool.by_kind.get(k)]
        if beds and rng.random() < 0.5:
            kind = beds[rng.integers(len(beds))]
            _, path = pool.by_kind[kind][rng.integers(len(pool.by_kind[kind]))]
            clip = load(path)
            clip = clip / (np.sqrt(np.mean(clip * clip)) + 1e-12)
            bed = 0.5 * bed + np.resize(clip, n)
        bed = bed / (np.sqrt(np.mean(bed * bed)) + 1e-12)
        fg += bed * 10 ** ((FG_DBFS - snr_db) / 20.0)
    peak = float(np.abs(fg).max(initial=0.0))
    if peak > 0.99:
        fg *= 0.99 / peak
    rows.sort(key=lambda r: (r["onset_s"], r["kind"] != "bout"))
    return fg, rows


def speech_only(pool: Pool, duration_s: float, seed: int) -> np.ndarray:
    """Turns of speech from every voice of the pool, pauses of 0.3-1.5 s, no laughter."""
    rng = np.random.default_rng(seed)
    n = int(duration_s * SAMPLE_RATE)
    out = np.zeros(n)
    t = 0
    while t < n:
        x = speech_turn(rng, pool, 8.0) * 10 ** ((FG_DBFS + rng.uniform(-6.0, 6.0)) / 20.0)
        _place(out, x, t)
        t += len(x) + int(rng.uniform(0.3, 1.5) * SAMPLE_RATE)
    return out


TRUTH_COLUMNS = ("kind", "bout", "onset_s", "offset_s", "intensity")


def write_truth(path: Path, rows: list[dict]) -> None:
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=TRUTH_COLUMNS, lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{r[k]:.4f}" if isinstance(r[k], float) else r[k]) for k in TRUTH_COLUMNS})


def write_set(out_dir: Path, kind: str, split: str, n: int, duration_s: float, snr_db: list, seed: int) -> list[Path]:
    """Write ``n`` scenes (``kind="mixed"``), ``n`` speech-only streams (``speech``), the annotated
    laughs themselves (``real``) or every other human sound of the split alone (``others``: the
    ``HUMAN_KINDS``, one file each, truth one row of its kind) with ``NAME.truth.csv`` beside each WAV;
    reuse them when their parameters and the lock are unchanged.  ``real`` and ``others`` have half a
    second of silence around each recording.  Returns the WAV paths."""
    import soundfile as sf

    spec = {"kind": kind, "split": split, "n": n, "duration_s": duration_s, "snr_db": list(snr_db), "seed": seed,
            "version": 2, "lock": hashlib.sha256(json.dumps(load_lock()["files"], sort_keys=True).encode())
            .hexdigest()[:16], "annotations": ann_mod.digest()}
    stamp = out_dir / "set.json"
    if stamp.exists() and json.loads(stamp.read_text(encoding="utf-8")) == spec:
        return sorted(out_dir.glob("*.wav"))
    pool = Pool.of_split(split)
    if kind == "real" and not pool.annotations:
        raise LaughlabError(f"no annotated laughs in the {split} split")
    out_dir.mkdir(parents=True, exist_ok=True)
    for old in list(out_dir.glob("*.wav")) + list(out_dir.glob("*.truth.csv")):
        old.unlink()
    paths = []
    if kind == "others":
        for kind_of in HUMAN_KINDS:
            for iid, path in sorted(pool.by_kind.get(kind_of, [])):
                name = f"{kind_of}__{iid.replace('/', '__')}"
                x = load(path)
                pad = np.zeros(int(0.5 * SAMPLE_RATE))
                sf.write(out_dir / f"{name}.wav", np.concatenate([pad, x, pad]), SAMPLE_RATE, subtype="PCM_16")
                write_truth(out_dir / f"{name}.truth.csv", [_event(kind_of, len(pad), x, 2 * len(pad) + len(x))])
                paths.append(out_dir / f"{name}.wav")
    elif kind == "real":
        for iid, a in sorted(pool.annotations.items()):
            name = iid.replace("/", "__")
            x = load(dict(pool.by_kind["laugh"])[iid])
            pad = np.zeros(int(0.5 * SAMPLE_RATE))  # half a second of silence around each laugh
            sf.write(out_dir / f"{name}.wav", np.concatenate([pad, x, pad]), SAMPLE_RATE, subtype="PCM_16")
            write_truth(out_dir / f"{name}.truth.csv", a.truth_rows(0.5))
            paths.append(out_dir / f"{name}.wav")
    else:
        for i in range(n):
            snr = snr_db[i % len(snr_db)] if snr_db else None
            rng = np.random.default_rng([seed, i])
            if kind == "speech":
                x, rows = speech_only(pool, duration_s, seed * 1000 + i), []
            else:
                x, rows = build_scene(rng, pool, duration_s, snr)
            tag = "clean" if snr is None or kind == "speech" else f"{int(snr)}dB"
            name = f"{kind}-{tag}-{i:02d}"
            sf.write(out_dir / f"{name}.wav", x, SAMPLE_RATE, subtype="PCM_16")
            write_truth(out_dir / f"{name}.truth.csv", rows)
            paths.append(out_dir / f"{name}.wav")
    tmp = stamp.with_name("set.json.part")
    tmp.write_text(json.dumps(spec), encoding="utf-8")
    os.replace(tmp, stamp)
    return paths
