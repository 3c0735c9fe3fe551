"""``hexsim fmu``: a leg or the whole platform as an FMI 3.0 co-simulation FMU (docs/fmu.md).

The FMU is packaged by pythonfmu3 (its FMI layer and export library; hexsim writes none of it) around a
slave class below, with the machine file and a tuned compensator file in its resources. Inside, each
communication step is a :class:`~hexsim.interfaces.cosim.CoSimulation` step: the same Simulator as
``hexsim run``. The FMU runs in the Python that has hexsim installed (pythonfmu3's export library calls the
interpreter of the process that loads it: fmpy in that Python, or a tool started with that Python's
libpython preloaded).

Variables (all Float64 unless said; units declared in the modelDescription's UnitDefinitions):

- the leg (``HexsimLeg``): inputs ``y_ref`` [m] (piston setpoint, closed loop) or ``u_v_set`` [V] (valve
  setpoint, with the parameter ``closed_loop`` false), ``F_ext`` [N]; outputs :data:`LEG_OUTPUTS`;
- the platform (``HexsimPlatform``): inputs ``surge``, ``sway``, ``heave`` [m], ``roll``, ``pitch``, ``yaw``
  [rad] (the platform's pose setpoint from neutral, :mod:`hexsim.control.kinematics`); outputs
  :data:`PLATFORM_OUTPUTS`;
- parameters of both: ``duration_s`` (the run's length: at least the master's stop time), ``interpolation``
  (Int32: how inputs become setpoints between communication points, :data:`~hexsim.interfaces.cosim.INTERPOLATIONS`:
  2 a cubic one step behind, the default; 1 a ramp one step behind; 0 held).
"""

from __future__ import annotations

import dataclasses
import json
import pathlib
import shutil
import tempfile
from dataclasses import dataclass

import numpy as np
from pythonfmu3 import (
    Boolean,
    Float64,
    Fmi3Causality,
    Fmi3Slave,
    Fmi3Variability,
    Int32,
)
from pythonfmu3.default_experiment import DefaultExperiment
from pythonfmu3.unit import Unit

from hexsim.errors import InputError
from hexsim.interfaces.cosim import INTERPOLATIONS, CoSimulation

#: The SI units the variables use, as FMI 3.0 UnitDefinitions (base-unit exponents).
UNITS = {"m": {"m": 1}, "m/s": {"m": 1, "s": -1}, "m/s2": {"m": 1, "s": -2}, "rad": {"rad": 1},
         "rad/s": {"rad": 1, "s": -1}, "Pa": {"kg": 1, "m": -1, "s": -2}, "N": {"kg": 1, "m": 1, "s": -2},
         "V": {"kg": 1, "m": 2, "s": -3, "A": -1}, "s": {"s": 1}}


@dataclass(frozen=True)
class Port:
    """An FMU variable: its name, unit (a key of :data:`UNITS`), description, and where it comes from in
    :attr:`CoSimulation.last <hexsim.interfaces.cosim.CoSimulation.last>` (key, index)."""

    name: str
    unit: str
    description: str
    key: str = ""
    index: int = 0


LEG_OUTPUTS = (
    Port("y", "m", "piston position from the retracted end as the position sensor reads it", "y"),
    Port("ydot", "m/s", "piston velocity", "ydot"),
    Port("acc", "m/s2", "accelerometer on the piston along its axis: specific force, mean over the last 1 ms", "acc", 2),
    Port("acc_max", "m/s2", "largest 1 ms accelerometer sample within the last communication step", "acc_max", 2),
    Port("acc_min", "m/s2", "smallest 1 ms accelerometer sample within the last communication step", "acc_min", 2),
    Port("p1", "Pa", "cap-side (bottom-chamber) pressure P1", "p1"),
    Port("p2", "Pa", "rod-side pressure P2 (the supply's with the seed's 3-way valve)", "p2"),
    Port("p_s", "Pa", "supply pressure P_s", "p_s"),
    Port("force", "N", "hydraulic force on the piston (P1 A1 - P2 A2), extending positive", "force"),
    Port("u_v", "V", "valve setpoint u_v given to the valve (P controller plus compensation, saturated)", "u_v"),
    Port("u_c", "V", "the compensator's voltage U_c", "u_c"),
    Port("y_ref_used", "m", "piston setpoint in force at the sample (the input one step behind when interpolated)",
         "y_ref"),
    Port("sample_time", "s", "time of the outputs' sample: the end of the step minus the 1 ms record period",
         "sample_time"),
)

