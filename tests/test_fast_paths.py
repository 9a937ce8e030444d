"""The speed-ups of issue 12 give the same numbers as the plain code they replace."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from laughlab.core.scalar import interp
from laughlab.io.audio import cut_frames

finite = st.floats(-1e3, 1e3, allow_nan=False)


@given(st.lists(finite, min_size=1, max_size=12), st.lists(finite, min_size=12, max_size=12),
       st.lists(finite, min_size=1, max_size=20))
@settings(max_examples=300, deadline=None)
def test_scalar_interp_is_numpy_interp_bit_for_bit(xs, ys, queries):
    xp = sorted(xs)
    fp = ys[: len(xp)]
    for q in queries + xp + [xp[0] - 1.0, xp[-1] + 1.0]:
        want = float(np.interp(q, np.array(xp), np.array(fp)))
        got = interp(q, xp, fp)
        assert got == want or (np.isnan(got) and np.isnan(want)), (q, xp, fp)


def test_scalar_interp_by_hand():
    assert interp(0.5, [0.0, 1.0], [0.0, 2.0]) == 1.0
    assert interp(-3.0, [0.0, 1.0], [5.0, 2.0]) == 5.0 and interp(7.0, [0.0, 1.0], [5.0, 2.0]) == 2.0
    assert interp(1.0, [0.0, 1.0, 1.0, 2.0], [0.0, 3.0, 4.0, 0.0]) == 4.0  # a step: the last knot's value


def cut_reference(chunks, sr, fps):
    """The frame-by-frame cutting the vectorised edges replace."""
    step = sr / fps
    buf, k, consumed = np.zeros(0, np.float32), 0, 0
    for chunk in chunks:
        buf = np.concatenate([buf, np.asarray(chunk, np.float32)])
        pos = 0
        while True:
            start, end = int(round(k * step)) - consumed, int(round((k + 1) * step)) - consumed
            if end > len(buf):
                break
            yield buf[start:end].copy()
            k, pos = k + 1, end
        buf, consumed = buf[pos:], consumed + pos
    if len(buf):
        yield buf.copy()


@given(st.sampled_from([8000, 16000, 22050, 44100, 48000, 96000]), st.sampled_from([24.0, 30.0, 60.0, 59.94]),
       st.lists(st.integers(1, 5000), min_size=1, max_size=30))
@settings(max_examples=200, deadline=None)
def test_vectorised_frame_cutting_gives_the_same_blocks(sr, fps, sizes):
    audio = np.arange(sum(sizes), dtype=np.float32)
    chunks = np.split(audio, np.cumsum(sizes)[:-1])
    got = [b.copy() for b in cut_frames(iter(chunks), sr, fps)]
    want = list(cut_reference(iter(chunks), sr, fps))
    assert len(got) == len(want)
    assert all(np.array_equal(a, b) for a, b in zip(got, want))


@given(st.data())
@settings(max_examples=100, deadline=None)
def test_clip_rows_are_the_per_frame_samples(data):
    from laughlab.motion.clips import ClipLibrary

    lib = _library()
    name = data.draw(st.sampled_from(sorted(lib.names) + ["idle"]))
    clip = lib.idle if name == "idle" else lib[name]
    # clip times are >= 0 in the mixer (a time before the start is clamped for clips that do not loop)
    times = data.draw(st.lists(st.floats(0.0, 3 * clip.duration_s, allow_nan=False), min_size=1, max_size=40))
    rows = clip.sample_rows(times)
    for t, row in zip(times, rows):
        assert np.array_equal(row, clip.sample(t)), (name, t)


_LIB = []


def _library():
    from laughlab.motion.clips import ClipLibrary

    if not _LIB:
        _LIB.append(ClipLibrary.load())
    return _LIB[0]


def test_the_mixer_renders_a_chunk_as_it_renders_frame_by_frame():
    """Chunked rendering (note + take) equals one pose per frame, through starts, blends, stops and offsets."""
    from laughlab.core.frame import ClipEvent, Frame
    from laughlab.core.mixer import Mixer

    lib = _library()
    names = sorted(lib.names)
    rng = np.random.default_rng(3)
    script = {}
    for k in sorted(rng.choice(600, 25, replace=False)):
        kind = "start" if rng.random() < 0.7 else "stop"
        script[int(k)] = ClipEvent(k / 60, kind, names[int(rng.integers(len(names)))], 1.0,
                                   speed=float(rng.uniform(0.8, 1.2)), blend_s=float(rng.choice([0.0, 0.2])))

    def run(chunk):
        mix, poses = Mixer(lib), []
        for k in range(600):
            f = Frame(k, k / 60, 1 / 60, events=[script[k]] if k in script else [])
            if k % 7 == 0:
                f.offsets = {"spine1": (0.5, -1.0, 0.25), "head": (-2.0, 0.0, 1.5)}
            mix.advance(f)
            mix.note(f)
            if (k + 1) % chunk == 0:
                poses.append(mix.take())
        poses.append(mix.take())
        return np.concatenate(poses)

    one, many = run(1), run(256)
    assert one.shape == (600, lib.skeleton.n_channels)
    assert np.array_equal(one, many)


@given(st.integers(1, 3), st.integers(1, 30000), st.sampled_from([8000, 44100, 48000]), st.integers(0, 2**32 - 1))
@settings(max_examples=25, deadline=None)
def test_pcm16_wav_reading_is_libsndfiles_conversion(tmp_path_factory, channels, n, sr, seed):
    """16-bit WAV through the standard library equals soundfile's float32 reading, mixed to mono."""
    import soundfile as sf

    from laughlab.io.audio import read_blocks, to_mono

    path = tmp_path_factory.mktemp("wav") / "x.wav"
    pcm = np.random.default_rng(seed).integers(-32768, 32768, size=(n, channels)).astype(np.int16)
    sf.write(str(path), pcm, sr, subtype="PCM_16")
    want = to_mono(sf.read(str(path), dtype="float32", always_2d=True)[0])
    got = np.concatenate(list(read_blocks(path, block_s=0.1)))
    assert got.dtype == np.float32 and np.array_equal(got, want)


