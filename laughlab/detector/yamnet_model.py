"""The bundled YAMNet file, loaded and split in its own layers (``laughlab.detector.yamnet`` uses it).

YAMNet (tensorflow/models, ``research/audioset/yamnet``; Apache-2.0) is a MobileNet v1 trained on
AudioSet's 521 classes.  The bundled file (``laughlab/data/yamnet/``, see ``PROVENANCE.md`` there)
takes one window of :data:`WINDOW` = 15,600 samples (0.975 s) of 16 kHz mono float audio in [-1, 1]
and returns the 521 class scores in the order of ``yamnet_class_map.csv``.  It runs with
``ai-edge-litert`` (Google's LiteRT interpreter, on PyPI), one thread, no network.  :class:`Yamnet`
checks the file (sha256), cuts it into its front end and its network (``_Layout``, bit for bit the
whole file's scores) and loads each part once per thread.
"""
from __future__ import annotations

import copy
import csv
import hashlib
import threading
from importlib import resources
from pathlib import Path

import numpy as np

from laughlab.core.quiet import quiet_stderr as _quiet_stderr  # LiteRT's C++ logging on fd 2

#: the model's input: samples at 16 kHz (0.975 s)
RATE = 16000
WINDOW = 15600
N_CLASSES = 521
#: the AudioSet laughter classes (display names of the class map)
LAUGH_CLASSES = ("Laughter", "Baby laughter", "Giggle", "Snicker", "Belly laugh", "Chuckle, chortle")
#: YAMNet's classes of the human voice's other non-speech sounds (AudioSet ontology, "Human voice" and
#: "Respiratory sounds"): where one of them outscores laughter, the gate does not take the window as laughter
OTHER_HUMAN_CLASSES = ("Screaming", "Crying, sobbing", "Baby cry, infant cry", "Whimper", "Wail, moan", "Sigh",
                       "Groan", "Grunt", "Breathing", "Wheeze", "Snoring", "Gasp", "Pant", "Snort", "Cough",
                       "Throat clearing", "Sneeze", "Sniff", "Burping, eructation", "Hiccup")
#: YAMNet's classes of steady noise (AudioSet ontology, "Noise" and its children that a room or a device makes): where
#: one of them scores above ``detector.noise_veto`` and above laughter, the head's probability does not count
NOISE_CLASSES = ("White noise", "Pink noise", "Static", "Noise", "Hiss", "Environmental noise")
#: ... above this (the live gate's ``detector.noise_veto`` and ``laughlab detect``'s; chosen on the train split)
NOISE_VETO = 0.1
MODEL_SHA256 = "469be6a3421cbc52cf97e9f2f966cba984198e8e7af9854d68b3e3ebb1e04194"
RESTORE = ("restore it with `git checkout laughlab/data/yamnet` in a source checkout, "
           "or reinstall laughlab (pip install --force-reinstall laughlab)")


def noise_vetoes(noise: float, laughter: float, at: float = NOISE_VETO) -> bool:
    """Does a window's steady-noise score (:data:`NOISE_CLASSES`) veto the head: above ``at`` and above the laughter
    classes' score?  One rule for the live gate, ``laughlab detect`` and ``yamnet_fit --rules``."""
    return noise > max(at, laughter)


class ModelFileError(ValueError):
    """The model file is missing or not the bundled YAMNet: the message names the file and the fix."""


def data_dir() -> Path:
    return Path(str(resources.files("laughlab").joinpath("data", "yamnet")))