PLATFORM_INPUTS = tuple(Port(n, "m" if i < 3 else "rad", f"platform {n} setpoint from neutral", "", i)
                        for i, n in enumerate(("surge", "sway", "heave", "roll", "pitch", "yaw")))

PLATFORM_OUTPUTS = (
    *(Port(f"{n}_out", "m" if i < 3 else "rad", f"platform {n} from neutral (position and ZYX angles)", "pose", i)
      for i, n in enumerate(("surge", "sway", "heave", "roll", "pitch", "yaw"))),
    *(Port(f"head_f{a}", "m/s2", f"specific force at the occupant's head along platform {a} (gravity included)",
           "head_f", i) for i, a in enumerate("xyz")),
    *(Port(f"head_w{a}", "rad/s", f"angular velocity about platform {a}", "head_w", i) for i, a in enumerate("xyz")),
    *(Port(f"acc_{a}", "m/s2", f"platform accelerometer {a} (sensor frame): specific force, mean over the last 1 ms",
           "acc", i) for i, a in enumerate("xyz")),
    *(Port(f"acc_{a}_max", "m/s2", f"largest 1 ms platform accelerometer {a} sample within the last communication step",
           "acc_max", i) for i, a in enumerate("xyz")),
    *(Port(f"acc_{a}_min", "m/s2", f"smallest 1 ms platform accelerometer {a} sample within the last communication step",
           "acc_min", i) for i, a in enumerate("xyz")),
    *(Port(f"leg{i + 1}_y", "m", f"leg {i + 1}'s piston position as its sensor reads it", "y", i) for i in range(6)),
    *(Port(f"leg{i + 1}_p1", "Pa", f"leg {i + 1}'s cap-side pressure P1", "p1", i) for i in range(6)),
    *(Port(f"leg{i + 1}_u_c", "V", f"leg {i + 1}'s compensator voltage U_c", "u_c", i) for i in range(6)),
    Port("p_s", "Pa", "supply pressure P_s", "p_s"),
    Port("sample_time", "s", "time of the outputs' sample: the end of the step minus the 1 ms record period",
         "sample_time"),
)

#: y_ref's start value: "not set" (the run then holds the neutral position)
Y_REF_START = -1.0

#: The FMUs hexsim builds: kind -> model name (the FMU's file name and modelIdentifier).
KINDS = {"leg": "HexsimLeg", "platform": "HexsimPlatform"}


