"""Keys of a file people write: an unknown one is an error that suggests the key they meant.

Every YAML file the package reads (``config/shadow.yaml`` and ``--params`` files, the calibration
file, ``config/bridge.yaml``, surrogate files) refuses a key it does not know instead of ignoring
it: ``windw_s: 30`` silently left at the default 60 s is worse than an error. The message names
the file's place, the key, and the closest known key::

    config/calibration.yaml: unknown key 'windw_s' (did you mean window_s?)
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable

from bridge_shadow.errors import ConfigError

__all__ = ["SIMILARITY", "check_keys", "did_you_mean"]

#: ``difflib`` ratio above which a known key is offered as the one meant: 0.6 is difflib's own
#: default, which takes one typo in a short key (``windw_s`` ~ ``window_s``: 0.93) and two in a
#: long one, and offers nothing for an unrelated word (``colour`` ~ ``window_s``: 0.29).
SIMILARITY = 0.6


def did_you_mean(key: str, known: Iterable[str]) -> str:
    """Return `` (did you mean NAME?)`` for the closest known key, or ``""`` when none is close."""
    close = difflib.get_close_matches(str(key), [str(k) for k in known], n=1, cutoff=SIMILARITY)
    return f" (did you mean {close[0]}?)" if close else ""


def check_keys(
    given: Iterable[object],
    known: Iterable[str],
    where: str,
    *,
    error: type[Exception] = ConfigError,
    listing: str | None = None,
) -> None:
    """Raise ``error`` (one line) naming the first unknown key of ``given`` and the key meant.

    Args:
        given: the keys of a mapping read from a file.
        known: the keys it may hold.
        where: the file and place, e.g. ``config/calibration.yaml: pairs[0]``.
        error: the exception class to raise (the reader's own, e.g. CalibrationError).
        listing: what to say where the known keys are (default: list them).

    """
    names = list(known)
    unknown = [k for k in given if k not in names]
    if not unknown:
        return
    key = unknown[0]
    more = f" (and {len(unknown) - 1} more)" if len(unknown) > 1 else ""
    hint = did_you_mean(str(key), names)
    see = listing if listing is not None else "known: " + ", ".join(names)
    raise error(f"{where}: unknown key {str(key)!r}{hint}{more}; {see}")
