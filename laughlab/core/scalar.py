"""Scalar twins of numpy helpers for per-frame code: the same floats, without numpy's per-call cost.

A call of ``np.interp`` on one number costs about 2.5 us, most of it argument handling; the
frame loop calls such helpers every frame.  These functions do numpy's arithmetic in the
same order on Python floats (IEEE doubles), so their results are bit-identical (tests compare
them with numpy over random inputs).
"""
from __future__ import annotations

import math
from bisect import bisect_right
from typing import Sequence


def interp(x: float, xp: Sequence[float], fp: Sequence[float]) -> float:
    """``float(np.interp(x, xp, fp))`` for one ``x`` (``xp`` increasing, as lists of floats).

    numpy's algorithm (``numpy/_core/src/multiarray/compiled_base.c``, ``arr_interp``):
    clamp outside ``[xp[0], xp[-1]]``; at the last point or an exact knot give ``fp[j]``;
    else ``slope * (x - xp[j]) + fp[j]`` with ``slope = (fp[j+1] - fp[j]) / (xp[j+1] - xp[j])``,
    and numpy's NaN fall-backs for infinite slopes.
    """
    n = len(xp)
    if x != x:  # NaN in, NaN out
        return math.nan
    if x > xp[-1]:
        return float(fp[-1])
    if x < xp[0]:
        return float(fp[0])
    j = bisect_right(xp, x) - 1
    if j >= n - 1:
        return float(fp[n - 1])
    if xp[j] == x:
        return float(fp[j])
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    y = slope * (x - xp[j]) + fp[j]
    if y != y:
        y = slope * (x - xp[j + 1]) + fp[j + 1]
        if y != y and fp[j] == fp[j + 1]:
            y = fp[j]
    return float(y)
