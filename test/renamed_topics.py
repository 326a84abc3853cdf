"""A bag whose input topics carry other names than the contract's (for the ``topic_*`` parameters)."""

from __future__ import annotations

from pathlib import Path

RENAMED = {
    "topic_frc_01": "/site/south_bearing/force",
    "topic_frc_02": "/site/north_bearing/force",
    "topic_air_temperature": "/site/weather/air_temperature",
    "topic_mean": "/site/shadow/settlement_mean",
}


def renamed_bag(src: Path, dst: Path) -> Path:
    """Copy a bag's input messages, byte for byte, under the topic names of ``RENAMED``."""
    from bridge_shadow.bagio import BagOutputWriter, read_raw_topics
    from bridge_shadow.contract import FORCE_TOPICS, INPUT_TOPICS, TEMPERATURE_TOPIC

    names = {
        FORCE_TOPICS["frc_01"]: RENAMED["topic_frc_01"],
        FORCE_TOPICS["frc_02"]: RENAMED["topic_frc_02"],
        TEMPERATURE_TOPIC: RENAMED["topic_air_temperature"],
    }
    with BagOutputWriter(dst) as writer:
        for topic, (log_ns, raws) in read_raw_topics(src, INPUT_TOPICS).items():
            writer.write_many_raw(names[topic], INPUT_TOPICS[topic], log_ns, raws)
    return dst
