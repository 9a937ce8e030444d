"""What the live viewer (``output=viewer``) costs the frame loop: per frame, the tracks' values (the same
functions ``character.glb`` bakes: ``mannequin_tracks``, ``avatar_tracks``) and the JSON message, as the sink
computes them on a live session's one-frame chunks, on laughlab's mannequin and on Godette (VRM 0.x).

Input: a run of the default pipeline with ``face=facs`` on a real laugh at 44.1 kHz (the corpus' btanks
``laugh01``, 22.05 kHz, brought to 44.1 kHz by scipy's ``resample_poly``; without the corpus, the synthetic
laughter, said in the output).
The server's thread (sending to the page) is not timed: it runs beside the frame loop.

Run: ``python benchmarks/bench_viewer_live.py`` (about 20 s); writes ``benchmarks/results/viewer_live.json``.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))


def laugh01(rate: int) -> np.ndarray | None:
    """The corpus' btanks ``laugh01`` (22.05 kHz) brought to ``rate`` by scipy's ``resample_poly``, or None
    without the corpus (also ``bench_session.py``'s input)."""
    from laughlab.corpora.fetch import corpus_dir

    laugh = corpus_dir() / "files" / "btanks" / "laugh01.ogg"
    if not laugh.exists():
        return None
    import soundfile as sf
    from scipy.signal import resample_poly

    x, sr = sf.read(laugh, dtype="float64")
    return resample_poly(x, rate, sr)


def run_channels(out: Path) -> tuple[str, dict, np.ndarray, object]:
    """A run's channels (arkit.* included) and poses per frame, and what it ran on."""
    from omegaconf import OmegaConf

    from laughlab.core import pipeline
    from laughlab.core.config import compose_config
    x = laugh01(44100)
    source = ["input.duration_s=6"]
    if x is not None:
        import soundfile as sf

        sf.write(out / "laugh44k.wav", x, 44100, subtype="FLOAT")
        source = ["input=file", f"input.path={out / 'laugh44k.wav'}"]
    out = out / "run"
    cfg = compose_config(["face=facs", *source])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k not in ("hydra", "harness")])
    cfg.output = {"csv": {}, "bvh": {}, "arkit": {}}
    pipeline.execute(pipeline.build(cfg), out)
    import pandas as pd

    from laughlab.io.bvh import read_bvh

    ch = pd.read_csv(out / "channels.csv")
    face = pd.read_csv(out / "face_arkit.csv")
    channels = {c: ch[c].to_numpy() for c in ch.columns if c != "time"}
    channels.update({"arkit." + c: face[c].to_numpy() for c in face.columns if c != "time"})
    skeleton, motion, _ = read_bvh(out / "motion.bvh")
    what = "btanks laugh01 (laugh01.ogg, 44.1 kHz)" if x is not None else "synthetic laughter, 6 s (no corpus)"
    return what, channels, motion, skeleton


def per_frame_ms(tracks, channels: dict, motion: np.ndarray, fps: float = 60.0) -> np.ndarray:
    from laughlab.viewer.live import frame_message

    out = []
    for k in range(len(motion)):
        chunk = SimpleNamespace(poses=motion[k:k + 1], times=np.array([k / fps]),
                                channels={c: v[k:k + 1] for c, v in channels.items()})
        t0 = time.perf_counter()
        _, values = tracks(chunk)
        frame_message(k, k / fps, values[0], 0.0, 0.0)
        out.append((time.perf_counter() - t0) * 1000)
    return np.array(out[10:])   # the first frames import and warm up


def main() -> None:
    from laughlab.avatar.load import load_character
    from laughlab.viewer.live import Tracks

    with tempfile.TemporaryDirectory() as tmp:
        what, channels, motion, skeleton = run_channels(Path(tmp))
    godette = HERE.parent / "tests" / "assets" / "avatars" / "Godette_vrm_v4.vrm"
    result = {"input": what, "frames": int(len(motion))}
    for name, avatar in (("mannequin", None), ("godette_vrm0", load_character(str(godette)))):
        ms = per_frame_ms(Tracks(skeleton, avatar), channels, motion)
        result[name] = {"mean_ms": round(float(ms.mean()), 3), "p50_ms": round(float(np.median(ms)), 3),
                        "p99_ms": round(float(np.percentile(ms, 99)), 3)}
        print(f"{name}: per frame mean {ms.mean():.3f} ms, median {np.median(ms):.3f} ms, p99 "
              f"{np.percentile(ms, 99):.3f} ms ({what}, {len(ms)} frames)")
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "viewer_live.json").write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":   # --help prints what it measures; it took no arguments and ran (a review)
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
