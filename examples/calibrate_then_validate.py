"""Calibrate, then validate: the measured-data loop on machines that are not their machine file.

Each machine is the seed's single actuator written independently of hexsim (``tests/independent_actuator.py``:
its own equations, error-controlled Dormand-Prince), with nominal parameters moved from appendix A within what a
data sheet allows and a valve that is not hexsim's default. hexsim is told nothing but the built-in machine file:

1. two calibration experiments of the machine (closed-loop sines: 8 s at 0.5 Hz and 60 mm, 6 s at 1.5 Hz
   and 30 mm) -> ``hexsim.measured.calibration.calibrate`` -> a calibrated machine file;
2. logs of the same machine running another motion (6 s at 1 Hz, 50 mm), nothing added (a null) or one
   effect added -> ``hexsim.validate`` against the calibrated file.

The script prints, per log, the hidden truth beside the verdict and the named effects; it made the
calibrate-then-validate table of docs/calibration.md. Noise: 2 µm, 0.02 bar, 0.02 m/s^2.

    python examples/calibrate_then_validate.py [--out DIR] [--machines port,quadratic,sharp,drawn11] [--only NAME ...]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

import numpy as np

import hexsim
from hexsim.measured.calibration import calibrate
from hexsim.measured.measurement import read_log
from hexsim.plant.machine import dump, load_machine

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))
from independent_actuator import Actuator, motion, write  # noqa: E402  (the truth plant lives with the tests)

#: The machines: the seed's actuator off appendix A within data-sheet tolerances, with three valves.
MACHINES = {
    "port": Actuator(area="port", flow_gain=1.07, k_at=0.95, overlap=8e-6, bulk=1.2e9, v_pl=1.0e-6, mass=44.0,
                     coulomb=(75.0, 52.0), viscous=(2600.0, 1500.0)),
    "quadratic": Actuator(area="quadratic", flow_gain=0.93, k_at=1.06, bulk=1.7e9, v_pl=2.0e-6, mass=37.0,
                          coulomb=(58.0, 70.0), viscous=(1900.0, 2100.0), static=(40.0, 22.0)),
    "sharp": Actuator(area="sharp", flow_gain=1.05, overlap=2.0e-5, null_offset=0.04, bulk=1.3e9, mass=42.0,
                      coulomb=(70.0, 66.0), viscous=(2400.0, 1700.0)),
}


def drawn(seed: int) -> Actuator:
    """A machine drawn at random within a data sheet's tolerances of appendix A: valve form, flow gain ±8 %,
    return edge ±6 %, overlap 0-25 µm, zero point ±0.05 V, bulk modulus 1.1-1.8 GPa, dead volume 0.2-2.5 cm^3,
    moving mass 35-46 kg, each direction's Coulomb 45-85 N, viscous 1500-2800 N s/m, static 15-45 N."""
    rng = np.random.default_rng(seed)

    def u(a, b):
        return float(rng.uniform(a, b))

    return Actuator(area=str(rng.choice(["port", "quadratic", "sharp"])), flow_gain=u(0.92, 1.08),
                    k_at=u(0.94, 1.06), overlap=u(0.0, 2.5e-5), null_offset=u(-0.05, 0.05), bulk=u(1.1e9, 1.8e9),
                    v_pl=u(2e-7, 2.5e-6), mass=u(35.0, 46.0), coulomb=(u(45.0, 85.0), u(45.0, 85.0)),
                    viscous=(u(1500.0, 2800.0), u(1500.0, 2800.0)), static=(u(15.0, 45.0), u(15.0, 45.0)))


#: name -> (hidden truth, the change to the machine)
EFFECTS = {
    "null": ("nothing", {}),
    "leakage": ("leakage C_l 3e-12 m^3/(s Pa)", {"leak": 3e-12}),
    "null_offset": ("the valve's null drifted by 0.15 V", {"null_offset": 0.15}),
    "edge": ("return edge worn: k_AT 0.8 of the calibrated", {"k_at": 0.8}),
    "friction": ("Coulomb and static friction 1.6x (cold seals)", {"coulomb": 1.6, "static": 1.6}),
    "spool": ("a 40 Hz spool (damping 0.7)", {"spool_hz": 40.0}),
    "sensor_delay": ("position measured 2 ms late", {"sensor_delay": 0.002}),
    "supply_pressure": ("the supply sags 1.2 bar per L/min drawn (30 ms)",
                        {"supply_resistance": 1.2e5 / (1e-3 / 60), "supply_tau": 0.03}),
    "hysteresis": ("0.25 V of play between the setpoint and the spool", {"play": 0.25}),
    "load": ("a heavier load on an inclined axis: 65 kg at 25 deg", {"mass": 65.0, "inclination_deg": 25.0}),
    "bulk_modulus": ("warm oil: bulk modulus 0.55 GPa", {"bulk": 0.55e9}),
    "entrained_air": ("3.5 % of air entrained in the oil", {"air": 0.035}),
}


