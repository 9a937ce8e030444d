"""The ``pressure`` extractor against the recording's level and a room's noise, on the corpus' real laughs.

DiLorenzo et al. (2008, 6) normalise the pressure by its average peak height, which "also accounts for
differences in recording levels". Two checks of laughlab's causal reading of it:

1. **Level.** Every real laugh of a split (the files of ``sets/real-SPLIT`` with their ``.truth.csv``), at its own
   rate, through the extractor at gains 1, 0.3, 0.1 and 0.03 (0, -10, -20, -30 dB): the mean pressure inside the
   annotated bouts at each gain over that at gain 1, per file; the median and the lowest over the files.
2. **Noise.** The same laughs after 2 s of white noise at -60, -50 and -40 dBFS (RMS; the noise goes on under
   the laugh): the largest pressure in those 2 s (the torso should stay still) and the mean in the bouts.

``python benchmarks/bench_pressure_level.py [--split test|train]`` prints both and writes
``benchmarks/results/pressure_level.json`` (not committed).  About 20 s.
"""
from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np

GAINS = (1.0, 0.3, 0.1, 0.03)
NOISE_DBFS = (-60, -50, -40)
LEAD_S = 2.0
FPS = 60.0


def pressures(x: np.ndarray, sr: int) -> np.ndarray:
    """The extractor's ``pressure`` (cm H2O) per 60 fps frame of ``x``, its defaults."""
    from laughlab.core.bases import Context
    from laughlab.core.frame import Frame
    from laughlab.io.audio import cut_frames
    from laughlab_plugins.extractor_pressure import PressureExtractor

    ext = PressureExtractor(None, Context(fps=FPS, sample_rate=sr))
    out = []
    for k, block in enumerate(cut_frames([x.astype(np.float32)], sr, FPS)):
        f = Frame(k, k / FPS, 1 / FPS)
        ext.step(block, f)
        out.append(f.control["pressure"])
    return np.asarray(out)


def in_bouts(truth: Path, n: int, lead_s: float = 0.0) -> np.ndarray:
    rows = list(csv.DictReader(open(truth, encoding="utf-8")))
    y = np.zeros(n, bool)
    for r in rows:
        if r["kind"] == "bout":
            y[int((lead_s + float(r["onset_s"])) * FPS):int((lead_s + float(r["offset_s"])) * FPS)] = True
    return y


def main() -> None:
    import soundfile as sf

    from laughlab.corpora.fetch import corpus_dir

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--split", choices=("test", "train"), default="test")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "pressure_level.json"))
    ns = ap.parse_args()
    folder = corpus_dir() / "sets" / f"real-{ns.split}"
    wavs = sorted(folder.glob("*.wav"))
    if not wavs:
        raise SystemExit(f"no real laughs in {folder}: python -m laughlab corpus fetch")
    ratios = {g: [] for g in GAINS[1:]}
    lead = {db: [] for db in NOISE_DBFS}
    bouts = {db: [] for db in NOISE_DBFS}
    for i, wav in enumerate(wavs):
        x, sr = sf.read(wav, dtype="float32", always_2d=True)
        x = x.mean(axis=1)
        truth = wav.with_name(wav.stem + ".truth.csv")
        base = None
        for g in GAINS:
            p = pressures(x * np.float32(g), sr)
            m = float(p[in_bouts(truth, len(p))].mean())
            if g == 1.0:
                base = m
            elif base:
                ratios[g].append(m / base)
        rng = np.random.default_rng(i)
        for db in NOISE_DBFS:
            y = np.concatenate([np.zeros(int(LEAD_S * sr), np.float32), x])
            y = y + (10 ** (db / 20) * rng.standard_normal(len(y))).astype(np.float32)
            p = pressures(y, sr)
            lead[db].append(float(p[:int(LEAD_S * FPS) - 6].max()))
            bouts[db].append(float(p[in_bouts(truth, len(p), LEAD_S)].mean()))
    res = {"split": ns.split, "files": len(wavs),
           "level": {f"{20 * np.log10(g):.0f} dB": {"median_ratio": float(np.median(v)), "lowest": float(np.min(v))}
                     for g, v in ratios.items()},
           "noise": {f"{db} dBFS": {"lead_max_cmh2o": float(np.max(lead[db])), "bouts_mean_cmh2o": float(np.mean(bouts[db]))}
                     for db in NOISE_DBFS}}
    print(f"{len(wavs)} real laughs ({ns.split} split), pressure in the bouts at a gain over that at full level:")
    for k, v in res["level"].items():
        print(f"  {k}: median {v['median_ratio']:.3f}, lowest {v['lowest']:.3f}")
    print(f"white noise for {LEAD_S:g} s before each laugh (and under it):")
    for k, v in res["noise"].items():
        print(f"  {k}: largest pressure before the laugh {v['lead_max_cmh2o']:.4f} cm H2O; mean in the bouts "
              f"{v['bouts_mean_cmh2o']:.4f}")
    Path(ns.out).parent.mkdir(parents=True, exist_ok=True)
    Path(ns.out).write_text(json.dumps(res, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
