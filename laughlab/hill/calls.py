"""Calls of a laugh for the Hill fit: cut at the pressure's valleys, or found in the frame RMS
(DiLorenzo, Zordan & Sanders 2008, 7: "we segmented the calls in the center of the valley between
the peaks"; :func:`segment_calls_level` is ours, for real call rates).  See :mod:`laughlab.hill.fit`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Call:
    """A call of the target: frames ``[start, end)`` and its peak frame."""

    start: int
    end: int
    peak: int


def segment_calls(pressure, fps: float, min_height_frac: float = 0.15, min_prominence_frac: float = 0.1,
                  min_distance_s: float = 0.08, floor_frac: float = 0.1, max_half_s: float = 0.25,
                  valley_tol: float = 0.05) -> list[Call]:
    """Cut a pressure curve into calls at the valleys between its peaks.

    Peaks: local maxima at least ``min_distance_s`` apart, higher than
    ``min_height_frac`` and more prominent than ``min_prominence_frac`` of the
    curve's 99th percentile.  Between two peaks the boundary is the centre of
    the valley (the middle of the frames within ``valley_tol`` of its floor,
    as the paper advises), unless the peaks are more than two ``max_half_s`` apart:
    then the call ends where the pressure falls below ``floor_frac`` of its peak
    (or ``max_half_s`` after it) and the next starts where it rises above (or
    ``max_half_s`` before its peak), leaving a rest between bouts.
    """
    from scipy.signal import find_peaks

    p = np.asarray(pressure, dtype=float)
    if p.size < 3:
        return []
    ref = float(np.percentile(p, 99))
    if not ref > 0:
        return []
    peaks, _ = find_peaks(p, height=min_height_frac * ref, prominence=min_prominence_frac * ref,
                          distance=max(1, int(round(min_distance_s * fps))))
    half = max(1, int(round(max_half_s * fps)))

    def rise_start(k: int, lo: int) -> int:
        i = k
        while i > lo and i > k - half and p[i - 1] > floor_frac * p[k]:
            i -= 1
        return i

    def fall_end(k: int, hi: int) -> int:
        i = k + 1
        while i < hi and i < k + 1 + half and p[i] > floor_frac * p[k]:
            i += 1
        return i

    calls = []
    for n, k in enumerate(peaks):
        if n == 0:
            start = rise_start(k, 0)
        else:
            prev = peaks[n - 1]
            if k - prev > 2 * half:
                start = rise_start(k, calls[-1].end)
            else:
                start = calls[-1].end
        if n + 1 < len(peaks) and peaks[n + 1] - k <= 2 * half:
            nxt = peaks[n + 1]
            seg = p[k + 1:nxt]
            low = np.flatnonzero(seg <= seg.min() + valley_tol * (min(p[k], p[nxt]) - seg.min()))
            end = k + 1 + int(round(0.5 * (low[0] + low[-1]))) if len(low) else nxt
        else:
            end = fall_end(k, len(p) if n + 1 == len(peaks) else peaks[n + 1])
        calls.append(Call(int(start), int(max(end, k + 1)), int(k)))
    return calls


def segment_calls_level(rms, fps: float, prominence_db: float = 5.0, min_distance_s: float = 0.08,
                        depth_db: float = 25.0, floor_db: float = 20.0, max_half_s: float = 0.25,
                        smooth_frames: int = 2, pressure=None, lag_s: float = 0.032) -> list[Call]:
    """Cut a recording into calls found in its level (frame RMS, full scale), not in the pressure.

    Why (departure from the paper's valleys of the pressure, issue 11): the
    target pressure is the audio envelope low-passed at 5 Hz, which merges calls
    that come faster than about five a second; real laughter has 3-8 (and up to
    11) calls a second, so on the held-out real laughs the pressure's valleys
    found the annotated call count within +/-1 in 23 % of files.  The frame RMS
    keeps every call; the pressure, fitted call by call, keeps its 5 Hz shape.

    The level ``L = 20 log10(max(rms, 1e-5))`` (dBFS) is averaged over
    ``smooth_frames`` frames.  Peaks: local maxima at least ``min_distance_s``
    apart (0.08 s: up to 12 calls a second), no lower than ``depth_db`` below
    the 99th percentile of ``L`` and more prominent than ``prominence_db``
    (chosen on the training split of the real corpus, docs/benchmarks.md).  Boundaries as
    :func:`segment_calls`: the centre of the valley between two peaks less than
    two ``max_half_s`` apart; otherwise the call ends where ``L`` falls
    ``floor_db`` below its peak (or ``max_half_s`` after it) and the next starts
    where it rises above that (or ``max_half_s`` before its peak).

    With ``pressure`` (the target the calls will be fitted to), a boundary
    between two peaks moves to the pressure's lowest frame between them, both
    shifted by ``lag_s`` (the 5 Hz low-pass's time constant, 32 ms): the fit
    needs each call's pressure pulse whole; cut at the level's valley, a pulse
    runs on into the next call and the torso handed over is still pushing
    (on a real laugh the median error rose from 0.11 to 0.99).  Quiet calls
    (whose pressure the extractor's floor has cleared) are kept: they are calls;
    :func:`fit` does not drive them (``FitParams.quiet_frac``).
    """
    from scipy.signal import find_peaks

    r = np.asarray(rms, dtype=float)
    if r.size < 3:
        return []
    lev = 20.0 * np.log10(np.maximum(np.nan_to_num(r, nan=0.0), 1e-5))
    if smooth_frames > 1:
        lev = np.convolve(lev, np.ones(smooth_frames) / smooth_frames, mode="same")
    ref = float(np.percentile(lev, 99))
    if not ref > -100.0 + 1e-9:
        return []
    peaks, _ = find_peaks(lev, height=ref - depth_db, prominence=prominence_db,
                          distance=max(1, int(round(min_distance_s * fps))))
    half = max(1, int(round(max_half_s * fps)))
    pr = None if pressure is None else np.asarray(pressure, dtype=float)
    calls: list[Call] = []
    for n, k in enumerate(peaks):
        floor = lev[k] - floor_db
        if n > 0 and k - peaks[n - 1] <= 2 * half:
            start = calls[-1].end
        else:
            lo = calls[-1].end if calls else 0
            start = k
            while start > lo and start > k - half and lev[start - 1] > floor:
                start -= 1
        if n + 1 < len(peaks) and peaks[n + 1] - k <= 2 * half:
            nxt = peaks[n + 1]
            if pr is not None:
                lag = int(round(lag_s * fps))
                a, b = min(k + 1 + lag, len(pr) - 1), min(nxt + lag, len(pr))
                end = a + int(np.argmin(pr[a:b])) if b > a else nxt
            else:
                seg = lev[k + 1:nxt]
                low = np.flatnonzero(seg <= seg.min() + 0.05 * (min(lev[k], lev[nxt]) - seg.min()))
                end = k + 1 + int(round(0.5 * (low[0] + low[-1]))) if len(low) else nxt
        else:
            hi = len(lev) if n + 1 == len(peaks) else int(peaks[n + 1])
            end = k + 1
            while end < hi and end < k + 1 + half and lev[end] > floor:
                end += 1
        # never empty: a cut at the pressure's valley may pass the next peak by the lag
        calls.append(Call(int(start), int(max(end, k + 1, start + 1)), int(k)))
    return calls


# --- the activation primitive -------------------------------------------------------------------
