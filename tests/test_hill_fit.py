"""Audio-driven optimisation (DiLorenzo 2008, 6.2): primitives, segmentation, cost, fit, playback, experiment."""
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

from laughlab.hill import fit as hf
from laughlab.core import plugins
from laughlab.core.bases import Context
from laughlab.core.frame import Frame
from laughlab.hill.torso import GROUPS, Torso, TorsoParams
from laughlab_plugins import body_hill, extractor_pressure
from laughlab_plugins.body_hill import HillBody, HillParams

FPS = 60.0



def test_primitive_is_one_period_of_a_raised_cosine():
    # A (1 - cos(2 pi f (t - t0))) / 2 on [t0, t0 + 1/f)
    assert hf.bump(0.1 + 0.05, 0.1, 5.0) == pytest.approx(0.5)      # quarter period
    assert hf.bump(0.1 + 0.1, 0.1, 5.0) == pytest.approx(1.0)       # half period: the peak
    assert hf.bump(0.09, 0.1, 5.0) == 0.0 and hf.bump(0.3, 0.1, 5.0) == 0.0
    x = np.array([0.8, 0.4, 0.1, 0.02, 5.0, 0.05, 4.0])             # the seven PARAMS
    t = np.array([1.12, 1.15])
    a = hf.call_activation(t, x, 1.0)
    ab, ii, di = GROUPS.index("abdomen"), GROUPS.index("inner_intercostals"), GROUPS.index("diaphragm")
    # the abdomen rises and holds: at half its period u = 0.5, u - sin(pi) / (2 pi) = 0.5
    assert a[0, ab] == pytest.approx(0.8 * 0.5)
    assert a[0, ii] == pytest.approx(0.4)   # ribcage on the abdomen's timing: half its period, (1 - cos pi) / 2 = 1
    # the diaphragm at f 4 Hz, 0.1 s after its start: 0.1 (1 - cos 0.8 pi) / 2, by hand
    assert a[1, di] == pytest.approx(0.1 * (1 + 0.8090169943749475) / 2) == pytest.approx(0.09045084971874737)
    assert a[:, [GROUPS.index("outer_intercostals")]].sum() == 0     # laughing is expiratory
    assert len(hf.PARAMS) == 7


def test_hold_is_the_integral_of_the_period_and_release_lets_go():
    t = np.linspace(-0.1, 0.6, 701)
    h = hf.hold(t, 0.0, 5.0)
    assert h[t < 0].max() == 0.0 and np.all(h[t >= 0.2] == 1.0)
    # its rate is 2 f times the raised cosine (a trapezoid integral of the bump matches the closed form)
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (hf.bump(t[1:], 0.0, 5.0) + hf.bump(t[:-1], 0.0, 5.0))
                                                * np.diff(t))]) * 2 * 5.0
    np.testing.assert_allclose(h, integral, atol=2e-4)
    assert hf.hold(0.05, 0.0, 5.0) == pytest.approx(0.25 - 1.0 / (2.0 * np.pi))   # u = 1/4 by hand
    r = hf.release(np.array([0.9, 1.0, 1.75, 2.5, 3.0]), 1.0, 1.5)
    np.testing.assert_allclose(r, [1.0, 1.0, 0.5, 0.0, 0.0], atol=1e-12)
    assert np.all(hf.release(t, None, 1.5) == 1.0)
    x = np.array([0.2, 0.0, 0.0, 0.0, 5.0, 0.0, 5.0])
    a = hf.call_activation(np.array([0.5, 1.75, 3.0]), x, 0.0, 1.0, 1.5)[:, GROUPS.index("abdomen")]
    np.testing.assert_allclose(a, [0.2, 0.1, 0.0], atol=1e-12)


def test_bouts_release_after_the_last_call():
    c = hf.Call
    calls = [c(0, 12, 6), c(12, 24, 18), c(30, 40, 35), c(100, 110, 105)]     # gaps 0, 0.1 s, 1 s at 60 fps
    rel = hf.bout_releases(calls, FPS, 0.3)
    assert rel[:3] == [pytest.approx(40 / FPS + 0.3)] * 3        # one bout: let go 0.3 s after its last call
    assert rel[3] == pytest.approx(110 / FPS + 0.3)
    assert hf.bout_releases(calls, FPS, 0.05)[1] == pytest.approx(24 / FPS + 0.05)   # 0.1 s gap > 0.05: a new bout
    with pytest.raises(ValueError):
        hf.FitParams(release_after_s=0.05, settle_s=0.1)