def changed(machine: Actuator, change: dict) -> Actuator:
    """``machine`` with ``change``: scales for the friction pairs and the return edge, values otherwise."""
    out = {}
    for key, value in change.items():
        if key in ("coulomb", "static"):
            out[key] = tuple(value * v for v in getattr(machine, key))
        elif key == "k_at":
            out[key] = machine.k_at * value
        elif key == "null_offset":
            out[key] = machine.null_offset + value
        else:
            out[key] = value
    return machine.replace(**out)


def calibrated(name: str, truth: Actuator, out: pathlib.Path, prior) -> pathlib.Path:
    """The machine file of ``truth`` calibrated on its two calibration experiments (the logs and the file
    written into ``out`` as ``NAME_calibration_{1,2}.csv``, ``NAME_calibrated.json``; kept if there)."""
    cal_logs = []
    for i, (duration, freq, amp) in enumerate(((8.0, 0.5, 0.06), (6.0, 1.5, 0.03))):
        path = out / f"{name}_calibration_{i + 1}.csv"
        if not path.exists():
            write(motion(truth, duration, freq, amp, np.random.default_rng(100 + i)), path, f"{name} calibration")
        cal_logs.append(read_log(path, machine=prior))
    cal_path = out / f"{name}_calibrated.json"
    if not cal_path.exists():
        start = time.perf_counter()
        result = calibrate(cal_logs, prior)
        machine, report = result.machine, result.report
        cal_path.write_text(dump(machine.document()))
        print(f"<!-- {name}: calibrated in {time.perf_counter() - start:.0f} s, flow area "
              f"{report['flow_area']['chosen']} -->", flush=True)
    return cal_path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="calibrate_then_validate", help="folder for the logs and answers")
    parser.add_argument("--machines", default=",".join(MACHINES),
                        help="which machines (comma separated): port, quadratic, sharp, or drawnSEED (a machine "
                             "drawn at random within the tolerances, e.g. drawn11)")
    parser.add_argument("--only", nargs="*", choices=sorted(EFFECTS), help="validate only these logs")
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    for name in args.machines.split(","):
        if name not in MACHINES and not (name.startswith("drawn") and name[5:].isdigit()):
            parser.error(f"--machines: unknown machine {name!r} ({', '.join(MACHINES)} or drawnSEED)")
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    prior = load_machine(None)
    print("| machine | log (hidden truth) | verdict | named effects (fitted) | held-out RMS / budget (position, P1, "
          "acceleration) | wall |")
    print("|---|---|---|---|---|---|")
    for name in args.machines.split(","):
        truth = MACHINES[name] if name in MACHINES else drawn(int(name[5:]))
        cal_path = calibrated(name, truth, out, prior)
        for seed, effect in enumerate(args.only or EFFECTS):
            what, change = EFFECTS[effect]
            log = out / f"{name}_{effect}.csv"
            if not log.exists():
                write(motion(changed(truth, change), 6.0, 1.0, 0.05, np.random.default_rng(200 + seed)), log, effect)
            start = time.perf_counter()
            doc = hexsim.validate(read_log(log, machine=load_machine(cal_path)), jobs=args.jobs,
                                  json_path=out / f"{name}_{effect}.answer.json")
            wall = time.perf_counter() - start
            named = "; ".join(f"{e['name']} (" + ", ".join(f"{k} = {v['value']:.4g} {v['unit']}"
                                                           for k, v in e["parameters"].items()) + ")"
                              for e in doc["added_effects"]) or "–"
            rms = doc["held_out_rms_in_budgets"]
            print(f"| {name} | {effect}: {what} | **{doc['verdict']}** | {named} | "
                  f"{rms['position']:.2f}, {rms['p1']:.2f}, {rms['acceleration']:.2f} | {wall:.0f} s |", flush=True)
            (out / f"{name}_{effect}.summary.json").write_text(json.dumps(
                {"truth": what, "verdict": doc["verdict"], "effects": named, "wall_s": wall}))


if __name__ == "__main__":
    main()
