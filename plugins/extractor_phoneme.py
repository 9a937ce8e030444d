"""Extractor ``phoneme``: online laughter pseudo-phonemes, prosody and call onsets (Ding et al. 2014, 3-4).

The method is :mod:`laughlab.signals.phonemes`; this module registers it as a plugin.
"""
from laughlab import hookimpl
from laughlab.signals.phonemes import PhonemeExtractor, PhonemeParams  # noqa: F401 - importable from here as before


@hookimpl
def register_extractors(register):
    register(PhonemeExtractor)
