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
* the machine: :class:`Machine`, :func:`load_machine` (a machine file or a built-in's name);
* the plant: :class:`HydraulicParams`, :class:`ControllerParams`, :class:`Effects`, :class:`LegChange`, :class:`WarmUp`;
* compensation: :class:`Compensator` (subclass it and pass the class as ``RunConfig(compensator=...)``),
  :class:`CompensatorSettings`;
* judging: :func:`smoothness` (of a result), :func:`compare`, :func:`sweep`;
* the driver's view: :func:`perception` (each bump of a run against the perception thresholds),
  :func:`vehicle_scenario` (a vehicle's motion through the classical washout, :class:`WashoutParams`),
  :func:`cue_report` (of a vehicle run), :func:`acceptance` with :class:`Tolerances` (the motion tests);
* measured data: :func:`read_log`, :func:`validate`.

The chain, one module per stage: :mod:`hexsim.control.scenario` → :mod:`hexsim.control.kinematics` →
:mod:`hexsim.control.controller` → :mod:`compensation` → :mod:`hexsim.plant.legs` (valve, chamber, friction,
effects) → :mod:`hexsim.engine.runner` (MuJoCo) → :mod:`hexsim.studies.metrics` and
:mod:`hexsim.studies.perception` → outputs; a vehicle's motion enters through :mod:`hexsim.control.washout`.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

#: public name -> (module, attribute)
_FACE = {
    "simulate": ("hexsim.engine.runner", "simulate"),
    "Simulator": ("hexsim.engine.runner", "Simulator"),
    "RunConfig": ("hexsim.engine.config", "RunConfig"),
    "SimulationResult": ("hexsim.engine.config", "SimulationResult"),
    "Scenario": ("hexsim.control.scenario", "Scenario"),
    "HydraulicParams": ("hexsim.plant.params", "HydraulicParams"),
    "ControllerParams": ("hexsim.plant.params", "ControllerParams"),
    "Effects": ("hexsim.plant.effects", "Effects"),
    "Machine": ("hexsim.plant.machine", "Machine"),
    "load_machine": ("hexsim.plant.machine", "load_machine"),
    "LegChange": ("hexsim.plant.effects", "LegChange"),
    "WarmUp": ("hexsim.plant.temperature", "WarmUp"),
    "Compensator": ("compensation.base", "Compensator"),
    "CompensatorSettings": ("compensation.base", "CompensatorSettings"),
    "smoothness": ("hexsim.studies.metrics", "run_smoothness"),
    "compare": ("hexsim.studies.comparison", "compare"),
    "sweep": ("hexsim.studies.sweeps", "sweep"),
    "perception": ("hexsim.studies.perception", "bump_perception"),
    "vehicle_scenario": ("hexsim.control.scenario", "vehicle_scenario"),
    "WashoutParams": ("hexsim.control.washout", "WashoutParams"),
    "cue_report": ("hexsim.studies.cueing", "cue_report"),
    "acceptance": ("hexsim.studies.acceptance", "run_acceptance"),
    "Tolerances": ("hexsim.studies.acceptance", "Tolerances"),
    "read_log": ("hexsim.measured.measurement", "read_log"),
    "validate": ("hexsim.measured.validation", "validate"),
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
