"""`replay --surrogate` picks the surrogate (default: the calibrated config/surrogate.yaml)."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import numpy as np

from bridge_shadow.cli import main
from bridge_shadow.model.surrogate_file import load_surrogate


def _replay(argv: list[str]) -> dict:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(argv) == 0
    return json.loads(out.getvalue())


def test_replay_uses_the_calibrated_surrogate_unless_told_otherwise(root) -> None:
    bag = str(root / "bags" / "baseline_1d")
    fe = root / "config" / "surrogate_fe.yaml"
    default = _replay(["replay", bag, "--json"])
    chosen = _replay(["replay", bag, "--json", "--surrogate", str(fe)])
    np.testing.assert_allclose(default["surrogate"]["A"], load_surrogate().A, rtol=1e-12)
    np.testing.assert_allclose(chosen["surrogate"]["A"], load_surrogate(fe).A, rtol=1e-12)
    assert not np.allclose(default["posterior"]["mean_m"], chosen["posterior"]["mean_m"], rtol=1e-3)


def test_a_loaded_surrogate_is_its_own_copy_of_the_file(root) -> None:
    """Loads share one parse of the file, and what a caller changes in one never reaches the next.

    ``load_surrogate`` copies only the six entries it reads (``LOADED_KEYS``), not the sweeps and
    sensitivities beside them; ``read_surrogate_document`` without ``keys`` copies everything.
    """
    from bridge_shadow.model.surrogate_file import LOADED_KEYS, read_surrogate_document

    path = root / "config" / "surrogate.yaml"
    whole = read_surrogate_document(path)
    part = read_surrogate_document(path, LOADED_KEYS)
    assert set(part) == set(whole) and set(whole) - set(LOADED_KEYS) == {"sweeps", "sensitivities"}
    # exact: two copies of one parse (no arithmetic on the numbers)
    assert all(part[k] == whole[k] for k in LOADED_KEYS) and part["sweeps"] is None
    part["provenance"]["solver"] = "changed"
    whole["sweeps"].clear()
    first = load_surrogate(path)
    first.provenance["calibration"]["priors"] = "changed"
    first.thermal["uniform"][:] = 0.0
    again = load_surrogate(path)
    assert again.provenance["solver"].startswith("bridge_shadow.fe")
    assert again.provenance["calibration"]["priors"] == "sources"
    assert np.abs(again.thermal["uniform"]).max() > 0
    assert read_surrogate_document(path)["sweeps"]  # the cached parse kept its sweeps


def test_a_relative_surrogate_path_not_found_names_the_folder_it_was_read_from(tmp_path, monkeypatch) -> None:
    """A relative ``surrogate_path`` is read from the working directory: the error says so."""
    import re

    import pytest

    from bridge_shadow.errors import ConfigError

    monkeypatch.chdir(tmp_path)
    with pytest.raises(
        ConfigError,
        match=rf"s\.yaml: surrogate file not found \(a relative path, read from {re.escape(str(tmp_path))}\)",
    ):
        load_surrogate("s.yaml")
    with pytest.raises(ConfigError, match=r"surrogate file not found$"):  # an absolute one says nothing more
        load_surrogate(tmp_path / "s.yaml")


def test_a_surrogate_path_that_exists_but_is_no_regular_file_is_not_called_missing(tmp_path) -> None:
    """``--surrogate /dev/null`` (or a named pipe) is there: "not found" sent the user looking for it."""
    import os

    import pytest

    from bridge_shadow.errors import ConfigError

    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    for path in (Path(os.devnull), fifo):
        with pytest.raises(ConfigError, match=r"not a regular file, so not a surrogate file"):
            load_surrogate(path)
