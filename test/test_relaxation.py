"""The relaxation allowance after a change: EN 1992-1-1 Annex B's creep coefficient for the deck."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from bridge_shadow.estimate import load_config
from bridge_shadow.estimate.settlement.relaxation import (
    BETA_H_DAYS,
    RELAXATION_PHI0,
    creep_coefficient,
    relaxation_variance,
)
from bridge_shadow.paths import config_file


def _annex_b(fcm: float, rh: float, h0_mm: float, t0_days: float) -> tuple[float, float]:
    """``phi_0`` and ``beta_H`` by EN 1992-1-1 (B.2)-(B.5), (B.8), written out from the standard."""
    a1, a2, a3 = ((35.0 / fcm) ** e for e in (0.7, 0.2, 0.5))
    if fcm <= 35.0:
        phi_rh = 1.0 + (1.0 - rh / 100.0) / (0.1 * h0_mm ** (1.0 / 3.0))
        beta_h = min(1.5 * (1.0 + (0.012 * rh) ** 18) * h0_mm + 250.0, 1500.0)
    else:
        phi_rh = (1.0 + (1.0 - rh / 100.0) / (0.1 * h0_mm ** (1.0 / 3.0)) * a1) * a2
        beta_h = min(1.5 * (1.0 + (0.012 * rh) ** 18) * h0_mm + 250.0 * a3, 1500.0 * a3)
    return phi_rh * (16.8 / math.sqrt(fcm)) / (0.1 + t0_days**0.2), beta_h


def test_the_constants_are_annex_b_for_the_model_deck() -> None:
    """C35/45 (f_cm 43 MPa), the deck of bridge.yaml (h_0 = 2 A_c / u), RH 80 %, six years old."""
    deck = yaml.safe_load(config_file("bridge.yaml").read_text())
    geo = deck.get("geometry", deck)
    b, t = float(geo["deck_width"]), float(geo["slab_thickness"])
    h0_mm = 2.0 * b * t / (2.0 * (b + t)) * 1e3
    phi0, beta_h = _annex_b(43.0, 80.0, h0_mm, 6 * 365.0)
    assert RELAXATION_PHI0 == pytest.approx(phi0, rel=5e-3)
    assert BETA_H_DAYS == pytest.approx(beta_h, rel=5e-3)
    assert load_config().relaxation_phi0 == pytest.approx(RELAXATION_PHI0)


def test_the_creep_coefficient_follows_b7_and_is_a_few_percent_in_the_first_hour() -> None:
    for t_s in (60.0, 720.0, 3600.0, 86400.0):
        t = t_s / 86400.0
        assert creep_coefficient(t_s) == pytest.approx(RELAXATION_PHI0 * (t / (BETA_H_DAYS + t)) ** 0.3)
    assert creep_coefficient(0.0) == 0.0  # exact: 0 ** 0.3
    assert 0.01 < creep_coefficient(60.0) < creep_coefficient(720.0) < creep_coefficient(3600.0) < 0.05


def test_the_variance_lies_along_the_change_only() -> None:
    change = (-24e3, -43e3)  # A dx of a 10 mm lowering, N
    a, b, d = relaxation_variance(change, 720.0, RELAXATION_PHI0)
    m = np.array([[a, b], [b, d]])
    assert np.linalg.matrix_rank(m, tol=1e-9 * a) == 1
    rho = creep_coefficient(720.0)
    np.testing.assert_allclose(m @ np.array(change), rho**2 * np.dot(change, change) * np.array(change))
    assert relaxation_variance(change, 720.0, 0.0) == (0.0, 0.0, 0.0)  # exact: phi_0 = 0 scales to 0
