"""Extractor ``rms``: the motion control signal (MCS) of van Duijn 2014 (ch. 3.1, listing 5.2).

The method is :mod:`laughlab.signals.mcs`; this module registers it as a plugin.
"""
from laughlab import hookimpl
from laughlab.signals.mcs import RmsExtractor, RmsParams, frame_rms  # noqa: F401 - importable from here as before


@hookimpl
def register_extractors(register):
    register(RmsExtractor)
