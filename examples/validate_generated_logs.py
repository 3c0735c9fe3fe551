"""The measured-data loop on logs from an independent plant, each with a hidden truth.

Each log is made by a plant the identifier does not replay: the hexapod's logs by the full multi-body
model (legs as bodies, closing constraints) at a 5e-5 s step, validated on the default platform-only
model at 1e-4 s; the single actuator's at 5e-5 s. All carry the sensor noise of
``hexsim.outputs.logio.SENSOR_NOISE`` (2 µm, 0.02 bar, 0.02 m/s^2). The identifier sees only the CSV and
its sidecar; the script then prints, per log, the hidden truth beside the verdict and the named effects.
This is how the table of the measured-data loop in docs/validation.md was made.

    python examples/validate_generated_logs.py [--out DIR] [--jobs 2] [--only NAME ...]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import numpy as np

import hexsim
from hexsim.outputs.logio import write_log

BAR_PER_LPM = 1e5 / (1e-3 / 60)  # [Pa s/m^3] per bar/(L/min)


def hexapod_plant(seed: int, effects: hexsim.Effects | None = None, **changes) -> hexsim.RunConfig:
    """The independent plant of the hexapod's logs: the full multi-body model at 5e-5 s, 6 s of 1 Hz heave,
    with ``effects`` (the machine's) and ``changes`` (leg_changes=…, compensator=…: the run's) hidden in it."""
    from hexsim.control.scenario import make_scenario

    run = hexsim.RunConfig(make_scenario("heave", duration=6.0, frequency=1.0), model="full", timestep=5e-5,
                           seed=seed, **changes)
    return run if effects is None else run.with_machine(effects=effects)


def actuator_plant(seed: int, effects: hexsim.Effects | None = None) -> hexsim.RunConfig:
    """The single actuator's logs: 6 s of 1 Hz motion at 5e-5 s, with ``effects`` hidden in it."""
    from hexsim.control.scenario import make_scenario

    run = hexsim.RunConfig(make_scenario("actuator", duration=6.0, frequency=1.0), timestep=5e-5, seed=seed)
    return run if effects is None else run.with_machine(effects=effects)


Effects, leg = hexsim.Effects, hexsim.LegChange.of
SUPPLY_30MS = {"supply_time_constant": 0.03}

#: name -> (hidden truth, the generator's RunConfig, validate's ``without``)
CASES = {
    "hexapod_null": ("nothing", hexapod_plant(1), ()),
    "hexapod_null_buffered": ("nothing (buffered compensator on the machine)",
                              hexapod_plant(2, compensator="buffered"), ()),
    "hexapod_leakage_leg3": ("leakage C_l 4e-12 m^3/(s Pa) on leg 3",
                             hexapod_plant(3, leg_changes=(leg(3, leakage=4e-12),)), ()),
    "hexapod_edge_leg5": ("return edge k_AT 0.70 on leg 5",
                          hexapod_plant(4, leg_changes=(leg(5, edge_gain_at=0.7),)), ()),
    "hexapod_supply": ("supply R_s 0.6 bar/(L/min), tau_s 30 ms",
                       hexapod_plant(5, effects=Effects(supply_resistance=0.6 * BAR_PER_LPM, **SUPPLY_30MS)), ()),
    "hexapod_payload": ("payload 120 kg at (0, 0.3) m",
                        hexapod_plant(6, effects=Effects(payload_kg=120.0, payload_at_m=(0.0, 0.3, 0.0))), ()),
    "hexapod_small_leakage_leg3": ("leakage C_l 1e-12 m^3/(s Pa) on leg 3",
                                   hexapod_plant(21, leg_changes=(leg(3, leakage=1e-12),)), ()),
    "hexapod_small_supply": ("supply R_s 0.15 bar/(L/min), tau_s 30 ms",
                             hexapod_plant(23, effects=Effects(supply_resistance=0.15 * BAR_PER_LPM, **SUPPLY_30MS)),
                             ()),
    "hexapod_small_payload": ("payload 30 kg at (0.1, 0) m",
                              hexapod_plant(24, effects=Effects(payload_kg=30.0, payload_at_m=(0.1, 0.0, 0.0))), ()),
    "hexapod_small_edge_leg5": ("return edge k_AT 0.90 on leg 5",
                                hexapod_plant(25, leg_changes=(leg(5, edge_gain_at=0.9),)), ()),
    "hexapod_two_effects": ("supply 0.3 bar/(L/min) and leakage 2e-12 on leg 1",
                            hexapod_plant(31, effects=Effects(supply_resistance=0.3 * BAR_PER_LPM, **SUPPLY_30MS),
                                          leg_changes=(leg(1, leakage=2e-12),)), ()),
    "hexapod_sensor_delay": ("position measured 2 ms late",
                             hexapod_plant(34, effects=Effects(sensor_delay=0.002)), ()),
    "hexapod_leakage_outside": ("leakage C_l 4e-12 on leg 3, leakage left out of the library",
                                hexapod_plant(3, leg_changes=(leg(3, leakage=4e-12),)), ("leakage",)),
    "hexapod_spool_outside": ("spool dynamics 40 Hz, spool_dynamics left out of the library",
                              hexapod_plant(35, effects=Effects(spool_frequency=40.0)), ("spool_dynamics",)),
    "actuator_null": ("nothing", actuator_plant(7), ()),
    "actuator_leakage": ("leakage C_l 3.9e-12 m^3/(s Pa)", actuator_plant(8, effects=Effects(leakage=3.9e-12)), ()),
    "actuator_air": ("entrained air 2.8 %", actuator_plant(9, effects=Effects(air_fraction=0.028)), ()),
    "actuator_leakage_outside": ("leakage C_l 3.9e-12, leakage left out of the library",
                                 actuator_plant(8, effects=Effects(leakage=3.9e-12)), ("leakage",)),
}


