"""Blending Fourier models (Unuma, Anjyo and Takeuchi 1995): interpolation, extrapolation and
transitions (Eq. 3), Fourier characteristics and their superposition (Eqs. 6-8, section 3.2), and
randomised shivering (section 3.3).  The models and their fitting: :mod:`laughlab.fourier.model`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from laughlab.fourier.model import MAX_HARMONICS, TWO_PI, FourierModel, wrap

__all__ = ["Characteristic", "Transition", "interpolate", "blend_time_domain", "characteristic", "superpose", "shiver"]


# ----------------------------------------------------------------------------- Eq. 3
def _phases_for_blend(a: FourierModel, b: FourierModel, eps: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Phases of ``a`` and ``b`` ready for linear interpolation.

    Where one amplitude is (near) zero its phase is meaningless, so it takes
    the other's; then ``b``'s phase is moved by a multiple of ``2 pi`` to lie
    within ``pi`` of ``a``'s (the short way round).  Unuma et al. 1995's Eq. 3
    blends the phases linearly, ``(1-s) phi + s psi`` (radians); a phase is
    defined only modulo ``2 pi`` and the paper does not say which ``psi`` to take:
    this is our choice of it, the blend itself stays linear.
    """
    scale = max(float(np.abs(a.amp).max(initial=0.0)), float(np.abs(b.amp).max(initial=0.0)), 1e-300)
    pa, pb = a.phase.copy(), b.phase.copy()
    za, zb = np.abs(a.amp) <= eps * scale, np.abs(b.amp) <= eps * scale
    pa[za] = pb[za]
    pb[zb & ~za] = pa[zb & ~za]
    return pa, pa + wrap(pb - pa)


def _pair(a: FourierModel, b: FourierModel) -> tuple[FourierModel, FourierModel]:
    if a.n_channels != b.n_channels:
        raise ValueError(f"the motions have {a.n_channels} and {b.n_channels} channels")
    n = max(a.n_harmonics, b.n_harmonics)
    return a.padded(n), b.padded(n)


def interpolate(a: FourierModel, b: FourierModel, s: float) -> FourierModel:
    """Eq. 3 at one ``s``: inter/extrapolation of two motions in amplitude and phase.

    ``Xi_m(s, t) = {(1-s) A_m0 + s B_m0} + sum_n {(1-s) A_mn + s B_mn}
    sin{n t + (1-s) phi_mn + s psi_mn}``.  ``s = 0`` gives ``a`` (Theta, Eq. 1),
    ``s = 1`` gives ``b`` (Pi, Eq. 2); ``0 < s < 1`` interpolates and any other
    ``s`` extrapolates (Fig. 3(d), (e)), where an amplitude may become
    negative, as the formula allows.  Phases are interpolated the short way
    round (module docstring).  The measured period becomes ``T_A^(1-s)
    T_B^s`` (our choice: rescaled time makes it a free playback rate).
    """
    a, b = _pair(a, b)
    pa, pb = _phases_for_blend(a, b)
    s = float(s)
    return FourierModel((1 - s) * a.mean + s * b.mean, (1 - s) * a.amp + s * b.amp, (1 - s) * pa + s * pb,
                        float(np.exp((1 - s) * np.log(a.period_s) + s * np.log(b.period_s))), 0.0,
                        a.channels or b.channels)


def blend_time_domain(a: FourierModel, b: FourierModel, s: float, t) -> np.ndarray:
    """The paper's alternative to Eq. 3 in the joint-angle (time) domain: ``(1-s) Theta(t) + s Pi(t)``.

    Reconstructed: the extracted text reads ``(1-s) Theta_m(t) + Pi_m(t)``,
    which does not reduce to ``Pi`` at ``s = 1``; the ``s`` is restored.
    """
    return (1.0 - s) * a(t) + s * b(t)


