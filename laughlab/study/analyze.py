"""``python -m laughlab study analyze DB_OR_CSV``: exclusions, means, a mixed model, contrasts, figures.

Input: the study's database (``responses.sqlite``: the design travels inside it), or CSV files in
the same columns (the page's "download my answers" files, one file or a folder of them; then
``--design STUDY_DIR`` supplies the exclusion rules, the condition order and what every row is checked
against, else the defaults): read by ``laughlab.study.answers``.

Steps, each written to the report folder:

1. ``tidy.csv``: one row per rating (``kind == rating``) of the included participants, the columns
   of ``laughlab.study.db.COLUMNS``.
2. ``exclusions.csv``: each excluded participant and why: the audio check (no attempt was the
   word, or none stored), attention items (more failed than ``attention_max_fail``; a slider item
   fails more than 5 % of the scale away from the value asked for), straight-lining (every rating
   of every question the same value, over at least four ratings), an incomplete session (fewer ratings
   or attention items than the participant's trials ask for), answers in a database without consent:
   :mod:`laughlab.study.exclusions`.
3. ``means.csv``: per question and condition the mean of the participants' means, its SD, n and a
   95 % t interval (participants are the unit, so the interval is over people, not trials).
4. ``model.csv``, ``variance.csv``: per question a linear mixed model
   ``value ~ condition + (1 | participant) + (1 | stimulus)`` fitted by REML with statsmodels'
   ``MixedLM`` (crossed random intercepts as variance components of one all-ones group).
   Each model is fitted twice, by L-BFGS and by Powell's method, and of the sound fits (converged,
   finite standard errors, no numerical warning) the one with the higher REML likelihood is kept: L-BFGS alone can stop short of the maximum and call it
   converged (on the study demo's naturalness ratings with ``smile_only`` as the reference level it
   stops at a log-likelihood of -118.79 with a stimulus variance of 0.02, where the maximum is
   -118.41 with that variance at 0; with another reference level it said so and statsmodels' retry
   found the maximum), which made the result depend on which condition is listed first.
   statsmodels' warnings while fitting go to ``report.json`` (``model_warnings``); the README says
   in one sentence per question what they mean for the result (:func:`fit_note`).
   Why this model: it is the one the design calls for (Baayen, Davidson & Bates 2008; Judd,
   Westfall & Kenny 2012): every participant rates every condition, and each stimulus is a
   sample of possible stimuli, so both are random; statsmodels is maintained, on PyPI, and fits
   it exactly.  A cumulative-link mixed model (ordinal) would respect the scale's steps, but no
   maintained Python package fits one with crossed random effects (R's ``ordinal::clmm`` does);
   with seven points and means away from the ends the linear model's estimates and tests are
   close to the ordinal model's, and its estimates are in scale points, which is what a reader
   wants to see.  Wald z tests, as statsmodels gives them: they take the condition effects' standard
   errors as known, and with few stimuli per condition the stimulus variance is estimated from few
   levels, so when that variance is not small the tests are liberal (a review's simulation,
   ``benchmarks/bench_study_type1.py``: 24 participants, 4 stimuli per condition, stimulus variance 0.5
   of 2.58 in all: familywise error 0.095 after Holm at a nominal 0.05; with the default 0.09: 0.050).
   Satterthwaite or Kenward-Roger degrees of freedom would correct this, but statsmodels' MixedLM has
   neither; the README warns per question instead (:func:`few_stimuli_note`).
5. ``contrasts.csv``: every pair of conditions per question, estimate (scale points), SE, 95 %
   CI, z, p and p Holm-corrected over the question's pairs; effect size ``d`` = the difference
   over the square root of the summed variance components (participant + stimulus + residual:
   Westfall, Kenny & Judd 2014), with the CI scaled alike.  Pairs of conditions whose videos are the same
   files (the riddle preset's SS and LS, SL and LL: the role is not presented) are not tested, and the
   README says so.
6. ``fig_means.png`` (condition means with their 95 % CIs, participants' means as dots; an interval past
   the scale's end marked there with its bound) and ``fig_participants.png`` (one line per participant
   across the conditions), each also as a PDF (``laughlab.study.plots``); ``README.md``
   with the tables and who came, agreed and stayed (:mod:`laughlab.study.participation`); ``report.json`` with
   everything as numbers.
"""
from __future__ import annotations

