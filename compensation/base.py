"""The compensator interface the per-leg controller calls at its sampling rate (seed §5.1, Fig. 5.3)."""

from __future__ import annotations

import abc

import numpy as np


class Compensator(abc.ABC):
    """Per-leg compensation voltage U_c [V] from the valve setpoint u_v [V] and the measured position [m].

    Subclasses override :meth:`update`. ``n_legs`` legs, called at ``rate_hz`` [Hz] (the motion
    computer's 500 Hz, seed §2.2.4). A compensator never sees the simulator's true velocity: velocity,
    if needed, comes from differentiating the measured position with a filter (seed §4.4, §5.1).
    """

    name = "base"

    def __init__(self, n_legs: int, rate_hz: float) -> None:
        self.n_legs = int(n_legs)
        self.rate_hz = float(rate_hz)

    @abc.abstractmethod
    def update(self, u_v: np.ndarray, y_measured: np.ndarray) -> np.ndarray:
        """U_c (n_legs,) [V] for this controller sample; u_v and y_measured are (n_legs,)."""

    def state(self) -> dict[str, np.ndarray]:
        """Parameters worth logging (name -> (n_legs,) array); empty if the compensator has none."""
        return {}


class NoCompensator(Compensator):
    """U_c = 0: the uncompensated valve, which shows the reversal bump."""

    name = "none"

    def update(self, u_v: np.ndarray, y_measured: np.ndarray) -> np.ndarray:
        return np.zeros(self.n_legs)
