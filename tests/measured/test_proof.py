"""The proof's verdict (``hexsim tune --check``) on small synthetic runs, values worked by hand: a measured run
against its prediction, within the uncertainty the reversal-to-reversal scatter gives, or by how much not and
where (at the reversals, or between them at one valve command: a corner of the flow curve)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hexsim.measured.proof import accelerometer_noise, between_peaks, ratio, verdict
from hexsim.studies.metrics import smoothness

F = 0.5  # Hz: reversals of 0.05 sin(2 pi F t) at t = 0.5, 1.5, 2.5, … s


def run(reversal_bump: float, corner_bump: float, duration: float = 20.0):
    """(t, acceleration, setpoint, valve command) of a 0.5 Hz, 50 mm sine with a 10 ms pulse of ``reversal_bump``
    [m/s^2] at each reversal and one of ``corner_bump`` 0.4 s after it, each scattered ±20 % from reversal to
    reversal, a 5 mm/s^2 ripple at 37 Hz under both; the valve command 2 V |cos(pi t)|, 0 at the reversals
    (2 sin(0.4 pi) = 1.90 V 0.4 s after one)."""
    t = np.arange(0.0, duration, 1e-3)
    setpoint = 0.05 * np.sin(2 * np.pi * F * t)
    acc = -(2 * np.pi * F) ** 2 * setpoint + 0.005 * np.sin(2 * np.pi * 37.0 * t)
    for k in range(int(duration)):
        for at, height in ((0.5 + k, reversal_bump), (0.9 + k, corner_bump)):
            acc += height * (1 + 0.2 * math.sin(1.7 * k)) * np.exp(-0.5 * ((t - at) / 0.005) ** 2)
    return t, acc, setpoint, 2.0 * np.abs(np.sin(2 * np.pi * F * t + np.pi / 2))


def judged(t, acc, setpoint):
    return smoothness(t, acc, F, 4.0, setpoint, name="acceleration", unit="m/s^2")


def test_the_ratio_is_of_geometric_means_with_welchs_interval_on_the_logarithms():
    """Ten peaks 0.027…0.033 m/s^2 against the same three times larger: the ratio 3 exactly, its 95 % interval
    from Welch's t on the logarithms (equal spreads: ln 3 ± t_0.975,18 sqrt(2 s^2 / 10)); against themselves
    1 exactly, within."""
    predicted = np.linspace(0.027, 0.033, 10)
    r = ratio("reversals", 3 * predicted, predicted)
    s = np.std(np.log(predicted), ddof=1)
    half = 2.100922 * math.sqrt(2 * s * s / 10)  # t_0.975 with 18 degrees of freedom
    assert r.ratio == pytest.approx(3.0) and not r.within
    assert (r.low, r.high) == pytest.approx((3 * math.exp(-half), 3 * math.exp(half)), rel=1e-4)
    same = ratio("reversals", predicted[::-1], predicted)
    assert same.ratio == pytest.approx(1.0) and same.within
    assert ratio("reversals", predicted[:2], predicted) is None  # too few to judge


def test_a_run_as_predicted_is_within_its_uncertainty():
    t, acc, setpoint, valve = run(0.1, 0.0)
    v = verdict(judged(t, acc, setpoint), judged(t, acc, setpoint), valve, t)
    assert v.within and v.sentence().startswith("within its uncertainty")


def test_a_bump_at_a_corner_between_reversals_is_placed_at_its_valve_command():
    """Measured: the same reversal bumps and a 0.1 m/s^2 pulse at 1.90 V every half period the prediction lacks.
    The reversals are within (ratio about 1), the stretches between them are not: their peaks about 0.1 against
    the 5 mm/s^2 ripple, more than ten times, at the valve command 2 sin(0.4 pi) = 1.90 V."""
    t, acc, setpoint, valve = run(0.1, 0.1)
    _, predicted_acc, _, _ = run(0.1, 0.0)
    measured, predicted = judged(t, acc, setpoint), judged(t, predicted_acc, setpoint)
    peaks, times = between_peaks(measured)
    assert np.allclose(times % 1.0, 0.9, atol=2e-3) and peaks.size == 15
    v = verdict(measured, predicted, valve, t)
    assert v.reversals.within and not v.between.within and not v.within
    assert v.between.low > 10.0
    assert v.corner_V == pytest.approx(2 * math.sin(0.4 * math.pi), abs=0.01)
    assert "between reversals, at a valve command of 1.90 V" in v.sentence()
    # where the calibration's logs dwelt (the file's calibration.commands_measured_V) says whether it saw 1.90 V
    beyond = verdict(measured, predicted, valve, t, (-0.74, 0.73)).sentence()
    assert "beyond the -0.74…0.73 V the calibration's logs measured" in beyond and "tune --from-logs" in beyond
    inside = verdict(measured, predicted, valve, t, (-2.5, 2.5)).sentence()
    assert "a corner of the flow curve the model lacks? the calibration's logs measured -2.5…2.5 V" in inside


def test_the_accelerometers_white_noise_is_read_under_the_motion_and_a_ringing():
    """0.05 m/s^2 of white noise a 1 kHz sample under a 1 m/s^2, 0.5 Hz motion and a 0.2 m/s^2 ringing at 120 Hz:
    the spectrum's floor gives the noise within 5 %, where the samples' spread is the motion's."""
    t = np.arange(0.0, 30.0, 1e-3)
    acc = (np.sin(2 * np.pi * 0.5 * t) + 0.2 * np.sin(2 * np.pi * 120.0 * t)
           + 0.05 * np.random.default_rng(3).standard_normal(t.size))
    assert accelerometer_noise(t, acc) == pytest.approx(0.05, rel=0.05)
    assert accelerometer_noise(t, np.sin(2 * np.pi * 0.5 * t)) < 1e-3