import json
import math
import warnings
from itertools import combinations
from pathlib import Path

import numpy as np

from laughlab.core.errors import LaughlabError
from laughlab.study import db as DB
from laughlab.study.answers import load
from laughlab.study.design import identical_conditions, scale_range
from laughlab.study.exclusions import (DEFAULT_RULES, exclusions, expected_counts,  # noqa: F401 (its API)
                                      reason_counts)
from laughlab.study.participation import line as participation_line, order_rows, participation, unconsented
from laughlab.study.reportdir import REPORT_FILES, check_out, put  # noqa: F401 (REPORT_FILES: the report's files)

# -- statistics -----------------------------------------------------------------------------------------------------

def condition_means(tidy, conditions: list[str], questions: list[str] | None = None):
    """Per question and condition: the participants' means' mean, SD, n and 95 % t interval.

    Rows in the order of ``questions`` (else alphabetical), and within a question of ``conditions``.
    """
    import pandas as pd

    from scipy import stats

    rows = []
    pm = tidy.groupby(["question", "condition", "participant"], observed=True)["value"].mean().reset_index()
    for (q, c), g in pm.groupby(["question", "condition"], observed=True):
        x = g["value"].to_numpy(float)
        x = x[np.isfinite(x)]
        n, m = len(x), float(x.mean()) if len(x) else float("nan")
        # a t interval, not the harness' bootstrap (results.mean_ci): a dozen participants are too few for
        # a percentile bootstrap, which is too narrow at small n; one participant: no spread, no interval
        sd = float(x.std(ddof=1)) if n > 1 else float("nan")
        h = float(stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n)) if n > 1 else float("nan")
        lo, hi = m - h, m + h
        rows.append({"question": q, "condition": c, "mean": m, "sd": sd, "n_participants": n,
                     "n_ratings": int((tidy["question"].eq(q) & tidy["condition"].eq(c)).sum()),
                     "ci_low": lo, "ci_high": hi})
    out = pd.DataFrame(rows)
    if not out.empty:
        out["condition"] = pd.Categorical(out["condition"], [c for c in conditions if c in set(out["condition"])])
        qs = [q for q in (questions or []) if q in set(out["question"])]
        out["question"] = pd.Categorical(out["question"], qs + sorted(set(out["question"]) - set(qs)))
        out = out.sort_values(["question", "condition"]).reset_index(drop=True)
        out["condition"] = out["condition"].astype(str)
        out["question"] = out["question"].astype(str)
    return out


#: the optimisers each mixed model is fitted with; of the sound fits (:func:`_sound`) the one with the
#: highest REML likelihood is kept (none sound: the first that converged, else the first)
FIT_METHODS = ("lbfgs", "powell")


def fit_model(data, conditions: list[str]):
    """The mixed model of one question's ratings (module doc, step 4): the statsmodels fit and its warnings."""
    import statsmodels.formula.api as smf

    d = data.assign(one=1, value=data["value"].astype(float), participant=data["participant"].astype(int).astype(str),
                    condition=data["condition"].astype(str), stimulus=data["stimulus"].astype(str))
    ref = next(c for c in conditions if c in set(d["condition"]))
    vc = {"participant": "0 + C(participant)"}
    if d["stimulus"].nunique() > d["condition"].nunique():  # a stimulus variance needs stimuli within conditions
        vc["stimulus"] = "0 + C(stimulus)"
    model = smf.mixedlm(f"value ~ C(condition, Treatment(reference={ref!r}))", d, groups="one", re_formula="0",
                        vc_formula=vc)
    fits = []
    for method in FIT_METHODS:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                fit = model.fit(reml=True, method=[method])
            except (np.linalg.LinAlgError, ValueError):  # this optimiser failed outright: the other one stands
                continue
            finite = bool(np.all(np.isfinite(np.asarray(fit.bse_fe, float))))  # may warn too: caught here
        warned = sorted({str(w.message).splitlines()[0] for w in caught})
        fits.append((fit, warned, _sound(fit, warned, finite)))
    if not fits:
        raise LaughlabError("the mixed model could not be fitted by any optimiser")
    sound = [f for f in fits if f[2]]
    fit, notes, _ = max(sound, key=lambda f: f[0].llf) if sound else \
        next((f for f in fits if f[0].converged), fits[0])
    return fit, ref, notes


