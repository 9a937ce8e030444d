"""Benchmark of the video's framing: how often the character touches or leaves the frame's edges.

What it measures: for every video frame ``output=video`` draws (style ``character``, 640 x 480, 30 fps, the
stimuli's settings), the projected extent of the character's mesh (every vertex, as the rasteriser receives
it: the pixels drawn are inside it) and whether it reaches the top, left or right edge of the frame (within
one output pixel: touching or cut).  The bottom edge cuts the body by design (the framing shows the upper
body), so it is not counted.  Also the smallest top and side margins seen (output pixels; negative: cut off),
how far the camera moved back (``zoomed_out``: frames drawn from farther than the configured distance;
``max_zoom_out``: the largest distance over the configured one, by which the face shrinks on screen) and the
face's height at rest (neck to the top of the head, output pixels): the framing must keep the face readable.

On which data:

* ``experiment=stimuli``'s conditions (``smile_only``, ``face_breathing``, ``laugh_energy``, ``laugh_concat``;
  the riddle preset's SL and LL are ``laugh_energy``'s settings, SS and LS ``smile_only``'s) over its default
  corpus: synthetic laughter, profiles mild and intense, 2 seeds, 8 s each (4 items, 960 frames a condition);
* the default run (``python -m laughlab output=video``: 30 s of synthetic laughter, 900 frames);
* a real recording at 44.1 kHz, ``btanks/laugh01.ogg`` of the corpus cache resampled by scipy
  (``bench_viewer_live.laugh01``), under ``laugh_energy``'s settings (skipped without the corpus);

each for the mannequin and for the avatar ``tests/assets/avatars/Godette_vrm_v4.vrm``.  The rasteriser is
replaced by a stub that records the vertices' pixels (the frames are then blank: this counts, it does not
look; the camera and everything before the rasteriser run as in a real run).

Run: ``python benchmarks/bench_framing.py`` (about 3 minutes on the 2-core machine); results in
``benchmarks/results/framing.json``.
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
AVATAR = ROOT / "tests" / "assets" / "avatars" / "Godette_vrm_v4.vrm"
CONDITIONS = {
    "smile_only": ["scheduler=none", "body.chest_gain=0.0", "body.belly_gain=0.0", "detector=none"],
    "face_breathing": ["scheduler=none", "detector=none"],
    "laugh_energy": ["scheduler=energy", "detector=none"],
    "laugh_concat": ["scheduler=concat", "detector=none"],
}
VIDEO = {"width": 640, "height": 480, "fps": 30.0, "crf": 20, "preset": "ultrafast", "threads": 2,
         "supersample": 2, "inset": True, "audio": False}


class Recorder:
    """Stands in for ``rasterise``: records each frame's vertex extent (supersampled pixels), returns the backdrop."""

    def __init__(self):
        self.lock = threading.Lock()
        self.frames: list[tuple[float, float, float, float, int, int]] = []

    def __call__(self, xy, depth, colour, tris, background):
        h, w = background.shape[:2]
        used = np.unique(tris)
        p = xy[used]
        with self.lock:
            self.frames.append((float(p[:, 0].min()), float(p[:, 1].min()), float(p[:, 0].max()),
                                float(p[:, 1].max()), w, h))
        return np.array(background, copy=True)

    def summary(self, ss: int) -> dict:
        a = np.array([f[:4] for f in self.frames]) / ss
        w, h = self.frames[0][4] / ss, self.frames[0][5] / ss
        top, left, right = a[:, 1] <= 1.0, a[:, 0] <= 1.0, a[:, 2] >= w - 1.0
        return {"frames": len(a), "top": int(top.sum()), "left": int(left.sum()), "right": int(right.sum()),
                "any": int((top | left | right).sum()), "min_top_margin_px": round(float(a[:, 1].min()), 1),
                "min_side_margin_px": round(float(min(a[:, 0].min(), w - a[:, 2].max())), 1)}


def _run(overrides: list[str], character: str | None, out: Path) -> dict:
    from omegaconf import OmegaConf

    from laughlab.core import pipeline
    from laughlab.harness.runner import _compose
    from laughlab.render import avatar_view, character_view
    import laughlab_experiments.stimuli as stimuli

    stimuli._register_sink()
    rec = Recorder()
    saved = character_view.rasterise, avatar_view.rasterise
    character_view.rasterise = avatar_view.rasterise = rec
    zoom: list[float] = []
    framing = None
    try:
        from laughlab.render import framing
    except ImportError:   # before the look-ahead framing (2026-11-27): the camera's distance never changed
        pass
    if framing is not None:
        plain = framing.Framing._distance

        def distance(self, i):
            d = plain(self, i)
            zoom.append(d / self.base)
            return d

        framing.Framing._distance = distance
    try:
        cfg = _compose(overrides)
        OmegaConf.set_struct(cfg, False)
        cfg.output = OmegaConf.create({"video": {**VIDEO, "character": character}})
        out.mkdir(parents=True, exist_ok=True)
        pipe = pipeline.build(cfg)
        pipeline.execute(pipe, out, OmegaConf.to_container(cfg, resolve=True))
    finally:
        character_view.rasterise, avatar_view.rasterise = saved
        if framing is not None:
            framing.Framing._distance = plain
    z = np.array(zoom or [1.0])
    return {**rec.summary(VIDEO["supersample"]), "zoomed_out": int((z > 1.0).sum()), "max_zoom_out": round(float(z.max()), 3)}


