"""Fourier functional models of periodic motion and emotion blending (Unuma, Anjyo & Takeuchi 1995)."""