def _sound(fit, warned: list[str], finite_se: bool) -> bool:
    """A fit to choose from: converged, finite standard errors of the condition effects, and no
    numerical trouble on the way (an "invalid value" warning: e.g. a residual variance run to zero
    on degenerate ratings, where the likelihood grows without bound)."""
    return bool(fit.converged) and finite_se and not any("invalid value" in w for w in warned)


#: what the statsmodels warnings of a MixedLM fit say, found by the start of their text
_UNCONVERGED = ("Maximum Likelihood optimization failed to converge", "Retrying MixedLM optimization",
                "Gradient optimization failed")
_BOUNDARY = "The MLE may be on the boundary"
_HESSIAN = "The Hessian matrix at the estimated parameter values is not positive definite"


def fit_note(fit, warned: list[str]) -> str:
    """One plain sentence on what statsmodels' warnings while fitting mean for the result ("" if none).

    statsmodels warns when an optimiser stops short, when an estimate lies on the edge of its range
    (a variance component at or near zero: the ratings show no spread between participants, or stimuli, beyond the residual
    noise, and the model is in effect the one without that random intercept) and when the
    curvature there is not positive definite (the variance components' own standard errors are
    then undefined).  None of these touches the condition estimates and their tests as long as
    the fit converged and their standard errors are finite; a fit that did not converge is not to
    be trusted.  Other warnings are named as such (their text is in ``report.json``).
    """
    if not warned:
        return ""
    fe_ok = bool(np.all(np.isfinite(np.asarray(fit.bse_fe, float))))
    if not fit.converged or not fe_ok:
        return ("The fit did not converge" if not fit.converged else "The condition estimates have no finite "
                "standard errors") + ", so this question's estimates and tests below are not to be trusted."
    head = "The fit converged"
    clauses, low = [], []
    if any(w.startswith(_BOUNDARY) for w in warned):
        var = {name: float(v) for name, v in zip(fit.model.exog_vc.names, fit.vcomp)}
        total = sum(var.values()) + float(fit.scale)
        low = [n for n, v in var.items() if v < 0.01 * total] or ([min(var, key=var.get)] if var else [])
        plural = {"participant": "participants", "stimulus": "stimuli"}
        clauses.append(f"the {' and '.join(low)} variance{'s are' if len(low) > 1 else ' is'} at or near zero ("
                       f"{' and '.join(plural.get(n, n) for n in low)} differ no more than the rating noise, so the "
                       "model is in effect one without that random intercept)")
    if any(w.startswith(_HESSIAN) for w in warned):
        clauses.append("the variances' own standard errors cannot be computed")
    known = (*_UNCONVERGED, _BOUNDARY, _HESSIAN)
    if any(not w.startswith(known) for w in warned):
        return head + ("; " + " and ".join(clauses) if clauses else "") + (
            ", but statsmodels also warned of something else (see report.json), so check these estimates.")
    if "stimulus" in low:
        # a statistician's review: then the tests count the stimuli as not varying, liberal with few of them
        return head + "; " + " and ".join(clauses) + (", so the tests below count the stimuli as not varying: with "
                                                      "few stimuli per condition they are then liberal (below).")
    return head + ("; " + " and ".join(clauses) if clauses else "") + (
        ", which by itself leaves the condition estimates and tests below as they are.")


#: below this many stimuli per condition the README warns that the tests are liberal (module doc, step 4); from
#: this share of the total the stimulus variance is said to vary
FEW_STIMULI, STIMULUS_SHARE = 10, 0.05


#: the familywise error of null studies (``benchmarks/bench_study_type1.py``), quoted by :func:`few_stimuli_note`
TYPE1 = ("0.065 with 12 participants and 4 stimuli per condition at the default stimulus variance 0.09, 0.075 with 2; "
         "0.095 with 24 and 4 stimuli varying more, 0.5 of 2.58 in all, 0.185 with 12 and 2")
#: below this many participants the README says the Wald tests are liberal
FEW_PARTICIPANTS = 12


def few_participants_note(n: int) -> str:
    """The README's caution for a question rated by few participants ("" when not): the Wald z tests take the
    estimated variances as known, which with few participants makes their p values too small (a user-study review:
    4 simulated participants' report called its tests valid)."""
    if n >= FEW_PARTICIPANTS:
        return ""
    return (f"Only {n} participants: the Wald z tests below take the estimated variances as known, which with so "
            "few makes their p values too small; read them as a pilot's.")