def face_size(character: str | None) -> float:
    """The head's height on screen in the rest pose (output pixels): the readable face the framing keeps."""
    from laughlab.motion.skeleton import HUMANOID as sk, global_transforms, rest_pose
    from laughlab.render.scene import Camera
    from laughlab_plugins.sink_video import VideoParams

    cam = Camera(**vars(VideoParams().character_camera))
    pose = rest_pose(sk)[None]
    if character is None:
        from laughlab.render.character_view import CharacterRenderer

        r = CharacterRenderer(sk, 640, 480, cam, 1)
        pos, _ = global_transforms(sk, pose[0])
        aim = r._follow(pos)
        xy, _ = r.camera.projector(640, 480, target=aim)(pos[[sk.index("neck"), sk.index("head")]])
        head_top = pos[sk.index("head")] + np.array([0.0, 20.0, 0.0])
        top, _ = r.camera.projector(640, 480, target=aim)(head_top)
        return round(float(xy[0, 1] - top[1]), 1)
    from laughlab.avatar.load import load_character
    from laughlab.render.avatar_view import AvatarRenderer

    av = load_character(character)
    r = AvatarRenderer(av, sk, 640, 480, cam, 1)
    world = r.worlds(pose)[0]
    aim = r._follow(world)
    b = av.bones
    pts = np.stack([world[b[n], :3, 3] for n in ("neck", "head")]) @ r.turn * 100.0
    v, _ = r.vertices(world, {})
    proj = r.camera.projector(640, 480, target=aim)
    xy, _ = proj(pts)
    top = float(proj(v)[0][:, 1].min())
    return round(float(xy[0, 1] - top), 1)


def main() -> None:
    tmp = Path(tempfile.mkdtemp(prefix="framing-bench-"))
    results: dict = {}
    try:
        real = None
        from bench_viewer_live import laugh01

        x = laugh01(44100)   # bench_viewer_live's loader (scipy's resample_poly; sox is not on a fresh machine)
        if x is not None:
            import soundfile as sf

            real = tmp / "laugh01_44k.wav"
            sf.write(real, x, 44100, subtype="FLOAT")
        for who, character in (("mannequin", None), ("godette", str(AVATAR))):
            rows = {}
            for cond, ovs in CONDITIONS.items():
                total: dict = {}
                for profile in ("mild", "intense"):
                    for seed in (0, 1):
                        s = _run(["input=synthetic", f"input.profile={profile}", "input.duration_s=8.0",
                                  f"input.seed={seed}", *ovs, "seed=0"], character, tmp / "run")
                        for k, v in s.items():
                            total[k] = (min(total.get(k, v), v) if k.startswith("min_") else
                                        max(total.get(k, v), v) if k.startswith("max_") else total.get(k, 0) + v)
                rows[f"stimuli/{cond}"] = total
            rows["default_30s"] = _run([], character, tmp / "run")
            if real is not None:
                rows["real_44k/laugh_energy"] = _run(["input=file", f"input.path={real}",
                                                      *CONDITIONS["laugh_energy"]], character, tmp / "run")
            rows["face_px_rest"] = face_size(character)
            results[who] = rows
            for name, r in rows.items():
                if isinstance(r, dict):
                    print(f"{who:<9} {name:<26} {r['any']:4d} of {r['frames']:4d} frames touch or leave the "
                          f"top/sides (top {r['top']}, left {r['left']}, right {r['right']}); min top margin "
                          f"{r['min_top_margin_px']:6.1f} px, min side margin {r['min_side_margin_px']:6.1f} px; zoomed out in {r['zoomed_out']} frames, at most x{r['max_zoom_out']}")
            print(f"{who:<9} face (neck to top of head) at rest: {rows['face_px_rest']} px of 480")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    out = HERE / "results"
    out.mkdir(exist_ok=True)
    (out / "framing.json").write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":   # --help prints what it measures; it took no arguments and ran (a review)
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
