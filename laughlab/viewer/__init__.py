"""The browser viewer of a run: ``python -m laughlab view RUN_DIR`` (page, script and three.js vendored here)."""
