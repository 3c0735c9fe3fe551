"""hexsim.measured.statistics on small arrays, against scipy's own regression statistics."""

import numpy as np
import pytest
from scipy import optimize, stats

from hexsim.measured.statistics import fit_statistics


def test_a_straight_line_gets_linregress_standard_errors():
    rng = np.random.default_rng(1)
    x = np.linspace(0.0, 2.0, 40)
    y = 0.3 + 1.7 * x + rng.normal(0.0, 0.05, x.size)
    ref = stats.linregress(x, y)
    design = np.column_stack([np.ones_like(x), x])
    fun = y - design @ np.array([ref.intercept, ref.slope])
    s = fit_statistics(design, fun)
    np.testing.assert_allclose(s.std_errors, [ref.intercept_stderr, ref.stderr], rtol=1e-10)
    # intercept and slope of a line over x >= 0 are negatively correlated: -mean(x) / rms(x)
    assert s.correlation[0, 1] == pytest.approx(-np.mean(x) / np.sqrt(np.mean(x * x)), rel=1e-10)


def test_a_nonlinear_fit_gets_curve_fits_covariance():
    rng = np.random.default_rng(2)
    t = np.linspace(0.0, 1.0, 60)

    def decay(t, a, k):
        return a * np.exp(-k * t)

    y = decay(t, 2.0, 3.0) + rng.normal(0.0, 0.02, t.size)
    popt, pcov = optimize.curve_fit(decay, t, y, p0=(1.0, 1.0))
    sol = optimize.least_squares(lambda p: decay(t, *p) - y, (1.0, 1.0), x_scale="jac", xtol=1e-14, ftol=1e-14)
    np.testing.assert_allclose(sol.x, popt, rtol=1e-6)
    s = fit_statistics(sol.jac, sol.fun)
    np.testing.assert_allclose(s.covariance, pcov, rtol=1e-4)


def test_a_parameter_at_its_bound_has_no_error_and_no_correlation():
    jac = np.array([[1.0, 0.5, 0.0], [1.0, 1.0, 1.0], [1.0, 2.0, 0.5], [1.0, 3.0, 2.0]])
    fun = np.array([0.1, -0.2, 0.05, 0.02])
    s = fit_statistics(jac, fun, free=np.array([True, False, True]), fill=np.nan)
    assert np.isnan(s.std_errors[1]) and np.all(np.isfinite(s.std_errors[[0, 2]]))
    assert s.covariance.shape == (2, 2)
    assert s.correlation[1, 0] == 0.0 and s.correlation[1, 1] == 1.0
    alone = fit_statistics(jac[:, [0, 2]], fun, n_parameters=3)  # the bound column dropped by hand
    np.testing.assert_allclose(s.std_errors[[0, 2]], alone.std_errors, rtol=1e-12)


def test_fewer_independent_residuals_widen_the_errors():
    rng = np.random.default_rng(3)
    jac = rng.normal(size=(200, 3))
    fun = rng.normal(size=200)
    white = fit_statistics(jac, fun)
    correlated = fit_statistics(jac, fun, n_independent=50)
    np.testing.assert_allclose(correlated.std_errors / white.std_errors, np.sqrt((200 - 3) / (50 - 3)), rtol=1e-12)


def test_a_direction_the_data_does_not_see_has_zero_variance():
    jac = np.column_stack([np.arange(5.0), np.zeros(5)])
    s = fit_statistics(jac, np.array([0.1, -0.1, 0.2, 0.0, -0.2]))
    assert s.std_errors[1] == 0.0 and s.std_errors[0] > 0


def test_mismatched_shapes_are_refused():
    with pytest.raises(ValueError, match="do not match"):
        fit_statistics(np.ones((4, 2)), np.ones(3))
