"""The plugins against the thesis' pseudo-code transcribed literally (tests/thesis_listings.py), tick by tick at 60 Hz.

Each test runs a plugin at 60 frames a second, in the configuration that
matches the listing, beside the transcription on the same input, and compares
every tick.  The configurations name what laughlab adds (floors, caps) and
switch it off, or keep the input where it never acts.
"""
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import thesis_listings as T
from laughlab.core.bases import Context
from laughlab.core.frame import Frame
from laughlab.signals.mcs import RmsExtractor, RmsParams
from laughlab_plugins.scheduler_energy import EnergyParams, EnergyScheduler

FPS = 60.0
N = 10  # samples per frame (sample rate 600 Hz: the mapping does not care)


def blocks_at(levels):
    """Frames of constant samples whose RMS is ``level`` (full scale)."""
    return [np.full(N, lv, dtype=np.float64) for lv in levels]


def rms(block):
    return math.sqrt(sum(float(x) * float(x) for x in block) / len(block))  # Eq. 3.1, written out


def run_extractor(params, blocks):
    ext = RmsExtractor(params, Context(fps=FPS, sample_rate=int(N * FPS)))
    out = []
    for k, b in enumerate(blocks):
        f = Frame(k, k / FPS, 1 / FPS)
        ext.step(b, f)
        out.append((f.control["mcs_raw"], f.control["mcs"]))
    return np.array(out)


levels = st.lists(st.floats(0.001, 1.0), min_size=2, max_size=400)


@settings(max_examples=60, deadline=None)
@given(levels, st.floats(0.0005, 0.01), st.floats(0.2, 1.0))
def test_mapping_3_1_1(lv, lo, hi):
    # linear RMS, no falloff, no rise/fall limit, no pow: the mapping alone; the floor of maxAmp (ours) at 0
    p = RmsParams(scale="linear", min_amp=lo, max_amp=hi, falloff_per_s=0.0, rise_per_s=1e12, fall_per_s=1e12,
                  power=1.0, max_floor=0.0)
    blocks = blocks_at(lv)
    got = run_extractor(p, blocks)
    want = T.mapping_3_1_1([rms(b) for b in blocks], lo, hi)
    assert got[:, 0] == pytest.approx(want, abs=1e-12)
    assert got[:, 1] == pytest.approx(want, abs=1e-12)


@settings(max_examples=60, deadline=None)
@given(levels)
def test_rise_and_fall_eq_3_2(lv):
    # the mapping as in 3.1.1, then Eq. 3.2 with the listing's 0.4 / 0.2 per tick (24 /s and 12 /s at 60 Hz)
    p = RmsParams(scale="linear", min_amp=0.0005, max_amp=1.0, falloff_per_s=0.0, power=1.0, max_floor=0.0)
    blocks = blocks_at(lv)
    got = run_extractor(p, blocks)
    mapped = T.mapping_3_1_1([rms(b) for b in blocks], 0.0005, 1.0)
    assert got[:, 1] == pytest.approx(T.rise_fall_3_2(mapped, 0.4, 0.2), abs=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-60.0, -3.0), min_size=1, max_size=600))
def test_listing_5_2(db):
    # the whole listing on SoundAnalyse's loudness (10 log10 RMS); a calibration left min -60 dB and max -3 dB.
    # Over 600 ticks the falloff (0.001 per tick) moves min and max 0.6 dB each: they never cross and maxAmp
    # never reaches laughlab's floor (set far below), so neither of our guards acts
    p = RmsParams(min_amp=-60.0, max_amp=-3.0, max_floor=-1e9)
    blocks = blocks_at([10 ** (d / 10) for d in db])   # loudness d itself: 10 log10 of an RMS of 10^(d/10)
    got = run_extractor(p, blocks)
    want = T.listing_5_2([10 * math.log10(rms(b)) for b in blocks], -60.0, -3.0)
    assert got[:, 1] == pytest.approx(want, abs=1e-9)


