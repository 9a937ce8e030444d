"""``python -m laughlab study power STUDY_DIR``: how many participants the design needs for an effect.

Simulation-based power from the analysis' own model (``laughlab.study.analyze``): for each number
of participants N, ``--sims`` data sets are drawn for N participants taking the design's
counterbalanced orders (the Latin-square rows of ``experiment=stimuli``, ``participant_trials``),

    rating = intercept + effect[condition] + u_participant + w_stimulus + e,
    u ~ N(0, var_participant), w ~ N(0, var_stimulus), e ~ N(0, var_residual),

rounded to the nearest point and clipped to the scale for Likert items.  ``effect`` is ``--effect``
scale points for condition ``a`` over ``b`` (``--contrast a:b``; every other condition as ``b``).
Each data set is fitted with the same mixed model and the same pairwise contrasts (Holm over the
pairs it tests: all but those whose conditions show the same videos; two-sided), and the contrast counts as detected when Holm's p < ``--alpha`` and its estimate has
the planted effect's sign (``a`` above ``b`` for a positive ``--effect``, below for a negative one: a
negative effect has the power of the same positive one, as the design is symmetric).  ``--effect`` must be
non-zero and keep ``a``'s mean on the scale (``intercept + effect`` within it: the simulation puts ``b``
at the intercept, so a larger effect would be cut at the scale's end and the one simulated would not be
the one reported).
Power is the detected share, with a 95 % Wilson interval.  The variance components are those a
pilot's report estimated (``--pilot REPORT_DIR``, its ``report.json``) or, without a pilot, values
typical of 7-point ratings of animated characters (participant SD 0.8, stimulus SD 0.3, residual
SD 1.2, intercept 4): state which you used.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from laughlab.core.errors import LaughlabError

HEADER = "n,detected,sims,power,ci_low,ci_high"   # the first line of power.csv
DEFAULT_VAR = {"participant": 0.8 ** 2, "stimulus": 0.3 ** 2, "residual": 1.2 ** 2}


def simulate(trials: list[list[tuple[str, str]]], effects: dict[str, float], var: dict[str, float], intercept: float,
             rng: np.random.Generator, scale: tuple[float, float] | None = None):
    """One data set: ``trials[p]`` are participant p's (condition, audio_id) pairs; a DataFrame of ratings."""
    import pandas as pd

    stimuli = sorted({f"{c}-{a}" for t in trials for c, a in t})
    w = dict(zip(stimuli, rng.normal(0, math.sqrt(var.get("stimulus", 0.0)), len(stimuli))))
    rows = []
    for p, ts in enumerate(trials, start=1):
        u = rng.normal(0, math.sqrt(var["participant"]))
        for c, a in ts:
            s = f"{c}-{a}"
            rows.append((p, c, s, intercept + effects.get(c, 0.0) + u + w[s] + rng.normal(0, math.sqrt(var["residual"]))))
    df = pd.DataFrame(rows, columns=["participant", "condition", "stimulus", "value"])
    if scale is not None:
        df["value"] = df["value"].round().clip(*scale)
    return df



def verdict(rows: list[dict], target: float) -> str:
    """What :func:`power`'s ``rows`` say: the fewest participants reaching ``target`` power, or the best tried."""
    enough = next((r["n"] for r in rows if r["power"] >= target), None)
    if enough is not None:
        return f"{enough} participants reach {target:.0%} power"
    best = max(rows, key=lambda r: (r["power"], r["n"]))
    return (f"none of {', '.join(str(r['n']) for r in rows)} participants reaches {target:.0%} power "
            f"(best {best['power']:.0%} with {best['n']})")


def advice(rows: list[dict], target: float, effect: float, built_for: int | None = None) -> str | None:
    """When no size reaches ``target``: what to change (None when one does).  ``built_for``: the participants the
    study was built for (its design's orders); more than that needs the stimuli built again for them (a new-user
    review: the advice named 64 participants of a study that serves 24)."""
    if any(r["power"] >= target for r in rows):
        return None
    top = max(r["n"] for r in rows)
    more = ",".join(str(k * top) for k in (2, 3, 4))
    rebuild = (f"; this study has orders for {built_for} participants: more need its stimuli made again with "
               "harness.participants=N, then study build" if built_for is not None and 2 * top > built_for else "")
    return (f"to reach {target:.0%}: more participants (--participants {more}{rebuild}), more stimuli per condition "
            f"(more audio items: experiment=stimuli with more recordings in harness.corpus.folder, or "
            f"harness.corpus.seeds=N of the synthetic laughter), or a larger effect than {effect:g}")


