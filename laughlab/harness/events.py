"""Matching detected event times (call onsets, ...) to ground truth.

One-to-one greedy matching by time, the usual onset-detection evaluation
(e.g. MIREX onset detection, a +/-50 ms window): every pair of a detected and a
true time closer than ``tol_s`` is a candidate; pairs are taken closest first,
and each detected and each true event is used at most once.  Ties in distance
go to the earlier true event, then the earlier detection, so the result does not
depend on the order of the inputs.

Examples
--------
>>> tp, fp, fn, err = match_onsets([0.10, 0.52, 0.90], [0.12, 0.50, 1.50], 0.05)
>>> tp, fp, fn
(2, 1, 1)
>>> [round(e, 3) for e in err]
[-0.02, 0.02]
>>> prf(tp, fp, fn)
(0.6666666666666666, 0.6666666666666666, 0.6666666666666666)
"""
from __future__ import annotations

import math
from typing import Iterable

import numpy as np

__all__ = ["match_onsets", "prf"]


def _times(values: Iterable[float], what: str) -> np.ndarray:
    arr = np.asarray(list(values) if not isinstance(values, np.ndarray) else values, dtype=float).ravel()
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} times must be finite (s)")
    return np.sort(arr)


def match_onsets(detected: Iterable[float], truth: Iterable[float], tol_s: float = 0.05
                 ) -> tuple[int, int, int, list[float]]:
    """Match detected event times to true ones, one to one, closest pairs first.

    Parameters
    ----------
    detected : iterable of float
        Detected event times (s), any order.
    truth : iterable of float
        True event times (s), any order.
    tol_s : float
        Largest distance (s) at which a detection counts for a true event
        (inclusive, with a 1e-9 s allowance for floating-point round-off).

    Returns
    -------
    tp : int
        Matched pairs (true positives).
    fp : int
        Detections left unmatched (false positives).
    fn : int
        True events left unmatched (false negatives, misses).
    errors : list of float
        ``detected - true`` (s) of every matched pair, in the order of the true
        events.  Positive: the detection came late.
    """
    if not (isinstance(tol_s, (int, float)) and math.isfinite(tol_s) and tol_s >= 0):
        raise ValueError(f"tol_s must be a finite number >= 0 (got {tol_s!r})")
    d = _times(detected, "detected")
    t = _times(truth, "true")
    if len(d) == 0 or len(t) == 0:
        return 0, len(d), len(t), []
    tol = tol_s + 1e-9
    # candidate pairs within tolerance: both arrays are sorted, so each true time's
    # candidates form a contiguous run of detections
    lo = np.searchsorted(d, t - tol, side="left")
    hi = np.searchsorted(d, t + tol, side="right")
    pairs: list[tuple[float, int, int]] = []
    for j in range(len(t)):
        for i in range(int(lo[j]), int(hi[j])):
            pairs.append((abs(d[i] - t[j]), j, i))
    pairs.sort()
    used_d = np.zeros(len(d), dtype=bool)
    match_of_t = np.full(len(t), -1)
    for _, j, i in pairs:
        if match_of_t[j] < 0 and not used_d[i]:
            match_of_t[j] = i
            used_d[i] = True
    tp = int(np.count_nonzero(match_of_t >= 0))
    errors = [float(d[i] - t[j]) for j, i in enumerate(match_of_t) if i >= 0]
    return tp, len(d) - tp, len(t) - tp, errors


def prf(tp: int, fp: int, fn: int) -> tuple[float, float, float]:
    """Precision, recall and F1 from counts.

    Conventions for empty sets: precision is 1 when nothing was detected,
    recall is 1 when there was nothing to find, F1 is their harmonic mean
    (0 if both are 0).
    """
    precision = tp / (tp + fp) if tp + fp else 1.0
    recall = tp / (tp + fn) if tp + fn else 1.0
    f1 = 2 * precision * recall / (precision + recall) if precision + recall else 0.0
    return precision, recall, f1
