"""Source ``synthetic``: the built-in seeded laughter generator with its ground truth."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from laughlab import hookimpl
from laughlab.io.audio import FloatWavWriter, cut_frames, n_frames_for
from laughlab.core.bases import Source
from laughlab.core.plugins import check_range
from laughlab.synth.laughter import PROFILES, SyntheticLaughter


@dataclass
class SyntheticParams:
    """Parameters of the ``synthetic`` source.

    Attributes
    ----------
    profile : str
        One of ``laughlab.synth.laughter.PROFILES`` (mixed, mild, intense, ...).
    duration_s : float
        Length of the laughter (s).
    sample_rate : int
        Audio rate (Hz).
    seed : int or None
        Seed of the laughter; None uses the run's ``seed``.
    save_audio : bool
        Write the audio as ``input.wav`` into the run directory, beside ``truth.csv``.
    """

    profile: str = "mixed"
    duration_s: float = 30.0
    sample_rate: int = 16000
    seed: int | None = None
    save_audio: bool = True

    def __post_init__(self) -> None:
        if self.profile not in PROFILES:
            raise ValueError(f"profile must be one of {', '.join(PROFILES)} (got {self.profile!r})")
        check_range("duration_s", self.duration_s, 0, lo_open=True)
        check_range("sample_rate", self.sample_rate, 8000, 192000)
        if self.seed is not None and self.seed < 0:
            raise ValueError(f"seed must be a whole number >= 0 or null (the run's seed), got {self.seed}")


class SyntheticSource(Source):
    """Renders :class:`laughlab.synth.laughter.SyntheticLaughter` block by block (constant memory)."""

    name = "synthetic"
    Params = SyntheticParams

    def open(self) -> None:
        p = self.params
        seed = self.ctx.seed if p.seed is None else p.seed
        self.truth = SyntheticLaughter(seed=seed, duration_s=p.duration_s, sample_rate=p.sample_rate,
                                       profile=p.profile)
        self.sample_rate = p.sample_rate
        self.n_frames = n_frames_for(self.truth.n_samples, p.sample_rate, self.ctx.fps)
        self.duration_s = self.truth.n_samples / p.sample_rate

    def _chunks(self, block: int = 16384):
        for start in range(0, self.truth.n_samples, block):
            yield self.truth.render(start, min(block, self.truth.n_samples - start))

    def blocks(self):
        return cut_frames(self._chunks(), self.sample_rate, self.ctx.fps)

    def save_artifacts(self, out_dir: Path) -> list[Path]:
        """Write ``truth.csv`` (bouts and calls) and, if asked, ``input.wav``; each whole or not at all."""
        from laughlab.core.outfiles import Staging

        staging = Staging()
        try:
            self.truth.write_truth(staging.path(Path(out_dir) / "truth.csv"))
            if self.params.save_audio:
                with FloatWavWriter(staging.path(Path(out_dir) / "input.wav"), self.sample_rate) as f:
                    for chunk in self._chunks():
                        f.write(chunk)
        except BaseException:
            staging.abort()
            raise
        return staging.commit()

    def audio_path(self):
        return None


@hookimpl
def register_sources(register):
    register(SyntheticSource)
