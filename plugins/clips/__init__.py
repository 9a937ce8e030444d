"""Bundled full-body laughter clip library (BVH files + ``library.json``).

Regenerate with ``python -m laughlab_plugins.clips.author``; load with
:meth:`laughlab.motion.clips.ClipLibrary.load`.
"""