class _HexsimSlave(Fmi3Slave):
    """What both FMUs share: the parameters, the units, the run set up when initialisation ends."""

    kind = ""
    author = "hexsim"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        resources = pathlib.Path(self.resources or ".")
        build = json.loads((resources / "hexsim_fmu.json").read_text()) if (resources / "hexsim_fmu.json").exists() \
            else {"machine": None, "compensator": "none"}
        self._build = build
        self._resources = resources
        self.description = build.get("description", f"hexsim {self.kind}")
        # a master that takes its communication step from here (fmpy does) steps the record period
        self.default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=1e-3)
        self.register_units([Unit(name, **exponents) for name, exponents in UNITS.items()])
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous, unit="s", description="simulation time",
                                       getter=lambda: self._run.time if self._run is not None else 0.0))
        self.duration_s = 60.0
        self.interpolation = INTERPOLATIONS["cubic"]
        self.register_variable(Float64("duration_s", causality=Fmi3Causality.parameter,
                                       variability=Fmi3Variability.fixed, unit="s", start=self.duration_s,
                                       description="length of the run: at least the master's stop time"))
        self.register_variable(Int32("interpolation", causality=Fmi3Causality.parameter,
                                     variability=Fmi3Variability.fixed, start=self.interpolation,
                                     description="setpoints between communication points: 2 a cubic one step behind "
                                                 "(continuous velocity), 1 a ramp one step behind, 0 each input held "
                                                 "over its step"))
        self._run = None
        self._inputs: dict[str, float] = {}
        self._outputs: dict[str, float] = {}

    def _input(self, port: Port, start: float) -> None:
        self._inputs[port.name] = start
        self.register_variable(Float64(port.name, causality=Fmi3Causality.input, start=start, unit=port.unit,
                                       description=port.description,
                                       getter=lambda: self._inputs[port.name],
                                       setter=lambda v: self._inputs.__setitem__(port.name, float(v))))

    def _output(self, port: Port) -> None:
        self._outputs[port.name] = 0.0
        self.register_variable(Float64(port.name, causality=Fmi3Causality.output, unit=port.unit,
                                       description=port.description, getter=lambda: self._outputs[port.name]))

    def _interpolation(self) -> str:
        names = {number: name for name, number in INTERPOLATIONS.items()}
        if self.interpolation not in names:
            raise InputError(f"interpolation = {self.interpolation}: 0 (hold), 1 (linear) or 2 (cubic)")
        return names[self.interpolation]

    def _config(self):
        """The run's RunConfig from the machine and compensator in the resources."""
        from hexsim.engine.config import RunConfig
        from hexsim.plant.machine import load_machine
        from hexsim.studies.tuning import compensator_options

        build, resources = self._build, self._resources
        machine = load_machine(str(resources / build["machine"]) if build.get("machine") else build.get("builtin"))
        compensator = build.get("compensator", "none")
        options = compensator_options(str(resources / compensator) if compensator.endswith(".json") else compensator)
        return RunConfig.from_machine(machine, "heave" if self.kind == "platform" else "actuator", **options)

    def _publish(self, last: dict[str, np.ndarray], ports) -> None:
        for port in ports:
            self._outputs[port.name] = float(np.atleast_1d(last[port.key])[port.index])


class LegSlave(_HexsimSlave):
    """One leg (a single actuator of the machine file) as a co-simulation slave (module doc)."""

    kind = "leg"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.closed_loop = True
        self.register_variable(Boolean("closed_loop", causality=Fmi3Causality.parameter,
                                       variability=Fmi3Variability.fixed, start=True,
                                       description="the P controller closes the loop on y_ref (false: u_v_set drives "
                                                   "the valve, no controller, no compensator)"))
        self._input(Port("y_ref", "m", "piston position setpoint from the retracted end (closed loop; not set: "
                              "the neutral position)"), Y_REF_START)
        self._input(Port("u_v_set", "V", "valve setpoint (open loop, closed_loop = false)"), 0.0)
        self._input(Port("F_ext", "N", "external force on the piston along its axis, extending positive"), 0.0)
        for port in LEG_OUTPUTS:
            self._output(port)

    def exit_initialization_mode(self):
        config = self._config()
        if not self.closed_loop:
            config = dataclasses.replace(config, compensator="none")
        self._run = CoSimulation(config, self.duration_s, open_loop=not self.closed_loop,
                                 interpolation=self._interpolation())
        if self.closed_loop and self._inputs["y_ref"] == Y_REF_START:  # not set: hold the neutral position
            self._inputs["y_ref"] = float(self._run.neutral[0])
        self._publish(self._run.initial(), LEG_OUTPUTS)

    def _value(self) -> np.ndarray:
        return np.array([self._inputs["y_ref"] if self.closed_loop else self._inputs["u_v_set"]])

    def do_step(self, current_time, step_size):
        last = self._run.advance(current_time, step_size, self._value(), self._inputs["F_ext"])
        self._publish(last, LEG_OUTPUTS)
        return True


