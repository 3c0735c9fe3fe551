"""Helpers shared by test modules (importable as ``helpers``: pytest puts tests/ on sys.path)."""

from __future__ import annotations

import pathlib

import numpy as np
from independent_actuator import Actuator, motion

from compensation import CompensatorSettings, make_compensator
from compensation.leg_model import LegModel, Reference
from hexsim.studies.metrics import smoothness


def write_heave_pitch_profile(path: pathlib.Path, duration: float, heave_m: float) -> pathlib.Path:
    """A ``file:`` scenario: heave ``heave_m`` at 0.5 Hz plus 2° pitch at 1.3 Hz, both faded in over 2 s."""
    t = np.arange(0, duration + 1e-9, 0.01)
    fade = np.clip(t / 2.0, 0, 1)
    z = fade * heave_m * np.sin(2 * np.pi * 0.5 * t)
    pitch = fade * np.radians(2) * np.sin(2 * np.pi * 1.3 * t)
    np.savetxt(path, np.column_stack([t, z, pitch]), delimiter=",", header="time_s,dof_ref_z_m,dof_ref_pitch_rad",
               comments="")
    return path


def in_the_loop(name: str, model: LegModel, settings: CompensatorSettings | None = None):
    """hexsim's compensator ``name`` on the leg ``model`` as the independent actuator's ``compensate``
    callback (:func:`independent_actuator.motion`): handed the P output, the measured position and pressure,
    the reference and its derivatives, as a motion computer has them. The compensator is its ``compensator``."""
    comp = make_compensator(name, 1, 500.0, settings=settings, model=model)

    def compensate(u_p, y, r, r_dot, r_ddot, r_dddot, p1):
        comp.observe(Reference(*(np.array([x]) for x in (r, r_dot, r_ddot, r_dddot, p1))))
        return comp.update(np.array([u_p]), np.array([y]))[0]

    compensate.compensator = comp
    return compensate


def truth_smoothness(truth: Actuator, duration: float, compensate=None, frequency: float = 0.5,
                     amplitude: float = 0.05):
    """The smoothness (:func:`hexsim.studies.metrics.smoothness`) of the independent actuator on a
    closed-loop sine: its acceleration without sensor noise, from the third period."""
    cols = motion(truth, duration, frequency, amplitude, np.random.default_rng(1), noise=(2e-6, 2e3, 0.0),
                  compensate=compensate)
    t = cols["time_s"]
    return smoothness(t, cols["acc_mps2"], frequency, 2.0 / frequency, cols["ref_m"], name="acc", unit="m/s^2",
                      velocity=np.gradient(cols["pos_m"], t))


def reversal_peaks(truth: Actuator, duration: float, compensate=None) -> np.ndarray:
    """The independent actuator's reversal peaks [m/s²] on a 0.5 Hz, 50 mm sine (:func:`truth_smoothness`)."""
    return truth_smoothness(truth, duration, compensate).reversal_peaks
