"""The skinned character: a procedural human mesh on the project's skeleton, with face and breathing morphs."""
