"""Errors raised by the FE solver; each is a :class:`BridgeShadowError` the CLI prints in one line."""

from __future__ import annotations

from bridge_shadow.errors import BridgeShadowError, ConfigError

__all__ = ["FEError", "ModelError", "SolverError"]


class FEError(BridgeShadowError):
    """Base of the FE solver's errors."""


class ModelError(FEError, ConfigError):
    """The model is inconsistent (bad index, unknown tag or support, bad constraint topology)."""


class SolverError(FEError):
    """The system cannot be solved (singular stiffness: a mechanism or missing supports)."""
