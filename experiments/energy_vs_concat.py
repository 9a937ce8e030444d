"""Experiment ``energy_vs_concat``: the thesis' laughing energy vs Ding et al.'s segment concatenation.

Both schedulers run on the same corpus and seeds with the same extractor, face
and body (``conf/experiment/energy_vs_concat.yaml``).  Besides the harness'
metrics, this module reports the cost gap of the concatenation: how far the
greedy real-time variant (Ding 2014, end of 4.2) is from the exact minimum of
Eq. 4, found by dynamic programming, on the pseudo-phoneme sequences of the
corpus' inputs.
"""
from __future__ import annotations

import numpy as np
from omegaconf import OmegaConf


def label_sequence(overrides: list[str]) -> tuple[list, float, object]:
    """Run only the extractor over an input; return its pseudo-phoneme sequence, dt and the scheduler."""
    from laughlab.core import pipeline
    from laughlab.concat.costs import to_sequence
    from laughlab.core.frame import Frame
    from laughlab.harness.runner import _compose

    cfg = _compose(overrides)
    pipe = pipeline.build(cfg)
    dt = pipe.ctx.dt
    labels = []
    try:
        for k, block in enumerate(pipe.source.blocks()):
            frame = Frame(k, k * dt, dt, {}, None, {}, {}, [], 0.0)
            pipe.extractor.step(block, frame)
            labels.append(pipe.scheduler.label_of(frame))
    finally:
        pipe.source.close()
    return to_sequence(labels, dt), dt, pipe.scheduler


def split_long_units(sequence: list, db) -> list:
    """Split each pseudo-phoneme longer than the longest segment of its class into equal units.

    A 5 s silence has no 5 s segment: C_dur = e^|d - d'| - 1 (Eq. 7) would be
    ~e^4 for every choice and swamp the sum.  The real-time scheduler chains
    segments during such a phoneme; splitting it into ceil(d / d_max) units of
    equal length is the offline equivalent, applied to both greedy and DP.
    """
    out = []
    for label, d in sequence:
        longest = float(db.durations[db.candidates(label)].max())
        n = max(1, int(np.ceil(d / longest)))
        out += [(label, d / n)] * n
    return out


def extra(run) -> dict:
    """Greedy vs optimal cost of Eq. 4 on up to ``harness.gap_inputs`` inputs of the corpus."""
    from laughlab.concat.costs import cost_gap

    cond = next((c for c, ov in run.conditions.items() if "scheduler=concat" in ov), None)
    if cond is None:
        return {}
    base = list(getattr(run, "base_overrides", []) or [])
    n = int(run.harness.get("gap_inputs", 12))
    step = max(1, len(run.items) // n)
    rows = []
    for item in run.items[::step][:n]:
        seq, _, sch = label_sequence([*base, *run.conditions[cond], *item.overrides])
        gap = cost_gap(split_long_units(seq, sch.db), sch.db, sch.params.gamma)
        rows.append({"input": item.id, **{k: float(v) for k, v in gap.items()}})
    rel = np.array([r["relative_gap"] for r in rows if np.isfinite(r["relative_gap"])])
    return {
        "concat_cost_gap": {
            "what": "Eq. 4 cost of the greedy real-time variant minus the dynamic-programming minimum, "
                    "on each input's pseudo-phoneme sequence (true durations; phonemes longer than the "
                    "longest segment of their class split into equal units)",
            "gamma": float(OmegaConf.select(run.cfg, "scheduler.gamma", default=0.5) or 0.5),
            "inputs": len(rows),
            "mean_units": float(np.mean([r["units"] for r in rows])),
            "mean_greedy": float(np.mean([r["greedy"] for r in rows])),
            "mean_optimal": float(np.mean([r["optimal"] for r in rows])),
            "mean_relative_gap": float(rel.mean()) if len(rel) else float("nan"),
            "max_relative_gap": float(rel.max()) if len(rel) else float("nan"),
            "per_input": rows,
        }
    }
