"""Experiment ``detector_eval``: the detectors' scores as precision-recall curves, beside the harness' metrics.

The harness' metrics judge each detector's *gate* (open or shut, and the clips it lets start).  This
module judges the *score* behind it: per 60 fps frame, the ``laughter`` probability each detector
condition writes (``detector=yamnet``: its head; ``detector=yamnet_fused``: the head fused with the feature MLP's
cues; ``detector=laugh``: the feature MLP; plus ``yamnet classes``: YAMNet's own largest laughter-class score,
``laughter_classes``), stepped over every held-out recording of the corpus that has a truth (the ``real``,
``mixed`` and ``between`` sets), exactly as live (causal, the frame's block).  A frame is laughter when it lies inside an annotated bout.

Writes ``plots/detector_pr.png`` (one curve per score, its average precision in the legend, the
operating points of the gates' thresholds marked) and returns the average precisions and the curves'
points at those thresholds for ``results.json``.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

#: score -> (condition's ``detector=`` option, control written per frame, the gate's threshold on it)
SCORES = {
    "yamnet (head)": ("yamnet", "laughter", 0.5),
    "yamnet classes": ("yamnet", "laughter_classes", 0.1),
    "yamnet fused": ("yamnet_fused", "laughter", 0.6),
    "laugh (feature MLP)": ("laugh", "laughter", 0.7),
}


#: a detector of one's own (not in :data:`SCORES`): its ``laughter`` control, the threshold taken as 0.5
OWN_THRESHOLD = 0.5
#: the parameter that sets the gate's threshold on each score (a condition's ``detector.open_at=0.8``)
GATE_PARAM = {"laughter": "open_at", "laughter_classes": "class_open"}


def curves(conditions: dict) -> list[tuple[str, str, tuple, str, float]]:
    """The PR curves of a run's ``conditions``: ``(name, detector option, its detector.* overrides, control,
    threshold)`` for each detector the conditions choose (not ``none``), built-in ones as :data:`SCORES` names
    them, any other (a plugin's) by its option on ``laughter`` (a plugin author's review: a detector of their own
    was in the table but left out of the curves, silently); a condition's ``detector.KEY=`` overrides are its own
    curve (they were dropped)."""
    out, seen = [], set()
    for ov in conditions.values():
        option = next((o.split("=", 1)[1] for o in ov if o.startswith("detector=")), None)
        own = tuple(sorted(o for o in ov if o.startswith("detector.")))
        if option in (None, "none") or (option, own) in seen:
            continue
        seen.add((option, own))
        tag = f" ({', '.join(o.split('.', 1)[1] for o in own)})" if own else ""
        named = [(n, key, at) for n, (d, key, at) in SCORES.items() if d == option] or \
            [(option, "laughter", OWN_THRESHOLD)]
        given = dict(o.split("=", 1) for o in own)   # a threshold the condition sets marks its operating point
        out += [(n + tag, option, own, key, float(given.get(f"detector.{GATE_PARAM[key]}", at)))
                for n, key, at in named]
    return out


def _detector(option: str, overrides: tuple = ()):
    """A ``detector=`` option's plugin class and parameters with a condition's ``detector.*`` overrides, composed as
    a run's (the harness' composition: Hydra once per option in a process, a copy per call)."""
    from omegaconf import OmegaConf

    from laughlab.core import plugins
    from laughlab.harness.runner import _compose

    conf = OmegaConf.to_container(_compose([f"detector={option}", *overrides]).detector)
    cls = plugins.get("detector", conf.pop("name")).obj
    return cls, plugins.make_params(cls, conf, f"detector.{option}")


def frame_scores(detector: str, path: str, fps: float = 60.0, overrides: tuple = ()) -> tuple[dict, float]:
    """Step one detector (a ``detector=`` option and ``detector.*`` overrides, its configuration composed as a
    run's) over a recording's frames (as the pipeline cuts them); its controls per frame."""
    from laughlab.core.bases import Context
    from laughlab.core.frame import Frame
    from laughlab.io.audio import cut_frames, probe_file, read_blocks

    sr = int(probe_file(path).samplerate)
    cls, params = _detector(detector, overrides)
    det = cls(params, ctx=Context(fps=fps, sample_rate=sr))
    det.reset()
    out: dict = {"laughter": [], "laughter_classes": []}
    dt = 1.0 / fps
    for k, block in enumerate(cut_frames(read_blocks(path), sr, fps)):
        frame = Frame(k, k * dt, dt, {"mcs": 0.0}, None, {}, {}, [], 0.0)
        det.step(block, frame)
        for key in out:
            out[key].append(float(frame.control.get(key, np.nan)))
    return {k: np.asarray(v) for k, v in out.items()}, dt


def truth_frames(truth: str, n: int, dt: float) -> np.ndarray:
    from laughlab.harness.trialdata import Truth

    return Truth.load(truth).in_bouts((np.arange(n) + 0.5) * dt)   # frame centres


def pr_curve(score: np.ndarray, y: np.ndarray):
    """Precision and recall at every distinct score (descending), and the average precision
    (sum over thresholds of precision x recall gained, as scikit-learn's ``average_precision_score``)."""
    order = np.argsort(-score, kind="stable")
    s, t = score[order], y[order]
    tp = np.cumsum(t)
    fp = np.cumsum(~t)
    last = np.r_[np.flatnonzero(np.diff(s)), len(s) - 1]   # the last frame of each distinct score
    tp, fp, thr = tp[last], fp[last], s[last]
    pos = max(int(y.sum()), 1)
    precision = tp / np.maximum(tp + fp, 1)
    recall = tp / pos
    ap = float(np.sum(np.diff(np.r_[0.0, recall]) * precision))
    return precision, recall, thr, ap


#: each score's line style: with the colour it tells the curves apart in greyscale and for red-green colour
#: blindness (blue and red are about as light as each other)
PR_STYLES = ("-", "--", "-.", ":")


def data_words(sets, split: str = "test") -> tuple[str, str]:
    """What the curves were measured on, long (for results.json) and short (for the title), from the items'
    profiles: the corpus' sets (held out when ``split`` is ``test``), your recordings (``recording``: a corpus
    folder), the synthetic laughter (a new-user review: a run on a folder of one's own was titled "held-out")."""
    corpus = [s for s in sets if s in ("real", "between") or s.startswith("mixed")]
    own, synth = "recording" in sets, [s for s in sets if s not in corpus and s != "recording"]
    kind = "held-out" if split == "test" else f"{split}-split"
    named = ", ".join(corpus[:-1]) + f" and {corpus[-1]}" if len(corpus) > 1 else "".join(corpus)
    long = [f"the {kind} recordings with a truth (sets {named})"] * bool(corpus) + \
        ["the recordings of harness.corpus.folder with a truth"] * own + ["the synthetic laughter"] * bool(synth)
    short = [f"{kind} recordings"] * bool(corpus) + ["your recordings"] * own + ["synthetic laughter"] * bool(synth)
    return " and ".join(long), " and ".join(short)


def pr_figure(scores: dict, y: np.ndarray, width: str = "page", sets=("real", "mixed", "between"),
              split: str = "test", thresholds: dict | None = None):
    """The precision-recall figure of ``scores`` (name: per-frame score, in :data:`SCORES`' order) against the
    frames' truth ``y``, and its numbers (``detector_pr`` of the results); ``thresholds``: each score's gate
    threshold (default :data:`SCORES`'s, else :data:`OWN_THRESHOLD`).  ``width``: ``page`` (6 in) or
    ``column`` (3.5 in, text 7-8 pt, the legend in one column under the axes), as the run's
    ``output.plots.width``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from laughlab.render.layout import COLUMN, layout_of, wrapped

    narrow = layout_of(width).column
    fig = Figure(figsize=(COLUMN.width_in, 4.2), dpi=150, layout="constrained") if narrow else \
        Figure(figsize=(6.0, 5.2), dpi=150)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    # the sets the run had (they were always said to be real, mixed and between: a new-user review ran mixed alone)
    long, short = data_words(sets, split)
    out = {"what": f"frame-level precision-recall of each detector's score on {long}, pooled over frames at 60 fps; "
                   "a frame is laughter inside a bout",
           "frames": int(len(y)), "laughter_share": float(y.mean()), "scores": {}}
    for i, (name, s) in enumerate(scores.items()):
        p, r, thr, ap = pr_curve(s, y)
        line, = ax.plot(r, p, lw=1.6, ls=PR_STYLES[i % len(PR_STYLES)], label=f"{name}: AP {ap:.2f}")
        at = (thresholds or {}).get(name, SCORES[name][2] if name in SCORES else OWN_THRESHOLD)
        k = np.flatnonzero(thr >= at)
        op = {"threshold": at, "precision": float(p[k[-1]]) if len(k) else float("nan"),
              "recall": float(r[k[-1]]) if len(k) else 0.0}
        if len(k):
            ax.plot([op["recall"]], [op["precision"]], "o", color=line.get_color(), ms=6)
        out["scores"][name] = {"average_precision": ap, "at_gate_threshold": op}
    ax.axhline(float(y.mean()), color="0.35", lw=1, ls=(0, (2, 4)), label=f"chance (laughter share {y.mean():.2f})")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1.02)
    ax.set_ylabel("precision")
    ax.grid(alpha=0.3)
    title = f"Laughter scores per frame, {short} (dots: the gates' thresholds)"
    if narrow:   # sizes set on the axes, not by rc: the ticks are made again when the figure is saved
        ax.set_xlabel("recall (laughter frames above the threshold)", fontsize=8)
        ax.yaxis.label.set_fontsize(8)
        ax.tick_params(labelsize=8)
        ax.set_title(wrapped(title, COLUMN.width_in, COLUMN.title), fontsize=COLUMN.title)
        fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncols=1, fontsize=7.5,
                   frameon=False)
        return fig, out
    ax.set_xlabel("recall (share of laughter frames above the threshold)")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, fontsize=8, frameon=False)
    fig.tight_layout()
    return fig, out


def extra(run) -> dict:
    items = [i for i in run.items if i.truth and i.profile not in ("speech", "others")]  # frames with laughter
    lines = curves(run.conditions)
    if not items or not lines:
        return {}
    paths = [i.path for i in items]
    first = {}   # the first recording's scores, each detector stepped over it once
    for w in sorted({(d, own) for _, d, own, _, _ in lines}):
        try:
            first[w] = frame_scores(w[0], paths[0], overrides=w[1])
        except Exception as exc:  # noqa: BLE001 - a plugin's own code stepped alone (frame.control: mcs 0 only)
            if w[0] in {d for d, _, _ in SCORES.values()}:
                raise
            print(f"laughlab: warning: detector_eval: no PR curve of detector={w[0]}: stepped alone over a recording "
                  f"(frame.control holds mcs 0 only) it raised {type(exc).__name__}: {exc}", file=sys.stderr)
    lines = [ln for ln in lines if (ln[1], ln[2]) in first]
    if not lines:
        return {}
    pooled: dict = {name: [] for name, *_ in lines}
    ys = []
    for k, path in enumerate(paths):
        got = first if k == 0 else {w: frame_scores(w[0], path, overrides=w[1]) for w in first}
        dt = next(iter(got.values()))[1]
        n = len(next(iter(got.values()))[0]["laughter"])
        ys.append(truth_frames(items[k].truth, n, dt))
        for name, d, own, key, _ in lines:
            pooled[name].append(got[(d, own)][0][key])
    y = np.concatenate(ys)
    from omegaconf import OmegaConf

    fig, out = pr_figure({name: np.nan_to_num(np.concatenate(parts), nan=0.0) for name, parts in pooled.items()}, y,
                         width=OmegaConf.select(run.cfg, "output.plots.width", default="page"),
                         sets=sorted({i.profile for i in items}),
                         split=OmegaConf.select(run.cfg, "harness.corpus.real.split", default="test"),
                         thresholds={name: at for name, *_, at in lines})
    plots = Path(run.out_dir) / "plots"
    plots.mkdir(parents=True, exist_ok=True)
    fig.savefig(plots / "detector_pr.png")
    return {"detector_pr": out}