class Transition:
    """Eq. 3 with a time-varying ``s``: a transition between two motions, streamed frame by frame.

    Each :meth:`step` first moves the rescaled time ``theta`` on by one frame
    of ``dt`` seconds, ``d theta / d tau = 2 pi speed / T(s)`` integrated with
    the trapezoid rule between the previous frame's ``s`` and this one's
    (the first frame after :meth:`reset` stays at ``theta = 0``), then returns
    ``Xi(s, theta)`` (Eq. 3).  ``T(s) = T_A^(1-s) T_B^s`` is the blended
    measured period (s).  The phase thus advances with real time, not frames:
    the same ``s(t)`` at any frame rate gives the same motion, to the
    integration error O(dt^2).  ``s`` may leave [0, 1] (extrapolation).  The
    work per step is a handful of array operations on ``(N, C)`` arrays.

    Parameters
    ----------
    a, b : FourierModel
        The two motions (Theta and Pi); ``s = 0`` plays ``a``, ``s = 1`` plays ``b``.
    speed : float
        The *speed* control (section 3.1): rescaled time runs ``speed`` times
        as fast, dividing the period by ``speed``.
    """

    def __init__(self, a: FourierModel, b: FourierModel, speed: float = 1.0):
        a, b = _pair(a, b)
        pa, pb = _phases_for_blend(a, b)
        self.a, self.b = a, b
        self.speed = float(speed)
        self.channels = a.channels or b.channels
        self._mean, self._dmean = a.mean.copy(), b.mean - a.mean
        self._amp, self._damp = a.amp.copy(), b.amp - a.amp
        self._phase, self._dphase = pa, pb - pa
        self._n = np.arange(1.0, a.n_harmonics + 1)[:, None]
        self._log_t, self._dlog_t = float(np.log(a.period_s)), float(np.log(b.period_s) - np.log(a.period_s))
        self.theta = 0.0
        self._rate = None  # 1 / T(s) of the previous frame (None before the first)

    @property
    def mean_change(self) -> np.ndarray:
        """``B_m0 - A_m0``: the change of the constant terms per unit of ``s`` (C,)."""
        return self._dmean

    def reset(self, theta: float = 0.0) -> None:
        """Back to the state before the first frame, rescaled time ``theta`` (radians)."""
        self.theta = float(theta)
        self._rate = None

    def period(self, s: float) -> float:
        """The blended measured period ``T(s) = T_A^(1-s) T_B^s`` (s)."""
        return math.exp(self._log_t + s * self._dlog_t)

    def value(self, s: float, theta: float | None = None, mean: bool = True) -> np.ndarray:
        """Eq. 3 at blend ``s`` and rescaled time ``theta`` (default: the current one); shape (C,).

        ``mean=False`` leaves out the constant terms (the oscillation only).
        """
        th = self.theta if theta is None else theta
        amp = self._amp + s * self._damp
        arg = self._n * th + (self._phase + s * self._dphase)
        out = (amp * np.sin(arg)).sum(axis=0)
        if mean:
            out += self._mean + s * self._dmean
        return out

    def move(self, s: float, dt: float) -> float:
        """Move to the next frame, ``dt`` seconds on, where the blend is ``s``; return the new ``theta``.

        ``theta += pi speed dt (1 / T(s_prev) + 1 / T(s))`` (trapezoid rule), modulo ``2 pi``;
        the first frame after :meth:`reset` keeps ``theta``.
        """
        rate = math.exp(-(self._log_t + s * self._dlog_t))
        if self._rate is not None:
            self.theta = (self.theta + math.pi * self.speed * dt * (self._rate + rate)) % TWO_PI
        self._rate = rate
        return self.theta

    def step(self, s: float, dt: float, mean: bool = True) -> np.ndarray:
        """The next frame (``dt`` s after the previous one) at blend ``s``: :meth:`move`, then Eq. 3."""
        self.move(s, dt)
        return self.value(s, mean=mean)

    def run(self, s, dt: float, mean: bool = True) -> np.ndarray:
        """A whole transition: ``s`` per frame (array), frames ``dt`` apart; shape (F, C)."""
        s = np.asarray(s, dtype=np.float64)
        return np.array([self.step(float(v), dt, mean) for v in s]).reshape(len(s), -1)


# ----------------------------------------------------------------------------- Eqs. 6-8
@dataclass(frozen=True, eq=False)
class Characteristic:
    """Fourier characteristics of two motions (Unuma et al. 1995, Eqs. 7-1, 7-2) and Eq. 8's function.

    Attributes
    ----------
    mean : ndarray (C,)
        ``A_m^1 - A_m^2`` (the constant terms; reconstructed, see the module docstring).
    amp : ndarray (N, C)
        ``A_mn^12 = A_mn^1 - A_mn^2`` (Eq. 7-1).
    phase : ndarray (N, C)
        ``phi_mn^12 = phi_mn^1 - phi_mn^2`` (Eq. 7-2), taken the short way round.
    period_ratio : float
        ``T^1 / T^2``: how much slower motion 1 is (our addition; 1 leaves periods alone).
    channels : tuple of str
    """

    mean: np.ndarray
    amp: np.ndarray
    phase: np.ndarray
    period_ratio: float = 1.0
    channels: tuple = ()

    def __call__(self, t) -> np.ndarray:
        """The Fourier characteristic function Psi_m(t) (Eq. 8) at rescaled times ``t`` (radians)."""
        t = np.asarray(t, dtype=np.float64)
        n = np.arange(1, self.amp.shape[0] + 1)
        return self.mean + np.sum(self.amp * np.sin(t[..., None, None] * n[:, None] + self.phase), axis=-2)


