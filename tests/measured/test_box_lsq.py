"""The bounded least squares of the flow-curve fits (hexsim/measured/box_lsq.py): the same minimum as scipy's
bounded-variable least squares, found by exchanging the bounds held without falling back to it."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear

import hexsim.measured.box_lsq as box


@pytest.mark.parametrize("seed", range(6))
def test_the_exchanges_reach_bvls_minimum_without_falling_back_to_it(seed, monkeypatch):
    """Openings held >= 0 on a curve-like basis (cumulative columns, 80 unknowns, many at their bound): the
    exchanges of the bounds held reach the minimum from the unconstrained solution's guess; with 8 exchanges
    two of these six fell back to bvls (0.7 s each on a calibration's curve)."""
    rng = np.random.default_rng(seed)
    n = 80
    a = np.cumsum(rng.normal(size=(3 * n, n)), axis=1) / np.sqrt(np.arange(1, n + 1))
    r = np.linalg.qr(a, mode="r")
    z = r @ rng.normal(size=n) + 2.0 * rng.normal(size=n)
    lo, hi = np.zeros(n), np.full(n, np.inf)
    expected = lsq_linear(r, z, bounds=(lo, hi), method="bvls").x

    def no_fallback(*args, **kwargs):
        raise AssertionError("box_lsq fell back to bvls")

    monkeypatch.setattr(box, "lsq_linear", no_fallback)
    x, held = box.box_lsq(r, z, lo, hi, np.zeros(n, dtype=int))
    assert np.max(np.abs(x - expected)) < 1e-10
    assert np.any(held) and np.all(x[held < 0] == 0.0)
