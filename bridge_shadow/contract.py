"""The machine interface of bridge_shadow: topics, message types, frames and units.

This module is the one source of the contract of DESIGN section 4. Units are SI everywhere:
forces in N (compression positive), settlements in m (positive upward), temperature in C.
"""

from __future__ import annotations

__all__ = [
    "CHANNELS",
    "COMPENSATED_TOPICS",
    "COVARIANCE_TOPIC",
    "DIAGNOSTICS_TOPIC",
    "FORCE_FRAMES",
    "FORCE_TOPICS",
    "FORCE_TYPE",
    "MEAN_TOPIC",
    "NODE_NAME",
    "RECORD_FILE_SUFFIXES",
    "SUPPORTS",
    "TEMPERATURE_FRAME",
    "TEMPERATURE_TOPIC",
    "TEMPERATURE_TYPE",
]

#: Load-cell channels, in the order used by every array ``[south, north]``.
CHANNELS: tuple[str, str] = ("frc_01", "frc_02")
#: Human names of the two central bearings, same order as ``CHANNELS``.
SUPPORTS: tuple[str, str] = ("south", "north")

FORCE_TYPE = "geometry_msgs/msg/WrenchStamped"
TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"
FLOAT_ARRAY_TYPE = "std_msgs/msg/Float64MultiArray"
DIAGNOSTICS_TYPE = "diagnostic_msgs/msg/DiagnosticArray"

#: Input topics: bearing reaction in ``wrench.force.z`` (N, compression positive).
FORCE_TOPICS: dict[str, str] = {ch: f"/bridge/{ch}/force" for ch in CHANNELS}
#: Expected ``header.frame_id`` of each force channel.
FORCE_FRAMES: dict[str, str] = {ch: ch for ch in CHANNELS}
#: Input topic: air temperature at the bridge (C); ``variance`` 0 if unknown.
TEMPERATURE_TOPIC = "/bridge/air_temperature"
TEMPERATURE_FRAME = "air_temperature"

NODE_NAME = "bridge_shadow"
#: ``[south, north]`` in m; layout dim label ``support``.
MEAN_TOPIC = "/bridge_shadow/settlement/mean"
#: 2x2 row-major in m^2; layout dims ``row``, ``col``.
COVARIANCE_TOPIC = "/bridge_shadow/settlement/covariance"
#: Temperature-compensated forces, same message type and frame as the input.
COMPENSATED_TOPICS: dict[str, str] = {ch: f"/bridge_shadow/compensated/{ch}" for ch in CHANNELS}
DIAGNOSTICS_TOPIC = "/diagnostics"

MEAN_LAYOUT_LABEL = "support"
COVARIANCE_LAYOUT_LABELS = ("row", "col")

#: File endings of munich-bridge-data records, which ``import-csv`` turns into a bag (a CSV, or a
#: zip holding some; a folder given is read for its files with these endings), any case.
RECORD_FILE_SUFFIXES: tuple[str, str] = (".csv", ".zip")

#: Every input topic with its type, for bag readers and writers.
INPUT_TOPICS: dict[str, str] = {
    **{topic: FORCE_TYPE for topic in FORCE_TOPICS.values()},
    TEMPERATURE_TOPIC: TEMPERATURE_TYPE,
}
#: Every output topic with its type (the node publishes exactly these).
OUTPUT_TOPICS: dict[str, str] = {
    MEAN_TOPIC: FLOAT_ARRAY_TYPE,
    COVARIANCE_TOPIC: FLOAT_ARRAY_TYPE,
    **{topic: FORCE_TYPE for topic in COMPENSATED_TOPICS.values()},
    DIAGNOSTICS_TOPIC: DIAGNOSTICS_TYPE,
}
