"""Built-in metrics: how well the animation answers the laughter, and what it costs.

Conventions: times in seconds; "start" is a clip (or segment) start in
``events.csv``; a bout or call comes from the ground truth (``truth.csv``);
metrics that need the truth are NaN without it.
"""
from __future__ import annotations

import numpy as np

from laughlab import hookimpl
from laughlab.harness.metrics import best_lag_correlation, finite_percentile, metric
from laughlab.harness.trialdata import SMOOTH_S, TrialData, moving_average

MAX_LAG_S = 2.0
REPEAT_WINDOW_S = 5.0
SILENT_AFTER_S = 1.0
FACE_RISE = 0.05
FACE_WINDOW_S = 1.0


def _tracking(trial: TrialData, animation: np.ndarray | None):
    if animation is None:
        return float("nan"), float("nan"), float("nan")
    x = trial.laughter_intensity
    r, lag_s, k = best_lag_correlation(x, animation, trial.fps, MAX_LAG_S)
    if np.isnan(r):
        return r, float("nan"), lag_s
    n = min(len(x), len(animation))
    from scipy import stats

    rho = float(stats.spearmanr(x[: n - k], animation[k:n]).statistic)
    return r, rho, lag_s


def _clip_energy(trial):
    return trial.channels["clip_energy"].to_numpy() if "clip_energy" in trial.channels else None


def _kinetic(trial):
    ke = trial.kinetic_energy
    return None if ke is None else moving_average(ke, int(round(SMOOTH_S * trial.fps)))


@metric("intensity_r_clip", True, "Pearson r")
def intensity_r_clip(trial):
    """Pearson r between laughter intensity I(t) and the playing clip's energy e(t + lag), best lag in [0, 2] s.

    I: the truth's graded call intensity, else the RMS inside its calls (throughout without a truth), smoothed
    over 1 s (``TrialData.laughter_intensity``); e: ``clip_energy`` channel.
    """
    return _tracking(trial, _clip_energy(trial))[0]


@metric("intensity_rho_clip", True, "Spearman rho")
def intensity_rho_clip(trial):
    """Spearman rho between I(t) and e(t + lag) at the lag of ``intensity_r_clip``."""
    return _tracking(trial, _clip_energy(trial))[1]


@metric("intensity_lag_clip_s", False, "s", search=(0.0, MAX_LAG_S))
def intensity_lag_clip_s(trial):
    """The lag in [0, 2] s maximising Pearson r between I(t) and e(t + lag)."""
    return _tracking(trial, _clip_energy(trial))[2]


@metric("intensity_r_kinetic", True, "Pearson r")
def intensity_r_kinetic(trial):
    """Pearson r between I(t) and the skeleton's kinetic energy K(t + lag), best lag in [0, 2] s.

    K = 0.5 * sum_j |v_j|^2 per unit mass over the joints of ``motion.bvh`` ((m/s)^2), smoothed over 1 s.
    """
    return _tracking(trial, _kinetic(trial))[0]


@metric("intensity_rho_kinetic", True, "Spearman rho")
def intensity_rho_kinetic(trial):
    """Spearman rho between I(t) and K(t + lag) at the lag of ``intensity_r_kinetic``."""
    return _tracking(trial, _kinetic(trial))[1]


@metric("intensity_lag_kinetic_s", False, "s", search=(0.0, MAX_LAG_S))
def intensity_lag_kinetic_s(trial):
    """The lag in [0, 2] s maximising Pearson r between I(t) and K(t + lag)."""
    return _tracking(trial, _kinetic(trial))[2]


def _bout_latencies(trial):
    if trial.truth is None or trial.truth.bouts.empty:
        return None
    starts = trial.starts().time.to_numpy()
    lat = []
    for on, off in trial.truth.bouts[["onset_s", "offset_s"]].itertuples(index=False):
        inside = starts[(starts >= on) & (starts <= off)]
        lat.append(inside[0] - on if len(inside) else np.nan)
    return np.array(lat)


@metric("onset_latency_median_s", False, "s")
def onset_latency_median_s(trial):
    """Median over bouts of (first clip start in the bout - bout onset); bouts without a clip excluded."""
    lat = _bout_latencies(trial)
    return finite_percentile(lat, 50)