def pulses(times, width=0.06, fps=FPS, n=None):
    t = (np.arange(n if n is not None else int(2.5 * fps)) + 1) / fps
    return np.sum([np.exp(-0.5 * ((t - c) / width) ** 2) for c in times], axis=0)


def test_segmentation_cuts_at_the_valley_centres():
    p = pulses([0.5, 0.7, 0.9, 1.8, 2.0])                           # a bout of 3 calls, a pause, 2 calls
    calls = hf.segment_calls(p, FPS)
    assert len(calls) == 5
    peaks = [c.peak for c in calls]
    assert [round((k + 1) / FPS, 2) for k in peaks] == [0.5, 0.7, 0.9, 1.8, 2.0]
    # inside a bout a call ends where the next starts, half-way between the peaks (the valley centre)
    assert calls[0].end == calls[1].start and calls[1].end == calls[2].start
    assert abs((calls[0].end + 0.5) / FPS - 0.6) <= 1 / FPS
    # across the pause the calls end and start where the pressure is below 10 % of the peak
    assert calls[2].end < calls[3].start
    assert p[calls[2].end] < 0.1 * p[calls[2].peak] and p[calls[3].start - 1] < 0.1 * p[calls[3].peak]
    assert hf.segment_calls(np.zeros(50), FPS) == []


def calls_audio(rate_hz: float, n_calls: int, sr: int = 44100, seed: int = 0, duty: float = 0.55,
                breath: float = 0.0, levels=None):
    """A bout of ``n_calls`` voiced calls (a 180 Hz buzz under a Hann window, ``duty`` of each period),
    ``rate_hz`` calls a second after 0.2 s of quiet, with 10 % jitter in the call levels; ``breath``:
    the amplitude of the breathy noise that fills the bout between the calls; ``levels``: call
    amplitudes taken in turn instead (e.g. a loud call, then a quiet one, as real laughs have)."""
    rng = np.random.default_rng(seed)
    period = 1.0 / rate_hz
    x = 1e-4 * rng.standard_normal(int(sr * (0.4 + n_calls * period)))
    for c in range(n_calls):
        on = int(sr * (0.2 + c * period))
        n = int(sr * 0.55 * period)
        t = np.arange(n) / sr
        amp = 0.3 * (0.9 + 0.2 * rng.random()) if levels is None else levels[c % len(levels)]
        x[on:on + n] += amp * np.hanning(n) * np.sign(np.sin(2 * np.pi * 180 * t))
    bout = slice(int(sr * 0.2), int(sr * (0.2 + n_calls * period)))
    x[bout] += breath * rng.standard_normal(bout.stop - bout.start)
    return x, sr


