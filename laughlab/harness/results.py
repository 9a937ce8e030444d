"""Aggregating trial records into ``results.json`` (schema ``laughlab.results/1``).

Schema of ``results.json``::

    {
      "schema": "laughlab.results/1",
      "experiment": str,                  # experiment name
      "date": str,                        # ISO 8601, UTC
      "git_hash": str | null,             # commit of the laughlab checkout, "+dirty" if modified
      "versions": {"laughlab": str, "python": str, "numpy": str, ...},
      "plugins": {"kind/name": "origin (distribution version)"},
      "config": {...},                    # the composed experiment configuration
      "corpus": {"inputs": [str], "profiles": [str], "seeds": [int],
                 "skipped": [{"file": str, "reason": str}],   # bad files left out (on_bad=skip)
                 "not_fetched": [str]},                        # real sets left out: corpus not fetched
      "conditions": {name: [override, ...]},
      "n_trials": int,
      "metrics": {name: {"higher_is_better": bool | null, "units": str, "description": str}},
      "results": {condition: {metric: {"mean": float, "ci95": [lo, hi], "std": float, "n": int}}},
      "by_profile": {condition: {profile: {metric: mean}}},
      "extra": {...}                      # experiment-specific numbers
    }

Means and 95 % confidence intervals use the trials with a finite value; NaN where n = 0.  The
interval is a seeded percentile bootstrap (:data:`N_RESAMPLES` resamples of the trials, the 2.5th
and 97.5th percentiles of their means, ``scipy.stats.bootstrap``): unlike the t interval
``mean +/- t * sd / sqrt(n)`` it stays inside the range of the values, so a fraction's interval
never leaves [0, 1] nor a count's goes below 0; and the same values give the same bytes.
"""
from __future__ import annotations

import datetime as dt
import hashlib
import json
import math
import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
from scipy import stats

SCHEMA = "laughlab.results/1"
#: resamples of the bootstrap interval (:func:`mean_ci`); its seed is fixed, so it is the same every run
N_RESAMPLES = 4999


def _finite(values) -> np.ndarray:
    return np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)


def _mean(values) -> float:
    x = _finite(values)
    return float(x.mean()) if len(x) else float("nan")


def mean_ci(values) -> dict:
    """Mean, 95 % CI (seeded percentile bootstrap of the mean), sd and n of the finite values.

    One value, or values all equal: the interval is [mean, mean].  The percentile interval lies
    within [min, max] of the values, so it respects whatever bounds the metric has.  The sd of one value is
    undefined: NaN (``null`` in results.json; it was 0, a data user's review).
    """
    x = _finite(values)
    n = len(x)
    if n == 0:
        return {"mean": float("nan"), "ci95": [float("nan"), float("nan")], "std": float("nan"), "n": 0}
    if np.all(x == x[0]):  # one value, or all the same (their computed mean can be an ulp off the value)
        m = float(x[0]) + 0.0  # -0.0 as 0.0
        return {"mean": m, "ci95": [m, m], "std": 0.0 if n > 1 else float("nan"), "n": n}
    m = float(x.mean())
    ci = stats.bootstrap((x,), np.mean, n_resamples=N_RESAMPLES, method="percentile", vectorized=True,
                         rng=np.random.default_rng(0)).confidence_interval
    # a resampled mean can differ from min/max in the last bit: keep the interval inside the values
    lo, hi = float(max(ci.low, x.min())), float(min(ci.high, x.max()))
    return {"mean": m, "ci95": [lo, hi], "std": float(x.std(ddof=1)), "n": n}


def separated(a: dict, b: dict) -> bool:
    """True when the 95 % intervals of two :func:`mean_ci` results do not overlap (a conservative test:
    intervals that overlap a little can still differ at 5 %)."""
    if any(v is None or not math.isfinite(v) for v in (*a["ci95"], *b["ci95"])):
        return False
    return a["ci95"][1] < b["ci95"][0] or b["ci95"][1] < a["ci95"][0]


def aggregate(records: list[dict], metric_names: list[str]) -> tuple[dict, dict]:
    """Per condition and metric, :func:`mean_ci`; per condition, profile and metric, the mean."""
    results, by_profile = {}, {}
    for cond in sorted({r["condition"] for r in records}):
        rs = [r for r in records if r["condition"] == cond]
        results[cond] = {m: mean_ci([r["metrics"].get(m) for r in rs]) for m in metric_names}
        by_profile[cond] = {}
        for prof in sorted({r["profile"] for r in rs}):
            pr = [r for r in rs if r["profile"] == prof]
            by_profile[cond][prof] = {m: _mean([r["metrics"].get(m) for r in pr]) for m in metric_names}
    return results, by_profile


#: tracked files whose changes do not change what a run computes: the committed reports (regenerating them one
#: after another made every report but the first say "+dirty") and the documentation
NOT_CODE = (":(exclude)reports", ":(exclude)docs", ":(exclude)*.md")


