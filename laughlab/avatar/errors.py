"""The error of a file that is not a usable avatar (:mod:`laughlab.avatar.load`, :mod:`laughlab.avatar.check`)."""


class AvatarError(ValueError):
    """A file that is not a usable humanoid avatar."""
