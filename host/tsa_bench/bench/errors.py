"""The error of a bench file that cannot be used."""


class BenchConfigError(ValueError):
    """A bench file that cannot be used; the message names file, position and key."""
