"""Write rosbag2 bags (sqlite3 or MCAP): the monitoring topics fast, output messages by type."""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Iterable, Mapping, Sequence
from functools import lru_cache
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from bridge_shadow.bagio.cdr import encode_stamped_floats
from bridge_shadow.bagio.errors import BagError, BagExistsError, UnexpectedTypeError
from bridge_shadow.contract import (
    CHANNELS,
    DIAGNOSTICS_TYPE,
    FLOAT_ARRAY_TYPE,
    FORCE_TOPICS,
    FORCE_TYPE,
    INPUT_TOPICS,
    OUTPUT_TOPICS,
    TEMPERATURE_TOPIC,
    TEMPERATURE_TYPE,
)
from bridge_shadow.series import MonitoringData

__all__ = ["STORAGES", "BagOutputWriter", "check_bag_target", "get_typestore", "write_monitoring"]

#: Storage plugins a bag can be written with.
STORAGES: tuple[str, ...] = ("sqlite3", "mcap")
#: Files a bag directory may hold; only such a directory is replaced by ``overwrite=True``.
_BAG_FILE_SUFFIXES = (".db3", ".mcap", ".yaml", ".db3-shm", ".db3-wal", ".zstd", ".md")

_CONTRACT_TYPES: dict[str, str] = {**INPUT_TOPICS, **OUTPUT_TOPICS}


@lru_cache(maxsize=1)
def get_typestore() -> Any:
    """Return the rosbags typestore of ROS 2 Jazzy (built once)."""
    from rosbags.typesys import Stores
    from rosbags.typesys import get_typestore as _get

    return _get(Stores.ROS2_JAZZY)


def _check_target(path: Path, overwrite: bool) -> None:
    """Refuse an existing target unless asked to overwrite it, and anything that is not a bag.

    Nothing is removed here: the old bag is replaced only once the new one is complete.
    """
    if not path.exists() and not path.is_symlink():
        return
    if not overwrite:
        raise BagExistsError(f"{path}: exists already; pass --force to replace it")
    if path.is_dir() and not path.is_symlink():
        entries = list(path.iterdir())
        looks_like_bag = all(e.is_file() and e.name.endswith(_BAG_FILE_SUFFIXES) for e in entries) and (
            not entries
            or (path / "metadata.yaml").exists()
            or any(e.suffix in (".db3", ".mcap") for e in entries)
        )
        if not looks_like_bag:
            raise BagExistsError(f"{path}: exists and is not a bag; refusing to overwrite it")
    else:
        raise BagExistsError(f"{path}: exists and is not a bag directory; refusing to overwrite it")


def check_bag_target(path: str | Path, overwrite: bool = False, reading: Sequence[str | Path] = ()) -> Path:
    """Check before any work that a bag can be written at ``path``; BagError in one line if not.

    ``reading``: the bags (or files) the command reads. The target may be none of them, nor hold
    one, nor lie inside one: ``--force`` replaces an output, never the input (``replay BAG --out
    BAG --force`` replaced the records it had just read by its outputs).
    """
    from bridge_shadow.fileio import check_output_dir

    target = Path(path)
    where = target.resolve()
    for source in reading:
        read = Path(source).resolve()
        how = (
            "is the input"
            if where == read
            else "holds the input"
            if where in read.parents
            else "lies inside the input"
            if read in where.parents
            else None
        )
        if how is not None:
            raise BagError(
                f"{target}: {how} {source}; write the outputs to another place (--force replaces "
                "an output, never the input)"
            )
    _check_target(target, overwrite)
    if not target.exists():
        check_output_dir(target, "bag")
    return target


def _storage_plugin(storage: str) -> Any:
    from rosbags.rosbag2 import StoragePlugin

    if storage not in STORAGES:
        raise BagError(f"unknown bag storage {storage!r}; choose one of {', '.join(STORAGES)}")
    return StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP


