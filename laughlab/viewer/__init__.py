"""The browser viewer of a run: ``python -m laughlab view RUN_DIR`` (page, script and three.js vendored here)."""

#: the files of a run the viewer plays (``python -m laughlab view``); light, for the run's closing line
NEEDED = ("motion.bvh", "channels.csv", "events.csv")
