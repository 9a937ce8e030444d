"""A user's humanoid avatar (VRM 0.x, VRM 1.0, or a glTF/GLB with known bone names) driven by a run."""


def sink_character(params):
    """The avatar (:class:`laughlab.avatar.load.Avatar`) a sink's ``character`` parameter names (the top-level
    ``character=PATH`` sets it), loaded as the sink is built, so a bad file stops the run before anything is
    written; None without one (and nothing imported: a run without an avatar does not load the glTF reader)."""
    path = getattr(params, "character", None)
    if not path:
        return None
    from laughlab.avatar.load import load_character

    return load_character(path)
