"""Control signals from audio: the thesis' rate-limited MCS smoothing (van Duijn 2014), offline Praat prosody (Ding et al. 2014)."""
