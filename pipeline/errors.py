"""Exception root of the numerical core."""


class PipelineError(Exception):
    """Root of every error raised by :mod:`pipeline`."""


class PipelineConfigError(PipelineError, ValueError):
    """A configuration value is out of range; the message names the value and its consequence."""


class SignalError(PipelineError, ValueError):
    """An input array cannot be analysed (wrong shape, non-finite values, too short)."""
