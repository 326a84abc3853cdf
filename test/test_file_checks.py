"""The limits of the file checks, pinned: a surrogate's symmetry and conditioning, the key suggested.

``SYMMETRY_RTOL`` and ``MAX_CONDITION`` (``model.surrogate_file``) and ``SIMILARITY``
(``keys``): a value just inside each limit is taken, one just outside is refused with its line,
and the committed surrogates sit far inside.
"""

from __future__ import annotations

import numpy as np
import pytest

from bridge_shadow.errors import ConfigError
from bridge_shadow.keys import did_you_mean
from bridge_shadow.model.surrogate_file import (
    MAX_CONDITION,
    SYMMETRY_RTOL,
    Surrogate,
    check_surrogate,
    load_surrogate,
)

U0 = np.array([2.4e5, 2.4e5])


def _with_eigenvalues(low: float, high: float) -> np.ndarray:
    """A symmetric (2, 2) N/m with these eigenvalues, eigenvectors the common and differential modes."""
    q = np.array([[1.0, 1.0], [1.0, -1.0]]) / np.sqrt(2.0)
    return q @ np.diag([low, high]) @ q.T


def test_the_committed_surrogates_are_far_inside_the_limits(root) -> None:
    for name in ("surrogate.yaml", "surrogate_fe.yaml"):
        s = load_surrogate(root / "config" / name)
        a = s.A
        assert abs(a[0, 1] - a[1, 0]) / np.abs(a).max() < 1e-3 * SYMMETRY_RTOL
        cond = check_surrogate(s)
        assert cond == pytest.approx(s.condition_number, rel=1e-9) and cond < 10.0


def test_symmetry_tolerance() -> None:
    a = _with_eigenvalues(5.6e6, 2.9e7)
    scale = np.abs(a).max()
    for rel, ok in ((0.5 * SYMMETRY_RTOL, True), (2.0 * SYMMETRY_RTOL, False)):
        skew = a + np.array([[0.0, rel * scale], [0.0, 0.0]])
        if ok:
            check_surrogate(Surrogate(skew, U0))
        else:
            with pytest.raises(ConfigError, match="A must be symmetric"):
                check_surrogate(Surrogate(skew, U0))


def test_condition_limit_and_definiteness() -> None:
    high = 2.9e7
    assert check_surrogate(Surrogate(_with_eigenvalues(high / (0.5 * MAX_CONDITION), high), U0)) == (
        pytest.approx(0.5 * MAX_CONDITION, rel=1e-3)
    )
    with pytest.raises(ConfigError, match=r"too ill-conditioned .* condition number 2e\+11"):
        check_surrogate(Surrogate(_with_eigenvalues(high / (2.0 * MAX_CONDITION), high), U0))
    for low in (0.0, -1e5):  # a mode no reaction feels; one that pushes back the wrong way
        with pytest.raises(ConfigError, match="A must be positive definite"):
            check_surrogate(Surrogate(_with_eigenvalues(low, high), U0))
    with pytest.raises(ConfigError, match="u0 must be finite"):
        check_surrogate(Surrogate(_with_eigenvalues(5.6e6, high), [np.nan, 2.4e5]))


def test_the_key_suggested() -> None:
    known = ["window_s", "window_min_samples", "prior_sigma_m"]
    assert did_you_mean("windw_s", known) == " (did you mean window_s?)"  # one letter left out
    assert did_you_mean("prior_sigma_mm", known) == " (did you mean prior_sigma_m?)"
    assert did_you_mean("colour", known) == ""  # nothing close: no guess