def few_stimuli_note(var: dict[str, float], per_condition: int) -> str:
    """The README's warning for a question with fewer than :data:`FEW_STIMULI` stimuli per condition ("" from
    there): the Wald tests take the stimulus variance as known though it rests on few stimuli, so their p values are
    too small, whatever that variance's estimate (a statistician's review, 2026-11-29: with the default 4 stimuli
    and an estimate under 5 % of the total the note had been left out, and 19 of 20 false positives came without
    it; ``benchmarks/bench_study_type1.py``'s figures in :data:`TYPE1`)."""
    if per_condition >= FEW_STIMULI:
        return ""
    total = sum(var.values())
    share = var.get("stimulus", 0.0) / total if total > 0 else 0.0
    seen = (f"and they vary (stimulus variance {var['stimulus']:.3g}, {share:.0%} of the total)" if share >= STIMULUS_SHARE
            else f"too few to tell how much stimuli vary (the estimate, {var.get('stimulus', 0.0):.3g}, rests on them)")
    return (f"Only {per_condition} stimuli per condition, {seen}: the Wald tests below take that variance as known, "
            f"so their p values are too small (null studies, familywise error after Holm at a nominal 0.05: {TYPE1}; "
            "benchmarks/bench_study_type1.py). Read p values near the threshold as not significant; more audio items "
            "per condition is the remedy.")


def _coef_index(fit, ref: str, cond: str) -> int | None:
    if cond == ref:
        return None
    names = list(fit.fe_params.index)
    return next(i for i, n in enumerate(names) if n.endswith(f"[T.{cond}]"))


def variance_components(fit) -> dict[str, float]:
    out = {name: float(v) for name, v in zip(fit.model.exog_vc.names, fit.vcomp)}
    out.setdefault("stimulus", 0.0)
    out["residual"] = float(fit.scale)
    return out


def contrasts(fit, ref: str, conditions: list[str], same: list[tuple[str, str]] = ()):
    """Every pair (a, b) of the fitted conditions: a - b with SE, CI, z, p, Holm's p and d (module doc, step 5);
    pairs in ``same`` (conditions showing the same videos: ``design.identical_conditions``) are left out."""
    import pandas as pd
    from scipy import stats
    from statsmodels.stats.multitest import multipletests

    k = len(fit.fe_params)
    beta = fit.fe_params.to_numpy()
    cov = np.asarray(fit.cov_params())[:k, :k]
    var = variance_components(fit)
    sd_total = math.sqrt(sum(var.values()))
    present = [c for c in conditions if c == ref or any(n.endswith(f"[T.{c}]") for n in fit.fe_params.index)]
    rows = []
    for a, b in combinations(present, 2):
        if (a, b) in same or (b, a) in same:
            continue
        L = np.zeros(k)
        for c, sign in ((a, 1.0), (b, -1.0)):
            i = _coef_index(fit, ref, c)
            if i is not None:
                L[i] += sign
        est, v = float(L @ beta), float(L @ cov @ L)
        se = math.sqrt(v) if v > 0 else float("nan")  # a degenerate fit's covariance may not be positive
        z = est / se if se > 0 else float("nan")
        rows.append({"a": a, "b": b, "estimate": est, "se": se, "ci_low": est - 1.959964 * se,
                     "ci_high": est + 1.959964 * se, "z": z, "p": float(2 * stats.norm.sf(abs(z))),
                     "d": est / sd_total, "d_low": (est - 1.959964 * se) / sd_total,
                     "d_high": (est + 1.959964 * se) / sd_total})
    out = pd.DataFrame(rows)
    if not out.empty:
        out["p_holm"] = multipletests(out["p"].fillna(1.0), method="holm")[1]
    return out


# -- the report -----------------------------------------------------------------------------------------------------

def _fmt(x, nd=2) -> str:
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{nd}f}"


def _p(x) -> str:
    return "< .001" if x < 0.001 else f"{x:.3f}"