def characteristic(m1: FourierModel, m2: FourierModel) -> Characteristic:
    """The Fourier characteristics of motion 1 relative to motion 2 (Eqs. 6-1, 6-2, 7-1, 7-2).

    E.g. "briskness" = characteristic(brisk walk, normal walk).  Amplitude and
    phase differences per harmonic, as Eq. 7 writes them (phase differences
    wrapped to ``(-pi, pi]``), so ``superpose(m2, characteristic(m1, m2), 1)``
    reproduces ``m1``.
    """
    m1, m2 = _pair(m1, m2)
    return Characteristic(m1.mean - m2.mean, m1.amp - m2.amp, wrap(m1.phase - m2.phase),
                          m1.period_s / m2.period_s, m1.channels or m2.channels)


def superpose(base: FourierModel, char: Characteristic, weight: float = 1.0) -> FourierModel:
    """Superpose a Fourier characteristic onto a motion (section 3.2), with weight ``w``.

    ``A_mn -> A_mn + w A_mn^12``, ``phi_mn -> phi_mn + w phi_mn^12``, ``A_m0
    -> A_m0 + w A_m0^12``, period ``T -> T (T^1/T^2)^w``.  The paper states
    the superposition in words ("Psi_m and Pi_m give a rich variation ...
    through linear interpolation, extrapolation, and transition", Fig. 7:
    a "brisk" run from a run and the briskness of walking, with Eq. 3 for the
    transition); this is that reading: Eq. 3 is the special case
    ``interpolate(a, b, s) == superpose(a, characteristic(b, a), s)`` (for
    harmonics present in both motions; see :func:`interpolate` for absent ones).
    """
    n = max(base.n_harmonics, char.amp.shape[0])
    base = base.padded(n)
    amp = np.zeros((n, base.n_channels))
    ph = np.zeros_like(amp)
    amp[:char.amp.shape[0]] = char.amp
    ph[:char.phase.shape[0]] = char.phase
    w = float(weight)
    return FourierModel(base.mean + w * char.mean, base.amp + w * amp, base.phase + w * ph,
                        base.period_s * char.period_ratio ** w, base.t0, base.channels or char.channels)


# ----------------------------------------------------------------------------- section 3.3
def shiver(model: FourierModel, rng: np.random.Generator, amplitude: float, n_terms: int = 8,
           first: int = MAX_HARMONICS + 1, falloff: float = 1.0) -> FourierModel:
    """Add randomised higher-frequency terms: a shivering version of a motion (section 3.3, Fig. 10(b)).

    The paper only says "adding randomized higher frequency terms"; here
    harmonics ``first .. first + n_terms - 1`` (default 8 to 15, above the
    <= 7 harmonics of a fitted motion) get, per channel, amplitude
    ``amplitude * u * (first / n) ** falloff`` with ``u ~ U(0, 1)`` and a
    phase ``~ U(-pi, pi)``, all drawn from ``rng`` (so a seeded generator
    gives the same shiver).  Harmonics between the model's last and ``first``
    are zero.

    Parameters
    ----------
    model : FourierModel
    rng : numpy.random.Generator
    amplitude : float
        Largest amplitude of a shiver term (channel units, degrees).
    n_terms : int
        Number of random harmonics.
    first : int
        Lowest random harmonic (must exceed the model's harmonics).
    falloff : float
        Amplitudes fall as ``n ** -falloff`` (1: a 1/f spectrum).
    """
    if first <= model.n_harmonics:
        raise ValueError(f"first shiver harmonic {first} must exceed the model's {model.n_harmonics}")
    if n_terms < 1:
        raise ValueError(f"n_terms must be >= 1 (got {n_terms})")
    c = model.n_channels
    n = np.arange(first, first + n_terms)[:, None]
    amp = float(amplitude) * rng.uniform(0.0, 1.0, size=(n_terms, c)) * (first / n) ** falloff
    ph = rng.uniform(-np.pi, np.pi, size=(n_terms, c))
    base = model.padded(first - 1)
    return replace(base, amp=np.vstack([base.amp, amp]), phase=np.vstack([base.phase, ph]))