def detected(df, conditions: list[str], a: str, b: str, alpha: float, effect: float = 1.0,
             same: list[tuple[str, str]] = ()) -> bool:
    """Is ``a - b`` significant (Holm's p < ``alpha``) in the direction of the planted ``effect``?  Holm's family
    is the one ``study analyze`` tests: every pair but those in ``same`` (conditions showing the same videos)."""
    from laughlab.study.analyze import contrasts, fit_model

    fit, ref, _ = fit_model(df, conditions)
    c = contrasts(fit, ref, conditions, same)
    row = c[((c["a"] == a) & (c["b"] == b)) | ((c["a"] == b) & (c["b"] == a))].iloc[0]
    sign = 1.0 if row["a"] == a else -1.0   # the pair as listed, a - b or b - a
    return bool(row["p_holm"] < alpha and sign * math.copysign(1.0, effect) * row["estimate"] > 0)


def check_effect(effect, intercept: float, scale: tuple[float, float] | None) -> float:
    """``--effect`` as a float: non-zero, finite and keeping ``intercept + effect`` on the scale (module doc)."""
    if isinstance(effect, bool) or not isinstance(effect, (int, float)):   # argparse hands --effect=-- on as []
        raise LaughlabError("--effect needs a number of scale points, e.g. --effect 0.5")
    if not math.isfinite(effect) or effect == 0:
        raise LaughlabError(f"--effect must be a non-zero, finite number of scale points (got {effect:g})")
    if scale is not None and not scale[0] <= intercept + effect <= scale[1]:
        lo, hi = scale
        raise LaughlabError(f"--effect {effect:g} is impossible on this {lo:g}..{hi:g} scale: from the base rating "
                            f"{intercept:g} it must lie between {lo - intercept:+g} and {hi - intercept:+g} "
                            "(and not be 0)")
    return float(effect)


def near_end_note(effect: float, intercept: float, scale: tuple[float, float] | None) -> str:
    """A note when ``intercept + effect`` lies within a point of the scale's end ("" otherwise): ratings cannot pass
    the end, so the effect shows smaller on the scale than planted and the power is for that smaller one (a
    statistician's review: +1 over a base of 6 on 1..7 showed as 0.63, over 4 as 0.95)."""
    if scale is None:
        return ""
    lo, hi = scale
    top = intercept + effect
    if lo + 1 <= top <= hi - 1:
        return ""
    end = hi if effect > 0 else lo
    return (f"power: note: the base rating {intercept:g} and the effect {effect:+g} reach {top:g}, within a point of "
            f"the scale's end ({end:g}): ratings cannot pass it, so the effect shows smaller than {abs(effect):g} on "
            "the scale, and the power below is for that smaller effect")


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """The 95 % Wilson score interval of ``k`` successes in ``n`` trials."""
    if n == 0:
        return 0.0, 1.0
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    # (at k = 0 or k = n the bound is exactly 0 or 1; rounding would leave it just inside)
    return (0.0 if k == 0 else max(0.0, centre - half)), (1.0 if k == n else min(1.0, centre + half))


def pilot_variance(report_dir: Path, question: str | None) -> tuple[dict, float, str, bool]:
    """Variance components and intercept of a pilot's report (one question's, default the first), the question, and
    whether the report's participants were simulated (a user-study review: power took the planted model's spreads
    as a pilot's without a word)."""
    doc_path = Path(report_dir).expanduser() / "report.json"
    if not doc_path.is_file():
        raise LaughlabError(f"no report.json in {report_dir}: analyse the pilot first (study analyze)")
    from laughlab.study.design import read_json

    doc = read_json(doc_path, "; analyse the pilot again (study analyze)")
    if not doc.get("variance"):
        raise LaughlabError(f"{doc_path} has no fitted model")
    v = next((x for x in doc["variance"] if question in (None, x["question"])), None)
    if v is None:
        raise LaughlabError(f"the pilot has no question {question!r}; it has: "
                            f"{', '.join(x['question'] for x in doc['variance'])}")
    icpt = next(f["estimate"] for f in doc["fixed"] if f["question"] == v["question"] and f["term"] == "Intercept")
    return ({"participant": v["var_participant"], "stimulus": v.get("var_stimulus") or 0.0,
             "residual": v["var_residual"]}, float(icpt), v["question"], bool(doc.get("simulated")))


