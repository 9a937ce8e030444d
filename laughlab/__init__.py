"""laughlab: audio-driven laughter animation, a plugin-based research framework.

The public names a plugin needs are importable from here (lazily, so ``import laughlab``
stays cheap): ``hookimpl``, the plugin bases (``Source``, ``Extractor``, ``Detector``,
``Face``, ``Body``, ``Scheduler``, ``Sink``), ``Context``, ``NoParams``, ``Chunk``,
``RunInfo``, ``Frame``, ``ClipEvent``, ``LaughlabError`` and ``check_range``; and ``Session``, the pipeline
from a Python program's own loop (``laughlab.session``).

Where things live: ``laughlab.core`` (the framework), ``laughlab.io`` (formats),
``laughlab.harness`` (experiments), and one subpackage per method family
(``signals``, ``detector``, ``hill``, ``fourier``, ``face``, ``concat``, ``motion``,
``synth``, ``render``).  The flat module paths of laughlab 0.1 still import, with a
DeprecationWarning (``laughlab._compat``).
"""
from laughlab import _kernels

_kernels.pin()  # before numpy is imported: the same bytes on AVX2 and AVX-512 machines (laughlab/_kernels.py)

from laughlab import _compat  # noqa: E402

__version__ = "0.2.0"

_PUBLIC = {
    "hookimpl": "laughlab.core.plugins", "check_range": "laughlab.core.plugins",
    "LaughlabError": "laughlab.core.errors",
    "Frame": "laughlab.core.frame", "ClipEvent": "laughlab.core.frame",
    "Session": "laughlab.session",   # from Python: feed audio, take frames (docs/pipeline.md)
    **{n: "laughlab.core.bases" for n in ("Source", "Extractor", "Detector", "Face", "Body", "Scheduler",
                                          "Sink", "Plugin", "Context", "NoParams", "Chunk", "RunInfo")},
}
__all__ = [*_PUBLIC, "__version__"]

_compat.install()


def __getattr__(name: str):
    if name in _PUBLIC:
        import importlib

        value = getattr(importlib.import_module(_PUBLIC[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'laughlab' has no attribute {name!r}")
