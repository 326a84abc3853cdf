"""Exceptions the command line turns into one readable line and a non-zero exit."""

__all__ = ["BridgeShadowError", "ConfigError", "InputError"]


class BridgeShadowError(Exception):
    """Base of every error a user can cause; the CLI prints ``str(err)`` without a traceback."""


class ConfigError(BridgeShadowError):
    """A configuration or parameter file is missing, malformed or inconsistent."""


class InputError(BridgeShadowError):
    """An input file or argument cannot be used (wrong format, out of range, ...)."""
