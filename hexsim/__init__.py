"""hexsim: a six-DOF hydraulic motion platform simulator (the Micro Motion System of Rexroth-Hydraudyne).

It reproduces the reversal bump, the acceleration spike each time a valve-controlled actuator changes
direction (seed: "Compensation of the reversal bump", Rexroth-Hydraudyne / TU Eindhoven, 2005),
compensates it, and confronts the model with measured logs.

The Python face, everything a notebook needs (imported on first use, so ``import hexsim`` is quick)::

    import hexsim
    result = hexsim.simulate(hexsim.RunConfig(hexsim.Scenario.sine("heave"), compensator="buffered"))
    print(hexsim.smoothness(result).noise_ratio)

* runs: :func:`simulate`, :class:`Simulator` (stepped), :class:`RunConfig`, :class:`Scenario` (``Scenario.sine``,
  ``Scenario.from_file``), :class:`SimulationResult`;
* the plant: :class:`HydraulicParams`, :class:`ControllerParams`, :class:`Effects`, :class:`LegChange`, :class:`WarmUp`;
* compensation: :class:`Compensator` (subclass it and pass the class as ``RunConfig(compensator=...)``),
  :class:`CompensatorSettings`;
* judging: :func:`smoothness` (of a result), :func:`compare`, :func:`sweep`;
* measured data: :func:`read_log`, :func:`validate`.

The chain, one module per stage: :mod:`hexsim.scenario` → :mod:`hexsim.kinematics` →
:mod:`hexsim.controller` → :mod:`compensation` → :mod:`hexsim.plant` (valve, chamber, friction,
effects) → :mod:`hexsim.runner` (MuJoCo) → :mod:`hexsim.metrics` → outputs.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

#: public name -> (module, attribute)
_FACE = {
    "simulate": ("hexsim.runner", "simulate"),
    "Simulator": ("hexsim.runner", "Simulator"),
    "RunConfig": ("hexsim.simulation", "RunConfig"),
    "SimulationResult": ("hexsim.simulation", "SimulationResult"),
    "Scenario": ("hexsim.scenario", "Scenario"),
    "HydraulicParams": ("hexsim.params", "HydraulicParams"),
    "ControllerParams": ("hexsim.params", "ControllerParams"),
    "Effects": ("hexsim.effects", "Effects"),
    "LegChange": ("hexsim.effects", "LegChange"),
    "WarmUp": ("hexsim.temperature", "WarmUp"),
    "Compensator": ("compensation.base", "Compensator"),
    "CompensatorSettings": ("compensation.base", "CompensatorSettings"),
    "smoothness": ("hexsim.metrics", "run_smoothness"),
    "compare": ("hexsim.comparison", "compare"),
    "sweep": ("hexsim.sweeps", "sweep"),
    "read_log": ("hexsim.measurement", "read_log"),
    "validate": ("hexsim.validation", "validate"),
}

__all__ = ["__version__", *_FACE]


def __getattr__(name: str):
    if name in _FACE:
        module, attr = _FACE[name]
        value = getattr(importlib.import_module(module), attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'hexsim' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
