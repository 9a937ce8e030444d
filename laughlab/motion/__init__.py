"""Body motion primitives: the humanoid skeleton and forward kinematics, the clip library, seeded noise."""