def analyze(source, out=None, design_dir=None, overwrite: bool = False, width: str = "page") -> Path:
    """Write the report folder (module doc); its path.  ``width``: the figures for a ``page`` or a ``column``
    (:mod:`laughlab.study.plots`)."""
    import pandas as pd

    import shlex

    # the report's first line: the command that makes it again, every option given (a review: --design and --out
    # were left out, and the command as printed gave another report)
    command = " ".join(["python -m laughlab study analyze", shlex.quote(str(source)),
                        *(["--design", shlex.quote(str(design_dir))] if design_dir is not None else []),
                        *(["--out", shlex.quote(str(out))] if out else [])])
    df, design = load(source, design_dir)
    source = Path(source).expanduser()
    out = Path(out).expanduser() if out else source.with_name(source.stem + "-report")
    check_out(out, overwrite)
    kind = DB.participants_kind(source) if source.is_file() and source.suffix.lower() != ".csv" else None
    rules = {**DEFAULT_RULES, **((design or {}).get("exclusions") or {})}
    slider = design["slider"]["max"] - design["slider"]["min"] if design and design.get("scale") == "slider" else None
    seen = [c for c in dict.fromkeys(df.loc[df["kind"] == "rating", "condition"]) if c]
    conditions = [c for c in (design or {}).get("conditions", []) if c in seen] + \
        [c for c in sorted(seen) if c not in (design or {}).get("conditions", [])]
    questions = [q["id"] for q in (design or {}).get("questions", [])] or \
        sorted(set(df.loc[df["kind"] == "rating", "question"]))
    same = identical_conditions(design)   # the riddle's SS and LS: one video, so no contrast (module doc, step 5)
    dbs = sorted(source.glob("*.sqlite")) if source.is_dir() else [source] if kind else []
    excluded = exclusions(df, rules, slider, expected_counts(design, df), unconsented(dbs))
    ratings = df[(df["kind"] == "rating") & df["value"].notna()]
    tidy = ratings[~ratings["participant"].astype(int).isin(excluded)].reset_index(drop=True)
    if tidy.empty:   # a report's tidy.csv given back as answers has ratings only (a study researcher's review)
        tidy_csv = not df["kind"].isin(["audio_check", "attention"]).any() and rules.get("audio_check", True)
        raise LaughlabError(f"no ratings are left after the exclusions ({len(excluded)} "
                            f"participant{'' if len(excluded) == 1 else 's'} excluded: "
                            f"{reason_counts(excluded)})" + (
                                "; these answers have no audio-check or attention rows, as a report's tidy.csv (its "
                                "ratings only): analyze the database or the participants' answer files" if tidy_csv
                                else ""))
    questions = [q for q in questions if q in set(tidy["question"])]
    means = condition_means(tidy, conditions, questions)
    fixed, variances, cons, notes, warned = [], [], [], {}, {}
    for q in questions:
        data = tidy[tidy["question"] == q]
        if data["condition"].nunique() < 2 or data["participant"].nunique() < 2:
            notes[q] = "Fewer than two conditions or participants: no model."
            continue
        fit, ref, warned[q] = fit_model(data, conditions)
        if warned[q]:
            notes[q] = fit_note(fit, warned[q])
        ci = fit.conf_int()
        for name in fit.fe_params.index:
            fixed.append({"question": q, "term": name.replace(f"C(condition, Treatment(reference={ref!r}))", "condition"),
                          "estimate": float(fit.fe_params[name]), "se": float(fit.bse_fe[name]),
                          "ci_low": float(ci.loc[name, 0]), "ci_high": float(ci.loc[name, 1]),
                          "z": float(fit.tvalues[name]), "p": float(fit.pvalues[name])})
        var = variance_components(fit)
        few = " ".join(filter(None, (few_stimuli_note(var, int(data.groupby("condition")["stimulus"].nunique().min())),
                                     few_participants_note(int(data["participant"].nunique())))))
        if few:
            notes[q] = f"{notes[q]} {few}" if notes.get(q) else few
        variances.append({"question": q, **{f"var_{k}": v for k, v in var.items()}, "converged": bool(fit.converged),
                          "n_ratings": len(data), "n_participants": int(data["participant"].nunique()),
                          "n_stimuli": int(data["stimulus"].nunique()), "reference": ref})
        c = contrasts(fit, ref, conditions, same)
        c.insert(0, "question", q)
        cons.append(c)
    contrast_df = pd.concat(cons, ignore_index=True) if cons else pd.DataFrame()
    ex_df = pd.DataFrame([{"participant": p, "reason": r} for p, rs in sorted(excluded.items()) for r in rs],
                         columns=["participant", "reason"])

    tmp = out.with_name(f".{out.name}.part")
    import shutil

    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    from laughlab.study.exclusions import cell_safe   # the participant's texts: no spreadsheet formula

    tidy = tidy.assign(**{c: tidy[c].map(cell_safe) for c in ("user_agent", "text") if c in tidy})
    tidy.to_csv(tmp / "tidy.csv", index=False, columns=list(DB.COLUMNS))
    ex_df.to_csv(tmp / "exclusions.csv", index=False)
    means.to_csv(tmp / "means.csv", index=False, float_format="%.4f")
    pd.DataFrame(fixed).to_csv(tmp / "model.csv", index=False, float_format="%.6g")
    pd.DataFrame(variances).to_csv(tmp / "variance.csv", index=False, float_format="%.6g")
    contrast_df.to_csv(tmp / "contrasts.csv", index=False, float_format="%.6g")
    from laughlab.study.plots import participant_lines, means_plot

    simulated = kind == "simulated"   # said in the figures' titles too: a figure travels without its README
    means_plot(tmp / "fig_means.png", means, tidy, questions, conditions, design, simulated=simulated, width=width)
    participant_lines(tmp / "fig_participants.png", tidy, means, questions, conditions, design, simulated=simulated,
                      width=width)
    n_all = int(df["participant"].nunique())
    doc = {"source": str(source), "design_id": (design or {}).get("id"), "participants": n_all,
           "simulated": kind == "simulated",
           "planted": DB.stored(source, "simulation") if kind == "simulated" else None,
           "excluded": {str(p): r for p, r in excluded.items()}, "included": n_all - len(excluded),
           "participation": participation(dbs, df, {s: v.get("duration_s") for s, v in
                                                    ((design or {}).get("stimuli") or {}).items()}),
           "order_rows": order_rows(df, excluded),
           "scale_range": list(scale_range(design)) if design and design.get("scale") == "likert" else None,
           "conditions": conditions, "questions": questions, "model_notes": notes,
           "untested": [list(p) for p in same if set(p) <= set(conditions)],
           "model_warnings": {q: w for q, w in warned.items() if w},
           "means": means.to_dict("records"), "fixed": fixed, "variance": variances,
           "contrasts": contrast_df.to_dict("records")}
    (tmp / "report.json").write_text(json.dumps(doc, indent=1, default=float) + "\n", encoding="utf-8")
    (tmp / "README.md").write_text(_markdown(doc, source, command, design is not None), encoding="utf-8")
    check_out(out, overwrite)  # again: the fit takes a while, and the folder may have been filled meanwhile
    put(tmp, out)
    return out