def test_a_channel_missing_in_some_frames_is_one_clear_error():
    import pytest

    from laughlab.core.errors import LaughlabError
    from laughlab.core.frame import Frame
    from laughlab.core.recorder import Recorder

    rec = Recorder(4, 3)
    rec.add(Frame(0, 0.0, 1 / 60, {"mcs": 0.1}, None, {"smile": 0.2}))
    rec.add(Frame(1, 1 / 60, 1 / 60, {"mcs": 0.3}, None, {}))
    with pytest.raises(LaughlabError, match="do not all write the same channels"):
        rec.take(np.zeros((2, 3)))
    rec = Recorder(4, 3)
    rec.add(Frame(0, 0.0, 1 / 60, {"mcs": 0.1}, None, {"smile": 0.2}))
    rec.add(Frame(1, 1 / 60, 1 / 60, {"mcs": 0.3}, None, {"smile": 0.4}))
    chunk = rec.take(np.zeros((2, 3)))
    assert chunk.channels["mcs"].tolist() == [0.1, 0.3] and chunk.channels["smile"].tolist() == [0.2, 0.4]


@given(st.lists(st.floats(-2.0, 2.0, allow_nan=False), min_size=1, max_size=200),
       st.floats(0.01, 5.0), st.floats(0.01, 5.0), st.floats(0.0, 0.4), st.floats(0.6, 1.0))
@settings(max_examples=200, deadline=None)
def test_smoother_is_the_rate_limit_with_min_and_max(xs, rise, fall, lo, hi):
    """The written-out comparisons of Smoother.smooth equal min()/max() (van Duijn 2014, Eq. 3.2)."""
    from laughlab.signals.smoothing import Smoother, SmootherParams

    s = Smoother(SmootherParams(rise=rise, fall=fall, min_e=lo, max_e=hi), 1 / 60)
    e = 0.0
    for x in xs:
        e = min(x, e + rise * (1 / 60)) if x > e else max(x, e - fall * (1 / 60))
        want = 0.0 if e < lo else 1.0 if e > hi else (e - lo) / (hi - lo)
        assert s.smooth(x) == want
