"""Exception root of the adapters package."""


class AdapterError(Exception):
    """Root of every error raised by :mod:`adapters`."""


class DataFileError(AdapterError, ValueError):
    """A data file cannot be read as the expected table; the message names file, line and column."""
