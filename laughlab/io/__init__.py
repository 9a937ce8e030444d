"""File and stream formats: audio blocks, BVH, Praat TextGrids, VMC over OSC."""