def class_names(path: str | Path | None = None) -> list[str]:
    p = Path(path) if path is not None else data_dir() / "yamnet_class_map.csv"
    try:
        with open(p, newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise ModelFileError(f"cannot read the YAMNet class map {p} ({exc.strerror}): {RESTORE}") from None
    names = [r[2] for r in rows[1:] if len(r) >= 3]
    if rows[:1] != [["index", "mid", "display_name"]] or len(names) != N_CLASSES:
        raise ModelFileError(f"the YAMNet class map {p} is damaged (expected {N_CLASSES} classes): {RESTORE}")
    return names


def laugh_indices(names: list[str], classes: tuple[str, ...] = LAUGH_CLASSES) -> list[int]:
    return [names.index(n) for n in classes]


#: The bundled model's layout, checked when it is loaded (``_Layout``).  The file computes, for one window:
#: 96 frames of 400 samples every 160 (ops 0-4, a reshape and a gather: ``frames``), their log-mel rows
#: (ops 5-14: Hann window, a 512-point DFT and a 64-band mel matrix as int8-weight matrix products with
#: the inputs quantized row by row, magnitude, log: ``FRONT``), the rows as a 96 x 64 patch (ops 15-18),
#: and the MobileNet v1 with its classifier (ops 19-59: ``NET``).  Each row depends on its own frame only,
#: so rows are computed once and kept while the windows overlap.  Both are bit for bit the whole file's
#: result (``tests/test_yamnet.py``), so the split changes no score.
FRAME, HOP, ROWS, BANDS = 400, 160, 96, 64
FRONT = (5, 15, 79, 89)            # (first op, end op, input tensor, output tensor)
NET = (19, 60, 93, 123)
#: the network's 14 layers (a convolution, then 13 depthwise + pointwise pairs) and the classifier: the first
#: op and the input tensor of each layer from the 4th (layers 1-3 are one piece, ops 19-23), and the end
LAYERS = {1: (19, 93), 4: (24, 98), 5: (27, 100), 6: (30, 102), 7: (33, 104), 8: (36, 106), 9: (39, 108),
          10: (42, 110), 11: (45, 112), 12: (48, 114), 13: (51, 116), 14: (54, 118), 15: (60, 123)}
#: ``model_frames`` -> the layers each of its parts starts at (the last part ends with the classifier).  The
#: window's own frame also converts its block and computes one or two rows, so its part is the lightest.
#: Medians of 150 calls of each part in turn (2026-11-26): 4 parts at layers 1-3, 4-7, 8-11, 12-14: 0.59,
#: 0.81, 0.88, 0.76 ms (1-3, 4-6, 7-10, 11-14: 0.59, 0.72, 0.78, 0.99 ms); 3 parts, 1-3, 4-9, 10-14: 0.80,
#: 1.53, 1.47 ms, the machine slower (1-4, 5-9, 10-14: 1.12, 1.18, 1.41 ms; 1-3, 4-8, 9-14: 0.79, 1.26, 1.64).
CUTS = {1: (1,), 2: (1, 10), 3: (1, 4, 10), 4: (1, 4, 8, 12)}
#: frames the live front end takes per call
SMALL = 8


def frame_starts(end: int) -> np.ndarray:
    """The first 16 kHz sample of each of a window's 96 frames, for the window ending at sample ``end``."""
    return end - WINDOW + HOP * np.arange(ROWS)


def frames_at(samples: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """The 400-sample frames of ``samples`` starting at ``starts`` (a copy, (len(starts), 400)).

    The frames are read through a strided view of ``samples`` made directly (numpy's
    ``sliding_window_view`` takes 0.05 ms to make the same view: as long as computing a log-mel row)."""
    x = np.ascontiguousarray(samples, np.float32)
    if x.ndim != 1 or len(x) < FRAME:
        return np.lib.stride_tricks.sliding_window_view(x, FRAME)[starts]
    return np.ndarray((len(x) - FRAME + 1, FRAME), np.float32, x, 0, (x.itemsize, x.itemsize))[starts]


def frames(window: np.ndarray) -> np.ndarray:
    """The window's 96 frames (96, 400) as the model cuts them (ops 0-4: 15,600 = 195 x 80 samples)."""
    return frames_at(window, HOP * np.arange(ROWS))


class _Layout:
    """The bundled file parsed, and its pieces as TensorFlow Lite files of their own (bytes): ``front`` (the
    log-mel rows), ``net`` (the network) and ``parts(n)``, the network cut in ``n`` parts at ``CUTS[n]``
    (made when first asked for: about 35 ms each).

    The ops, tensors and weights are the bundled file's; each piece keeps only the tensors and buffers its
    ops use.  Raises ValueError when ``data`` is not laid out as the bundled YAMNet."""

    def __init__(self, data: bytes):
        from ai_edge_litert import schema_py_generated as fb

        self.model = model = fb.ModelT.InitFromObj(fb.Model.GetRootAsModel(data, 0))
        g = model.subgraphs[0]
        codes = {v: k for k, v in vars(fb.BuiltinOperator).items() if not k.startswith("_")}

        def opname(i):
            c = model.operatorCodes[g.operators[i].opcodeIndex]
            return codes.get(max(c.builtinCode, c.deprecatedBuiltinCode))

        shape = {t: list(g.tensors[t].shape) for t in (79, 89, 93, 123)} if len(g.tensors) > 123 else {}
        if (len(g.operators) != 60 or opname(5) != "MUL" or opname(14) != "LOG" or opname(19) != "CONV_2D"
                or opname(59) != "LOGISTIC" or shape.get(79) != [ROWS, FRAME] or shape.get(89) != [ROWS, BANDS]
                or shape.get(93) != [1, ROWS, BANDS, 1] or shape.get(123) != [1, N_CLASSES]):
            raise ValueError("its layers are not YAMNet's")
        self.front, self.net = self.piece(*FRONT), self.piece(*NET)
        self._parts: dict = {}
        self._lock = threading.Lock()

    def parts(self, n: int) -> list:
        with self._lock:
            if n not in self._parts:
                starts = [LAYERS[k] for k in CUTS[n]] + [LAYERS[15]]
                self._parts[n] = [self.piece(a[0], b[0], a[1], b[1]) for a, b in zip(starts, starts[1:])]
            return self._parts[n]

    def piece(self, first: int, end: int, t_in: int, t_out: int) -> bytes:
        """Ops ``first`` to ``end`` - 1, from tensor ``t_in`` to tensor ``t_out``, as a file of their own."""
        import flatbuffers

        model = self.model
        g = model.subgraphs[0]
        ops = g.operators[first:end]
        used = sorted({int(t) for o in ops for t in list(o.inputs) + list(o.outputs) if t >= 0} | {t_in, t_out})
        tmap = {t: i for i, t in enumerate(used)}
        bufs = [0] + sorted({int(g.tensors[t].buffer) for t in used} - {0})
        bmap = {b: i for i, b in enumerate(bufs)}
        tensors = []
        for t in used:
            tt = copy.copy(g.tensors[t])
            tt.buffer = bmap[int(tt.buffer)]
            tensors.append(tt)
        new_ops = []
        for o in ops:
            oo = copy.copy(o)
            oo.inputs = np.array([tmap[int(t)] if t >= 0 else -1 for t in o.inputs], np.int32)
            oo.outputs = np.array([tmap[int(t)] for t in o.outputs], np.int32)
            new_ops.append(oo)
        sg = copy.copy(g)
        sg.tensors, sg.operators = tensors, new_ops
        sg.inputs, sg.outputs = np.array([tmap[t_in]], np.int32), np.array([tmap[t_out]], np.int32)
        m = copy.copy(model)
        m.subgraphs, m.buffers = [sg], [model.buffers[b] for b in bufs]
        m.metadata, m.signatureDefs, m.metadataBuffer = None, None, None
        b = flatbuffers.Builder(1 << 16)
        b.Finish(m.Pack(b), file_identifier=b"TFL3")
        return bytes(b.Output())


class _Runner:
    """One TensorFlow Lite interpreter on one input, its first dimension resized when a call needs it."""

    def __init__(self, data: bytes):
        from ai_edge_litert.interpreter import Interpreter

        with _quiet_stderr():  # LiteRT prints "INFO: Created TensorFlow Lite XNNPACK delegate" on fd 2
            self.it = Interpreter(model_content=data, num_threads=1)
            self.it.allocate_tensors()
        self._in = self.it.get_input_details()[0]["index"]
        self._out = self.it.get_output_details()[0]["index"]
        self.shape = tuple(self.it.get_input_details()[0]["shape"])

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.ascontiguousarray(x, np.float32)
        if x.shape != self.shape:
            self.it.resize_tensor_input(self._in, list(x.shape))
            self.it.allocate_tensors()
            self.shape = x.shape
        self.it.set_tensor(self._in, x)
        self.it.invoke()
        return self.it.get_tensor(self._out).copy()


class _Models:
    """The interpreters of one thread (an interpreter is used by one call at a time)."""

    def __init__(self, data: bytes, split: _Layout):
        self.data, self.split = data, split
        self.front = _Runner(split.front)         # SMALL rows at a time, never resized (a resize costs 0.3 ms)
        self.net = _Runner(split.net)             # one patch at a time, never resized
        self._front_many = self._net_many = None  # many rows / patches at once (offline), resized as needed
        self._front_few: dict = {}                # n < SMALL rows at a time, one interpreter per n (never resized)
        self._parts: dict = {}                    # model_frames -> its parts' interpreters
        self._full = None
        self.lock = threading.Lock()
        self.front(np.zeros((SMALL, FRAME), np.float32))

    @property
    def front_many(self) -> _Runner:
        if self._front_many is None:
            self._front_many = _Runner(self.split.front)
        return self._front_many

    def front_few(self, n: int) -> _Runner:
        r = self._front_few.get(n)
        if r is None:
            r = self._front_few[n] = _Runner(self.split.front)
            r(np.zeros((n, FRAME), np.float32))
        return r

    @property
    def net_many(self) -> _Runner:
        if self._net_many is None:
            self._net_many = _Runner(self.split.net)
        return self._net_many

    def parts(self, n: int) -> list:
        if n not in self._parts:
            self._parts[n] = [_Runner(d) for d in self.split.parts(n)]
        return self._parts[n]

    @property
    def full(self) -> _Runner:
        if self._full is None:
            self._full = _Runner(self.data)
        return self._full


#: loaded models by (file, bundled, size, mtime, thread): a changed file is read and checked again
_LOADED: dict = {}
#: the split files by (file, size, mtime): made once per process
_SPLIT: dict = {}


class Yamnet:
    """The bundled YAMNet: ``scores(window)`` -> 521 class scores of one 0.975 s window at 16 kHz.

    The work is split as the file's own layers are (``FRONT``, ``NET``): ``logmel(frames)`` gives the
    log-mel rows of 400-sample frames, ``network(patches)`` the scores of 96 x 64 patches of rows (many
    at once), ``part(i, x, n)`` part ``i`` of the network cut in ``n``.  Each is bit for bit the whole file's result."""

    def __init__(self, path: str | Path | None = None):
        p = Path(path) if path is not None else data_dir() / "yamnet.tflite"
        self.path, self.bundled = p, path is None
        try:
            st = p.stat()
        except OSError as exc:
            raise ModelFileError(f"cannot read the YAMNet model {p} ({exc.strerror or exc}): {RESTORE}") from None
        fkey = (str(p.resolve()), path is None, st.st_size, st.st_mtime_ns)
        key = (*fkey, threading.get_ident())
        cached = _LOADED.get(key)
        if cached is None:
            cached = _LOADED[key] = self._load(p, path is None, fkey)
        self.m = cached

    @staticmethod
    def _load(p: Path, bundled: bool, fkey) -> _Models:
        """Read, check and split the model file once per process, load it once per thread (an interpreter
        holds no state between windows, so runs in one thread share it: the fuzz suite and the harness build
        many pipelines)."""
        try:
            data = p.read_bytes()
        except OSError as exc:
            raise ModelFileError(f"cannot read the YAMNet model {p} ({exc.strerror or exc}): {RESTORE}") from None
        if bundled and hashlib.sha256(data).hexdigest() != MODEL_SHA256:
            raise ModelFileError(f"the YAMNet model {p} is damaged (sha256 differs from the bundled file's): {RESTORE}")
        try:
            import ai_edge_litert.interpreter  # noqa: F401
        except ImportError:
            raise ModelFileError("the yamnet detector needs ai-edge-litert (pip install ai-edge-litert); "
                                 "where it has no wheel (Intel Macs), use detector=laugh or detector=none") from None
        split = _SPLIT.get(fkey)
        try:
            if split is None:
                split = _SPLIT[fkey] = _Layout(data)
            return _Models(data, split)
        except (ValueError, RuntimeError, IndexError, TypeError, AttributeError) as exc:
            msg = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
            raise ModelFileError(f"{p} is not the YAMNet model ({msg}): {RESTORE}") from None

    def logmel(self, frames: np.ndarray) -> np.ndarray:
        """The log-mel rows (n, 64) of ``n`` frames of 400 samples (the file's ops 5-14).

        Up to 32 frames go in ``SMALL`` at a time and the rest (fewer than ``SMALL``) in an interpreter made
        for that many: rows do not depend on each other, and no interpreter is resized on the live path (the
        window's own frame computes one or two rows: 0.04 ms, against 0.08 ms padded to ``SMALL``).  More
        than 32 go in at once."""
        x = np.asarray(frames, np.float32).reshape(-1, FRAME)
        n = len(x)
        with self.m.lock:
            if n > 4 * SMALL:
                return self.m.front_many(x)
            full = n - n % SMALL
            out = [self.m.front(x[i:i + SMALL]) for i in range(0, full, SMALL)]
            if full < n:
                out.append(self.m.front_few(n - full)(x[full:]))
            return out[0] if len(out) == 1 else np.concatenate(out) if out else np.empty((0, BANDS), np.float32)

    def network(self, patches: np.ndarray) -> np.ndarray:
        """The 521 scores (float64) of each 96 x 64 patch of log-mel rows: (n, 96, 64) -> (n, 521)."""
        x = np.asarray(patches, np.float32).reshape(-1, ROWS, BANDS, 1)
        with self.m.lock:
            return (self.m.net if len(x) == 1 else self.m.net_many)(x).astype(np.float64)

    def load_parts(self, n: int) -> None:
        """Make the network's ``n`` parts and their interpreters now (about 50 ms), not on the first window."""
        with self.m.lock:
            self.m.parts(n)

    def part(self, i: int, x: np.ndarray, n: int) -> np.ndarray:
        """Part ``i`` of the network cut in ``n`` parts (``CUTS``) on one patch (part 0) or on the output of
        part ``i`` - 1; the last part gives the (1, 521) scores."""
        x = np.asarray(x, np.float32)
        if i == 0:
            x = x.reshape(1, ROWS, BANDS, 1)
        with self.m.lock:
            return self.m.parts(n)[i](x)

    def scores(self, window: np.ndarray) -> np.ndarray:
        """The 521 scores of one window (``WINDOW`` samples at 16 kHz, float in [-1, 1]).

        Safe from any thread: the interpreters are used by one call at a time (LiteRT releases the GIL
        while it runs, so a call in a helper thread leaves the frame thread free)."""
        return self.network(self.logmel(frames(window)))[0]

    def whole_file_scores(self, window: np.ndarray) -> np.ndarray:
        """The scores by the unsplit file, in one call (the reference the split is tested against)."""
        with self.m.lock:
            return self.m.full(np.asarray(window, np.float32).reshape(1, WINDOW))[0].astype(np.float64)
