"""A user's humanoid avatar (VRM 0.x, VRM 1.0, or a glTF/GLB with known bone names) driven by a run."""