class PlatformSlave(_HexsimSlave):
    """The platform (the machine file's hexapod) as a co-simulation slave (module doc)."""

    kind = "platform"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        for port in PLATFORM_INPUTS:
            self._input(port, 0.0)
        for port in PLATFORM_OUTPUTS:
            self._output(port)

    def exit_initialization_mode(self):
        self._run = CoSimulation(self._config(), self.duration_s, interpolation=self._interpolation())
        self._publish(self._run.initial(), PLATFORM_OUTPUTS)

    def do_step(self, current_time, step_size):
        value = np.array([self._inputs[p.name] for p in PLATFORM_INPUTS])
        self._publish(self._run.advance(current_time, step_size, value), PLATFORM_OUTPUTS)
        return True


_SCRIPT = '''"""hexsim's {kind} as an FMI 3.0 co-simulation FMU, built by ``hexsim fmu {kind}`` (hexsim {version}).
The slave is hexsim.interfaces.fmu.{base}; the machine and compensator files are in the resources."""
from pythonfmu3 import Fmi3Slave

from hexsim.interfaces.fmu import {base}


class {name}({base}, Fmi3Slave):
    """hexsim's {kind}: see hexsim.interfaces.fmu."""
'''


def build_fmu(kind: str, out_dir: str | pathlib.Path, machine: str | None = None,
              compensator: str = "none") -> pathlib.Path:
    """Build the FMU of ``kind`` (``"leg"`` or ``"platform"``, :data:`KINDS`) into ``out_dir`` from the machine
    file ``machine`` (None: the built-in Micro Motion System) and ``compensator`` (a built-in's name or a tuned
    file, ``hexsim tune --out``), both copied into the FMU's resources. Returns the FMU's path
    (``out_dir/HexsimLeg.fmu`` or ``HexsimPlatform.fmu``). The machine and compensator are checked by
    building the run once here. Raises InputError for an unknown kind, a machine whose system does not fit
    (a platform FMU needs a hexapod), a file that cannot be read, or an FMU that cannot be written."""
    from pythonfmu3.builder import FmuBuilder

    from hexsim import __version__
    from hexsim.plant.machine import load_machine

    if kind not in KINDS:
        raise InputError(f"hexsim fmu: kind {kind!r}: one of {', '.join(KINDS)}")
    loaded = load_machine(machine)
    if kind == "platform" and loaded.system != "hexapod":
        raise InputError(f"a platform FMU needs a hexapod machine; {loaded.label} is a {loaded.system}")
    out_dir = pathlib.Path(out_dir)
    with tempfile.TemporaryDirectory(prefix="hexsim_fmu_") as tmp:
        tmp = pathlib.Path(tmp)
        info = {"kind": kind, "hexsim": __version__, "compensator": compensator,
                "description": f"hexsim {kind}: {loaded.label}, compensator {pathlib.Path(compensator).name}"}
        files = []
        if loaded.path is None:
            info["builtin"] = loaded.name
        else:
            info["machine"] = "machine.json"
            shutil.copyfile(loaded.path, tmp / "machine.json")
            files.append(tmp / "machine.json")
        if compensator.endswith(".json"):
            if not pathlib.Path(compensator).is_file():
                raise InputError(f"{compensator}: no such compensator file")
            info["compensator"] = "compensator.json"
            shutil.copyfile(compensator, tmp / "compensator.json")
            files.append(tmp / "compensator.json")
        (tmp / "hexsim_fmu.json").write_text(json.dumps(info, indent=1))
        files.append(tmp / "hexsim_fmu.json")
        slave = LegSlave if kind == "leg" else PlatformSlave
        name, base = KINDS[kind], slave.__name__
        script = tmp / "script" / f"{name}.py"
        script.parent.mkdir()
        script.write_text(_SCRIPT.format(kind=kind, version=__version__, base=base, name=name))
        check = slave(instance_name="check", resources=str(tmp))
        check._config()  # the machine and compensator as the FMU will read them (errors here, not in the tool)
        try:
            out_dir.mkdir(parents=True, exist_ok=True)
            return FmuBuilder.build_FMU(script, dest=out_dir, project_files=files)
        except OSError as exc:
            raise InputError(f"cannot write the FMU into {out_dir}: {exc.strerror or exc}") from None
