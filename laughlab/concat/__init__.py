"""Segment concatenation (Ding et al. 2014, 4.2): motion segments, selection costs, head and eyebrow motion."""
