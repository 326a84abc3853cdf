"""The contract's input messages of a ``MonitoringData``, serialized (CDR) as a node receives them."""

from __future__ import annotations

import numpy as np

from bridge_shadow.bagio import encode_stamped_floats
from bridge_shadow.series import MonitoringData


def raw_inputs(data: MonitoringData) -> list[list[bytes]]:
    """Return the raw messages of frc_01, frc_02 and the air temperature, in that order."""
    out = []
    for ch in ("frc_01", "frc_02"):
        s = data.forces[ch]
        values = np.zeros((len(s), 6))
        values[:, 2] = s.force_n
        out.append(encode_stamped_floats(s.stamp_ns, s.frame_id, values))
    t = data.temperature
    out.append(encode_stamped_floats(t.stamp_ns, t.frame_id, np.column_stack([t.temp_c, t.variance])))
    return out