def power(design: dict, contrast: tuple[str, str], effect: float, ns: list[int], sims: int = 200,
          alpha: float = 0.05, var: dict | None = None, intercept: float = 4.0, seed: int = 0,
          progress=None) -> list[dict]:
    """Power per number of participants (module doc): rows ``n, detected, sims, power, ci_low, ci_high``."""
    from laughlab_experiments.stimuli import participant_trials

    from laughlab.study.design import scale_range

    conditions = list(design["conditions"])
    a, b = contrast
    for c in (a, b):
        if c not in conditions:
            raise LaughlabError(f"unknown condition {c!r}; the design has: {', '.join(conditions)}")
    if a == b:
        raise LaughlabError("the contrast needs two different conditions")
    from laughlab.study.design import identical_conditions

    same = identical_conditions(design)
    if (a, b) in same or (b, a) in same:
        raise LaughlabError(f"{a} and {b} show the same videos (the page does not present what tells them apart), so "
                            "the analysis does not test their difference; choose conditions whose videos differ")
    items = sorted({s["audio_id"] for s in design["stimuli"].values()})
    kind = design.get("design") or "all"
    scale = scale_range(design) if design.get("scale") == "likert" else None
    effect = check_effect(effect, intercept, scale_range(design))
    var = {**DEFAULT_VAR, **(var or {})}
    rng = np.random.default_rng(seed)
    out = []
    for n in ns:
        trials = participant_trials(conditions, items, n, kind)
        hits = sum(detected(simulate(trials, {a: effect}, var, intercept, rng, scale), conditions, a, b, alpha,
                            effect, same)   # Holm over the pairs analyze tests (a diff review: all pairs)
                   for _ in range(sims))
        lo, hi = wilson(hits, sims)
        out.append({"n": n, "detected": hits, "sims": sims, "power": hits / sims, "ci_low": lo, "ci_high": hi})
        if progress:
            progress(f"power: {n} participants: {hits}/{sims} = {hits / sims:.2f}")
    return out


def check_out(out: Path) -> None:
    """Refuse an output folder whose ``power.csv`` or ``power.png`` is not an earlier ``study power``'s
    (which it replaces); other files in it are left alone."""
    if out.exists() and not out.is_dir():
        raise LaughlabError(f"{out} exists and is not a folder; choose another --out")
    csv_, png = out / "power.csv", out / "power.png"
    try:
        head = csv_.open(encoding="utf-8").readline() if csv_.exists() else ""
    except (OSError, UnicodeDecodeError):
        head = "?"
    ours = head.startswith(HEADER)
    if (csv_.exists() and not ours) or (png.exists() and not ours):
        name = csv_.name if csv_.exists() else png.name
        raise LaughlabError(f"{out / name} is not an earlier study power's result; choose another --out "
                            "(power replaces only its own power.csv and power.png)")


def plot(path: Path, rows: list[dict], target: float, title: str) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    import textwrap

    fig = Figure(figsize=(5.4, 3.6), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    n = [r["n"] for r in rows]
    p = np.array([r["power"] for r in rows])
    err = np.vstack([p - [r["ci_low"] for r in rows], [r["ci_high"] for r in rows] - p])
    ax.errorbar(n, p, yerr=err, fmt="o-", capsize=4, color="tab:blue",
                label=f"power, {rows[0]['sims']} simulated studies each (95 % Wilson CI)")
    ax.axhline(target, color="tab:red", ls="--", lw=1, label=f"target {target:.0%}")
    ax.set_xticks(sorted(set(n)))           # whole participants, not 8.5
    ax.set_xlabel("participants")
    ax.set_ylabel("power (95 % CI)")
    ax.set_ylim(-0.04, 1.04)                # a power of 0 or 1 shows whole, not cut at the axis
    ax.set_title("\n".join(textwrap.wrap(title, 75)), fontsize=9)   # a review: a long pilot path cut it at both ends
    ax.grid(alpha=0.3)
    # under the axes, where it covers no point (a review: in the corner it sat on the 12-participant point)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), ncols=2, fontsize=8, frameon=False)
    fig.savefig(path, format="png", dpi=200)   # as sharp as the analysis' figures for a page (it was 594 x 396 px)
