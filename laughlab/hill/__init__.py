"""The Hill-muscle torso and lungs (DiLorenzo, Zordan & Sanders 2008): model, compiled step, presets, audio fitting, live control."""
