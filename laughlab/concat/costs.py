"""Synthesis by segment concatenation: costs, greedy and optimal selection (Ding et al. 2014, 4.2).

Given a pseudo-phoneme sequence ``(p_1, ..., p_K)`` with durations ``d(p_u)``,
choose one segment ``s_u`` of the class of each ``p_u`` (from a
:class:`~laughlab.concat.segments.SegmentDB`) minimising Eqs. 4-6::

    C = gamma * sum_{u=1..K} C_dur(d(s_u), d(p_u))
        + (1 - gamma) * sum_{u=2..K} C_cont(s_{u-1}, s_u)

with (Eq. 7) ``C_dur(d, d') = exp(|d - d'|) - 1`` and (Eq. 8)
``C_cont(s, s') = ||last(s) - first(s')||^2``.

Units.  Durations are in seconds.  The pose features of the segments are
key-joint positions in cm; :func:`c_cont` measures them in metres
(``CONT_UNIT_CM = 100``), so C_cont is a squared distance in m^2 summed over the
key joints.  Then a 0.3 s duration mismatch (C_dur 0.35) weighs about three
times a 20 cm jump of three joints (0.12 m^2): the same order, which keeps both terms in play at
the paper's kind of gamma; in cm^2 the continuity term would swamp the duration
term for any gamma < 0.999.  The paper gives no units.

Selected segments are linearly stretched to the target duration: playback speed
``d(s) / d(p)`` in clip seconds per second (:func:`stretch`).  :func:`greedy` is
the paper's real-time variant (segment by segment, local cost
``gamma * C_dur(d(s), d(p)) + (1 - gamma) * C_cont(s', s)``); :func:`optimal` is
the exact minimum of Eq. 4 by dynamic programming (Viterbi over the candidates
of each class).  Ties go to the lowest segment index.
"""
from __future__ import annotations

import itertools
import math
from typing import NamedTuple, Sequence

import numpy as np

from laughlab.concat.segments import Segment, SegmentDB

__all__ = [
    "CONT_UNIT_CM",
    "Concatenation",
    "c_dur",
    "c_cont",
    "cont_matrix",
    "local_costs",
    "choose",
    "total_cost",
    "greedy",
    "optimal",
    "exhaustive",
    "stretch",
    "label_runs",
    "to_sequence",
    "cost_gap",
]

CONT_UNIT_CM = 100.0
"""Length unit of the continuity cost, in cm: C_cont is in m^2."""


class Concatenation(NamedTuple):
    """A chosen segment sequence.

    Attributes
    ----------
    segments : tuple of Segment
        One segment per unit, in order.
    cost : float
        Its total cost, Eq. 4 (plus ``(1 - gamma) C_cont(prev, s_1)`` when a
        previous segment was given).
    indices : tuple of int
        The segments' indices in the database.
    targets : tuple of float
        The target durations ``d(p_u)`` (s).
    """

    segments: tuple
    cost: float
    indices: tuple
    targets: tuple

    @property
    def speeds(self) -> tuple[float, ...]:
        """Playback speed of each unit, ``d(s_u) / d(p_u)`` (unbounded)."""
        return tuple(stretch(s.duration_s, d) for s, d in zip(self.segments, self.targets))


def c_dur(d, d_target):
    """Duration cost, Eq. 7: ``C_dur(d, d') = exp(|d - d'|) - 1``.

    Parameters
    ----------
    d, d_target : float or ndarray
        Segment and target durations (s); broadcast together.

    Returns
    -------
    float or ndarray
    """
    out = np.expm1(np.abs(np.asarray(d, dtype=np.float64) - d_target))
    return float(out) if out.ndim == 0 else out


def c_cont(last, first):
    """Continuity cost, Eq. 8: squared distance between ``last(s)`` and ``first(s')``.

    Parameters
    ----------
    last, first : ndarray (..., D)
        Pose features in cm (key-joint positions); broadcast together.

    Returns
    -------
    float or ndarray
        ``sum(((last - first) / 100)^2)`` over the last axis: m^2.
    """
    diff = (np.asarray(last, dtype=np.float64) - np.asarray(first, dtype=np.float64)) / CONT_UNIT_CM
    out = np.einsum("...i,...i->...", diff, diff)
    return float(out) if out.ndim == 0 else out


def cont_matrix(db: SegmentDB, from_idx, to_idx) -> np.ndarray:
    """C_cont between every segment of ``from_idx`` and every one of ``to_idx``, shape (n_from, n_to)."""
    return c_cont(db.last[np.asarray(from_idx)][:, None, :], db.first[np.asarray(to_idx)][None, :, :])