@metric("onset_latency_p90_s", False, "s")
def onset_latency_p90_s(trial):
    """90th percentile over bouts of (first clip start in the bout - bout onset)."""
    lat = _bout_latencies(trial)
    return finite_percentile(lat, 90)


@metric("miss_rate", False, "fraction")
def miss_rate(trial):
    """Fraction of bouts during which no clip starts: #{bouts with no start in [onset, offset]} / #bouts."""
    lat = _bout_latencies(trial)
    return float(np.mean(np.isnan(lat))) if lat is not None else float("nan")


@metric("offset_tail_s", False, "s")
def offset_tail_s(trial):
    """Median over bouts of how long clips go on after the bout ends.

    For bout b ending at t_b with the next bout at t_n (or the end of the run):
    max(0, max(stop of the clips playing between t_b and t_n) - t_b), at most t_n - t_b.
    """
    if trial.truth is None or trial.truth.bouts.empty:
        return float("nan")
    plays = trial.plays()
    b = trial.truth.bouts.sort_values("onset_s")
    ends = b.offset_s.to_numpy()
    nexts = np.r_[b.onset_s.to_numpy()[1:], trial.duration_s]
    tails = []
    for t_b, t_n in zip(ends, nexts):
        if t_n <= t_b:
            continue
        live = plays[(plays.stop > t_b) & (plays.start < t_n)]
        tails.append(0.0 if live.empty else float(min(max(live.stop.max() - t_b, 0.0), t_n - t_b)))
    return float(np.median(tails)) if tails else float("nan")


@metric("silent_start_rate", False, "fraction")
def silent_start_rate(trial):
    """Fraction of clip starts in silence: more than 1 s after the last bout ended (or before any bout); NaN without a
    start, as the other rates of clips (it was 0, a perfect score for a run that never moved: a metrics audit)."""
    if trial.truth is None:
        return float("nan")
    starts = trial.starts().time.to_numpy()
    if len(starts) == 0:
        return float("nan")
    b = trial.truth.bouts
    heard = np.zeros(len(starts), dtype=bool)
    for on, off in b[["onset_s", "offset_s"]].itertuples(index=False):
        heard |= (starts >= on) & (starts <= off + SILENT_AFTER_S)
    return float(np.mean(~heard))


@metric("cutoff_rate", False, "fraction")
def cutoff_rate(trial):
    """Fraction of played clips stopped by another before half of them played (played fraction < 0.5)."""
    plays = trial.plays()
    if plays.empty:
        return float("nan")
    cut = (plays.reason != "finished") & (plays.reason != "end") & (plays.fraction < 0.5)
    return float(np.mean(cut))


@metric("repetition_rate", False, "fraction")
def repetition_rate(trial):
    """Fraction of clip starts whose clip already started within the previous 5 s."""
    s = trial.starts()
    if s.empty:
        return float("nan")
    rep = 0
    for i, (clip, t) in enumerate(zip(s["clip"], s["time"])):
        prev = s.iloc[:i]
        rep += bool(((prev["clip"] == clip) & (prev.time >= t - REPEAT_WINDOW_S)).any())
    return rep / len(s)


@metric("clip_entropy", True, "fraction of log K")
def clip_entropy(trial):
    """Normalised entropy of clip use: -sum p_i log p_i / log K over the K clips of the library (idle excluded)."""
    from laughlab.harness.trialdata import clip_durations

    s = trial.starts()
    if s.empty:
        return float("nan")
    k = len([c for c in clip_durations() if c != "idle"])
    p = s["clip"].value_counts(normalize=True).to_numpy()
    return float(-(p * np.log(p)).sum() / np.log(k))


def _face_latency(trial, channel):
    if trial.truth is None or channel not in trial.channels or trial.truth.calls.empty:
        return float("nan")
    y = trial.channels[channel].to_numpy()
    t = trial.times
    win = int(round(FACE_WINDOW_S * trial.fps))
    lat = []
    for on in trial.truth.calls.onset_s:
        i = int(np.searchsorted(t, on))
        if i >= len(y) or y[i] >= 0.95:
            continue
        seg = y[i:i + win] - y[i]
        hit = np.nonzero(seg >= FACE_RISE)[0]
        if len(hit):
            lat.append(hit[0] / trial.fps)
    return float(np.median(lat)) if lat else float("nan")


