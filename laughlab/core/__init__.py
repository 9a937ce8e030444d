"""The framework: frames, plugin interfaces, hookspecs, the registry, the pipeline, the mixer, errors, safe output files."""
