"""Experiment ``energy_readings``: Eq. 4.1 against listings 5.4/5.5 as printed (van Duijn 2014).

Both readings of the energy update run on the same inputs and seeds
(``conf/experiment/energy_readings.yaml``).  Besides the harness' metrics, this
module replays the extractor and the scheduler alone over every input under
each reading and reports how the laughing energy and the clip choice differ:
clip starts per minute, which clip energies get played, how long a clip plays,
and how low the energy goes.
"""
from __future__ import annotations

import numpy as np


def energy_trace(overrides: list[str]) -> dict:
    """Run only the extractor and the scheduler over an input: energy per frame, starts, seconds of clip playing."""
    from laughlab.core import pipeline
    from laughlab.core.frame import Frame
    from laughlab.harness.runner import _compose

    pipe = pipeline.build(_compose(overrides))
    dt = pipe.ctx.dt
    energy, starts, playing = [], [], 0
    try:
        for k, block in enumerate(pipe.source.blocks()):
            frame = Frame(k, k * dt, dt, {}, None, {}, {}, [], 0.0)
            pipe.extractor.step(block, frame)
            pipe.scheduler.step(frame)
            energy.append(frame.channels["energy"])
            playing += frame.channels["clip_energy"] > 0
            starts += [e.energy for e in frame.events if e.kind == "start"]
    finally:
        pipe.source.close()
    return {"energy": np.array(energy), "starts": starts, "seconds": len(energy) * dt, "playing_s": playing * dt}


def summarise(traces: list[dict]) -> dict:
    """One reading's figures over its inputs."""
    minutes = sum(t["seconds"] for t in traces) / 60.0
    starts = [e for t in traces for e in t["starts"]]
    energy = np.concatenate([t["energy"] for t in traces])
    levels = sorted({5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 40.0} | set(starts))
    return {
        "clip_starts_per_min": len(starts) / minutes,
        "mean_clip_energy": float(np.mean(starts)) if starts else 0.0,
        **{f"share_e{int(e)}": (starts.count(e) / len(starts) if starts else 0.0) for e in levels},
        "clip_playing_fraction": sum(t["playing_s"] for t in traces) / (minutes * 60.0),
        "energy_min": float(energy.min()),
        "energy_median": float(np.median(energy)),
        "energy_below_zero_fraction": float(np.mean(energy < 0.0)),
    }


def extra(run) -> dict:
    """Per reading: starts per minute, the clip energies chosen, time playing and the energy's range."""
    base = list(getattr(run, "base_overrides", []) or [])
    rows = []
    for cond, overrides in run.conditions.items():
        traces = [energy_trace([*base, *overrides, *item.overrides]) for item in run.items]
        rows.append({"reading": cond, **summarise(traces)})
    return {
        "energy_readings": {
            "what": "the extractor and the energy scheduler replayed over every input of the corpus under each "
                    "reading: clip starts per minute, the share of starts by clip energy e (5 ... 40), the "
                    "fraction of time a clip plays, and the laughing energy's minimum and median",
            "inputs": len(run.items),
            "per_reading": rows,
        }
    }
