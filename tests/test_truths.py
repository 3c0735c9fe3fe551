"""The truths themselves: the independent actuator's integrator converged where its machine is stiffest.

``independent_actuator.motion`` integrates by Dormand-Prince 5(4) under an error control (``_advance``); the
classical RK4 at a fixed small step (``_advance_rk4``) is the reference it is held to. A wide-open valve near the
supply pressure and a piston driven into its end stop (2e8 N/m) are the stiffest states the truth reaches; a sine
is where the reversal bumps are measured."""

from __future__ import annotations

import independent_actuator as ia
import numpy as np
import pytest
from independent_actuator import Actuator, motion

SHARP = Actuator(area="sharp", flow_gain=1.05, overlap=2.0e-5, null_offset=0.04, bulk=1.3e9, mass=42.0, play=0.01)
SPOOL = Actuator(area="spool", underlap=6e-6, rounding=8e-6, port_width=0.85, flow_gain=1.04, k_at=0.93,
                 spool_hz=150.0)


def _both(truth: Actuator, monkeypatch, **kwargs) -> tuple[dict, dict]:
    """The run under the error control, and under RK4 at 1 µs."""
    controlled = motion(truth, noise=(0.0, 0.0, 0.0), rng=np.random.default_rng(1), **kwargs)
    with monkeypatch.context() as patch:  # only this patch undone after the run, not the caller's
        patch.setattr(ia, "_advance", lambda z, u, c, span, h: (ia._advance_rk4(z, u, c, 1e-6, 1000), h))
        fixed = motion(truth, noise=(0.0, 0.0, 0.0), rng=np.random.default_rng(1), **kwargs)
    return controlled, fixed


@pytest.mark.parametrize("truth", [SHARP, SPOOL], ids=["sharp-edged, overlapped", "underlapped spool, 150 Hz"])
def test_the_truths_integrator_holds_on_a_sine_and_into_an_end_stop(truth, monkeypatch):
    """On a sine the logged acceleration within 1e-4 m/s² of RK4 at 1 µs (measured 5e-6; the smallest compensated
    reversal bump the tests read is 1e-3); steps that drive the piston into its end stop (peaks of 1,200-1,600
    m/s²) within 2 m/s² and 2 kPa (measured 0.54 m/s² and 0.25-0.54 kPa; RK4 at 2 µs, the truth's integrator until
    it was error-controlled, was 6 m/s² and 3.5 kPa off RK4 at 0.5 µs on the sharp-edged valve, the error control
    0.9 m/s² and 0.6 kPa)."""
    sine, sine_ref = _both(truth, monkeypatch, duration=2.0, frequency=1.0, amplitude=0.05)
    assert np.max(np.abs(sine["acc_mps2"] - sine_ref["acc_mps2"])) < 1e-4
    assert np.max(np.abs(sine["p1_Pa"] - sine_ref["p1_Pa"])) < 5.0
    steps = 0.25 + 0.1 * np.sign(np.sin(2 * np.pi * np.arange(0.0, 1.2, 1e-3)))  # beyond the 0.2 m stroke
    hit, hit_ref = _both(truth, monkeypatch, duration=1.2, frequency=1.0, amplitude=0.0, reference=steps)
    assert np.max(np.abs(hit_ref["acc_mps2"])) > 1000.0  # the stop was hit
    assert np.max(np.abs(hit["acc_mps2"] - hit_ref["acc_mps2"])) < 2.0
    assert np.max(np.abs(hit["p1_Pa"] - hit_ref["p1_Pa"])) < 2e3
