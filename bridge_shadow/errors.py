"""Exceptions the command line turns into one readable line and a non-zero exit."""

__all__ = ["BridgeShadowError", "ConfigError", "InputError", "ResultError"]


class BridgeShadowError(Exception):
    """Base of every error a user can cause; the CLI prints ``str(err)`` without a traceback."""


class ConfigError(BridgeShadowError):
    """A configuration or parameter file is missing, malformed or inconsistent."""


class InputError(BridgeShadowError):
    """An input file or argument cannot be used (wrong format, out of range, ...)."""


class ResultError(BridgeShadowError):
    """A computed result is not finite: an error, never printed as if it were a result."""
