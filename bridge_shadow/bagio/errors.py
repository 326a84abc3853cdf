"""Errors of bag reading and writing: each names the file and the problem in one line."""

from __future__ import annotations

from bridge_shadow.errors import BridgeShadowError

__all__ = [
    "BagError",
    "BagExistsError",
    "BagNotFoundError",
    "CorruptBagError",
    "MissingTopicError",
    "NotABagError",
    "UnexpectedTypeError",
]


class BagError(BridgeShadowError):
    """Base of every bag problem; ``str(err)`` is one readable line naming the bag."""


class BagNotFoundError(BagError):
    """The bag path does not exist."""


class NotABagError(BagError):
    """The path exists but is not a rosbag2 directory, ``.db3`` or ``.mcap`` file."""


class MissingTopicError(BagError):
    """A required topic is absent from the bag."""


class UnexpectedTypeError(BagError):
    """A topic carries a message type other than the contract's."""


class CorruptBagError(BagError):
    """The storage is truncated or corrupt, or a message does not decode."""


class BagExistsError(BagError):
    """The output bag exists and overwriting was not requested."""
