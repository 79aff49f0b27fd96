"""Exception root of the models package."""


class ModelError(Exception):
    """Root of every error raised by :mod:`models`."""


class ModelConfigError(ModelError, ValueError):
    """A model parameter is out of range; the message names the value and its consequence."""


class IdentificationError(ModelError, ValueError):
    """The data cannot support the requested identification; the message says what is missing."""
