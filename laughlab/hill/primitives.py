"""Activation primitives of one call and of a bout (DiLorenzo et al. 2008, 6.2; the abdomen's hold
and the bout's release are ours): see :mod:`laughlab.hill.fit` for why.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from laughlab.hill.torso import GROUPS, NG

if TYPE_CHECKING:  # pragma: no cover
    from laughlab.hill.problem import FitParams

_AB, _DI, _II, _CU = GROUPS.index("abdomen"), GROUPS.index("diaphragm"), GROUPS.index("inner_intercostals"), \
    GROUPS.index("clavicle_up")


def bump(t, start, freq):
    """One period of a raised cosine: ``(1 - cos(2 pi f (t - t0))) / 2`` on ``[t0, t0 + 1/f)``, else 0."""
    u = (np.asarray(t, dtype=float) - start) * freq
    return np.where((u >= 0.0) & (u < 1.0), 0.5 - 0.5 * np.cos(2.0 * np.pi * u), 0.0)


def hold(t, start, freq):
    """Rise and hold: the integral of one period of :func:`bump`, normalised to end at 1.

    ``u - sin(2 pi u) / (2 pi)`` with ``u = clip(f (t - t0), 0, 1)``: 0 before
    ``t0``, 1 from ``t0 + 1/f`` on, its rate a raised cosine (module notes).
    """
    u = np.clip((np.asarray(t, dtype=float) - start) * freq, 0.0, 1.0)
    return u - np.sin(2.0 * np.pi * u) / (2.0 * np.pi)


def release(t, t_release, release_s: float):
    """The let-go of a bout's held activations: 1 before ``t_release``, a half cosine down to 0 over
    ``release_s`` (s) after it; ``t_release`` None: held (1)."""
    t = np.asarray(t, dtype=float)
    if t_release is None:
        return np.ones_like(t)
    s = np.clip((t - t_release) / release_s, 0.0, 1.0)
    return 0.5 + 0.5 * np.cos(np.pi * s)


def bout_releases(calls, fps: float, after_s: float) -> list:
    """Release time (s) of each call's held activation: ``after_s`` after the end of the last call of its bout.

    A bout goes on while the next call begins less than ``after_s`` after the
    previous one's end; the last known call's bout ends with it (a causal rule:
    at ``end + after_s`` it is known whether another call has begun).
    """
    out = [0.0] * len(calls)
    t_rel = None
    for i in range(len(calls) - 1, -1, -1):
        end = calls[i].end / fps
        if i + 1 == len(calls) or calls[i + 1].start / fps - end >= after_s:
            t_rel = end + after_s
        out[i] = t_rel
    return out


def call_activation(t, x, t_call: float, t_release=None, release_s: float = 1.5):
    """Group activations ``(len(t), [batch,] 6)`` of one call's parameters ``x`` (physical, ``PARAMS``).

    ``x`` may be ``(7,)`` or ``(batch, 7)``; times are absolute (s); ``t_call`` is the call's start (s).
    Abdomen: ``abdomen_amp * hold`` (let go from ``t_release``, :func:`release`); ribcage:
    ``ribcage_amp * bump`` on the abdomen's timing; diaphragm: ``diaphragm_amp * bump`` on its own.
    """
    x = np.asarray(x, dtype=float)
    t = np.asarray(t, dtype=float)
    tt = t[:, None] if x.ndim == 2 else t
    ab_amp, rc_amp, di_amp, t_ab, f_ab, t_di, f_di = (x[..., i] for i in range(7))
    h_ab = hold(tt, t_call + t_ab, f_ab)
    if t_release is not None:
        env = release(t, t_release, release_s)
        h_ab = h_ab * (env[:, None] if x.ndim == 2 else env)
    b_ab = bump(tt, t_call + t_ab, f_ab)
    b_di = bump(tt, t_call + t_di, f_di)
    out = np.zeros(b_ab.shape + (NG,))
    out[..., _AB] = ab_amp * h_ab
    out[..., _II] = rc_amp * b_ab
    out[..., _DI] = di_amp * b_di
    return out


def call_span(x, t_call: float, t_release, release_s: float) -> tuple[float, float]:
    """First and last time (s) at which a call's primitives play; the abdomen's hold lasts until its
    release ends (forever while ``t_release`` is None)."""
    first = t_call + min(x[3], x[5])
    last = t_call + max(x[3] + 1.0 / max(x[4], 1e-9), x[5] + 1.0 / max(x[6], 1e-9))
    if x[0] != 0.0:
        last = math.inf if t_release is None else max(last, t_release + release_s)
    return first, last


def play(t, calls, release_s: float) -> np.ndarray:
    """The sum of the primitives ``(len(t), 6)`` of ``calls``, ``(x, t_call, t_release)`` each, at times
    ``t`` (s), not clipped; only the calls whose primitives overlap ``t`` are evaluated."""
    t = np.asarray(t, dtype=float)
    out = np.zeros((t.size, NG))
    if not t.size:
        return out
    lo, hi = float(t.min()), float(t.max())
    for x, t_call, t_release in calls:
        first, last = call_span(x, t_call, t_release, release_s)
        if first <= hi and last >= lo:
            out += call_activation(t, x, t_call, t_release, release_s)
    return out


def with_secondary(primitives, fit: "FitParams"):
    """``(activations in [0, 1] with the clavicle elevators, spine target rad)`` from summed primitives
    ``(..., 6)``: the secondary motion follows the abdomen (as the ``hill`` body's recipe)."""
    acts = np.clip(primitives, 0.0, 1.0)
    acts[..., _CU] = np.minimum(acts[..., _CU] + fit.clavicle_ratio * acts[..., _AB], 1.0)
    return acts, np.radians(fit.spine_deg) * acts[..., _AB]


# --- one call as an optimisation problem -------------------------------------------------------
