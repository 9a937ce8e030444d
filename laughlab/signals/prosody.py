"""Offline prosody of a whole recording with Praat (parselmouth): the reference for the online extractor.

Ding et al. (2014, section 3) take the laughter prosody, energy and pitch, of
the AVLaughterCycle database from PRAAT.  :func:`praat_prosody` runs Praat's own
analyses through parselmouth (``Sound.to_intensity`` and ``Sound.to_pitch_ac``,
Boersma 1993) on a whole file, so the per-frame online estimates of the
``phoneme`` extractor can be checked against Praat's numbers:

* **intensity** (dB re 2e-5, samples taken as Pa): Praat's Kaiser-windowed mean
  square with the mean subtracted; its window is ``6.4 / minimum_pitch`` long,
  so ``minimum_pitch = 6.4 / window_s`` gives the online window exactly.
* **F0** (Hz): Praat's autocorrelation method with ``pitch_floor`` setting a
  window of 3 periods (``3 / pitch_floor``, 40 ms at 75 Hz: the online window),
  its default silence, voicing and octave costs, and its Viterbi path (which
  looks at the whole file: the one thing the online estimate cannot copy).

Examples
--------
>>> import numpy as np
>>> sr = 16000
>>> t = np.arange(sr) / sr
>>> x = 0.1 * np.sin(2 * np.pi * 220 * t)
>>> f0, db = praat_prosody(x, sr, [0.5])
>>> round(float(f0[0])), round(float(db[0]))
(220, 71)
"""
from __future__ import annotations

import math

import numpy as np

from laughlab.core.errors import LaughlabError

__all__ = ["praat_prosody", "frame_centers", "PRAAT_REF_POWER"]

#: reference mean square of Praat's intensity: (2e-5 Pa)^2
PRAAT_REF_POWER = 4.0e-10


def frame_centers(n_frames: int, sample_rate: int, fps: float, window_s: float) -> np.ndarray:
    """Centres (s) of the analysis windows of the online extractor, one per frame.

    Frame ``k``'s block ends at sample ``round((k + 1) * sr / fps)``; the online
    analysis window is the ``window_s`` of audio that ends there, so its centre
    is ``end / sr - window_s / 2``.
    """
    ends = np.round(np.arange(1, n_frames + 1) * (sample_rate / fps))
    return ends / sample_rate - window_s / 2.0


def praat_prosody(audio, sample_rate: int, times, *, window_s: float = 0.04, pitch_floor_hz: float = 75.0,
                  pitch_ceiling_hz: float = 1000.0, time_step_s: float = 0.005,
                  silence_threshold: float = 0.03, voicing_threshold: float = 0.45,
                  octave_cost: float = 0.01, octave_jump_cost: float = 0.35,
                  voiced_unvoiced_cost: float = 0.14) -> tuple[np.ndarray, np.ndarray]:
    """Praat's F0 and intensity of a whole recording, sampled at ``times``.

    Parameters
    ----------
    audio : array_like (n,)
        Mono samples (full scale; taken as Pa, as Praat does).  Non-finite
        samples are replaced by 0.
    sample_rate : int
        Hz.
    times : array_like
        Times (s) at which to report the values, e.g. :func:`frame_centers`.
    window_s : float
        Intensity window (s): Praat's ``minimum_pitch`` is ``6.4 / window_s``.
    pitch_floor_hz, pitch_ceiling_hz : float
        Pitch range of ``Sound.to_pitch_ac`` (window ``3 / pitch_floor_hz``).
    time_step_s : float
        Analysis step of both analyses (s).
    silence_threshold, voicing_threshold, octave_cost, octave_jump_cost, voiced_unvoiced_cost : float
        Praat's pitch parameters (its defaults).

    Returns
    -------
    f0 : ndarray
        F0 (Hz) of the nearest Praat pitch frame, 0 where Praat says unvoiced,
        NaN outside Praat's analysis range (the first and last half window).
    intensity : ndarray
        Intensity (dB), linearly interpolated between Praat's frames, NaN
        outside its analysis range.

    Raises
    ------
    LaughlabError
        If parselmouth is not installed.
    """
    try:
        import parselmouth
    except ImportError as exc:  # pragma: no cover - a declared dependency
        raise LaughlabError("the Praat reference needs parselmouth: pip install praat-parselmouth") from exc
    x = np.array(audio, dtype=np.float64).ravel()
    x[~np.isfinite(x)] = 0.0
    t = np.asarray(times, dtype=float).ravel()
    f0 = np.full(t.shape, np.nan)
    db = np.full(t.shape, np.nan)
    snd = parselmouth.Sound(x, sampling_frequency=float(sample_rate))
    try:
        inten = snd.to_intensity(minimum_pitch=6.4 / window_s, time_step=time_step_s, subtract_mean=True)
    except parselmouth.PraatError:  # too short for one window
        return f0, db
    xs, vals = inten.xs(), inten.values[0]
    inside = (t >= xs[0]) & (t <= xs[-1])
    db[inside] = np.interp(t[inside], xs, vals)
    try:
        pitch = snd.to_pitch_ac(time_step=time_step_s, pitch_floor=pitch_floor_hz, max_number_of_candidates=15,
                                very_accurate=False, silence_threshold=silence_threshold,
                                voicing_threshold=voicing_threshold, octave_cost=octave_cost,
                                octave_jump_cost=octave_jump_cost, voiced_unvoiced_cost=voiced_unvoiced_cost,
                                pitch_ceiling=pitch_ceiling_hz)
    except parselmouth.PraatError:
        return f0, db
    pxs = pitch.xs()
    freq = pitch.selected_array["frequency"]
    if len(pxs):
        dx = pxs[1] - pxs[0] if len(pxs) > 1 else time_step_s
        k = np.round((t - pxs[0]) / dx).astype(int)
        ok = (k >= 0) & (k < len(pxs)) & (t >= pxs[0] - dx / 2) & (t <= pxs[-1] + dx / 2)
        f0[ok] = freq[k[ok]]
    if not math.isfinite(float(np.nansum(db))):  # pragma: no cover - Praat gives -300 dB for digital silence
        db[~np.isfinite(db)] = np.nan
    return f0, db
