"""Seeded synthetic laughter with ground truth: the built-in default input."""