def _check_gamma(gamma: float) -> float:
    gamma = float(gamma)
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f"gamma must be in [0, 1] (got {gamma})")
    return gamma


def _prev_feature(db: SegmentDB, prev) -> np.ndarray | None:
    """The feature the next segment joins: ``prev`` a segment (its index or itself), or a pose feature (an array:
    the idle pose shown before the first segment, :func:`laughlab.concat.segments.pose_features`)."""
    if prev is None:
        return None
    if isinstance(prev, Segment):
        return np.asarray(prev.last, dtype=np.float64)
    if isinstance(prev, np.ndarray):
        return np.asarray(prev, dtype=np.float64)
    return db.last[int(prev)]


def local_costs(db: SegmentDB, candidates, d_target: float, gamma: float, prev=None) -> np.ndarray:
    """The greedy local cost of each candidate: ``gamma C_dur(d(s), d(p)) + (1 - gamma) C_cont(prev, s)``.

    Parameters
    ----------
    db : SegmentDB
    candidates : ndarray of int
        Segment indices.
    d_target : float
        Target duration d(p) (s).
    gamma : float
    prev : int, Segment or ndarray, optional
        The previous segment, or the pose feature shown before it; without it the continuity term is 0.
    """
    cand = np.asarray(candidates)
    cost = gamma * c_dur(db.durations[cand], d_target)
    last = _prev_feature(db, prev)
    if last is not None:
        cost = cost + (1.0 - gamma) * c_cont(last, db.first[cand])
    return cost


def choose(db: SegmentDB, label: str, d_target: float, gamma: float, prev=None) -> int:
    """Index of the segment of class ``label`` with the lowest local cost (lowest index on ties)."""
    cand = db.candidates(label)
    return int(cand[int(np.argmin(local_costs(db, cand, d_target, _check_gamma(gamma), prev)))])


def total_cost(indices: Sequence[int], durations: Sequence[float], db: SegmentDB, gamma: float,
               prev=None) -> float:
    """Eq. 4-6 of a segment sequence against target durations.

    ``gamma * sum_u C_dur(d(s_u), d(p_u)) + (1 - gamma) * sum_{u>=2} C_cont(s_{u-1}, s_u)``,
    plus ``(1 - gamma) * C_cont(prev, s_1)`` when ``prev`` is given.  Summed unit by unit.
    """
    gamma = _check_gamma(gamma)
    total, last = 0.0, _prev_feature(db, prev)
    for i, d in zip(indices, durations):
        total += gamma * c_dur(db.durations[i], d)
        if last is not None:
            total += (1.0 - gamma) * c_cont(last, db.first[i])
        last = db.last[i]
    return float(total)


def _result(indices, sequence, db, gamma, prev) -> Concatenation:
    durations = tuple(float(d) for _, d in sequence)
    idx = tuple(int(i) for i in indices)
    return Concatenation(tuple(db[i] for i in idx), total_cost(idx, durations, db, gamma, prev), idx, durations)


def greedy(sequence: Sequence[tuple[str, float]], db: SegmentDB, gamma: float, prev=None) -> Concatenation:
    """The paper's real-time variant: choose segment by segment by the local cost.

    Parameters
    ----------
    sequence : sequence of (label, duration)
        Pseudo-phonemes and their durations d(p_u) (s).
    db : SegmentDB
    gamma : float
        Weight of the duration cost, in [0, 1].
    prev : int, Segment or ndarray, optional
        The segment played before the sequence, or the pose feature shown (continuity of the first choice).

    Returns
    -------
    Concatenation
        Segments and their total cost (Eq. 4, see :func:`total_cost`).
    """
    gamma = _check_gamma(gamma)
    chosen, last = [], prev
    for label, d in sequence:
        last = choose(db, label, d, gamma, last)
        chosen.append(last)
    return _result(chosen, sequence, db, gamma, prev)


