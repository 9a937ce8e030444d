"""Faces: FACS action units with ARKit names, the contextual Gaussian lip/jaw model (Ding et al. 2014), blinks (van Duijn 2014)."""
