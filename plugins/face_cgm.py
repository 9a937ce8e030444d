"""Face ``cgm``: lips and jaw from prosody by contextual Gaussian models (Ding et al. 2014, 4.1, Eqs. 1-3).

One CGM per pseudo-phoneme (:mod:`laughlab.face.cgm`); each frame the mean
``mu(theta_t) = Z Omega_t`` of the current pseudo-phoneme's model, with the
prosody ``theta_t = (intensity dB, F0 Hz)``, gives jaw, lip aperture and
lip-corner pull (Ding's real-time synthesis).  Eyes: the ``smile`` face's clip
keys plus blinks (thesis 3.3.3).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from laughlab import hookimpl
from laughlab.core.bases import Face
from laughlab.face.cgm import CGMSet, load_default
from laughlab.core.errors import LaughlabError
from laughlab.face.facs import Blinker
from laughlab.core.plugins import check_range
from laughlab.concat.segments import PSEUDO_PHONEMES

#: Praat's reference power (2e-5 Pa)^2: intensity dB = 10 log10(mean square / this)
_REF_POWER = 4.0e-10
#: without intensity or RMS, MCS 0..1 maps linearly onto this range of dB (the synthetic
#: laughter's -60 dBFS floor is ~34 dB, its loudest calls ~80 dB)
MCS_DB_RANGE = (35.0, 80.0)

ARKIT_NAMES = ("eyeBlinkLeft", "eyeBlinkRight", "jawOpen", "mouthClose", "mouthSmileLeft", "mouthSmileRight",
               "mouthLowerDownLeft", "mouthLowerDownRight", "mouthUpperUpLeft", "mouthUpperUpRight")
"""The ARKit shapes the ``cgm`` face writes (Apple's order)."""


@dataclass
class CgmParams:
    """Parameters of the ``cgm`` face.

    Attributes
    ----------
    model : str or None
        A fitted model file (``.json`` or ``.npz``, :meth:`laughlab.face.cgm.CGMSet.save`);
        None: the bundled default (fitted on the synthetic laughter, see :mod:`laughlab.face.cgm`).
    join_s : float
        Ding et al. smooth the synthesised signal "at articulation between successive
        pseudo-phonemes": at a label change the jump from the value shown to the
        new model's mean is faded out linearly over this time (s).
    mcs_silence : float
        Without a label: ``silence`` when MCS is below this, else ``unlabelled``.
    unlabelled : str
        The pseudo-phoneme of sounding frames without a label (``vowel``, as the
        ``concat`` scheduler).
    blink_mean_s, blink_sd_s, blink_min_interval_s, blink_close_s, blink_open_s : float
        Blinks as the ``smile`` face: interval ~ N(4 s, 2 s) (thesis 3.3.3).
    """

    model: str | None = None
    join_s: float = 0.06
    mcs_silence: float = 0.1
    unlabelled: str = "vowel"
    blink_mean_s: float = 4.0
    blink_sd_s: float = 2.0
    blink_min_interval_s: float = 0.5
    blink_close_s: float = 0.08
    blink_open_s: float = 0.12

    def __post_init__(self) -> None:
        check_range("join_s", self.join_s, 0)
        check_range("mcs_silence", self.mcs_silence, 0, 1)
        if self.unlabelled not in PSEUDO_PHONEMES:
            raise ValueError(f"unlabelled must be a pseudo-phoneme (got {self.unlabelled!r}); "
                             f"choose from: {', '.join(PSEUDO_PHONEMES)}")
        check_range("blink_mean_s", self.blink_mean_s, 0, lo_open=True)
        check_range("blink_sd_s", self.blink_sd_s, 0)
        check_range("blink_min_interval_s", self.blink_min_interval_s, 0, lo_open=True)
        check_range("blink_close_s", self.blink_close_s, 0, lo_open=True)
        check_range("blink_open_s", self.blink_open_s, 0, lo_open=True)


def intensity_db(control: dict) -> float:
    """The frame's intensity (dB re 2e-5): ``control['intensity']`` (the ``phoneme`` extractor),
    else from ``control['rms']`` (``20 log10(rms / 2e-5)``, the ``rms`` extractor's block RMS; floor 0 dB),
    else ``MCS_DB_RANGE`` mapped linearly from ``control['mcs']`` (0 if absent)."""
    v = control.get("intensity")
    if v is not None:
        return float(v)
    rms = control.get("rms")
    if rms is not None:
        return 10.0 * math.log10(max(float(rms) ** 2, _REF_POWER) / _REF_POWER)
    lo, hi = MCS_DB_RANGE
    return lo + (hi - lo) * float(control.get("mcs", 0.0))


class CgmFace(Face):
    """Jaw, lips and smile from prosody and pseudo-phoneme (Ding et al. 2014, Eqs. 1-3).

    Per frame:

    * label: ``frame.label`` (the ``phoneme`` extractor); without one,
      ``silence`` if MCS < ``mcs_silence`` else ``unlabelled``;
    * context ``theta = (I, F0)``: ``I`` by :func:`intensity_db`; ``F0 =
      control['f0']`` (Hz), but when it is absent or <= 0 (unvoiced) the
      model's mean training F0 of this class (0 for the unvoiced classes, whose
      models do not use F0; for a voiced class an unvoiced frame would otherwise
      pull the mean far outside its training range);
    * ``(jaw, lip_open, lip_corner) = g clip(Z_label Omega_t, 0, 1)`` (Eq. 1),
      with the join smoothing of ``join_s`` (clipped to [0, 1] again); ``g``
      the detector's gain on the face (``control['face_gate']``,
      ``detector=yamnet``; else ``laugh_gate``; 1 with ``detector=none``, the
      paper's face).  Our addition: the prosody is the sound's, ungated, so a
      detector that judged the sound talk left the face talking with it (smile
      above 0.5 on 70% of a Russian speaker's frames; a facial animator's
      review);
    * ``smile`` = ``lip_corner``; ``blink``, ``eyes_closed`` = max(clip eye key, blink);
    * ARKit (``arkit.NAME`` in [0, 1]): ``jawOpen`` = jaw; ``mouthClose`` =
      clip(jaw - lip_open) (lips closer than the jaw); ``mouthLowerDown*``,
      ``mouthUpperUp*`` = clip(lip_open - jaw) (lips parted beyond the jaw);
      ``mouthSmile*`` = lip_corner; ``eyeBlink*`` = eyes_closed.

    A label without a model in the file raises LaughlabError.
    """

    name = "cgm"
    Params = CgmParams

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        p = self.params
        if p.model is None:
            self.model = load_default()
        else:
            try:
                self.model = CGMSet.load(p.model)
            except FileNotFoundError:
                raise LaughlabError(f"CGM model file not found: {p.model}") from None
            except (ValueError, KeyError, OSError) as exc:
                raise LaughlabError(f"cannot read CGM model {p.model}: {exc}") from None
        if self.model.outputs[:3] != ("jaw", "lip_open", "lip_corner") or len(self.model.context) != 2:
            raise LaughlabError(f"CGM model {p.model}: needs outputs jaw, lip_open, lip_corner and context "
                                f"(intensity, f0); has {self.model.outputs} and {self.model.context}")
        # per label: three rows (w_I, w_F0, mu_bar) and the mean training F0
        self._rows = {k: ([tuple(float(v) for v in row) for row in m.Z[:3]],
                          float(m.theta_mean[1]) if m.theta_mean is not None else 0.0)
                      for k, m in self.model.models.items()}
        self.blinker = Blinker(self.ctx.rng, p.blink_mean_s, p.blink_sd_s, p.blink_min_interval_s,
                               p.blink_close_s, p.blink_open_s, dt=self.ctx.dt)
        self.reset()

    def reset(self) -> None:
        self.blinker.reset()
        self.label: str | None = None
        self._shown = (0.0, 0.0, 0.0)
        self._jump = (0.0, 0.0, 0.0)
        self._jump_t = 0.0

    def predict(self, label: str, intensity: float, f0: float) -> tuple[float, float, float]:
        """``clip(mu(theta), 0, 1)`` of the model of ``label`` (Eq. 1), F0 <= 0 replaced as in :meth:`step`."""
        try:
            rows, f0_mean = self._rows[label]
        except KeyError:
            raise LaughlabError(f"the CGM model has no pseudo-phoneme {label!r}; it has: "
                                f"{', '.join(sorted(self._rows))}") from None
        if not f0 > 0.0:
            f0 = f0_mean
        out = []
        for wi, wf, mu in rows:
            v = wi * intensity + wf * f0 + mu
            out.append(0.0 if v < 0.0 else (1.0 if v > 1.0 else v))
        return out[0], out[1], out[2]

    def step(self, frame) -> None:
        p, c = self.params, frame.control
        label = frame.label
        if label is None:
            label = "silence" if c.get("mcs", 0.0) < p.mcs_silence else p.unlabelled
        f0 = c.get("f0")
        mu = self.predict(label, intensity_db(c), 0.0 if f0 is None else float(f0))
        g = c.get("face_gate", c.get("laugh_gate", 1.0))
        if g < 1.0:
            mu = tuple(g * m for m in mu)
        t = frame.time_s
        if label != self.label:
            if self.label is not None:
                self._jump = tuple(s - m for s, m in zip(self._shown, mu))
                self._jump_t = t
            self.label = label
        w = 1.0 - (t - self._jump_t) / p.join_s if p.join_s > 0.0 else 0.0
        if w > 0.0:
            mu = tuple(min(1.0, max(0.0, m + w * j)) for m, j in zip(mu, self._jump))
        self._shown = mu
        jaw, lip, corner = mu
        ch = frame.channels
        ch["jaw"], ch["lip_open"], ch["lip_corner"], ch["smile"] = jaw, lip, corner, corner
        blink = self.blinker.step(t, frame.clip_eyes > 0.0)
        eyes = max(frame.clip_eyes, blink)
        ch["blink"], ch["eyes_closed"] = blink, eyes
        close = jaw - lip if jaw > lip else 0.0
        part = lip - jaw if lip > jaw else 0.0
        arkit = {"eyeBlinkLeft": eyes, "eyeBlinkRight": eyes, "jawOpen": jaw, "mouthClose": close,
                 "mouthSmileLeft": corner, "mouthSmileRight": corner, "mouthLowerDownLeft": part,
                 "mouthLowerDownRight": part, "mouthUpperUpLeft": part, "mouthUpperUpRight": part}
        for name in ARKIT_NAMES:
            ch["arkit." + name] = arkit[name]


@hookimpl
def register_faces(register):
    register(CgmFace)
