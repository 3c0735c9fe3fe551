"""Calibrate, then validate, on a hexapod that is not its machine file.

The machine is the hexapod of ``tests/measured/test_calibration_hexapod.py`` (``tests/independent_hexapod.py``: its
own legs, platform dynamics, inverse kinematics and controller, RK4, no hexsim import), off the built-in
file within data-sheet tolerances: each leg's valve 4-7 % off with its own return edge, port-limited
valves, softer oil, more friction, a 60 kg payload off centre. hexsim is told nothing but the built-in file:

1. one calibration log (8 s of heave, roll and pitch) -> ``hexsim.measured.calibration.calibrate`` (smooth
   and port valves screened) -> a calibrated machine file;
2. logs of another motion (5 s of surge, heave and yaw), nothing added or one effect added on one leg or on
   all -> ``hexsim.validate`` against the calibrated file.

The script prints, per log, the hidden truth beside the verdict and the named effects (the hexapod table
of docs/calibration.md).

    python examples/hexapod_calibrate_then_validate.py [--out DIR] [--only NAME ...]
"""

from __future__ import annotations

import argparse
import dataclasses
import pathlib
import sys
import time

import numpy as np

import hexsim
from hexsim.measured.calibration import calibrate
from hexsim.measured.measurement import read_log
from hexsim.plant.machine import dump, load_machine

TESTS = pathlib.Path(__file__).resolve().parents[1] / "tests"
sys.path[:0] = [str(TESTS), str(TESTS / "measured")]  # the truth plant and its test's motions live with the tests
from independent_hexapod import Hexapod, motion, write  # noqa: E402
from test_calibration_hexapod import _calibration_motion, _machine, _other_motion  # noqa: E402


def on_legs(machine: Hexapod, legs, **change) -> Hexapod:
    """``machine`` with ``change`` on the legs ``legs`` (1-based; None: all): a value, or a function of the
    leg's :class:`independent_actuator.Actuator`."""
    out = list(machine.legs)
    for i, leg in enumerate(out):
        if legs is None or i + 1 in legs:
            out[i] = leg.replace(**{k: (v(leg) if callable(v) else v) for k, v in change.items()})
    return dataclasses.replace(machine, legs=tuple(out))


#: name -> (hidden truth, the machine with it)
CASES = {
    "null": ("nothing", lambda m: m),
    "leakage": ("a leak of 4e-12 m^3/(s Pa) across leg 6's piston", lambda m: on_legs(m, (6,), leak=4e-12)),
    "edge": ("leg 5's return edge worn: 0.75 of the calibrated", lambda m: on_legs(m, (5,), k_at=lambda a: 0.75 * a.k_at)),
    "friction": ("every seal's Coulomb and static friction 2x (cold)",
                 lambda m: on_legs(m, None, coulomb=lambda a: tuple(2 * c for c in a.coulomb),
                                   static=lambda a: tuple(2 * c for c in a.static))),
    "bulk_modulus": ("warm oil: bulk modulus 0.6 GPa (calibrated 1.25)", lambda m: on_legs(m, None, bulk=0.6e9)),
    "entrained_air": ("3 % of air entrained in the oil", lambda m: on_legs(m, None, air=0.03)),
    "null_offset": ("leg 4's valve null drifted by 0.2 V",
                    lambda m: on_legs(m, (4,), null_offset=lambda a: a.null_offset + 0.2)),
    "supply_pressure": ("the supply sags 0.4 bar per L/min the six legs draw (30 ms)",
                        lambda m: dataclasses.replace(m, supply_resistance=0.4e5 / (1e-3 / 60), supply_tau=0.03)),
    "spool_dynamics": ("every valve's spool a 40 Hz loop (damping 0.7)", lambda m: on_legs(m, None, spool_hz=40.0)),
    "hysteresis": ("0.3 V of play before leg 3's spool", lambda m: on_legs(m, (3,), play=0.3)),
    "sensor_delay": ("the leg positions measured 2 ms late", lambda m: dataclasses.replace(m, sensor_delay=0.002)),
    "payload": ("90 kg more on the platform, at its centre of gravity",
                lambda m: dataclasses.replace(m, mass=m.mass + 90.0)),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="hexapod_calibrate_then_validate", help="folder for the logs and answers")
    parser.add_argument("--only", nargs="*", choices=sorted(CASES), help="validate only these logs")
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    prior = load_machine(None)
    cal_log = out / "calibration.csv"
    if not cal_log.exists():
        write(motion(_machine(), 8.0, _calibration_motion, np.random.default_rng(1)), cal_log, "heave, roll and pitch")
    cal_path = out / "calibrated.json"
    if not cal_path.exists():
        start = time.perf_counter()
        result = calibrate([read_log(cal_log, machine=prior)], prior, flow_areas=("smooth", "port"))
        calibrated, report = result.machine, result.report
        cal_path.write_text(dump(calibrated.document()))
        print(f"<!-- calibrated in {time.perf_counter() - start:.0f} s, flow area {report['flow_area']['chosen']} -->",
              flush=True)
    print("| log (hidden truth) | verdict | named effects (fitted) | held-out RMS / budget (position, P1, "
          "acceleration) | wall |")
    print("|---|---|---|---|---|")
    for seed, name in enumerate(args.only or CASES):
        what, make = CASES[name]
        log = out / f"{name}.csv"
        if not log.exists():
            write(motion(make(_machine()), 5.0, _other_motion, np.random.default_rng(30 + seed)), log, name)
        start = time.perf_counter()
        doc = hexsim.validate(read_log(log, machine=load_machine(cal_path)), jobs=args.jobs,
                              json_path=out / f"{name}.answer.json")
        wall = time.perf_counter() - start
        named = "; ".join(e["name"] + (f" on leg {e['leg']}" if e["leg"] else "") + " (" + ", ".join(
            f"{k} = {v['value']:.4g} {v['unit']}" for k, v in e["parameters"].items()) + ")"
            for e in doc["added_effects"]) or "–"
        rms = doc["held_out_rms_in_budgets"]
        print(f"| {name}: {what} | **{doc['verdict']}** | {named} | {rms['position']:.2f}, {rms['p1']:.2f}, "
              f"{rms['acceleration']:.2f} | {wall:.0f} s |", flush=True)


if __name__ == "__main__":
    main()
