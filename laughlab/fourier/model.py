"""Fourier functional models of periodic motion (Unuma, Anjyo and Takeuchi 1995).

A periodic joint-angle series is approximated by a short Fourier series in
*rescaled* time (the paper's "rescaled Fourier functional model")::

    Theta_m(t) = A_m0 + sum_{n=1..N} A_mn sin(n t + phi_mn)          (Eq. 1)

where ``t`` is the phase in radians: real time ``tau`` (s) maps to
``t = 2 pi (tau - t0) / T``, so every motion has period ``2 pi`` whatever its
measured period ``T`` (s).  ``m`` indexes channels (one joint's Z, X or Y Euler
angle, degrees, in this project's convention), ``N <= 7`` harmonics (the paper:
"n is usually 3, and 7 at most").  Because two motions fitted this way share
the same rescaled time, they can be blended coefficient by coefficient:

* :func:`fit` -- least-squares fit of Eq. 1 (or Eq. 2 for a second motion),
  with the period estimated from the data when it is not given;
* :func:`~laughlab.fourier.blend.interpolate` / :class:`~laughlab.fourier.blend.Transition` -- Eq. 3, interpolation (``0 <= s
  <= 1``), extrapolation (any other ``s``) and transitions (``s`` varying with
  time) in the amplitude-phase domain;
* :func:`~laughlab.fourier.blend.characteristic` / :func:`~laughlab.fourier.blend.superpose` -- the Fourier characteristics of
  two motions (Eqs. 6-8) and their superposition onto a third (section 3.2);
* :meth:`FourierModel.with_step` and the ``speed`` arguments -- the
  step-constraint parameters *step* (amplitude) and *speed* (time warp) of
  section 3.1;
* :func:`~laughlab.fourier.blend.shiver` -- randomised higher-frequency terms (section 3.3, Fig. 10b).

Where the paper's extracted text is garbled it is reconstructed, and each place
says so: Eqs. 1 and 2 read ``A_m 0`` / ``B_m 0`` (the constant terms
``A_m0``, ``B_m0``); the time-domain alternative after Eq. 3 reads
``(1-s) Theta_m(t) + Pi_m(t)`` (the ``s`` of the second term is missing, see
:func:`blend_time_domain`); Eq. 8's constant term reads ``A_m^12`` (the
difference of the constant terms ``A_m^1 - A_m^2`` of Eq. 6); the closing
remark of 3.2 says "``Phi_m^2`` in (8)" where Eq. (6-2) is meant.

Conventions chosen here (the paper does not say): amplitudes from a fit are
>= 0 with phases in ``(-pi, pi]``; phase differences are taken the short way
round (wrapped to ``(-pi, pi]``) before they are interpolated; a harmonic whose
amplitude is (near) zero in one motion takes its phase from the other motion;
the measured period of a blend is interpolated geometrically, ``T(s) =
T_A^(1-s) T_B^s``, which stays positive for every ``s``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

__all__ = [
    "MAX_HARMONICS",
    "FourierModel",
    "fit",
    "estimate_period",
    "max_harmonics_for",
    "align",
    "band_limit",
    "active_segment",
    "joint_channels",
    "wrap",
]

MAX_HARMONICS = 7
"""At most 7 harmonics (Unuma et al. 1995, end of 2.3: "n is usually 3, and 7 at most")."""

TWO_PI = 2.0 * np.pi


def wrap(angle):
    """Angles (radians) wrapped to ``(-pi, pi]``."""
    a = np.asarray(angle, dtype=np.float64)
    w = np.mod(a + np.pi, TWO_PI) - np.pi
    return np.where(w == -np.pi, np.pi, w)


@dataclass(frozen=True, eq=False)
class FourierModel:
    """A rescaled Fourier functional model of C channels (Unuma et al. 1995, Eqs. 1 and 2).

    ``value(t)[m] = mean[m] + sum_n amp[n-1, m] sin(n t + phase[n-1, m])`` with
    ``t`` the rescaled time in radians (period ``2 pi``).

    Attributes
    ----------
    mean : ndarray, shape (C,)
        Constant terms ``A_m0`` (channel units, degrees for joint angles).
    amp : ndarray, shape (N, C)
        Amplitudes ``A_mn`` of harmonics ``n = 1..N`` (channel units).
    phase : ndarray, shape (N, C)
        Phases ``phi_mn`` (radians).
    period_s : float
        The measured period ``T`` (s): real time ``tau`` is rescaled time
        ``2 pi (tau - t0) / T``.
    t0 : float
        Real time (s) at which the rescaled time is 0.
    channels : tuple of str
        Channel labels (e.g. ``spine2_Xrotation``); may be empty.
    """

    mean: np.ndarray
    amp: np.ndarray
    phase: np.ndarray
    period_s: float = 1.0
    t0: float = 0.0
    channels: tuple = field(default=())

    def __post_init__(self) -> None:
        mean = np.atleast_1d(np.asarray(self.mean, dtype=np.float64))
        amp = np.asarray(self.amp, dtype=np.float64).reshape(-1, mean.size)
        phase = np.asarray(self.phase, dtype=np.float64).reshape(amp.shape)
        if not (np.isfinite(self.period_s) and self.period_s > 0):
            raise ValueError(f"period_s must be > 0 (got {self.period_s})")
        if self.channels and len(self.channels) != mean.size:
            raise ValueError(f"{len(self.channels)} channel names for {mean.size} channels")
        for name, a in (("mean", mean), ("amp", amp), ("phase", phase)):
            a.flags.writeable = False
            object.__setattr__(self, name, a)
        object.__setattr__(self, "channels", tuple(self.channels))
        object.__setattr__(self, "period_s", float(self.period_s))

    @property
    def n_harmonics(self) -> int:
        """Number of harmonics ``N``."""
        return self.amp.shape[0]

    @property
    def n_channels(self) -> int:
        """Number of channels ``C``."""
        return self.mean.size

    def __call__(self, t) -> np.ndarray:
        """Eq. 1 at rescaled times ``t`` (radians): shape ``(len(t), C)``, or ``(C,)`` for a scalar."""
        t = np.asarray(t, dtype=np.float64)
        n = np.arange(1, self.n_harmonics + 1)
        arg = t[..., None, None] * n[:, None] + self.phase  # (..., N, C)
        return self.mean + np.sum(self.amp * np.sin(arg), axis=-2)

    def rescaled(self, time_s, speed: float = 1.0) -> np.ndarray:
        """Rescaled time ``2 pi speed (tau - t0) / T`` of real times ``tau`` (s).

        ``speed`` is the paper's *speed* (3.1, a time warp): 2 halves the period.
        """
        return TWO_PI * speed * (np.asarray(time_s, dtype=np.float64) - self.t0) / self.period_s

    def at_time(self, time_s, speed: float = 1.0) -> np.ndarray:
        """The model at real times ``tau`` (s), played at ``speed`` (section 3.1)."""
        return self(self.rescaled(time_s, speed))

    def with_step(self, step: float) -> "FourierModel":
        """The *step* control (section 3.1): every ``A_mn`` (n >= 1) replaced by ``step * A_mn``."""
        return replace(self, amp=self.amp * float(step))

    def shifted(self, dt_rad: float) -> "FourierModel":
        """The origin of rescaled time moved by ``dt_rad``: ``phi_mn -> phi_mn + n dt``.

        The new model ``m'`` has ``m'(t) = m(t + dt)``; ``t0`` moves with it, so
        the motion in real time (:meth:`at_time`) is unchanged.
        """
        n = np.arange(1, self.n_harmonics + 1)[:, None]
        t0 = self.t0 + dt_rad * self.period_s / TWO_PI
        return replace(self, phase=wrap(self.phase + n * dt_rad), t0=t0)

    def padded(self, n_harmonics: int) -> "FourierModel":
        """Zero-amplitude harmonics appended up to ``n_harmonics``."""
        extra = n_harmonics - self.n_harmonics
        if extra <= 0:
            return self
        z = np.zeros((extra, self.n_channels))
        return replace(self, amp=np.vstack([self.amp, z]), phase=np.vstack([self.phase, z]))

    def take(self, channels) -> "FourierModel":
        """The model restricted to some channels (indices or labels)."""
        idx = [self.channels.index(c) if isinstance(c, str) else int(c) for c in channels]
        names = tuple(self.channels[i] for i in idx) if self.channels else ()
        return replace(self, mean=self.mean[idx], amp=self.amp[:, idx], phase=self.phase[:, idx], channels=names)

    def sin_cos(self) -> tuple[np.ndarray, np.ndarray]:
        """Coefficients ``a_mn, b_mn`` of ``a sin(n t) + b cos(n t)`` (``a = A cos phi, b = A sin phi``)."""
        return self.amp * np.cos(self.phase), self.amp * np.sin(self.phase)


# ----------------------------------------------------------------------------- fitting (Eqs. 1, 2)
def _design(t: np.ndarray, n_harmonics: int) -> np.ndarray:
    """Columns ``1, sin(t), cos(t), sin(2t), cos(2t), ...`` at rescaled times ``t``."""
    cols = [np.ones_like(t)]
    for n in range(1, n_harmonics + 1):
        cols += [np.sin(n * t), np.cos(n * t)]
    return np.column_stack(cols)


def _solve(y: np.ndarray, tau: np.ndarray, period: float, n_harmonics: int):
    """Least-squares coefficients (2N+1, C) and the residual sum of squares at one period."""
    basis = _design(TWO_PI * tau / period, n_harmonics)
    coef, _, rank, _ = np.linalg.lstsq(basis, y, rcond=None)
    r = y - basis @ coef
    return coef, float(np.sum(r * r)), rank


def max_harmonics_for(period_s: float, dt: float) -> int:
    """Largest harmonic count below the Nyquist rate of samples ``dt`` apart, capped at 7.

    Harmonic ``n`` of a period ``T`` has frequency ``n / T``; it must stay
    below ``1 / (2 dt)``.  Returns at least 1.
    """
    n = int(np.floor(period_s / (2.0 * dt) - 1e-9))
    return int(min(MAX_HARMONICS, max(1, n)))


def estimate_period(samples, dt: float, period_range: tuple[float, float], n_harmonics: int = 3,
                    tolerance: float = 0.05) -> float:
    """Estimate the common period (s) of the channels of a periodic series.

    The paper notes the period "is rather hard to estimate from the measured
    data" and does not say how it did it; this is our procedure.  For periods
    on a geometric grid over ``period_range`` (steps small enough that the
    phase of harmonic N drifts by at most ``pi / 4`` over the data) it fits
    Eq. 1 by least squares and keeps ``1 - R^2`` (the unexplained share of
    the variance).  Among the grid's local minima it takes the *shortest*
    period whose ``1 - R^2`` is within ``tolerance`` of the best (so that 2T,
    3T, which fit as well, lose to T), then refines it by bounded scalar
    minimisation and Gauss-Newton steps on the angular frequency (variable
    projection, Kaufman's Jacobian), which converge to machine precision on
    noise-free data.

    Parameters
    ----------
    samples : ndarray, shape (F,) or (F, C)
        Samples ``dt`` apart.
    dt : float
        Sample interval (s).
    period_range : (float, float)
        Shortest and longest period to consider (s).
    n_harmonics : int
        Harmonics of the model used to judge a period.
    tolerance : float
        Slack in ``1 - R^2`` when preferring shorter periods.

    Returns
    -------
    float
        The period (s).
    """
    from scipy.optimize import minimize_scalar

    y = np.asarray(samples, dtype=np.float64)
    y = y.reshape(len(y), -1)
    f = len(y)
    lo, hi = float(period_range[0]), float(period_range[1])
    if not (0 < lo < hi):
        raise ValueError(f"period_range must satisfy 0 < lo < hi (got {period_range})")
    if f < 2 * n_harmonics + 2:
        raise ValueError(f"{f} samples are too few to fit {n_harmonics} harmonics")
    tau = np.arange(f) * dt
    yc = y - y.mean(axis=0)
    total = float(np.sum(yc * yc))
    if total <= 0.0:
        raise ValueError("the series is constant: it has no period")
    duration = f * dt
    df = 1.0 / (8.0 * n_harmonics * duration)  # harmonic N drifts by pi/4 over the data
    grid = 1.0 / np.linspace(1.0 / lo, 1.0 / hi, int(np.ceil((1.0 / lo - 1.0 / hi) / df)) + 2)
    cost = np.array([_solve(y, tau, p, n_harmonics)[1] / total for p in grid])
    interior = np.r_[True, cost[1:] <= cost[:-1]] & np.r_[cost[:-1] <= cost[1:], True]
    minima = np.flatnonzero(interior)
    best = cost[minima].min()
    k = int(minima[np.flatnonzero(cost[minima] <= best + tolerance)[0]])
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    period = float(grid[k])
    if b > a:
        res = minimize_scalar(lambda p: _solve(y, tau, p, n_harmonics)[1], bounds=(a, b), method="bounded",
                              options={"xatol": 1e-12 * period})
        if res.fun <= _solve(y, tau, period, n_harmonics)[1]:
            period = float(res.x)
    refined = _refine_period(y, tau, period, n_harmonics)
    return refined if lo <= refined <= hi else period


def _refine_period(y: np.ndarray, tau: np.ndarray, period: float, n_harmonics: int, iters: int = 30) -> float:
    """Gauss-Newton on the angular frequency with the coefficients projected out (Kaufman 1975)."""
    w = TWO_PI / period
    n = np.arange(1, n_harmonics + 1)
    coef, cost, _ = _solve(y, tau, TWO_PI / w, n_harmonics)
    for _ in range(iters):
        basis = _design(w * tau, n_harmonics)
        a, b = coef[1::2], coef[2::2]  # (N, C) sin and cos coefficients
        arg = w * tau[:, None] * n  # (F, N)
        # d/dw of sum_n a sin(n w tau) + b cos(n w tau)
        deriv = (tau[:, None] * n * np.cos(arg)) @ a - (tau[:, None] * n * np.sin(arg)) @ b  # (F, C)
        q, _ = np.linalg.qr(basis)
        jac = deriv - q @ (q.T @ deriv)
        r = y - basis @ coef
        den = float(np.sum(jac * jac))
        if den <= 0.0:
            break
        step = float(np.sum(jac * r)) / den
        w_new = w + step
        coef_new, cost_new, _ = _solve(y, tau, TWO_PI / w_new, n_harmonics)
        if not cost_new <= cost:  # no progress: keep what we have
            break
        w, coef, cost = w_new, coef_new, cost_new
        if abs(step) <= 1e-15 * w:
            break
    return TWO_PI / w


def fit(samples, dt: float, period_s: float | None = None, n_harmonics: int = 3,
        period_range: tuple[float, float] | None = None, channels=(), t0: float = 0.0) -> FourierModel:
    """Fit the rescaled Fourier functional model (Eq. 1, or Eq. 2 for another motion) by least squares.

    The samples ``y_k`` at real times ``tau_k = t0 + k dt`` are rescaled to
    ``t_k = 2 pi k dt / T`` and the coefficients of ``A_0 + sum_n a_n sin(n t)
    + b_n cos(n t)`` solved with ``numpy.linalg.lstsq`` (all channels at once;
    they share the period, as the paper's joints do), then written as
    amplitude and phase: ``A_n = hypot(a_n, b_n) >= 0``, ``phi_n = atan2(b_n,
    a_n)``.  The paper estimates the coefficients from "sample values in a
    larger interval" than one period; any number of periods works here.

    Parameters
    ----------
    samples : ndarray, shape (F,) or (F, C)
        Joint-angle samples (degrees) ``dt`` apart.
    dt : float
        Sample interval (s).
    period_s : float, optional
        The period ``T`` (s); estimated with :func:`estimate_period` when None.
    n_harmonics : int
        ``N``, 1 to 7 (:data:`MAX_HARMONICS`).
    period_range : (float, float), optional
        Search range of the period (s) when it is estimated; default from
        ``4 dt`` to the data's duration.
    channels : sequence of str
        Channel labels.
    t0 : float
        Real time of the first sample (s); rescaled time 0 is there.

    Returns
    -------
    FourierModel

    Raises
    ------
    ValueError
        Bad harmonic count, too few samples, or a rank-deficient fit (too many
        harmonics for the samples available: see :func:`max_harmonics_for`).
    """
    y = np.asarray(samples, dtype=np.float64)
    y = y.reshape(len(y), -1)
    if not 1 <= int(n_harmonics) <= MAX_HARMONICS:
        raise ValueError(f"n_harmonics must be 1 to {MAX_HARMONICS} (got {n_harmonics})")
    n_harmonics = int(n_harmonics)
    if not (dt > 0 and np.isfinite(dt)):
        raise ValueError(f"dt must be > 0 (got {dt})")
    if not np.all(np.isfinite(y)):
        raise ValueError("samples contain non-finite values")
    if len(y) < 2 * n_harmonics + 1:
        raise ValueError(f"{len(y)} samples are too few to fit {n_harmonics} harmonics")
    if period_s is None:
        rng = period_range or (4.0 * dt, len(y) * dt)
        period_s = estimate_period(y, dt, rng, n_harmonics)
    tau = np.arange(len(y)) * dt
    coef, _, rank = _solve(y, tau, float(period_s), n_harmonics)
    if rank < 2 * n_harmonics + 1:
        raise ValueError(f"{n_harmonics} harmonics cannot be fitted from these samples (rank {rank}); "
                         f"use at most {max_harmonics_for(float(period_s), dt)}")
    a, b = coef[1::2], coef[2::2]
    model = FourierModel(coef[0], np.hypot(a, b), np.arctan2(b, a), float(period_s), float(t0),
                         tuple(channels) if channels else ())
    return model


# ----------------------------------------------------------------------------- preparing data
def align(model: FourierModel, channel=None) -> FourierModel:
    """Synchronise a motion: shift rescaled time so a reference channel's fundamental has phase 0.

    The paper notes the rescaled models synchronise two data sets "automatically"
    (2.3); that holds when both series start at the same event of the cycle.
    Data cut at arbitrary moments (clip segments) need a common origin: after
    this, the reference channel goes ``A_1 sin(t) + ...`` (rising through its
    mean at ``t = 0``).  ``channel`` is an index or label; default the channel
    with the largest fundamental.  A channel without a fundamental (amplitude
    0) falls back to the default.
    """
    if channel is None or (isinstance(channel, str) and channel not in model.channels):
        k = int(np.argmax(model.amp[0]))
    else:
        k = model.channels.index(channel) if isinstance(channel, str) else int(channel)
        if model.amp[0, k] <= 1e-9 * max(float(model.amp[0].max()), 1e-300):
            k = int(np.argmax(model.amp[0]))
    return model.shifted(-float(model.phase[0, k]))


def band_limit(samples, dt: float, lo_hz: float | None = None, hi_hz: float | None = None,
               order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth filter along axis 0: keep ``lo_hz .. hi_hz`` (either may be None).

    Used to split a clip into its slow sway (low-pass) and its fast laughter
    shake (band-pass) before each part is fitted with its own period.
    """
    from scipy.signal import butter, sosfiltfilt

    y = np.asarray(samples, dtype=np.float64)
    nyq = 0.5 / dt
    lo = lo_hz if lo_hz and lo_hz > 0 else None
    hi = hi_hz if hi_hz and hi_hz < nyq else None
    if lo is None and hi is None:
        return y.copy()
    if lo is not None and hi is not None:
        sos = butter(order, [lo / nyq, hi / nyq], btype="bandpass", output="sos")
    elif lo is not None:
        sos = butter(order, lo / nyq, btype="highpass", output="sos")
    else:
        sos = butter(order, hi / nyq, btype="lowpass", output="sos")
    padlen = min(len(y) - 1, 3 * (2 * len(sos) + 1))
    return sosfiltfilt(sos, y, axis=0, padlen=padlen)


def active_segment(samples, dt: float, window_s: float, threshold: float = 0.5) -> tuple[int, int]:
    """The longest run of frames where the signal's RMS envelope exceeds ``threshold`` x its maximum.

    The envelope is the RMS over all channels in a centred window of
    ``window_s`` (s).  Returns ``(start, stop)`` frame indices (stop exclusive).
    """
    y = np.asarray(samples, dtype=np.float64).reshape(len(samples), -1)
    power = np.sum(y * y, axis=1)
    w = max(1, int(round(window_s / dt)))
    env = np.sqrt(np.convolve(power, np.ones(w) / w, mode="same"))
    on = env > threshold * env.max() if env.max() > 0 else np.ones(len(env), bool)
    best, start = (0, len(env)), None
    best_len = -1
    for i, v in enumerate(np.r_[on, False]):
        if v and start is None:
            start = i
        elif not v and start is not None:
            if i - start > best_len:
                best, best_len = (start, i), i - start
            start = None
    return best


def joint_channels(skeleton, poses: np.ndarray, joints) -> tuple[np.ndarray, tuple[str, ...]]:
    """The Euler angle series of some joints: ``(F, 3 len(joints))`` degrees and their labels.

    Columns per joint in BVH order ``Z, X, Y``; labels ``<joint>_Zrotation`` etc.
    The angles are unwrapped in time (no 360-degree jumps).
    """
    cols, names = [], []
    for j in joints:
        sl = skeleton.angle_slice(j)
        cols.append(np.asarray(poses)[:, sl])
        names += [f"{j}_{a}rotation" for a in "ZXY"]
    out = np.unwrap(np.concatenate(cols, axis=1), period=360.0, axis=0)
    return out, tuple(names)