def optimal(sequence: Sequence[tuple[str, float]], db: SegmentDB, gamma: float, prev=None) -> Concatenation:
    """The exact minimum of Eq. 4 by dynamic programming (Viterbi).

    ``A_1(j) = gamma C_dur(d(j), d(p_1)) [+ (1 - gamma) C_cont(prev, j)]``,
    ``A_u(j) = gamma C_dur(d(j), d(p_u)) + min_i [A_{u-1}(i) + (1 - gamma) C_cont(i, j)]``
    over the candidates ``i`` of ``p_{u-1}`` and ``j`` of ``p_u``; the transition
    matrices are computed with numpy.  Cost O(K n^2) for n candidates per class.
    Ties go to the lowest index.

    Parameters and returns as :func:`greedy`.
    """
    gamma = _check_gamma(gamma)
    if not sequence:
        return Concatenation((), 0.0, (), ())
    cands = [db.candidates(label) for label, _ in sequence]
    acc = gamma * c_dur(db.durations[cands[0]], float(sequence[0][1]))
    last = _prev_feature(db, prev)
    if last is not None:
        acc = acc + (1.0 - gamma) * c_cont(last, db.first[cands[0]])
    back = []
    for u in range(1, len(sequence)):
        tot = acc[:, None] + (1.0 - gamma) * cont_matrix(db, cands[u - 1], cands[u])
        arg = np.argmin(tot, axis=0)
        acc = tot[arg, np.arange(len(cands[u]))] + gamma * c_dur(db.durations[cands[u]], float(sequence[u][1]))
        back.append(arg)
    j = int(np.argmin(acc))
    path = [j]
    for arg in reversed(back):
        j = int(arg[j])
        path.append(j)
    path.reverse()
    return _result([c[j] for c, j in zip(cands, path)], sequence, db, gamma, prev)


def exhaustive(sequence: Sequence[tuple[str, float]], db: SegmentDB, gamma: float, prev=None,
               max_combinations: int = 1_000_000) -> Concatenation:
    """Brute-force minimum of Eq. 4 over every combination (a reference for tests).

    Raises ValueError if there are more than ``max_combinations`` combinations.
    """
    gamma = _check_gamma(gamma)
    cands = [db.candidates(label) for label, _ in sequence]
    if math.prod(len(c) for c in cands) > max_combinations:
        raise ValueError(f"more than {max_combinations} combinations")
    durations = [float(d) for _, d in sequence]
    best, best_cost = None, math.inf
    for combo in itertools.product(*cands):
        cost = total_cost(combo, durations, db, gamma, prev)
        if cost < best_cost:
            best, best_cost = combo, cost
    return _result(best or (), sequence, db, gamma, prev)


def stretch(segment_s: float, target_s: float, speed_min: float = 0.0, speed_max: float = math.inf) -> float:
    """Playback speed that stretches a segment to a target duration, within bounds.

    ``speed = d(s) / d(p)``: clip seconds played per second, so the segment
    lasts ``d(s) / speed = d(p)`` (the paper's linear stretching), clipped to
    ``[speed_min, speed_max]``.  A target <= 0 gives ``speed_max``.
    """
    if target_s <= 0.0:
        if math.isinf(speed_max):
            raise ValueError("a target duration <= 0 needs a finite speed_max")
        return float(speed_max)
    return float(min(speed_max, max(speed_min, segment_s / target_s)))


def label_runs(labels: Sequence[str]) -> list[tuple[str, int, int]]:
    """Runs of equal consecutive labels: ``(label, first frame, number of frames)``."""
    runs: list[tuple[str, int, int]] = []
    for k, label in enumerate(labels):
        if runs and runs[-1][0] == label:
            lab, start, n = runs[-1]
            runs[-1] = (lab, start, n + 1)
        else:
            runs.append((label, k, 1))
    return runs


def to_sequence(labels: Sequence[str], dt: float) -> list[tuple[str, float]]:
    """Per-frame labels -> pseudo-phoneme sequence ``[(label, duration s)]`` (frames of ``dt`` s)."""
    return [(label, n * dt) for label, _, n in label_runs(labels)]


def cost_gap(sequence: Sequence[tuple[str, float]], db: SegmentDB, gamma: float) -> dict:
    """How much the greedy real-time variant loses against the optimum of Eq. 4.

    Returns
    -------
    dict
        ``units`` (K), ``greedy`` and ``optimal`` (Eq. 4 costs), ``gap``
        (greedy - optimal, >= 0), ``relative_gap`` (gap / optimal; 0 when both
        are 0), ``differing_units`` (units where the two choose different segments).
    """
    g = greedy(sequence, db, gamma)
    o = optimal(sequence, db, gamma)
    gap = g.cost - o.cost
    return {"units": len(sequence), "greedy": g.cost, "optimal": o.cost, "gap": gap,
            "relative_gap": gap / o.cost if o.cost > 0 else (0.0 if gap == 0 else math.inf),
            "differing_units": sum(a != b for a, b in zip(g.indices, o.indices))}
