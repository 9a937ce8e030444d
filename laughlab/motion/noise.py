"""Seeded 1-D gradient (Perlin) noise, so that procedural motion never freezes.

Ding et al. (2014, 4.3) add Perlin noise [Perlin 2002, "Improving noise"] to
the three rotation axes of the torso joints driven by their PD controllers "to
avoid any freezing effect".  This module implements the 1-D case of Perlin's
gradient noise:

* every integer lattice point ``i`` carries a pseudo-random gradient
  ``g_i`` in [-1, 1];
* between ``i`` and ``i + 1``, with ``u = x - i`` in [0, 1), the noise blends
  the two linear ramps ``g_i u`` and ``g_{i+1} (u - 1)`` with Perlin's
  improved fade curve ``s(u) = 6u^5 - 15u^4 + 10u^3``::

      n(x) = (1 - s(u)) g_i u + s(u) g_{i+1} (u - 1)            (N1)

Properties (tested): ``n(i) = 0`` at every lattice point; ``n`` is C2
continuous (``s`` has zero first and second derivatives at 0 and 1);
``|n(x)| <= 0.5`` (the bound is reached at ``u = 1/2`` when ``g_i = -g_{i+1} =
+-1``); the same seed and stream give the same values.

Gradients.  Perlin's reference code takes gradients from a shuffled table of
256 entries (so the noise repeats every 256 units); here each gradient is a
hash of ``(seed, stream, i)`` (SplitMix64, Steele et al. 2014), which never
repeats and needs no table: ``g_i = 2 h / 2^64 - 1`` with ``h`` the 64-bit hash.
Different ``stream`` numbers give independent noises from one seed (one per
joint axis).

:class:`NoiseSignal` turns the noise into a motion signal of time: a sum of
``octaves`` octaves (fractal sum, each octave at twice the frequency and
``gain`` times the amplitude of the previous one), scaled so that its peak
value is at most ``amplitude``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["fade", "Perlin1D", "NoiseSignal", "splitmix64"]

_MASK = (1 << 64) - 1
_GOLDEN = 0x9E3779B97F4A7C15


def splitmix64(z: int) -> int:
    """The SplitMix64 finaliser of a 64-bit integer (Steele, Lea & Flood 2014), as a Python int."""
    z = (z + _GOLDEN) & _MASK
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK
    return z ^ (z >> 31)


def _splitmix64_array(z: np.ndarray) -> np.ndarray:
    """:func:`splitmix64` over a uint64 array (wrapping arithmetic)."""
    z = z + np.uint64(_GOLDEN)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def fade(u):
    """Perlin's improved fade curve ``s(u) = 6u^5 - 15u^4 + 10u^3`` (Perlin 2002)."""
    return u * u * u * (u * (u * 6.0 - 15.0) + 10.0)


class Perlin1D:
    """1-D gradient noise ``n(x)``, Eq. (N1) of the module docstring.

    Parameters
    ----------
    seed : int
        Seed (e.g. the run's ``ctx.seed``).
    stream : int
        Independent noise number for the same seed (e.g. one per joint axis).

    Examples
    --------
    >>> n = Perlin1D(seed=0)
    >>> n(3.0)
    0.0
    >>> abs(n(2.5)) <= 0.5
    True
    """

    __slots__ = ("seed", "stream", "_key", "_cell", "_g0", "_g1")

    def __init__(self, seed: int = 0, stream: int = 0):
        self.seed, self.stream = int(seed), int(stream)
        self._key = splitmix64((splitmix64(self.seed & _MASK) + (self.stream & _MASK) * _GOLDEN) & _MASK)
        self._cell = None
        self._g0 = self._g1 = 0.0

    def gradient(self, i: int) -> float:
        """The gradient ``g_i`` in [-1, 1] of lattice point ``i``."""
        h = splitmix64((self._key ^ (int(i) & _MASK)) & _MASK)
        return h * (2.0 / 2.0 ** 64) - 1.0

    def gradients(self, i: np.ndarray) -> np.ndarray:
        """Gradients of an integer array of lattice points (vectorised :meth:`gradient`)."""
        z = np.asarray(i, dtype=np.int64).astype(np.uint64) ^ np.uint64(self._key)
        return _splitmix64_array(z).astype(np.float64) * (2.0 / 2.0 ** 64) - 1.0

    def __call__(self, x):
        """Noise at ``x`` (float or array), Eq. (N1); a float gives a float."""
        if np.ndim(x) == 0:
            return self.value(float(x))
        x = np.asarray(x, dtype=np.float64)
        i = np.floor(x)
        u = x - i
        ii = i.astype(np.int64)
        g0, g1 = self.gradients(ii), self.gradients(ii + 1)
        s = fade(u)
        return (1.0 - s) * g0 * u + s * g1 * (u - 1.0)

    def value(self, x: float) -> float:
        """Scalar noise at ``x``; the last cell's two gradients are cached (motion is sampled in order)."""
        i = int(np.floor(x))
        if i != self._cell:
            self._cell, self._g0, self._g1 = i, self.gradient(i), self.gradient(i + 1)
        u = x - i
        s = u * u * u * (u * (u * 6.0 - 15.0) + 10.0)
        return (1.0 - s) * self._g0 * u + s * self._g1 * (u - 1.0)


@dataclass
class NoiseSignal:
    """A smooth random motion signal of time built from :class:`Perlin1D`.

    ``v(t) = amplitude * 2 * sum_k gain^k n_k(f 2^k t) / sum_k gain^k`` over
    ``k = 0 .. octaves - 1``, each octave ``n_k`` an independent stream, so
    ``|v(t)| <= amplitude`` and ``v`` changes on the time scale ``1 / f``.

    Attributes
    ----------
    seed, stream : int
        Seed and stream of the first octave (octave ``k`` uses stream ``stream * 16 + k``).
    frequency_hz : float
        Lattice points per second of the first octave.
    amplitude : float
        Peak value (the signal's units, e.g. degrees).
    octaves : int
    gain : float
        Amplitude ratio of successive octaves.
    """

    seed: int = 0
    stream: int = 0
    frequency_hz: float = 0.5
    amplitude: float = 1.0
    octaves: int = 2
    gain: float = 0.5

    def __post_init__(self) -> None:
        if self.octaves < 1:
            raise ValueError(f"octaves must be >= 1 (got {self.octaves})")
        self._noise = [Perlin1D(self.seed, self.stream * 16 + k) for k in range(self.octaves)]
        weights = [self.gain ** k for k in range(self.octaves)]
        norm = 2.0 * self.amplitude / sum(weights)
        self._terms = [(n, self.frequency_hz * 2.0 ** k, w * norm) for k, (n, w) in enumerate(zip(self._noise, weights))]

    def __call__(self, t: float) -> float:
        """The signal at time ``t`` (s)."""
        return sum(w * n.value(f * t) for n, f, w in self._terms)
