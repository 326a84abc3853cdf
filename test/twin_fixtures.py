"""Pytest fixtures that write fresh truth-twin bags into a temporary folder.

Register with ``pytest_plugins = ["twin_fixtures"]`` in ``test/conftest.py``. Usage::

    def test_something(synth_bag):
        bag = synth_bag(days=1, rate_hz=0.1, seed=3, effects={"settlement_offset": 7e-4})
        truth = read_truth(bag)          # scoring only

Bags are cached per argument set for the whole session (same arguments, same bag), so several
tests can share one without paying for it twice. The placeholder surrogate is used unless
``surrogate="file"`` is passed, so that fixtures do not change when ``config/surrogate.yaml``
appears.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest


@pytest.fixture(scope="session")
def synth_bag(tmp_path_factory: pytest.TempPathFactory) -> Callable[..., Path]:
    """Return a factory ``synth_bag(days=1, rate_hz=0.1, seed=0, effects=None, storage="sqlite3", ...)``.

    Extra keyword arguments go to ``bridge_shadow.twin.simulate`` (``start``, ``temp_rate_hz``,
    ``steps``, ``config``); ``compress=True`` writes zstd-compressed MCAP. Returns the bag path;
    its truth is ``bag / "truth.yaml"``.
    """
    from bridge_shadow.model.surrogate_file import placeholder_surrogate
    from bridge_shadow.twin.bag import write_twin_bag

    root = tmp_path_factory.mktemp("twin_bags")
    cache: dict[str, Path] = {}

    def make(
        days: float = 1.0,
        rate_hz: float = 0.1,
        seed: int = 0,
        effects: dict[str, float] | None = None,
        storage: str = "sqlite3",
        *,
        compress: bool = False,
        surrogate: str = "placeholder",
        **kwargs: Any,
    ) -> Path:
        key = json.dumps(
            [days, rate_hz, seed, effects or {}, storage, compress, surrogate, repr(sorted(kwargs.items()))],
            sort_keys=True,
        )
        if key not in cache:
            out = root / f"bag_{len(cache):03d}"
            sur = placeholder_surrogate() if surrogate == "placeholder" else None
            write_twin_bag(
                out,
                storage=storage,
                compress=compress,
                days=days,
                rate_hz=rate_hz,
                seed=seed,
                effects=effects,
                surrogate=sur,
                **kwargs,
            )
            cache[key] = out
        return cache[key]

    return make
