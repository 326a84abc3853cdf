"""Bag I/O: rosbags read/write of the contract topics, vectorized CDR codec, typed errors.

No ROS import: bags are read and written with ``rosbags`` in sqlite3 or MCAP storage.
"""

from __future__ import annotations

from bridge_shadow.bagio.cdr import (
    N_FLOATS,
    RawBlock,
    decode_buffer,
    decode_stamped_floats,
    encode_stamped_floats,
)
from bridge_shadow.bagio.errors import (
    BagError,
    BagExistsError,
    BagNotFoundError,
    CorruptBagError,
    MissingTopicError,
    NotABagError,
    UnexpectedTypeError,
)
from bridge_shadow.bagio.reader import (
    bag_summary,
    iter_raw,
    open_bag,
    read_blocks,
    read_monitoring,
    read_raw_topics,
)
from bridge_shadow.bagio.writer import (
    STORAGES,
    BagOutputWriter,
    check_bag_target,
    get_typestore,
    write_monitoring,
)

__all__ = [
    "N_FLOATS",
    "STORAGES",
    "BagError",
    "BagExistsError",
    "BagNotFoundError",
    "BagOutputWriter",
    "CorruptBagError",
    "MissingTopicError",
    "NotABagError",
    "RawBlock",
    "UnexpectedTypeError",
    "bag_summary",
    "check_bag_target",
    "decode_buffer",
    "decode_stamped_floats",
    "encode_stamped_floats",
    "get_typestore",
    "iter_raw",
    "open_bag",
    "read_blocks",
    "read_monitoring",
    "read_raw_topics",
    "write_monitoring",
]