def git_hash(root: Path | None = None) -> str | None:
    """The laughlab checkout's commit, with ``+dirty`` when a tracked file other than :data:`NOT_CODE` differs
    from it; None outside a git checkout, and None where ``root`` is only inside another repository (laughlab
    installed into a virtual environment within the user's own project: its commit is not laughlab's)."""
    root = Path(root or Path(__file__).resolve().parents[2]).resolve()
    try:
        h = subprocess.run(["git", "rev-parse", "--show-toplevel", "HEAD"], cwd=root, capture_output=True, text=True,
                           timeout=10)
        if h.returncode != 0:
            return None
        top, head = h.stdout.strip().splitlines()
        if Path(top).resolve() != root:
            return None
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".", *NOT_CODE],
                               cwd=root, capture_output=True, text=True, timeout=10).stdout.strip()
        return head + ("+dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return None


def git_diff_sha256(root: Path | None = None) -> str | None:
    """The sha256 of ``git diff HEAD`` over the tracked files other than :data:`NOT_CODE`, where the checkout is
    ``+dirty`` (None where it is clean or not laughlab's checkout): two runs of one ``+dirty`` commit with different
    edits said the same, with different outputs (a reproducibility review)."""
    root = Path(root or Path(__file__).resolve().parents[2]).resolve()
    if not (git_hash(root) or "").endswith("+dirty"):
        return None
    try:
        d = subprocess.run(["git", "diff", "--no-color", "--no-ext-diff", "HEAD", "--", ".", *NOT_CODE], cwd=root,
                           capture_output=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return None
    return hashlib.sha256(d.stdout).hexdigest() if d.returncode == 0 else None


def made_by(doc: dict) -> str:
    """A report's line of what made the results: laughlab's commit, or its version where it ran as an installed
    package without a git checkout (a packaging review: the report said ``commit: `None```)."""
    if doc.get("git_hash"):
        return f"- laughlab commit: `{doc['git_hash']}`"
    version = (doc.get("versions") or {}).get("laughlab")
    return f"- laughlab {version or '(version not recorded)'}: an installed package, no git checkout"


def versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    from laughlab import _kernels

    # the CPU family and the packages that decide bytes: YAMNet's interpreter (the default detector, by family),
    # numba (body=hill), Praat (extractor=phoneme), libsndfile's and ffmpeg's decoders, matplotlib (a JOSS-style
    # review: metrics.json left out what docs/pipeline.md says changes the bytes)
    out = {"python": platform.python_version(), "cpu_kernels": _kernels.state(), "cpu_family": _kernels.cpu_family()}
    # LAUGHLAB_NUMBA=0 runs body=hill's torso in numpy: the last bits differ (a reproducibility review: unrecorded)
    # the kernel the run used where body=hill imported it (a diff review: the variable read again could disagree)
    kernel = sys.modules.get("laughlab.hill.kernel")
    if kernel is not None:
        out["hill_kernel"] = "numba" if kernel.AVAILABLE else ("numpy (LAUGHLAB_NUMBA=0)" if "LAUGHLAB_NUMBA" in
                                                               kernel.WHY else f"numpy ({kernel.WHY})")
    else:
        from importlib.util import find_spec

        out["hill_kernel"] = ("numpy (LAUGHLAB_NUMBA=0)" if os.environ.get("LAUGHLAB_NUMBA", "1") == "0" else
                              "numba" if find_spec("numba") else "numpy (numba missing)")
    for pkg in ("laughlab", "numpy", "scipy", "hydra-core", "pluggy", "ai-edge-litert", "numba",
                "praat-parselmouth", "soundfile", "imageio-ffmpeg", "matplotlib"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = None
    return out


def provenance(input_path: str | None = None) -> dict:
    """What a single run's ``metrics.json`` records to be made again: laughlab's commit and the versions (as an
    experiment's ``results.json``), and the input file's absolute path and sha256 (None for synthetic or live
    input; a reproducibility review: with ``hydra.job.chdir=true`` the run's ``.hydra/config.yaml`` keeps the path as
    given, ``../a44.wav``, which does not lead to it from the run folder)."""
    from laughlab.core.outfiles import file_sha256

    digest = file_sha256(input_path) if input_path else None
    where = str(Path(input_path).expanduser().resolve()) if input_path else None
    return {"git_hash": git_hash(), "git_diff_sha256": git_diff_sha256(), "versions": versions(), "input_path": where,
            "input_sha256": digest}


def plugin_origins() -> dict:
    from laughlab.core import plugins

    return {f"{kind}/{name}": info.origin for kind, named in plugins.registry().items() for name, info in named.items()}


def json_clean(obj):
    """NaN and infinities become null (strict JSON)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: json_clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_clean(v) for v in obj]
    return obj


def write_json(path: Path, obj) -> None:
    tmp = path.with_name(f".{path.name}.part")
    tmp.write_text(json.dumps(json_clean(obj), indent=2, sort_keys=False) + "\n", encoding="utf-8")
    tmp.replace(path)


def now_iso() -> str:
    return dt.datetime.now(dt.timezone.utc).replace(microsecond=0).isoformat()


def read_results(path: Path) -> dict:
    """A ``results.json`` read for a report: a JSON object naming its ``experiment`` with its ``results`` by
    condition; anything else (truncated, empty, another program's JSON) is one line naming the file (a review:
    a traceback)."""
    from laughlab.core.errors import read_json_object

    # its run finished (results.json is written last), so the same command alone is refused: it needs overwrite=true
    return read_json_object(path, "; run the experiment again (its command with overwrite=true)",
                            damaged="is not a laughlab results file", keys={"experiment": str, "results": dict})