def near_end(means: list[dict], scale) -> str:
    """The README's line for condition means within a point of the scale's end ("" when none): ratings cannot pass
    it, so differences there show smaller than they are (a statistician's review: +1 over a base of 6 on 1..7 showed
    as 0.63)."""
    if not scale:
        return ""
    lo, hi = scale
    close = [f"{m['question']} {m['condition']} {m['mean']:.2f}" for m in means
             if m.get("mean") == m.get("mean") and (m["mean"] <= lo + 1 or m["mean"] >= hi - 1)]
    if not close:
        return ""
    return (f"Within a point of the scale's end ({lo:g}..{hi:g}): {', '.join(close)}. Ratings cannot pass the end, so "
            "differences involving these means show smaller than they are.")


#: the report's line when no design was found or given (CSV answers without --design)
NO_DESIGN = ("No study design was found or given (`--design STUDY_DIR`): the conditions are in alphabetical "
             "order, and the default exclusion rules apply.")


def _markdown(doc: dict, source: Path, command: str, has_design: bool = True) -> str:
    lines = [f"# Study report: {source.name}", "", f"`{command}`", ""]
    if not has_design:
        lines += [NO_DESIGN, ""]
    if doc.get("simulated"):
        lines += ["**Simulated participants** (`study simulate`, answers drawn from a planted effect), not people.", ""]
        sim = doc.get("planted")
        if sim:   # what the analysis should recover (a review: the report did not say)
            eff = ", ".join(f"`{c}` {v:+g}" for c, v in sim["effects"].items()) or "none"
            lines += [f"Planted: {eff} rating points on every question, over a base of {sim['base']:g}; participant "
                      f"offsets SD {sim['sd_participant']:g}, answer noise SD {sim['sd_noise']:g}; seed {sim['seed']}, "
                      f"{sim['participants']} participants.", ""]
    lines += [
             f"{doc['participants']} participants, {doc['included']} included, "
             f"{doc['participants'] - doc['included']} excluded (`exclusions.csv`).", ""]
    if participation_line(doc.get("participation") or {}):
        lines += [participation_line(doc["participation"]), ""]
    for p, reasons in doc["excluded"].items():
        lines.append(f"- participant {p}: {'; '.join(reasons)}")
    rows = doc.get("order_rows") or {}
    if doc["excluded"] and len({kept for kept, _ in rows.values()}) > 1:   # the exclusions unbalanced the square
        lines += ["", "Included per order row (the Latin square's rows, whose order effects cancel only over whole "
                      "rows; the model has no order term, so the analysis takes the excluded as missing at random): "
                  + ", ".join(f"row {r}: {kept} of {n}" for r, (kept, n) in rows.items()) + "."]
    lines += ["", "## Condition means (95 % CI over participants)", "",
              "| question | condition | mean | 95 % CI | n |", "|---|---|---|---|---|"]
    for m in doc["means"]:
        lines.append(f"| {m['question']} | {m['condition']} | {_fmt(m['mean'])} | "
                     f"[{_fmt(m['ci_low'])}, {_fmt(m['ci_high'])}] | {m['n_participants']} |")
    near = near_end(doc["means"], doc.get("scale_range"))
    if near:
        lines += ["", near]
    lines += ["", "![condition means](fig_means.png)", "", "![participants](fig_participants.png)", "",
              "## Mixed model per question", "",
              "`value ~ condition + (1 | participant) + (1 | stimulus)`, REML, statsmodels MixedLM "
              "(why: see `laughlab/study/analyze.py`). It assumes each condition's effect is the same for every "
              "participant (no by-participant slope: if it varies, the tests are liberal) and takes each video as a "
              "stimulus of its own (an audio item shown in every condition is no variance component: its effect "
              "cancels within the contrasts, which are then conservative); the condition means' intervals are over "
              "participants, for these stimuli (docs/study.md).", "",
              "| question | var participant | var stimulus | var residual | converged |", "|---|---|---|---|---|"]
    for v in doc["variance"]:
        lines.append(f"| {v['question']} | {_fmt(v['var_participant'], 3)} | {_fmt(v.get('var_stimulus'), 3)} | "
                     f"{_fmt(v['var_residual'], 3)} | {v['converged']} |")
    if doc["model_notes"]:
        lines.append("")
    for q, note in doc["model_notes"].items():
        lines.append(f"- {q}: {note}")
    lines += ["", "## Pairwise contrasts (Holm over each question's pairs)", "",
              "Estimates in rating points from the mixed model; d is the estimate over the square root of the summed "
              "variance components (participant + stimulus + residual; Westfall, Kenny & Judd 2014), its interval "
              "the estimate's scaled alike.", ""]
    if doc.get("untested"):
        pairs = ", ".join(f"{a} - {b}" for a, b in doc["untested"])
        lines += [f"Not tested: {pairs}. Each pair's conditions show the same videos, byte for byte, and the "
                  "page does not present what tells them apart (the riddle preset's role, Speaks or Listens), so "
                  "their difference can only be noise; they are left out of the contrasts and of Holm's family.",
                  ""]
    lines += ["| question | a - b | estimate | 95 % CI | z | p | p (Holm) | d [95 % CI] |",
              "|---|---|---|---|---|---|---|---|"]
    for c in doc["contrasts"]:
        lines.append(f"| {c['question']} | {c['a']} - {c['b']} | {_fmt(c['estimate'])} | "
                     f"[{_fmt(c['ci_low'])}, {_fmt(c['ci_high'])}] | {_fmt(c['z'])} | {_p(c['p'])} | "
                     f"{_p(c['p_holm'])} | {_fmt(c['d'])} [{_fmt(c['d_low'])}, {_fmt(c['d_high'])}] |")
    return "\n".join(lines) + "\n"