def _unit(unit: str) -> str:
    """A parameter's unit after its value: '× 1e-12 m^3/(s Pa)' for a scaled unit, nothing for '-'."""
    return f" × {unit}" if unit[:1].isdigit() else f" {unit}" if unit not in ("", "-") else ""


def _effects(doc: dict) -> str:
    """The named effects with their legs and fitted parameters, or what discovery added."""
    named = []
    for effect in doc["added_effects"]:
        params = ", ".join(f"{k} = {v['value']:.4g}{_unit(v['unit'])}" for k, v in effect["parameters"].items())
        on = f" on leg {effect['leg']}" if effect.get("leg") else ""
        named.append(f"{effect['name']}{on} ({params})")
    terms = (doc.get("discovery") or {}).get("terms") or []
    if terms:
        recovered = doc["discovery"].get("held_out_cost_recovered")
        named += [f"discovered: {t['meaning']}" for t in terms]
        if recovered is not None:
            named.append(f"{100 * recovered:.1f} % of the held-out error recovered")
    return "; ".join(named) or "–"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="generated_logs", help="folder for the logs and answers")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--only", nargs="*", choices=sorted(CASES), help="run only these cases")
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print("| log (hidden truth) | verdict | added effects | position | P1 | acceleration | wall |")
    print("|---|---|---|---|---|---|---|")
    for name in args.only or CASES:
        truth, config, without = CASES[name]
        log = out / f"{name.removesuffix('_outside')}.csv"
        if not log.exists():
            write_log(log, hexsim.simulate(config), noise=np.random.default_rng(config.seed))
        start = time.perf_counter()
        doc = hexsim.validate(log, json_path=out / f"{name}.answer.json", jobs=args.jobs, without=without)
        wall = time.perf_counter() - start
        err = {ch: f"{doc['error_before'].get(ch, float('nan')):.2g} → {doc['error_after'].get(ch, float('nan')):.2g}"
               for ch in ("position", "p1", "acceleration")}
        print(f"| {name}: {truth} | **{doc['verdict']}** | {_effects(doc)} | {err['position']} | {err['p1']} | "
              f"{err['acceleration']} | {wall:.0f} s |", flush=True)
        (out / f"{name}.summary.json").write_text(json.dumps({"truth": truth, "verdict": doc["verdict"],
                                                              "effects": _effects(doc), "wall_s": wall}))


if __name__ == "__main__":
    main()
