"""The vestibular organs as linear models, and their detection thresholds: what a cueing algorithm
optimises for (:mod:`hexsim.control.mpc_cueing`) and what the occupant's perception judges with
(:mod:`hexsim.studies.perception`, whose module doc gives the forms, their sources and the units)."""

from __future__ import annotations

import math

from hexsim.signals import LinearModel, polynomial_product


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