def level_and_pressure(x, sr):
    """Frame RMS and the ``pressure`` extractor's target, 60 frames a second (as ``experiment=hill_fit``)."""
    ext = extractor_pressure.PressureExtractor(None, Context(fps=FPS, sample_rate=sr))
    hop = int(sr / FPS)
    rms, p = [], []
    for k in range(len(x) // hop):
        f = Frame(k, k / FPS, 1 / FPS)
        ext.step(x[k * hop:(k + 1) * hop], f)
        rms.append(f.control["rms"])
        p.append(f.control["pressure"])
    return np.array(rms), np.array(p)


@settings(max_examples=15, deadline=None)
@given(rate=st.floats(3.0, 10.0), n=st.integers(3, 14), seed=st.integers(0, 1000))
def test_level_segmentation_follows_3_to_10_calls_a_second(rate, n, seed):
    """Issue 11: every call is found at real call rates, and inner boundaries sit at the pressure's valleys."""
    rms, p = level_and_pressure(*calls_audio(rate, n, seed=seed))
    calls = hf.find_calls(p, FPS, hf.FitParams(), level=rms)
    assert len(calls) == n
    for a, b in zip(calls, calls[1:]):
        assert a.end == b.start and a.peak < a.end <= b.peak + 2
        lo, hi = a.peak + 3, b.peak + 2           # the peaks shifted by the low-pass lag (32 ms = 2 frames)
        assert p[a.end] == pytest.approx(p[lo:hi].min())


def test_pressure_valleys_merge_fast_calls_the_level_does_not():
    """The paper's segmentation at the pressure's valleys against the frame RMS's (the default), on a real fast
    laugh of the corpus' test split (hedgewars' HillBilly-Laugh, 20 annotated calls in 4.2 s at 44.1 kHz): since the
    extractor subtracts its noise floor (2026-11-29) the synthetic calls' valleys all resolve, but on this laugh
    the pressure still merges calls, 10 found, where the level finds 17 (on the 26 laughs: 208 and 281 of 302)."""
    import soundfile as sf

    from laughlab.corpora.fetch import corpus_dir

    x, sr = sf.read(corpus_dir() / "sets" / "real-test" / "hedgewars__HillBilly-Laugh.wav", dtype="float32",
                    always_2d=True)
    rms, p = level_and_pressure(x.mean(axis=1), sr)
    by_level = len(hf.find_calls(p, FPS, hf.FitParams(), level=rms))
    by_pressure = len(hf.find_calls(p, FPS, hf.FitParams(segment="pressure"), level=rms))
    assert by_level >= 17 and by_pressure <= by_level - 5, (by_level, by_pressure)
    assert hf.find_calls(p, FPS, hf.FitParams()) == hf.segment_calls(p, FPS)   # no level: the pressure's


def problem(target, state=None, fit=None, t0=0.0):
    state = Torso().get_state(0) if state is None else state
    return hf.CallProblem(target, t0, FPS, lambda t: np.zeros((len(t), 6)), state, TorsoParams(),
                          fit or hf.FitParams())


def test_scaling_of_the_parameters_by_hand():
    pr = problem(np.ones(12))
    assert pr.length == pytest.approx(0.2) and pr.horizon == pytest.approx(0.3)
    u = np.array([0.5, 1.0, 0.5, 0.0, 0.5, 0.5, 1.0])
    x = pr.to_physical(u)
    assert x[0] == pytest.approx(1.0 * 0.25) and x[1] == 1.0 and x[2] == pytest.approx(0.3 * 0.25)  # A = A_max u^2
    assert x[5] == pytest.approx(0.5 * 0.7 * 0.2)                                     # start, linear
    assert x[4] == pytest.approx(1.5 * (12.0 / 1.5) ** 0.5)                            # frequency, logarithmic
    assert x[6] == pytest.approx(12.0)
    np.testing.assert_allclose(pr.to_unit(x), u, atol=1e-12)
    # a primitive must end within the look-ahead: f >= 1 / (0.3 s - start)
    late = pr.to_physical(np.array([0.5, 0.5, 0.5, 1.0, 0.0, 1.0, 0.0]))
    assert late[4] == pytest.approx(1.0 / (0.3 - 0.14)) and late[6] == pytest.approx(1.0 / (0.3 - 0.14))


def test_error_is_normalised_by_a_constant_zero_pressure():
    target = pulses([0.1], n=12)
    pr = problem(target, fit=hf.FitParams(settle_weight=0.0))
    cost, err = pr.costs(pr.to_unit(np.zeros((1, 7))))
    assert err[0] == pytest.approx(1.0)                      # the torso at rest: zero pressure -> error 1
    p, _ = pr.simulate(np.array([[0.3, 0.1, 0.0, 0.0, 6.0, 0.0, 6.0]]), look=False)
    rms = np.sqrt(np.mean((p[:, 0] - target) ** 2)) / np.sqrt(np.mean(target ** 2))
    assert pr.costs(pr.to_unit(np.array([[0.3, 0.1, 0.0, 0.0, 6.0, 0.0, 6.0]])))[1][0] == pytest.approx(rms)


def test_the_lead_frames_count_in_the_cost_with_the_settling_penalty_too():
    """With ``lead_s`` and ``settle_weight`` > 0 the optimised cost is the RMS error over the lead and
    the call frames (against the previous call's target there) plus the weighted settling term, the
    same cost :meth:`CallProblem.residuals` reports (the lead frames' cost used to be dropped)."""
    lead_target = 0.08 * pulses([0.05], n=6)                  # the end of the previous call
    target = pulses([0.1], n=12)
    pr = hf.CallProblem(target, 0.1, FPS, lambda t: np.zeros((len(t), 6)), Torso().get_state(0), TorsoParams(),
                        hf.FitParams(settle_weight=2.0, lead_s=0.1), lead_frames=6, lead_target=lead_target)
    u = pr.to_unit(np.array([[0.1, 0.6, 0.3, -0.05, 6.0, 0.14, 6.0]]))   # pushes in the lead, inhales after
    p, _ = pr.simulate(pr.to_physical(u))
    p = p[:, 0]
    norm = np.sqrt(np.mean(target ** 2))
    over_lead_and_call = np.sqrt(np.mean((p[:18] - np.concatenate([lead_target, target])) ** 2)) / norm
    settle = np.sqrt(np.mean(np.minimum(p[18:], 0.0) ** 2)) / norm
    assert len(p) == 6 + 12 + 6 and settle > 0.1 and over_lead_and_call != pytest.approx(
        np.sqrt(np.mean((p[6:18] - target) ** 2)) / norm)    # the lead frames change the cost here
    cost, err = pr.costs(u)
    assert err[0] == pytest.approx(np.sqrt(np.mean((p[6:18] - target) ** 2)) / norm)   # the paper's error: the call
    assert cost[0] == pytest.approx(over_lead_and_call + 2.0 * settle)
    assert pr.residuals(u)[1][0] == pytest.approx(cost[0])


def oracle(xs, n_frames=12, gap=0):
    """A target made by the model itself: calls of n_frames with known parameters."""
    calls, f0 = [], 6
    for _ in xs:
        calls.append(hf.Call(f0, f0 + n_frames, f0 + n_frames // 2))
        f0 += n_frames + gap
    n = f0 + 12
    fp = hf.FitParams()
    res = hf.FitResult(FPS, [hf.CallFit(c, np.array(x), 0.0, 0, 0.0) for c, x in zip(calls, xs)], np.zeros(n),
                       np.zeros(n), fp, TorsoParams())
    hf._advance(res, Torso().get_state(0), 0, n, FPS, TorsoParams(), fp)
    return res.simulated.copy(), calls


def test_true_parameters_score_zero_and_batches_agree():
    x = np.array([0.15, 0.1, 0.02, 0.01, 6.0, 0.0, 5.0])
    target, calls = oracle([x])
    c = calls[0]
    state = hf._advance(hf.FitResult(FPS, [], target, np.zeros_like(target), hf.FitParams(), TorsoParams()),
                        Torso().get_state(0), 0, c.start, FPS, TorsoParams(), hf.FitParams())
    pr = hf.CallProblem(target[c.start:c.end], c.start / FPS, FPS, lambda t: np.zeros((len(t), 6)), state,
                        TorsoParams(), hf.FitParams(settle_weight=0.0))
    u = pr.to_unit(x)
    others = np.random.default_rng(0).uniform(size=(5, 7))
    cost, err = pr.costs(np.vstack([u, others]))
    assert err[0] < 1e-9                                      # the generating parameters reproduce the target
    single = [pr.costs(o[None, :])[1][0] for o in others]
    np.testing.assert_allclose(err[1:], single, rtol=1e-9)    # a batch of torsos == one at a time
    assert pr.evals == 11 and len(pr.history) == 11
    assert all(a >= b for a, b in zip(pr.history, pr.history[1:]))


@pytest.fixture(scope="module")
def oracle_fit():
    xs = [np.array([0.12, 0.1, 0.02, 0.0, 6.0, 0.0, 5.0]), np.array([0.2, 0.05, 0.0, 0.02, 5.0, 0.05, 6.0])]
    target, calls = oracle(xs)
    res = hf.fit(target, FPS, hf.FitParams(max_evals=250, polish_evals=60, settle_weight=0.0), calls=calls)
    return target, res


def test_fit_recovers_a_model_made_target(oracle_fit):
    target, res = oracle_fit
    s = res.summary()
    assert s["calls"] == 2 and s["error_mean"] < 0.35
    assert all(cf.evals <= 250 + 60 + 32 for cf in res.calls)


def test_playback_on_the_body_reproduces_the_fit(oracle_fit):
    """The hill body playing the fitted schedule gives the simulated pressure of the fit, frame by frame."""
    target, res = oracle_fit
    body = HillBody(HillParams(), Context(fps=FPS))
    body.play(res.schedule)
    p = []
    for k in range(len(target)):
        f = Frame(k, k / FPS, 1 / FPS, {"pressure": 0.0, "mcs": 0.0})
        body.step(f)
        p.append(f.channels["lung_pressure"])
    np.testing.assert_allclose(p, res.simulated, atol=1e-9)


def test_compare_methods_records_running_best():
    target, calls = oracle([np.array([0.12, 0.1, 0.02, 0.0, 6.0, 0.0, 5.0])])
    out = hf.compare_methods(target, FPS, 0, methods=("nelder-mead", "annealing", "pds", "cma"), max_evals=60,
                             fit_params=hf.FitParams(polish_evals=0, init_points=15, popsize=12))
    assert set(out) == {"nelder-mead", "annealing", "pds", "cma"}
    # the same budget for each (a new-user review: dual_annealing's soft maxfun let it take 1311 of a budget of 100)
    assert out["annealing"]["evals"] <= 60 and out["nelder-mead"]["evals"] <= 60, {m: r["evals"] for m, r in out.items()}
    for r in out.values():
        h = r["history"]
        assert len(h) >= 30 and all(a >= b for a, b in zip(h, h[1:]))
        assert r["error"] == pytest.approx(h[-1]) and 0 <= r["error"] <= 1.0 + 1e-9
        assert h[-1] < h[0]                 # each method improved on its first guess (a flat history passed above)



def test_compare_methods_counts_the_polish_inside_the_budget():
    """A sweep researcher's review: at max_evals=500 pds spent 647 evaluations and cma 520 (the Levenberg-Marquardt
    polish came on top), against 500 for Nelder-Mead and annealing; Fig. 7 compared unequal budgets."""
    target, calls = oracle([np.array([0.12, 0.1, 0.02, 0.0, 6.0, 0.0, 5.0])])
    out = hf.compare_methods(target, FPS, 0, methods=("pds", "cma", "nelder-mead"), max_evals=90,
                             fit_params=hf.FitParams(polish_evals=40, init_points=15, popsize=12))
    assert all(r["evals"] <= 90 and len(r["history"]) <= 90 for r in out.values()), \
        {m: r["evals"] for m, r in out.items()}
    assert out["pds"]["evals"] > 50   # the polish ran in what the search left (50 evaluations at most without it)

def test_fit_params_validate():
    with pytest.raises(ValueError):
        hf.FitParams(method="genetic")
    with pytest.raises(ValueError):
        hf.FitParams(freq_min_hz=5.0, freq_max_hz=2.0)
    with pytest.raises(ValueError, match="segment must be one of level, pressure"):
        hf.FitParams(segment="onsets")


def png_width(path) -> int:
    from PIL import Image

    with Image.open(path) as im:
        return im.size[0]


def test_experiment_writes_the_figures_and_numbers(hill_plugins, tmp_path):
    from laughlab.core.config import compose_config
    from laughlab_experiments import hill_fit as exp

    cfg = compose_config(["experiment=hill_fit", "input.duration_s=2.5", "input.profile=intense",
                          "harness.fit.max_evals=60", "harness.fit.polish_evals=0", "harness.fit.popsize=12",
                          "harness.fit.init_points=11", "harness.compare.calls=1", "harness.compare.max_evals=30",
                          "harness.compare.methods=[nelder-mead,cma]", "harness.corpus.profiles=[giggle]",
                          "harness.corpus.duration_s=2.0", "output.plots.width=column", "output.plots.pdf=true"])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    assert cfg.body.name == "hill" and cfg.extractor.name == "pressure"
    doc = exp.run(cfg, tmp_path)
    for name in ("channels.csv", "events.csv", "motion.bvh", "metrics.json", "calls.csv", "hill_fit.json",
                 "plots/fig10_pressure.png", "plots/fig7_optimisers.png"):
        assert (tmp_path / name).exists(), name
    # the run's output.plots.width and .pdf reach the experiment's own figures (Fig. 7 took neither)
    for fig in ("fig10_pressure", "fig7_optimisers"):
        assert (tmp_path / "plots" / f"{fig}.pdf").exists(), fig
        assert png_width(tmp_path / "plots" / f"{fig}.png") == 3.5 * 150, fig
    data = json.loads((tmp_path / "hill_fit.json").read_text())
    assert data["overall"]["calls"] == len((tmp_path / "calls.csv").read_text().splitlines()) - 1
    assert set(data["inputs"]) == {"input", "giggle-s00"}
    assert math.isfinite(doc["overall"]["error_mean"])
    head = (tmp_path / "channels.csv").read_text().splitlines()[0].split(",")
    assert {"lung_pressure", "chest", "belly", "act_abdomen"} <= set(head)
    # issue 11: every call of the input found (intense synthetic laughter: calls at ~5 per second)
    ov = data["overall"]
    assert ov["input_calls_annotated"] == len(exp.extract_target(cfg)[2].calls)
    assert abs(ov["input_calls_found"] - ov["input_calls_annotated"]) <= 1
    assert ov["evals_per_call_mean"] <= 60 + 3 and ov["seconds_per_call_median"] > 0


def test_experiment_reads_the_annotation_beside_a_recording(tmp_path):
    from laughlab.core.config import compose_config
    from laughlab_experiments import hill_fit as exp

    wav = tmp_path / "laugh.wav"
    wav.write_bytes(b"")
    (tmp_path / "laugh.txt").write_text("0.1\t0.9\tlaugh\n0.1\t0.3\tcall\n0.4\t0.6\tcall\n")
    cfg = compose_config(["experiment=hill_fit", "input=file", f"input.path={wav}"])
    assert exp.annotated_calls(cfg, None) == 2
    (tmp_path / "laugh.txt").unlink()
    assert exp.annotated_calls(cfg, None) is None


def test_quiet_calls_are_counted_but_not_driven():
    """A call whose pressure the extractor's floor cleared (< quiet_frac of the 99th percentile) gets no
    activation and no error; the others are fitted and reported as usual."""
    p = 0.1 * pulses([0.4, 0.9, 1.4], n=120)
    p[72:] *= 0.02                                                         # the third call, nearly silent
    calls = [hf.Call(12, 36, 23), hf.Call(36, 70, 53), hf.Call(70, 110, 83)]
    fp = hf.FitParams(max_evals=60, polish_evals=0, popsize=12, init_points=11)
    res = hf.fit(p, FPS, fp, calls=calls)
    assert [c.driven for c in res.calls] == [True, True, False]
    assert np.all(res.calls[2].x[:3] == 0.0) and res.calls[2].evals == 0          # no amplitude: no activation and math.isnan(res.calls[2].error)
    assert all(math.isfinite(c.error) for c in res.calls[:2])
    s = res.summary()
    assert s["quiet_calls"] == 1 and s["calls"] == 3 and s["evals_mean"] == np.mean([c.evals for c in res.calls[:2]])


def test_fig7s_optimisers_are_told_apart_without_their_hues():
    """Fig. 7's CMA-ES (purple) and parallel direct search (blue) lines were both solid and as light as each other:
    one line in a greyscale print and for a red-green colour vision deficiency."""
    from laughlab.render.labels import lines_told_apart_by_hue
    from laughlab_experiments.hill_fit import figure_7_drawn

    h = list(np.linspace(1.0, 0.2, 50))
    runs = {m: {"history": h, "error": 0.2, "seconds": 1.0} for m in ("nelder-mead", "annealing", "pds", "cma")}
    fig = figure_7_drawn({"call 1": {"methods": runs}, "call 2": {"methods": runs}})   # a bare Figure: nothing
    assert lines_told_apart_by_hue(fig) == []                                           # to close
    assert len({line.get_linestyle() for line in fig.axes[0].lines[:4]}) == 4
    # a best error above 1.2 is inside the axes (a new-user review: Nelder-Mead's 1.62 was drawn nowhere)
    high = {**runs, "nelder-mead": {"history": list(np.linspace(3.0, 1.62, 50)), "error": 1.62, "seconds": 1.0}}
    fig = figure_7_drawn({"call 1": {"methods": high}})
    assert fig.axes[0].get_ylim()[1] >= 1.62 * 1.1 - 1e-9
