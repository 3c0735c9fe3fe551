"""hexsim.measured.statistics on small arrays, against scipy's own regression statistics."""

import numpy as np
import pytest
from scipy import optimize, stats

from hexsim.measured.statistics import effective_groups, fit_statistics


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


def test_residuals_sharing_a_group_error_get_cluster_robust_errors_the_plain_ones_understate():
    """Residuals sharing an error within each of 40 groups (as a replay window shares its start's): over 400 draws
    the sandwich's standard errors match the estimates' own spread (intercept and slope within 15 %), where
    s² (JᵀJ)⁻¹ puts the intercept's at under half of it. With no more groups than parameters it is not used."""
    rng = np.random.default_rng(7)
    groups, size = 40, 25
    ids = np.repeat(np.arange(groups), size)
    x = rng.uniform(-1.0, 1.0, groups * size)
    design = np.column_stack([np.ones_like(x), x])
    estimates, robust, plain = [], [], []
    for _ in range(400):
        y = 0.3 + 1.7 * x + rng.normal(0.0, 0.1, groups)[ids] + rng.normal(0.0, 0.05, x.size)
        coef = np.linalg.lstsq(design, y, rcond=None)[0]
        fun = y - design @ coef
        estimates.append(coef)
        robust.append(fit_statistics(design, fun, clusters=ids).std_errors)
        plain.append(fit_statistics(design, fun).std_errors)
    spread = np.std(estimates, axis=0)
    np.testing.assert_allclose(np.mean(robust, axis=0), spread, rtol=0.15)
    assert np.mean(plain, axis=0)[0] < 0.5 * spread[0]
    assert fit_statistics(design, fun, clusters=ids).clustered
    few = fit_statistics(design, fun, clusters=np.minimum(ids, 1))
    np.testing.assert_allclose(few.std_errors, fit_statistics(design, fun).std_errors, rtol=1e-12)
    with pytest.raises(ValueError, match="clusters"):
        fit_statistics(design, fun, clusters=ids[:-1])


def test_a_sandwich_that_one_group_carries_is_not_used():
    """40 groups, one of which the model misses by 50 times the others' scatter (as a replay window the model
    cannot follow): the sandwich would be that group's alone, a rank-one covariance with the slope's and the
    intercept's errors locked together; the groups count as about one, fewer than the two parameters, and the
    covariance is s² (JᵀJ)⁻¹. Equal shares count as every group (Kish's effective number)."""
    rng = np.random.default_rng(3)
    ids = np.repeat(np.arange(40), 25)
    x = rng.uniform(-1.0, 1.0, ids.size)
    design = np.column_stack([np.ones_like(x), x])
    fun = rng.normal(0.0, 0.05, x.size)
    fun[ids == 7] += 2.5 * (1.0 + x[ids == 7])
    fun -= design @ np.linalg.lstsq(design, fun, rcond=None)[0]  # residuals at the least-squares optimum
    s = fit_statistics(design, fun, clusters=ids)
    assert s.effective_groups < 2 and not s.clustered
    np.testing.assert_allclose(s.std_errors, fit_statistics(design, fun).std_errors, rtol=1e-12)
    assert effective_groups(np.eye(5), np.eye(5)) == pytest.approx(5.0)
    assert effective_groups(np.diag([1.0, 0, 0]), np.eye(3)) == pytest.approx(1.0)
