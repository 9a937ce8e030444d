"""Benchmark of video rendering (issue 13, item 4): the skinned character in software vs the stick figure.

20 s of synthetic laughter, ``output=video`` at 640 x 480, 30 fps, 2x supersampling, on this
machine (no GPU): frames drawn and piped to ffmpeg per second of wall time (``video_render_fps``
in ``metrics.json``).  Target: the character at least real time (30 fps).

Run: ``make bench`` (or ``python benchmarks/bench_render.py``); results in
``benchmarks/results/render.json``.
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent


def render_fps(style: str) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        r = subprocess.run([sys.executable, "-m", "laughlab", f"hydra.run.dir={out}", "input.duration_s=20",
                            "output=video", "face=facs", f"output.video.style={style}"], capture_output=True, text=True)
        if r.returncode:
            raise SystemExit(f"run failed: {r.stderr.strip()}")
        return float(json.loads((out / "metrics.json").read_text())["video_render_fps"])


def main() -> None:
    results = {style: render_fps(style) for style in ("character", "schematic")}
    for style, fps in results.items():
        print(f"{style:<10} {fps:6.1f} frames/s at 640x480 (target for the character: >= 30)")
    results["character_real_time"] = results["character"] >= 30.0
    out = HERE / "results"
    out.mkdir(exist_ok=True)
    (out / "render.json").write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
