"""Metrics registered by name (the pattern of lm-evaluation-harness).

A metric is a function of one trial's outputs (:class:`~laughlab.harness.trialdata.TrialData`)
returning a float (NaN when it does not apply, e.g. no ground truth).  Each has
a stable name, ``higher_is_better`` (None when neither is), units, and a
docstring with its formula.  Built-in metrics are a plugin
(``laughlab_plugins.metrics_laughter``) registered through ``register_metrics``
like any third-party metric.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Callable

import numpy as np

from laughlab.core.summary import counted
from laughlab.harness.trialdata import TrialData


@dataclass(frozen=True)
class Metric:
    """A named metric.

    Attributes
    ----------
    name : str
    fn : callable
        ``fn(trial) -> float``.
    higher_is_better : bool or None
    units : str
    search : tuple of two floats, or None
        For a metric that is the best of a bounded search (a lag in [0, 2] s): the search's range, so that a
        report can say when a value sits at its edge (the best may lie beyond it).
    """

    name: str
    fn: Callable[[TrialData], float]
    higher_is_better: bool | None
    units: str
    search: tuple | None = None

    @property
    def description(self) -> str:
        """The docstring's first paragraph, on one line (a report's definition column; its first line alone
        stopped mid-sentence)."""
        doc = (self.fn.__doc__ or "").strip().split("\n\n")[0]
        return " ".join(doc.split())

    def __call__(self, trial: TrialData) -> float:
        return self.fn(trial)


def metric(name: str, higher_is_better: bool | None, units: str, search: tuple | None = None):
    """Decorator turning ``fn(trial) -> float`` into a :class:`Metric` (``search``: see :class:`Metric`)."""

    def wrap(fn):
        return Metric(name, fn, higher_is_better, units, tuple(search) if search is not None else None)

    return wrap


def registered() -> dict[str, Metric]:
    """All metrics, by name."""
    from laughlab.core import plugins

    return {name: info.obj for name, info in plugins.registry()["metric"].items()}


def compute(trial: TrialData, names: list[str] | None = None, why: dict | None = None) -> dict[str, float]:
    """Evaluate metrics on one trial; a metric that fails on missing data gives NaN (a third-party metric's
    exception then goes into ``why``: name -> ``"KeyError: 'jawopen'"``, for :func:`warn_unmeasured`)."""
    out = {}
    for name, m in registered().items():
        if names is not None and name not in names:
            continue
        try:
            v = float(m(trial))
        except (KeyError, ValueError, ZeroDivisionError) as exc:
            v = float("nan")
            near = _near_column(exc, trial) if why is not None else None
            if near and m.fn.__module__.split(".")[0] not in ("laughlab", "laughlab_plugins"):
                why[name] = f"KeyError: {exc}, a column the trial does not have (did you mean {near!r}?)"
        except Exception as exc:   # e.g. a plugin's metric returning None: one line naming it, not a traceback
            from laughlab.core.errors import LaughlabError

            raise LaughlabError(f"metric {name!r} failed: {type(exc).__name__}: {exc} (a metric returns a number, "
                                "or NaN where it does not apply)") from None
        out[name] = v if math.isfinite(v) else float("nan")
    return out


def _near_column(exc: Exception, trial) -> str | None:
    """For a ``KeyError`` of a name that is no column of the trial's channels: the column it misspells (the same
    name in other case, or difflib's nearest at 0.8), else None (a metric of another face's channels: n/a)."""
    import difflib

    key = exc.args[0] if isinstance(exc, KeyError) and exc.args and isinstance(exc.args[0], str) else None
    columns = [str(c) for c in getattr(getattr(trial, "channels", None), "columns", ())]
    if key is None or key in columns:
        return None
    same = [c for c in columns if c.lower() == key.lower()]
    return (same or difflib.get_close_matches(key, columns, n=1, cutoff=0.8) or [None])[0]


def warn_unmeasured(records: list[dict]) -> None:
    """One warning line per third-party metric that gave no number on any trial because it read a misspelt column
    (the records' ``metrics_na``, :func:`_near_column`): a plugin authors' review: a metric reading
    ``trial.channels["arkit.jawopen"]`` was "n/a" in every cell of the report, without a word.  A metric of
    channels the trials' plugins do not write is n/a without one."""
    reasons: dict = {}
    for r in records:
        for name, why in (r.get("metrics_na") or {}).items():
            reasons.setdefault(name, why)
    for name, why in sorted(reasons.items()):
        values = [r["metrics"].get(name) for r in records]
        if not any(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
            print(f"laughlab: warning: metric {name!r} gave no number on {'the' if len(records) == 1 else 'any of the'} {counted(len(records), 'trial')} (n/a in "
                  f"the report): it raised {why}", file=sys.stderr)


def best_lag_correlation(x: np.ndarray, y: np.ndarray, fps: float, max_lag_s: float) -> tuple[float, float, int]:
    """Pearson r between ``x`` and ``y`` delayed by a lag in [0, max_lag_s]; the lag maximising r.

    ``r(k) = corr(x[t], y[t + k])`` for k = 0 .. round(max_lag_s * fps) frames:
    the animation ``y`` answers the sound ``x`` k frames later.

    Returns
    -------
    r : float
        Pearson correlation at the best lag (NaN if either signal is constant).
    lag_s : float
        The best lag (s).
    k : int
        The best lag (frames).
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    n = min(len(x), len(y))
    best = (float("nan"), float("nan"), 0)
    for k in range(0, min(int(round(max_lag_s * fps)), n - 3) + 1):
        a, b = x[: n - k], y[k:n]
        if a.std() == 0 or b.std() == 0:
            continue
        r = float(np.corrcoef(a, b)[0, 1])
        if not r <= best[0]:  # also replaces the NaN start
            best = (r, k / fps, k)
    return best


def finite_percentile(values, q: float) -> float:
    """The ``q``-th percentile of the finite ``values`` (NaN marks e.g. a missed bout); NaN when none is finite."""
    if values is None:
        return float("nan")
    v = np.asarray(values, dtype=float)
    return float(np.nanpercentile(v, q)) if np.isfinite(v).any() else float("nan")