class BagOutputWriter:
    """Context manager writing messages to a new rosbag2 bag by topic and log time.

    Connections are created on first use of a topic; contract topics must carry their contract
    type. The typed helpers take plain numbers and strings (SI units), so callers need not
    build rosbags message objects::

        with BagOutputWriter(out, "mcap") as bag:
            bag.write_wrench("/bridge_shadow/compensated/frc_01", t_ns, t_ns, "frc_01", 2.6e5)
            bag.write_float64_array("/bridge_shadow/settlement/mean", t_ns, [1e-4, -2e-4], ["support"])

    The bag is closed (metadata written, readable) on leaving the block, also after an error.
    """

    def __init__(
        self, path: str | Path, storage: str = "sqlite3", *, overwrite: bool = False, compress: bool = False
    ) -> None:
        self.path = Path(path)
        self.storage = storage
        self._plugin = _storage_plugin(storage)
        if compress and storage != "mcap":
            raise BagError(f"{self.path}: compression is available for mcap storage only")
        self._overwrite = overwrite
        self._compress = compress
        self._writer: Any = None
        self._stage: Path | None = None
        self._connections: dict[tuple[str, str], Any] = {}
        self._templates: dict[tuple[tuple[str, ...], tuple[int, ...]], bytes] = {}
        self.counts: dict[str, int] = {}

    @property
    def staged_path(self) -> Path:
        """Where the bag is being written (renamed to ``path`` when the block succeeds)."""
        return self._stage / self.path.name

    def __enter__(self) -> BagOutputWriter:
        from rosbags.rosbag2 import Writer, WriterError

        from bridge_shadow.fileio import remove_orphans, temp_name

        check_bag_target(self.path, self._overwrite)
        remove_orphans(self.path)
        self._stage = temp_name(self.path)
        try:
            self._stage.parent.mkdir(parents=True, exist_ok=True)
            self._stage.mkdir()
            self._writer = Writer(self.staged_path, version=9, storage_plugin=self._plugin)
            if self._compress:  # zstd-compressed MCAP chunks, transparent to every MCAP reader
                from rosbags.rosbag2 import CompressionFormat, CompressionMode

                self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
            self._writer.open()
        except BaseException as err:  # also an interrupt while opening: no stage is left behind
            self._discard()
            if isinstance(err, (WriterError, OSError)):
                raise BagError(f"{self.path}: cannot create bag: {err}") from None
            raise
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def close(self) -> None:
        """Write the metadata, close the storage and move the bag into place (idempotent).

        With ``overwrite`` the old bag is replaced only now, when the new one is complete.
        """
        writer, self._writer = self._writer, None
        if writer is None:
            return
        try:
            writer.close()
            self._commit()
        except BaseException as err:
            self._discard()
            if isinstance(err, OSError):
                raise BagError(f"{self.path}: cannot write bag: {err.strerror or err}") from None
            raise

    def abort(self) -> None:
        """Close and remove the unfinished bag; the target (and an old bag there) stays as it was."""
        writer, self._writer = self._writer, None
        if writer is not None:
            with contextlib.suppress(Exception):
                writer.close()
        self._discard()

    def _commit(self) -> None:
        assert self._stage is not None
        old = None
        if self.path.exists() or self.path.is_symlink():
            _check_target(self.path, self._overwrite)  # it may have appeared while we wrote
            old = self._stage / f".old-{self.path.name}"  # removed with the stage directory
            os.replace(self.path, old)
        try:
            os.replace(self.staged_path, self.path)
        except BaseException:  # an error or an interrupt between the two renames: the old bag returns
            if old is not None and not (self.path.exists() or self.path.is_symlink()):
                os.replace(old, self.path)
            raise
        self._discard()

    def _discard(self) -> None:
        stage = getattr(self, "_stage", None)
        if stage is not None and stage.exists():
            shutil.rmtree(stage, ignore_errors=True)

    def _connection(self, topic: str, msgtype: str) -> Any:
        key = (topic, msgtype)
        conn = self._connections.get(key)
        if conn is None:
            if self._writer is None:
                raise BagError(f"{self.path}: bag is not open (use BagOutputWriter as a context manager)")
            expected = _CONTRACT_TYPES.get(topic)
            if expected is not None and expected != msgtype:
                raise UnexpectedTypeError(f"{self.path}: topic {topic} takes {expected}, not {msgtype}")
            conn = self._writer.add_connection(topic, msgtype, typestore=get_typestore())
            self._connections[key] = conn
            self.counts.setdefault(topic, 0)
        return conn

    def write_raw(self, topic: str, msgtype: str, log_ns: int, raw: bytes) -> None:
        """Write one already serialized CDR message."""
        self._writer.write(self._connection(topic, msgtype), int(log_ns), raw)
        self.counts[topic] += 1

    def write_many_raw(self, topic: str, msgtype: str, log_ns: Iterable[int], raws: Iterable[bytes]) -> None:
        """Write many serialized messages of one topic."""
        conn = self._connection(topic, msgtype)
        write = self._writer.write
        n = 0
        for t, raw in zip(log_ns, raws, strict=True):
            write(conn, int(t), raw)
            n += 1
        self.counts[topic] += n

    def write_merged(
        self, conns: Sequence[Any], which: np.ndarray, log_ns: np.ndarray, raws: Sequence[bytes]
    ) -> None:
        """Write messages of several connections, already in log-time order (``which``: index into ``conns``).

        Into sqlite3 storage one ``executemany`` into rosbags' own ``messages`` table (its open
        cursor, the statement its ``write`` runs per message): a 100 Hz day is 17 M messages, and
        the per-message call was most of ``synth --archive``'s time. The writer's counts and time
        range are kept as its ``write`` keeps them; other storage writes message by message.
        """
        from rosbags.rosbag2 import CompressionMode
        from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer

        writer = self._writer
        storage = getattr(writer, "storage", None)
        if not isinstance(storage, Sqlite3Writer) or writer.compression_mode != CompressionMode.NONE:
            write = writer.write
            for k, t, raw in zip(which.tolist(), log_ns.tolist(), raws, strict=True):
                write(conns[k], t, raw)
            return
        if not len(log_ns):
            return
        ids = np.array([c.id for c in conns], np.int64)[which]
        storage.cursor.executemany(
            "INSERT INTO messages (topic_id, timestamp, data) VALUES(?, ?, ?)",
            zip(ids.tolist(), log_ns.tolist(), raws, strict=True),
        )
        for k, n in enumerate(np.bincount(which, minlength=len(conns)).tolist()):
            writer.counts[conns[k].id] += n
        writer.min_timestamp = min(writer.min_timestamp, int(log_ns.min()))
        writer.max_timestamp = max(writer.max_timestamp, int(log_ns.max()))

    def write_message(self, topic: str, msg: Any, log_ns: int) -> None:
        """Serialize a rosbags message object (its ``__msgtype__`` is the type) and write it."""
        msgtype = msg.__msgtype__
        self.write_raw(topic, msgtype, log_ns, bytes(get_typestore().serialize_cdr(msg, msgtype)))

    # typed helpers ---------------------------------------------------------------------------

    def write_wrench(
        self,
        topic: str,
        log_ns: int,
        stamp_ns: int,
        frame_id: str,
        force_z_n: float,
        force_xy_n: tuple[float, float] = (0.0, 0.0),
        torque_nm: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> None:
        """Write a ``geometry_msgs/msg/WrenchStamped`` (force in N, torque in N m)."""
        values = np.array([[*force_xy_n, force_z_n, *torque_nm]], dtype=np.float64)
        (raw,) = encode_stamped_floats(np.array([stamp_ns]), frame_id, values)
        self.write_raw(topic, FORCE_TYPE, log_ns, raw)

    def write_temperature(
        self, topic: str, log_ns: int, stamp_ns: int, frame_id: str, temp_c: float, variance: float = 0.0
    ) -> None:
        """Write a ``sensor_msgs/msg/Temperature`` (C, C^2)."""
        (raw,) = encode_stamped_floats(np.array([stamp_ns]), frame_id, np.array([[temp_c, variance]]))
        self.write_raw(topic, TEMPERATURE_TYPE, log_ns, raw)

    def write_float64_array(
        self,
        topic: str,
        log_ns: int,
        values: np.ndarray | Sequence[float],
        labels: Sequence[str] = (),
    ) -> None:
        """Write a ``std_msgs/msg/Float64MultiArray``; one layout dim per label, row-major strides.

        ``values`` of shape (2,) with ``["support"]`` or (2, 2) with ``["row", "col"]``; no labels
        gives an empty layout.
        """
        ts = get_typestore()
        arr = np.asarray(values, dtype=np.float64)
        shape = arr.shape if labels else ()
        if labels and len(labels) != arr.ndim:
            raise ValueError(f"{len(labels)} layout labels for an array of {arr.ndim} dimensions")
        strides = [int(np.prod(shape[i:])) for i in range(len(shape))]
        dims = [
            ts.types["std_msgs/msg/MultiArrayDimension"](label=str(lab), size=int(size), stride=stride)
            for lab, size, stride in zip(labels, shape, strides, strict=False)
        ]
        layout = ts.types["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=0)
        msg = ts.types[FLOAT_ARRAY_TYPE](layout=layout, data=np.ascontiguousarray(arr.ravel()))
        self.write_message(topic, msg, log_ns)

    def float64_array_raws(self, values: np.ndarray, labels: Sequence[str] = ()) -> list[bytes]:
        """Serialize many ``Float64MultiArray`` of one shape at once (for ``write_raw``).

        ``values`` is ``(n, *shape)``; each message is byte for byte what ``write_float64_array``
        writes: rosbags serializes one template, whose trailing float64 data is then replaced.
        """
        arr = np.ascontiguousarray(values, dtype="<f8")
        n, shape = arr.shape[0], arr.shape[1:]
        if labels and len(labels) != len(shape):
            raise ValueError(f"{len(labels)} layout labels for arrays of {len(shape)} dimensions")
        key = (tuple(labels), shape)
        prefix = self._templates.get(key)
        if prefix is None:
            ts = get_typestore()
            strides = [int(np.prod(shape[i:])) for i in range(len(shape))] if labels else []
            dims = [
                ts.types["std_msgs/msg/MultiArrayDimension"](label=str(lab), size=int(size), stride=stride)
                for lab, size, stride in zip(labels, shape, strides, strict=False)
            ]
            layout = ts.types["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=0)
            size = int(np.prod(shape))
            msg = ts.types[FLOAT_ARRAY_TYPE](layout=layout, data=np.zeros(size))
            template = bytes(ts.serialize_cdr(msg, FLOAT_ARRAY_TYPE))
            prefix = self._templates[key] = template[: len(template) - 8 * size]
        flat = arr.reshape(n, -1)
        return [prefix + row.tobytes() for row in flat]

    def write_diagnostics(
        self,
        topic: str,
        log_ns: int,
        stamp_ns: int,
        statuses: Sequence[Mapping[str, Any]],
        frame_id: str = "",
    ) -> None:
        """Write a ``diagnostic_msgs/msg/DiagnosticArray``.

        Each status is ``{"name", "level" (0 OK, 1 WARN, 2 ERROR, 3 STALE), "message",
        "hardware_id" (optional), "values" (optional mapping; a str value as it is, any other
        as JSON text: ``kv_text``)}``.
        """
        ts = get_typestore()
        status_t = ts.types["diagnostic_msgs/msg/DiagnosticStatus"]
        kv_t = ts.types["diagnostic_msgs/msg/KeyValue"]
        items = [
            status_t(
                level=int(s.get("level", 0)),
                name=str(s["name"]),
                message=str(s.get("message", "")),
                hardware_id=str(s.get("hardware_id", "")),
                values=[kv_t(key=str(k), value=kv_text(v)) for k, v in dict(s.get("values", {})).items()],
            )
            for s in statuses
        ]
        msg = ts.types[DIAGNOSTICS_TYPE](header=_header(stamp_ns, frame_id), status=items)
        self.write_message(topic, msg, log_ns)


def kv_text(value: Any) -> str:
    """Return a diagnostic value as text another program parses: a str as is, else JSON.

    ``str()`` wrote numpy reprs (``[np.float64(-1.78e-06), ...]``) and Python dicts (``{'nonfinite':
    7}``), which no JSON reader takes; non-finite numbers are ``null``, as in every JSON written.
    """
    import json

    from bridge_shadow.jsonvalues import jsonable

    return value if isinstance(value, str) else json.dumps(jsonable(value), allow_nan=False)


def _header(stamp_ns: int, frame_id: str) -> Any:
    ts = get_typestore()
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    stamp = ts.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
    return ts.types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)


def write_monitoring(
    path: str | Path,
    data: MonitoringData,
    storage: str = "sqlite3",
    *,
    overwrite: bool = False,
    compress: bool = False,
    extra_files: Mapping[str, str] | None = None,
) -> Path:
    """Write the three contract input topics, merged in log-time order, CDR built with numpy.

    Ties in log time keep the order frc_01, frc_02, temperature. Every topic gets a connection,
    even when its series is empty. ``compress`` (mcap only) zstd-compresses the MCAP chunks
    (about 3.5x smaller bags). ``extra_files`` (name -> text) go into the bag directory with it
    (a twin's ground-truth file): the bag appears complete with them, or not at all.

    Returns:
        the bag path.

    Raises:
        BagExistsError: the path exists and ``overwrite`` is False (or it is not a bag).

    """
    path = Path(path)
    topics = [FORCE_TOPICS[ch] for ch in CHANNELS] + [TEMPERATURE_TOPIC]
    types = [FORCE_TYPE] * len(CHANNELS) + [TEMPERATURE_TYPE]
    raws: list[bytes] = []
    logs = []
    which = []
    for k, ch in enumerate(CHANNELS):
        s = data.forces[ch]
        values = np.zeros((len(s), 6))
        values[:, 2] = s.force_n
        raws += encode_stamped_floats(s.stamp_ns, s.frame_id, values)
        logs.append(s.log_ns)
        which.append(np.full(len(s), k, dtype=np.int64))
    t = data.temperature
    raws += encode_stamped_floats(t.stamp_ns, t.frame_id, np.column_stack([t.temp_c, t.variance]))
    logs.append(t.log_ns)
    which.append(np.full(len(t), len(CHANNELS), dtype=np.int64))
    log_ns = np.concatenate(logs)
    topic_idx = np.concatenate(which)
    order = np.argsort(log_ns, kind="stable")
    with BagOutputWriter(path, storage, overwrite=overwrite, compress=compress) as bag:
        conns = [bag._connection(topic, msgtype) for topic, msgtype in zip(topics, types, strict=True)]
        bag.write_merged(conns, topic_idx[order], log_ns[order], [raws[i] for i in order.tolist()])
        for idx, topic in enumerate(topics):
            bag.counts[topic] = int(np.count_nonzero(topic_idx == idx))
        for name, text in (extra_files or {}).items():
            (bag.staged_path / name).write_text(text, encoding="utf-8")
    return path
