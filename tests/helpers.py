"""Helpers shared by test modules (importable as ``helpers``: pytest puts tests/ on sys.path)."""

from __future__ import annotations

import pathlib

import numpy as np


def write_heave_pitch_profile(path: pathlib.Path, duration: float, heave_m: float) -> pathlib.Path:
    """A ``file:`` scenario: heave ``heave_m`` at 0.5 Hz plus 2° pitch at 1.3 Hz, both faded in over 2 s."""
    t = np.arange(0, duration + 1e-9, 0.01)
    fade = np.clip(t / 2.0, 0, 1)
    z = fade * heave_m * np.sin(2 * np.pi * 0.5 * t)
    pitch = fade * np.radians(2) * np.sin(2 * np.pi * 1.3 * t)
    np.savetxt(path, np.column_stack([t, z, pitch]), delimiter=",", header="time_s,dof_ref_z_m,dof_ref_pitch_rad",
               comments="")
    return path
