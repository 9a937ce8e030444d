"""laughlab: audio-driven laughter animation, a plugin-based research framework."""
from .plugins import hookimpl

__version__ = "0.1.0"
__all__ = ["hookimpl", "__version__"]
