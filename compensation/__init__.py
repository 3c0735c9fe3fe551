"""Reversal-bump compensators: per-leg feedforward voltages U_c added to the valve setpoint.

A compensator sees only what a real motion computer sees (seed §5.1): the output u_p of the position
controller (the valve setpoint before compensation; the seed calls it u_v in ch. 5) and the measured
piston position, at the controller rate. It returns the compensation voltage U_c [V]; the valve gets
u_v = sat(u_p + U_c, ±u_v,max) (seed Fig. 5.3).

- ``none``: U_c = 0.
- ``iterative-1``, ``iterative-2``: seed §5.3-5.4, look-up table + function (1) / (2).
- ``buffered``: seed §5.5 and appendix C.
- ``directional``: two buffered curves, for rising and falling u_v (seed ch. 6 recommendation).
- ``feedforward``: model-based feedforward from the inverse of the machine's leg model (flow curve,
  friction, chamber compressibility) and the reference's derivatives (:mod:`compensation.model_based`).
- ``adaptive``: the feedforward with an inverse that learns the machine's drift, under a never-worse guard.
- ``oracle``: exact static inverse of the true plant; a yardstick, not a product feature.
"""

from __future__ import annotations

import importlib

from compensation.settings import CompensatorSettings, SettingsError

#: Names of the built-in compensators, in league order (``hexsim run --compensator NAME``).
NAMES = ("none", "iterative-1", "iterative-2", "buffered", "directional", "feedforward", "adaptive", "oracle")

#: The compensators built on the machine's leg model (:class:`compensation.leg_model.LegModel`).
MODEL_BASED = ("feedforward", "adaptive")

#: public name -> module; the compensators (numba, scipy) load on first use
_LAZY = {"Compensator": "compensation.base", "FlowCurveObserver": "compensation.base",
         "NoCompensator": "compensation.base", "PlantTruth": "compensation.base",
         "BufferedCompensator": "compensation.buffered", "DirectionalCompensator": "compensation.buffered",
         "Iterative1": "compensation.iterative", "Iterative2": "compensation.iterative",
         "OracleCompensator": "compensation.oracle", "FeedforwardCompensator": "compensation.model_based",
         "AdaptiveFeedforward": "compensation.model_based",
         "LegModel": "compensation.leg_model", "Reference": "compensation.leg_model"}


def __getattr__(name: str):
    if name == "COMPENSATORS":
        classes = [__getattr__(n) for n in ("NoCompensator", "Iterative1", "Iterative2", "BufferedCompensator",
                                             "DirectionalCompensator", "FeedforwardCompensator", "AdaptiveFeedforward",
                                             "OracleCompensator")]
        value = {c.name: c for c in classes}  # in the order of NAMES
    elif name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
    else:
        raise AttributeError(f"module 'compensation' has no attribute {name!r}")
    globals()[name] = value
    return value


def make_compensator(name: str, n_legs: int, rate_hz: float, *, u_v_max: float = 10.0,
                     settings: CompensatorSettings | None = None, plant=None, model=None):
    """A compensator by name for ``n_legs`` legs driven at ``rate_hz`` [Hz].

    ``plant`` (:class:`~compensation.base.PlantTruth`) is passed to the oracle only, ``model`` (the
    machine's :class:`~compensation.leg_model.LegModel`) to the model-based ones (:data:`MODEL_BASED`).
    Raises SettingsError (a ValueError) naming the choices for an unknown name or a bad setting.
    """
    if name not in NAMES:
        raise SettingsError(f"unknown compensator {name!r}; choose one of {', '.join(NAMES)}")
    kwargs = {"plant": plant} if name == "oracle" else {"model": model} if name in MODEL_BASED else {}
    return __getattr__("COMPENSATORS")[name](n_legs, rate_hz, u_v_max, settings, **kwargs)


__all__ = ["COMPENSATORS", "MODEL_BASED", "NAMES", "Compensator", "CompensatorSettings", "FlowCurveObserver", "NoCompensator",
           "PlantTruth", "SettingsError", "make_compensator", *sorted(set(_LAZY) - {"Compensator"})]
