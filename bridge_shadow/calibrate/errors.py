"""Errors of the calibration (one readable line each; the CLI prints them without a traceback)."""

from __future__ import annotations

from bridge_shadow.errors import BridgeShadowError

__all__ = ["CalibrationError"]


class CalibrationError(BridgeShadowError):
    """The calibration input cannot be used (records, imposed settlements, parameter names)."""
