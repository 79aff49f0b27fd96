"""Exception root of the service package."""


class ServiceError(Exception):
    """Root of every error raised by :mod:`service`."""


class UsageError(ServiceError):
    """The command line or the configuration asks for something that cannot be done."""
