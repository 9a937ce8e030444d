"""Pictures of a run: the thesis-style figures, stick figures, and the rendered video scene."""
