"""The vestibular organs as linear models, and their detection thresholds: what a cueing algorithm
optimises for (:mod:`hexsim.control.mpc_cueing`) and what the occupant's perception judges with
(:mod:`hexsim.studies.perception`, whose module doc gives the forms, their sources and the units)."""

from __future__ import annotations

import math

import numpy as np

from hexsim.signals import LinearModel, polynomial_product

#: the axes, translations then rotations (specific force x, y, z; angular velocity roll, pitch, yaw)
AXES = ("x", "y", "z", "roll", "pitch", "yaw")


def otolith(tau_a: float = 13.2, tau_l: float = 5.33, tau_s: float = 0.66) -> LinearModel:
    """Otolith model of specific force (:mod:`hexsim.studies.perception`'s doc), unit DC gain."""
    return LinearModel("otolith", polynomial_product([tau_a, 1.0]), polynomial_product([tau_l, 1.0], [tau_s, 1.0]), "m/s^2",
                       "Young & Meiry (1968); parameters as in Telban & Cardullo (2005), NASA/CR-2005-213747")


def canal(tau_a: float = 80.0, tau_1: float = 5.73, tau_l: float = 0.06, tau_2: float = 0.005) -> LinearModel:
    """Semicircular-canal model of angular velocity (:mod:`hexsim.studies.perception`'s doc), unit
    mid-band gain."""
    return LinearModel("semicircular canal", polynomial_product([tau_a, 0.0], [tau_1, 0.0], [tau_l, 1.0]),
                       polynomial_product([tau_a, 1.0], [tau_1, 1.0], [tau_2, 1.0]), "rad/s",
                       "Fernandez & Goldberg (1971); form and parameters as in Telban & Cardullo (2005)")


#: detection thresholds of the stimulus (Benson et al. 1986, 1989; perception's doc): m/s^2 (x, y, z), rad/s (roll, pitch, yaw)
VESTIBULAR_THRESHOLDS = {"x": 0.063, "y": 0.057, "z": 0.154,
                         "roll": math.radians(2.0), "pitch": math.radians(2.0), "yaw": math.radians(1.6)}
#: duration of the threshold experiments' stimulus [s] (a single cycle of sinusoidal acceleration)
THRESHOLD_STIMULUS_S = 3.0


def threshold_stimulus(axis: str, amplitude: float, fs: float, duration: float = THRESHOLD_STIMULUS_S) -> np.ndarray:
    """The threshold experiments' stimulus on ``axis`` with peak ``amplitude`` sampled at ``fs`` [Hz] and
    followed by as long at rest: for a translation the specific force of one cycle of a sinusoidal
    acceleration of ``duration`` [s]; for a rotation the angular velocity of that profile (a raised cosine,
    its peak the threshold's rate)."""
    t = np.arange(int(round(2 * duration * fs))) / fs
    phase = 2 * np.pi * np.clip(t / duration, 0, 1)
    if AXES.index(axis) < 3:
        return amplitude * np.sin(phase)
    return amplitude * 0.5 * (1 - np.cos(phase))


def vestibular_model(axis: str) -> LinearModel:
    """The organ that senses ``axis``: the otolith for x, y, z, the canal for roll, pitch, yaw."""
    return otolith() if AXES.index(axis) < 3 else canal()


def sensed_level(axis: str, amplitude: float, fs: float = 1000.0, duration: float = THRESHOLD_STIMULUS_S) -> float:
    """The organ's peak output to the threshold stimulus of ``axis`` at ``amplitude`` (:func:`threshold_stimulus`),
    in the stimulus' unit: the level its output must exceed to be perceived
    (:func:`hexsim.studies.perception.sensed_threshold`)."""
    x = threshold_stimulus(axis, amplitude, fs, duration)
    return float(np.max(np.abs(vestibular_model(axis).apply(x, fs))))
