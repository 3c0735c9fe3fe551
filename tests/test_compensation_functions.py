"""The compensation building blocks on known inputs (seed §5.2-5.5, appendix C)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from compensation import CompensatorSettings, FlowCurveObserver, SettingsError, make_compensator
from compensation.buffered import ParameterBuffers
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


def test_buffers_give_appendix_c_parameters_and_only_increase():
    n = 1000  # 2 s at 500 Hz holding one period of a 0.5 Hz motion
    buf = ParameterBuffers(1, n, 500.0, 0.032)
    all_legs = np.array([True])
    phase = np.linspace(0, 2 * np.pi, n)
    u, uc = 0.8 * np.sin(phase), 0.2 * np.abs(np.sin(phase))
    for k in range(n):
        uy = np.array([0.03 if k % 50 == 0 else np.nan])
        buf.add(all_legs, np.array([u[k]]), np.array([uc[k]]), uy)
    assert buf.updates == 1
    # the maxima fall in the second half of the buffer, where W(i) = 1/(1 + exp(-10 i/l)) is 0.99…1;
    # the 32 ms low-pass barely touches 0.5 Hz
    assert buf.a[0] == pytest.approx(0.2, rel=0.03)
    assert buf.b[0] == pytest.approx(1 / 0.8, rel=0.03)
    assert 0 < buf.c[0] / buf.b[0] <= 0.03  # b times the mean of the filtered UY (0.03 V samples)
    a1, b1 = buf.a[0], buf.b[0]
    for k in range(n):  # a second buffer with half the compensation: a and b are kept
        buf.add(all_legs, np.array([u[k]]), np.array([0.5 * uc[k]]), np.array([np.nan]))
    assert buf.updates == 2 and buf.a[0] == a1 and buf.b[0] == b1


def test_buffered_amplitude_is_limited_to_a_quarter_of_the_valve_range():
    """A buffer that saw a small valve range but large u_v - ydot/s (e.g. shorter than the motion's period)
    must not set a above q/4 = 1/(4 b) (safety bound, as the iterative compensators)."""
    n = 500
    buf = ParameterBuffers(1, n, 500.0, 0.032)
    phase = np.linspace(0, 2 * np.pi, n)
    for k in range(n):
        buf.add(np.array([True]), np.array([0.4 * np.sin(phase[k])]), np.array([3.0]), np.array([np.nan]))
    assert buf.b[0] == pytest.approx(1 / 0.4, rel=0.03)
    assert buf.a[0] == pytest.approx(0.25 / buf.b[0])


def test_settings_are_validated():
    with pytest.raises(SettingsError, match="buffer_time"):
        CompensatorSettings(buffer_time=0)
    with pytest.raises(SettingsError, match="unknown compensator"):
        make_compensator("magic", 6, 500.0)
    with pytest.raises(SettingsError, match="PlantTruth"):
        make_compensator("oracle", 6, 500.0)
