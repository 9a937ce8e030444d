"""Old import paths (laughlab 0.1's flat modules) keep working, with a DeprecationWarning.

``import laughlab.bases`` gives ``laughlab.core.bases``, and so on; user plugins written
against 0.1 load unchanged.  New code imports the public names from ``laughlab`` itself
(``from laughlab import hookimpl, Extractor, Control``) or from the subpackages.
"""
from __future__ import annotations

import importlib
import importlib.util
import sys
import warnings

#: laughlab 0.1 module -> where it lives now
MOVED = {
    "frame": "core.frame", "bases": "core.bases", "hookspecs": "core.hookspecs", "plugins": "core.plugins",
    "pipeline": "core.pipeline", "mixer": "core.mixer", "errors": "core.errors", "outfiles": "core.outfiles",
    "audio": "io.audio", "bvh": "io.bvh", "textgrid": "io.textgrid", "vmc": "io.vmc",
    "smoothing": "signals.smoothing", "prosody": "signals.prosody",
    "detector_fit": "detector.fit",
    "lung": "hill.lung", "hill_kernel": "hill.kernel", "hill_fit": "hill.fit",
    "hill_live": "hill.live", "hill_presets": "hill.presets",
    "facs": "face.facs", "cgm": "face.cgm", "blink": "face.blink",
    "segments": "concat.segments", "head_motion": "concat.head_motion",
    "skeleton": "motion.skeleton", "clips": "motion.clips", "noise": "motion.noise",
    "figure": "render.figure", "plots": "render.plots",
    "events": "harness.events",
}


class _Alias:
    """Resolve ``laughlab.<old>`` to the module it moved to.

    A finder and loader by protocol (``find_spec``, ``create_module``, ``exec_module``), not by the
    ``importlib.abc`` classes: importing those pulls in tempfile, random and typing (40 ms here), all before
    ``python -m laughlab`` can install its signal handler.
    """

    def find_spec(self, fullname, path=None, target=None):
        pkg, _, name = fullname.partition(".")
        if pkg != "laughlab" or name not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        return None  # a fresh module that shares the moved module's objects (classes stay identical)

    def exec_module(self, module):
        new = "laughlab." + MOVED[module.__name__.split(".", 1)[1]]
        warnings.warn(f"{module.__name__} moved to {new}; import from there (public names: from laughlab import ...)",
                      DeprecationWarning, stacklevel=2)
        target = importlib.import_module(new)
        module.__dict__.update({k: v for k, v in vars(target).items()
                                if k not in ("__name__", "__spec__", "__loader__", "__package__", "__path__")})


def install() -> None:
    if not any(isinstance(f, _Alias) for f in sys.meta_path):
        sys.meta_path.append(_Alias())
