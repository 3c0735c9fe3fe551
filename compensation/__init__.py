"""Reversal-bump compensators: per-leg feedforward voltages U_c added to the valve setpoint.

A compensator sees only what a real motion computer sees (seed §5.1): the valve setpoint u_v that the
position controller computed and the measured piston position, at the controller rate. It returns the
compensation voltage U_c [V], which the controller adds to u_v before the ±u_v,max saturation
(seed Fig. 5.3).

- ``none``: U_c = 0.
- ``iterative-1``, ``iterative-2``: seed §5.3-5.4, look-up table + function (1) / (2).
- ``buffered``: seed §5.5 and appendix C.
- ``directional``: two buffered curves, for rising and falling u_v (seed ch. 6 recommendation).
- ``oracle``: exact static inverse of the true plant; a yardstick, not a product feature.
"""

from __future__ import annotations

from compensation.base import (Compensator, CompensatorSettings, FlowCurveObserver, NoCompensator, PlantTruth,
                               SettingsError)
from compensation.buffered import BufferedCompensator, DirectionalCompensator
from compensation.iterative import Iterative1, Iterative2
from compensation.oracle import OracleCompensator

#: Compensators selectable with ``hexsim run --compensator NAME``.
COMPENSATORS: dict[str, type[Compensator]] = {
    c.name: c
    for c in (NoCompensator, Iterative1, Iterative2, BufferedCompensator, DirectionalCompensator, OracleCompensator)
}


def make_compensator(name: str, n_legs: int, rate_hz: float, *, u_v_max: float = 10.0,
                     settings: CompensatorSettings | None = None, plant: PlantTruth | None = None) -> Compensator:
    """A compensator by name for ``n_legs`` legs driven at ``rate_hz`` [Hz].

    ``plant`` is passed to the oracle only. Raises SettingsError (a ValueError) naming the choices for an
    unknown name or a bad setting.
    """
    if name not in COMPENSATORS:
        raise SettingsError(f"unknown compensator {name!r}; choose one of {', '.join(COMPENSATORS)}")
    kwargs = {"plant": plant} if name == "oracle" else {}
    return COMPENSATORS[name](n_legs, rate_hz, u_v_max, settings, **kwargs)


__all__ = ["COMPENSATORS", "Compensator", "CompensatorSettings", "FlowCurveObserver", "NoCompensator", "PlantTruth",
           "SettingsError", "make_compensator"]