@metric("jaw_onset_latency_s", False, "s")
def jaw_onset_latency_s(trial):
    """Median over calls of the time from the call onset until ``jaw`` rose by 0.05 (within 1 s).

    Calls where the jaw is already at >= 0.95 are skipped.
    """
    return _face_latency(trial, "jaw")


@metric("smile_onset_latency_s", False, "s")
def smile_onset_latency_s(trial):
    """Median over calls of the time from the call onset until ``smile`` rose by 0.05 (within 1 s).

    Calls where the smile is already at >= 0.95 (saturated) are skipped.
    """
    return _face_latency(trial, "smile")


@metric("jaw_call_r", True, "Pearson r")
def jaw_call_r(trial):
    """Pearson r between the call envelope c(t) and the jaw opening j(t + lag), best lag in [0, 0.5] s.

    c: ground-truth call intensity inside calls, 0 outside (unsmoothed); or the RMS without truth.
    """
    if "jaw" not in trial.channels:
        return float("nan")
    if trial.truth is not None:
        c = trial.truth.intensity(trial.times)
    else:
        c = trial.channels["rms"].to_numpy()
    return best_lag_correlation(c, trial.channels["jaw"].to_numpy(), trial.fps, 0.5)[0]


#: best lag of the jaw behind the sound's envelope (s): the mouth must answer each call within 0.1 s (issue 11)
JAW_ENVELOPE_LAG_S = 0.1


def jaw_opening(trial) -> np.ndarray | None:
    """The face's jaw opening per frame: ``arkit.jawOpen`` when the face writes ARKit weights, else ``jaw``."""
    for name in ("arkit.jawOpen", "jaw"):
        if name in trial.channels:
            return trial.channels[name].to_numpy()
    return None


@metric("jaw_envelope_r", True, "Pearson r")
def jaw_envelope_r(trial):
    """Pearson r between the sound's RMS envelope a(t) and the jaw opening j(t + lag), best lag in [0, 0.1] s.

    a: the ``rms`` channel (full-scale RMS of each frame's audio block, written by
    every extractor, before any detector gate); j: :func:`jaw_opening`.  Unlike
    ``jaw_call_r`` it needs no ground truth and allows only 0.1 s of lag, so it
    asks that the mouth open and close with each call of a real recording.
    """
    j = jaw_opening(trial)
    if j is None or "rms" not in trial.channels:
        return float("nan")
    return best_lag_correlation(trial.channels["rms"].to_numpy(), j, trial.fps, JAW_ENVELOPE_LAG_S)[0]


@metric("frame_ms_p50", False, "ms")
def frame_ms_p50(trial):
    """Median per-frame compute time of the plugins and mixer (ms), from ``metrics.json``."""
    return trial.run_metrics["frame_ms_p50"]


@metric("frame_ms_p99", False, "ms")
def frame_ms_p99(trial):
    """99th percentile per-frame compute time (ms), from ``metrics.json``."""
    return trial.run_metrics["frame_ms_p99"]


@metric("realtime_factor", True, "x real time")
def realtime_factor(trial):
    """Audio duration / wall time of the frame loop, from ``metrics.json``."""
    return trial.run_metrics["realtime_factor"]


ALL = [intensity_r_clip, intensity_rho_clip, intensity_lag_clip_s, intensity_r_kinetic, intensity_rho_kinetic,
       intensity_lag_kinetic_s, onset_latency_median_s, onset_latency_p90_s, miss_rate, offset_tail_s,
       silent_start_rate, cutoff_rate, repetition_rate, clip_entropy, jaw_onset_latency_s,
       smile_onset_latency_s, jaw_call_r, jaw_envelope_r, frame_ms_p50, frame_ms_p99, realtime_factor]


@hookimpl
def register_metrics(register):
    for m in ALL:
        register(m)
