"""Reversal-bump compensators: per-leg feedforward voltages U_c added to the valve setpoint.

A compensator sees only what a real motion computer sees (seed §5.1): the valve setpoint u_v that the
position controller computed and the measured piston position, at the controller rate. It returns the
compensation voltage U_c [V], which the controller adds to u_v before the ±u_v,max saturation
(seed Fig. 5.3). The seed's adaptive compensators (ch. 5) build on :class:`Compensator`.
"""

from __future__ import annotations


from compensation.base import Compensator, NoCompensator

#: Compensators selectable with ``hexsim run --compensator NAME``.
COMPENSATORS: dict[str, type[Compensator]] = {"none": NoCompensator}


def make_compensator(name: str, n_legs: int, rate_hz: float) -> Compensator:
    """A compensator by name for ``n_legs`` legs driven at ``rate_hz`` [Hz].

    Raises ValueError naming the choices for an unknown name.
    """
    if name not in COMPENSATORS:
        raise ValueError(f"unknown compensator {name!r}; choose one of {', '.join(COMPENSATORS)}")
    return COMPENSATORS[name](n_legs=n_legs, rate_hz=rate_hz)


__all__ = ["COMPENSATORS", "Compensator", "NoCompensator", "make_compensator"]
