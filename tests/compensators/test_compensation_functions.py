"""The compensation building blocks on known inputs (seed §5.2-5.5, appendix C)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from compensation import (
    CompensatorSettings,
    FlowCurveObserver,
    SettingsError,
    make_compensator,
)
from compensation.buffered import Buffers, update_parameters
from compensation.functions import function1, function2, signed_sqrt


def test_functions_are_normalised_and_odd():
    a, b = 0.3, 0.8
    u = np.linspace(-1 / b, 1 / b, 2001)
    f2 = function2(u, a, b, 0.0)
    assert f2.max() == pytest.approx(a, rel=1e-4)
    assert u[np.argmax(f2)] == pytest.approx(0.25 / b, abs=2e-3)  # maximum at b u = 1/4
    assert function2(1 / b, a, b, 0.0) == pytest.approx(0.0, abs=1e-12)  # zero again at b u = 1
    np.testing.assert_allclose(f2, -f2[::-1], atol=1e-12)
    f1 = function1(u, a, math.pi * b, 0.0)
    assert f1.max() == pytest.approx(a, rel=1e-4)
    np.testing.assert_allclose(f1, -f1[::-1], atol=1e-12)
    assert signed_sqrt(-4.0) == -2.0
    # c shifts the curve: zero at u = c / b
    assert function2(0.05, a, b, b * 0.05) == pytest.approx(0.0, abs=1e-12)


def test_function2_is_the_exact_compensation_of_the_quadratic_flow_area():
    # Seed eq. (5.1): with a = 300 x_v^2 the static velocity is C u|u|; the desired line s u with
    # s = C u_max needs U_c = u_max [sqrt(u/u_max) - u/u_max] = function (2) with a = u_max/4, b = 1/u_max.
    c_gain, u_max = 0.16, 0.9
    s = c_gain * u_max
    u = np.linspace(-u_max, u_max, 401)
    v = u + function2(u, u_max / 4, 1 / u_max, 0.0)
    np.testing.assert_allclose(c_gain * v * np.abs(v), s * u, atol=1e-12)


def test_observer_recovers_velocity_and_slope_from_noisy_positions():
    rate, f = 500.0, 0.5
    t = np.arange(0, 6, 1 / rate)
    w = 2 * np.pi * f
    y = 0.1 + 0.05 * np.sin(w * t)
    u = 0.9 * np.cos(w * t)  # a valve setpoint in phase with the velocity
    rng = np.random.default_rng(1)
    obs = FlowCurveObserver(1, rate, 20.0)
    vel = np.array([obs.update(np.array([u[k]]), np.array([y[k] + 2e-6 * rng.standard_normal()]))[1][0]
                    for k in range(t.size)])
    true = 0.05 * w * np.cos(w * t)
    lag = int(round(0.012 * rate))  # the 20 Hz Butterworth delays ~12 ms at low frequency
    err = vel[lag + 500:] - true[500:-lag]
    assert np.sqrt(np.mean(err**2)) < 2e-3
    assert obs.slope[0] == pytest.approx(0.05 * w / 0.9, rel=0.03)


def test_observer_filter_is_lfilter_one_sample_at_a_time():
    rng = np.random.default_rng(4)
    u = rng.normal(size=(400, 3))
    y = np.cumsum(rng.normal(size=(400, 3)), axis=0) * 1e-4
    obs = FlowCurveObserver(3, 500.0, 20.0)
    out = np.array([obs.update(u[k], y[k]) for k in range(len(u))])  # (N, 2, 3)
    v_raw = np.diff(y, axis=0, prepend=y[:1]) * 500.0
    assert np.allclose(out[:, 0], lfilter(obs.b, obs.a, u, axis=0), rtol=0, atol=1e-12)
    assert np.allclose(out[:, 1], lfilter(obs.b, obs.a, v_raw, axis=0), rtol=0, atol=1e-12)


def test_the_per_sample_sections_are_sosfilt_one_sample_at_a_time():
    """The model-based compensators' loop and pressure filters step scipy.signal.sosfilt's recursion one
    controller sample at a time (compensation.base.sos_tick): the same outputs and state as sosfilt on the
    whole record, to the bit, for a 2nd- and a 4th-order Butterworth started from sosfilt_zi."""
    from scipy.signal import butter, sosfilt, sosfilt_zi

    from compensation.base import sos_tick

    rng = np.random.default_rng(7)
    x = rng.normal(size=(300, 3)) * np.array([1.0, 1e5, 1e-3])
    for order, cutoff in ((2, 0.04), (4, 0.3)):
        sos = butter(order, cutoff, output="sos")
        zi = sosfilt_zi(sos)[:, :, None] * x[0][None, None, :]
        want, zf = sosfilt(sos, x, axis=0, zi=zi.copy())
        got, out = np.empty_like(x), np.empty(3)
        for k in range(len(x)):
            sos_tick(sos, zi, x[k], out)
            got[k] = out
        assert np.array_equal(got, want) and np.array_equal(zi, zf)


POLE = math.exp(-1.0 / (500.0 * 0.032))  # appendix C's 32 ms low-pass at 500 Hz


def _fill_and_update(B, uv, uc, uy):
    """Put one full buffer of samples (L,) into set 0, leg 0 and run appendix C's update."""
    B.uv[0, :, 0], B.uc[0, :, 0], B.uy[0, :, 0] = uv, uc, uy
    B.fill[0, 0] = len(uv)
    update_parameters(B, 0, 0, POLE, np.empty(len(uv)))


