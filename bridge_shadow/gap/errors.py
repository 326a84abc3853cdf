"""Errors of the gap diagnosis (each a ``BridgeShadowError``: one readable line at the CLI)."""

from __future__ import annotations

from bridge_shadow.errors import InputError

__all__ = ["GapError"]


class GapError(InputError):
    """The data cannot be diagnosed (too short, no overlapping force and temperature, ...)."""