def run_listing_scheduler(mcs, seed):
    ctx = Context(fps=FPS, rng=np.random.default_rng(seed))
    # listing units: MCS once per tick (gain 60 /s), fixed decrease 0.2 per tick (12 /s), cap 60, c = 2,
    # I = 120 ticks (2 s; + half a tick so that summed 1/60 steps meet the integer tick count exactly)
    s = EnergyScheduler(EnergyParams(consumption="listing", gain_per_s=60.0, decrease_per_s=12.0, max_energy=60.0,
                                     overrule_c=2.0, min_inactive_s=2.0 + 0.5 / FPS), ctx)
    energies, events = [], []
    for k, m in enumerate(mcs):
        f = Frame(k, k / FPS, 1 / FPS, {"mcs": float(m)})
        s.step(f)
        energies.append(f.channels["energy"])
        events += [(k, e.kind, e.clip) for e in f.events]
    return energies, events


def reference(mcs, seed):
    return T.listings_5_4_and_5_5([float(m) for m in mcs], np.random.default_rng(seed), fixedDecreasingFactor=0.2,
                                  maxLaughingEnergy=60.0, overruleThreshold=2.0, minInactiveTics=120)


def test_the_clip_library_is_listing_5_5s():
    lib = Context().clips
    printed = [(a.name, a.length, a.energy) for a in T.animation_actions()]
    assert [(c.name, round(c.duration_s * 24), c.energy) for c in lib if not c.loop] == printed


@pytest.fixture(scope="module")
def synthetic_mcs():
    """The MCS of 60 s of the synthetic laughter (rms extractor, defaults) at 60 Hz."""
    from laughlab.core import pipeline
    from laughlab.core.config import compose_config
    from omegaconf import OmegaConf

    cfg = compose_config(["input.duration_s=60", "scheduler=none", "face=smile", "body=shapes", "detector=none"])
    pipe = pipeline.build(OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"]))
    mcs = []
    for k, block in enumerate(pipe.source.blocks()):
        f = Frame(k, k / FPS, 1 / FPS)
        pipe.extractor.step(block, f)
        mcs.append(f.control["mcs"])
    return np.array(mcs)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_listings_5_4_and_5_5_on_the_synthetic_laughter(synthetic_mcs, seed):
    got_e, got_ev = run_listing_scheduler(synthetic_mcs, seed)
    want_e, want_ev = reference(synthetic_mcs, seed)
    assert got_ev == want_ev
    assert len(got_ev) >= 2           # the trace starts clips, so the comparison covers selection and consumption
    assert got_e == pytest.approx(want_e, abs=1e-9)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=60), st.integers(1, 12), st.integers(0, 2**32 - 1))
def test_listings_5_4_and_5_5_on_random_traces(values, hold, seed):
    mcs = np.repeat(values, hold)          # held values: bouts and pauses of random lengths
    got_e, got_ev = run_listing_scheduler(mcs, seed)
    want_e, want_ev = reference(mcs, seed)
    assert got_ev == want_ev
    assert got_e == pytest.approx(want_e, abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=50), st.integers(1, 20))
def test_listing_5_3_smoothers_and_eqs_3_3_3_4(values, hold):
    # face=smile (smile, jaw) and body=shapes (chest, belly) with their defaults, at 60 Hz, against 5.3
    from laughlab_plugins.body_shapes import ShapesBody, ShapesParams
    from laughlab_plugins.face_smile import SmileFace, SmileParams

    mcs = np.repeat(values, hold)
    ctx = Context(fps=FPS)
    face, body = SmileFace(SmileParams(), ctx), ShapesBody(ShapesParams(), ctx)
    want = T.smoothers_5_3([float(m) for m in mcs])
    for k, m in enumerate(mcs):
        f = Frame(k, k / FPS, 1 / FPS, {"mcs": float(m)})
        body.step(f)
        face.step(f)
        for name in ("smile", "jaw", "chest", "belly"):
            assert f.channels[name] == pytest.approx(want[k][name], abs=1e-9), (k, name)