def _appendix_c(uv, uc, uy, a_old, b_old):
    """Appendix C written out with scipy: filter, weight, a = max, b = 1/max|.|, c = b mean(filtered UY)."""
    num, den = [1.0 - POLE], [1.0, -POLE]
    w = 1.0 / (1.0 + np.exp(-10.0 * np.arange(1, len(uv) + 1) / len(uv)))
    b = max(b_old, 1.0 / np.abs(lfilter(num, den, uv) * w).max())
    a = min(max(a_old, (lfilter(num, den, uc) * w).max()), 0.25 / b)
    kept = uy[np.isfinite(uy)]
    return a, b, b * np.mean(lfilter(num, den, kept))


def test_buffer_update_is_appendix_c():
    rng = np.random.default_rng(2)
    n = 700
    uv, uc = rng.normal(0, 0.5, n), rng.normal(0, 0.05, n) + 0.1
    uy = np.where(rng.random(n) < 0.1, rng.normal(0.02, 0.005, n), np.nan)
    B = Buffers.empty(1, n, 1)
    _fill_and_update(B, uv, uc, uy)
    np.testing.assert_allclose(B.abc[0, :, 0], _appendix_c(uv, uc, uy, 0.0, 0.0), rtol=1e-12)
    assert B.fill[0, 0] == 0 and np.all(np.isnan(B.uy))  # emptied for the next round


def test_buffers_give_appendix_c_parameters_and_only_increase():
    n = 1000  # 2 s at 500 Hz holding one period of a 0.5 Hz motion
    B = Buffers.empty(1, n, 1)
    phase = np.linspace(0, 2 * np.pi, n)
    u, uc = 0.8 * np.sin(phase), 0.2 * np.abs(np.sin(phase))
    uy = np.where(np.arange(n) % 50 == 0, 0.03, np.nan)
    _fill_and_update(B, u, uc, uy)
    a, b, c = B.abc[0, :, 0]
    # the maxima fall in the second half of the buffer, where W(i) = 1/(1 + exp(-10 i/l)) is 0.99…1;
    # the 32 ms low-pass barely touches 0.5 Hz
    assert a == pytest.approx(0.2, rel=0.03)
    assert b == pytest.approx(1 / 0.8, rel=0.03)
    assert 0 < c / b <= 0.03  # b times the mean of the filtered UY (0.03 V samples)
    _fill_and_update(B, u, 0.5 * uc, np.full(n, np.nan))  # half the compensation: a and b are kept
    assert B.abc[0, 0, 0] == a and B.abc[0, 1, 0] == b and B.abc[0, 2, 0] == c  # no UY samples: c kept


def test_a_buffer_of_a_platform_standing_still_teaches_nothing():
    """After a motion's update, a buffer of a platform standing still (the P output the sensor's noise, mV) leaves
    a, b, c as they were: b = 1/q of the noise grew without bound before, and the directional compensator's U_c
    reached 2000 V three seconds after a heave stopped (the buffered one dithered at 28x the seat threshold)."""
    n = 1000
    B = Buffers.empty(1, n, 1)
    phase = np.linspace(0, 2 * np.pi, n)
    _fill_and_update(B, 0.8 * np.sin(phase), 0.2 * np.abs(np.sin(phase)), np.where(np.arange(n) % 50 == 0, 0.03, np.nan))
    moved = B.abc[0, :, 0].copy()
    noise = np.random.default_rng(4).normal(0.0, 0.002, n)
    _fill_and_update(B, noise, noise, noise)
    assert np.array_equal(B.abc[0, :, 0], moved) and B.fill[0, 0] == 0 and np.all(np.isnan(B.uy))


def test_buffered_amplitude_is_limited_to_a_quarter_of_the_valve_range():
    """A buffer that saw a small valve range but large u_v - ydot/s (e.g. shorter than the motion's period)
    must not set a above q/4 = 1/(4 b) (safety bound, as the iterative compensators)."""
    n = 500
    B = Buffers.empty(1, n, 1)
    _fill_and_update(B, 0.4 * np.sin(np.linspace(0, 2 * np.pi, n)), np.full(n, 3.0), np.full(n, np.nan))
    assert B.abc[0, 1, 0] == pytest.approx(1 / 0.4, rel=0.03)
    assert B.abc[0, 0, 0] == pytest.approx(0.25 / B.abc[0, 1, 0])


def test_settings_are_validated():
    with pytest.raises(SettingsError, match="buffer_time"):
        CompensatorSettings(buffer_time=0)
    with pytest.raises(SettingsError, match="unknown compensator"):
        make_compensator("magic", 6, 500.0)
    with pytest.raises(SettingsError, match="PlantTruth"):
        make_compensator("oracle", 6, 500.0)
