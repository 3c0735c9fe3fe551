"""Calibrate, then validate, a 4-way servo axis hexsim did not write: a vertical 300 mm differential cylinder, 123 kg.

The machine is ``tests/independent_servo_axis.py`` (no hexsim import: its own valve with a knee in its flow curve at
3 V and a 60 Hz spool, four edges each its own, Stribeck friction, dead volumes, end stops, P control at 500 Hz with
K_p 800 V/m, 5 µm and 0.045 bar of sensor noise). A user who has its data sheets does what docs/calibration.md says,
here through hexsim's command line:

1. ``hexsim machine show servo_cylinder > rig.json`` and ``hexsim machine set rig.json …`` with the data sheets'
   values (bore, rod, stroke, dead volumes, rated flow, spool bandwidth, supply, the load's mass and a vertical axis,
   the controller; friction and bulk modulus guessed);
2. two closed-loop calibration logs (a chirp, steps) -> ``hexsim calibrate`` with default options;
3. logs of a 0.5 Hz, 80 mm sine, nothing added (a null) or one effect -> ``hexsim validate --machine CAL.json``.

It prints the calibrated values beside the truth, the held-out windows in budgets, and per log the hidden truth beside
the verdict and the named effects, with the wall time of each step (docs/calibration.md, "A 4-way servo axis").

``--proof`` then goes on as a user tuning a compensator would: ``hexsim tune --machine CAL.json`` (its answer printed),
and every kind of compensator tune tried, built from the calibrated file, run *in the axis's own loop* on the seed's
50 mm, 0.5 Hz sine for ``--duration`` s, with the valve's null still and drifting 1 mV/s, beside hexsim's prediction of
the same run (the passenger's view of the second half, :func:`hexsim.measured.proof.passenger_view`): whether tune's
answer holds on the machine (docs/compensation.md, "A 4-way vertical axis whose bump is its friction's"); then a log
of the axis running the tuned file, and ``hexsim tune --check`` on it.

    python examples/four_way_axis.py [--out DIR] [--only null leak …] [--jobs 2] [--proof [--duration 60]]
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import json
import pathlib
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from compensation import MODEL_BASED
from hexsim.cli import main as hexsim
from hexsim.control.scenario import make_scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import simulate
from hexsim.measured.proof import passenger_view
from hexsim.plant.machine import load_machine
from hexsim.studies.tuning import NEIGHBOURS, leg_model_of, read_tuned

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))
from helpers import in_the_loop as compensator_hook  # noqa: E402  (hexsim's compensator as the truth's callback)
from independent_servo_axis import Axis, chirp, run, sine, steps, write  # noqa: E402  (the truth lives with the tests)

TRUTH = Axis()

#: What a user's data sheets and guesses give (hexsim machine set KEY=VALUE): the geometry, the valve's rated flow
#: and bandwidth, the supply, the load, the controller are the data sheets'; friction, bulk modulus and the tank
#: pressure are guesses; the edges' matching, the knee and the overlap are not known.
DATA_SHEET = {
    "valve.rated_flow_m3ps": 4e-4, "valve.rated_dp_Pa": 3.5e6, "valve.spool_frequency_Hz": 60.0,
    "valve.spool_damping": 0.7, "cylinder.bore_m": 0.04, "cylinder.rod_m": 0.025, "cylinder.stroke_m": 0.3,
    "cylinder.dead_volume_cap_m3": 1e-4, "cylinder.dead_volume_rod_m3": 1e-4, "supply.pressure_Pa": 1e7,
    "supply.tank_pressure_Pa": 0.0, "oil.bulk_modulus_Pa": 1.5e9, "load.mass_kg": 123.0, "load.inclination_deg": 0.0,
    "friction.positive.coulomb_N": 150.0, "friction.negative.coulomb_N": 150.0,
    "friction.positive.viscous_Nspm": 1000.0, "friction.negative.viscous_Nspm": 1000.0,
    "friction.positive.static_N": 30.0, "friction.negative.static_N": 30.0, "sensors.position_noise_m": 5e-6,
    "controller.type": "P", "controller.kp_VPm": 800.0, "controller.rate_hz": 500.0,
}

#: The calibrated keys set beside the truth: key -> the truth's value.
COMPARED = {
    "valve.edge_gain_PA": TRUTH.k_pa, "valve.null_offset_V": TRUTH.null_offset,
    "valve.edge_gain_AT": TRUTH.k_at / TRUTH.k_pa, "valve.edge_gain_PB": TRUTH.k_pb / TRUTH.k_pa,
    "valve.edge_gain_BT": TRUTH.k_bt / TRUTH.k_pa, "oil.bulk_modulus_Pa": TRUTH.bulk,
    "cylinder.dead_volume_cap_m3": TRUTH.v_a, "cylinder.dead_volume_rod_m3": TRUTH.v_b,
    "friction.positive.coulomb_N": TRUTH.coulomb[0], "friction.negative.coulomb_N": TRUTH.coulomb[1],
    "friction.positive.static_N": TRUTH.static[0], "friction.negative.static_N": TRUTH.static[1],
    "friction.positive.viscous_Nspm": TRUTH.viscous, "friction.negative.viscous_Nspm": TRUTH.viscous,
    "load.mass_kg": TRUTH.mass, "supply.tank_pressure_Pa": TRUTH.tank,
}

#: name -> (the log's motion, the truth it runs on, the hidden truth in words, its seed)
LOGS = {
    "cal_chirp": (chirp, TRUTH, "calibration: a chirp 0.2-2 Hz, 30 mm", 1),
    "cal_steps": (steps, TRUTH, "calibration: steps 40-260 mm, one a second", 2),
    "null": (sine, TRUTH, "nothing", 3),
    "leak": (sine, TRUTH.replace(leakage=4e-12), "a leak across the piston, C_l 4e-12 m^3/(s Pa)", 4),
    "worn_bt": (sine, TRUTH.replace(k_bt=0.80), "the rod side's return edge B->T worn: 0.80 (0.95 before)", 5),
    "null_offset": (sine, TRUTH.replace(null_offset=0.15), "the valve's null drifted by 0.15 V", 6),
    "heavier": (sine, TRUTH.replace(mass=163.0), "40 kg more on the axis (163 kg)", 7),
}


#: The compensators of ``--proof`` besides the file ``hexsim tune`` writes: one of each kind it tries (label, name,
#: settings changed), each at the valve's edges as calibrated.
PROOF = (("none", "none", {}), ("buffered buffer_time=1.5", "buffered", {"buffer_time": 1.5}),
         ("feedforward", "feedforward", {}), ("adaptive adapt_time=1", "adaptive", {"adapt_time": 1.0}))
#: The seed's sine (hexsim's ``actuator`` scenario on a 300 mm stroke: 50 mm about mid-stroke at 0.5 Hz), the
#: null's drift of tune's ``drift`` neighbour [V/s] (its 15 K warm-up the axis does not model), the noise seed.
SINE, FREQUENCY, DRIFT_V_PER_S, PROOF_SEED = {"f": 0.5, "mid": 0.15, "amp": 0.05}, 0.5, 1e-3, 11


def in_the_loop(cal: pathlib.Path, name: str, changes: dict | pathlib.Path, duration: float, drift: bool):
    """The passenger's view of compensator ``name`` (settings ``changes``, or a tuned file) built from the
    calibrated file ``cal``, run in the axis's own loop on the seed's sine (its null drifting where ``drift``), and
    of hexsim's prediction of the same run on ``cal`` (on tune's ``drift`` neighbour where ``drift``): (measured,
    predicted)."""
    base = RunConfig.from_machine(load_machine(cal), make_scenario("actuator", duration=duration))
    if isinstance(changes, pathlib.Path):
        name, settings, model = read_tuned(changes)
    else:
        settings = dataclasses.replace(base.compensator_settings, **changes)
        model = leg_model_of(base) if name in MODEL_BASED else None
    hook = None if name == "none" else compensator_hook(name, model, settings)
    ref, states = sine(duration, **SINE), {}
    run(TRUTH.replace(null_rate=DRIFT_V_PER_S if drift else 0.0), ref, PROOF_SEED, compensate=hook, states=states)
    t = np.arange(ref.size) / 1000.0
    measured = passenger_view(t, states["acc_mps2"], ref, FREQUENCY, duration / 2, states["velocity_mps"])
    config = dataclasses.replace(base, compensator=name, compensator_settings=settings, compensator_model=model)
    if drift:
        config = next(n for n in NEIGHBOURS if n.name == "drift").apply(config)
    result = simulate(config)
    predicted = passenger_view(result.t, result.acc[:, 2], config.scenario.axis_setpoint(result.t), FREQUENCY,
                               duration / 2, result.ydot[:, 0])
    return measured, predicted


def proof(out: pathlib.Path, cal: pathlib.Path, duration: float, jobs: int) -> None:
    """``hexsim tune`` on the calibrated file, then :data:`PROOF`'s compensators in the axis's loop: the table."""
    start = time.perf_counter()
    text = io.StringIO()
    with contextlib.redirect_stdout(text), contextlib.redirect_stderr(text):
        code = hexsim(["tune", "--machine", str(cal), "--out", str(out / "tuned.json"), "--jobs", str(jobs)])
    print(f"\nhexsim tune --machine {cal.name} (exit {code}, {time.perf_counter() - start:.0f} s):\n"
          f"{text.getvalue().strip()}\n")
    tuned = [(f"the tuned file ({read_tuned(out / 'tuned.json')[0]})", "", out / "tuned.json")] if code == 0 else []
    cases = [(label, name, changes, drift) for label, name, changes in (*PROOF, *tuned) for drift in (False, True)]
    start = time.perf_counter()
    with ProcessPoolExecutor(max(jobs, 1)) as pool:
        views = list(pool.map(in_the_loop, *zip(*[(cal, n, c, duration, d) for _, n, c, d in cases])))
    print(f"in the axis's own loop, {len(cases)} runs of {duration:g} s in {time.perf_counter() - start:.0f} s\n")
    none = {d: views[i] for i, (_, n, _, d) in enumerate(cases) if n == "none"}
    print("| compensator | null | mean reversal peak, measured [m/s²] | predicted | measured / none's | predicted / "
          "none's | worst reversal / none's, measured | predicted | seat / threshold, measured | predicted |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for (label, _, _, drift), (m, p) in zip(cases, views):
        nm, npred = none[drift]
        print(f"| {label} | {'drifting 1 mV/s' if drift else 'still'} | {m.mean:.4f} | {p.mean:.4f} | "
              f"{m.mean / nm.mean:.2f} | {p.mean / npred.mean:.2f} | {m.worst_against(nm):.2f} | "
              f"{p.worst_against(npred):.2f} | {m.seat_ratio:.1f} | {p.seat_ratio:.1f} |", flush=True)
    if tuned:
        check(out, cal, tuned[0][2], duration)


def check(out: pathlib.Path, cal: pathlib.Path, tuned: pathlib.Path, duration: float) -> None:
    """The commissioning loop's first step as a user takes it: a log of the axis running the tuned file (with an
    accelerometer on the piston, 0.05 m/s² of noise), then ``hexsim tune --check`` on it; its verdict printed."""
    name, settings, model = read_tuned(tuned)
    hook = compensator_hook(name, model, settings)
    log = write(TRUTH, sine(duration, **SINE), out / "tuned_run.csv", PROOF_SEED, "the seed's sine, the tuned file",
                compensate=hook, accelerometer=0.05)
    text = _cli("tune", "--check", str(log), "--compensator", str(tuned), "--machine", str(cal))
    print(f"\nhexsim tune --check {log.name} --compensator {tuned.name} --machine {cal.name}:\n{text.strip()}")


def _log(out: pathlib.Path, name: str) -> pathlib.Path:
    motion, axis, what, seed = LOGS[name]
    path = out / f"{name}.csv"
    if not path.exists():
        write(axis, motion(), path, seed, what)
    return path


def _cli(*args: str) -> str:
    """``hexsim ARGS`` as a user types it; its standard output. Raises SystemExit on a non-zero exit."""
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        code = hexsim(list(args))
    if code:
        raise SystemExit(f"hexsim {' '.join(args)} exited {code}")
    return text.getvalue()


def calibrated(out: pathlib.Path) -> pathlib.Path:
    """The data sheets' machine file, then its calibration on the two logs (kept if there)."""
    rig, cal = out / "rig.json", out / "calibrated.json"
    if not cal.exists():
        rig.write_text(_cli("machine", "show", "servo_cylinder"))
        _cli("machine", "set", str(rig), *(f"{k}={v}" for k, v in DATA_SHEET.items()))
        start = time.perf_counter()
        text = _cli("calibrate", str(out / "cal_chirp.csv"), str(out / "cal_steps.csv"), "--machine", str(rig),
                    "--out", str(cal))
        (out / "calibration.txt").write_text(text)
        print(f"calibrated on two 20 s logs in {time.perf_counter() - start:.0f} s\n")
    doc = json.loads(cal.read_text())
    rows = {r["key"]: r for r in doc["calibration"]["parameters"]}
    print("| key | truth | calibrated ± s.e. | status |\n|---|---|---|---|")
    for key, truth in COMPARED.items():
        r = rows.get(key)
        if r is not None:
            print(f"| `{key}` | {truth:.4g} | {r['value']:.4g} ± {r['std_error']:.2g} | {r['status']} |")
    for row in doc["calibration"]["transients"]:
        after = row["after"]["held_out_rms_in_budgets"]
        print(f"\nheld-out windows of {row['after']['log']} (RMS / budget): "
              + ", ".join(f"{ch} {v:.2f}" for ch, v in after.items()))
    return cal


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="four_way_axis", help="folder for the logs, the machine files and answers")
    parser.add_argument("--only", nargs="*", choices=[n for n in LOGS if not n.startswith("cal_")],
                        help="validate only these logs")
    parser.add_argument("--jobs", type=int, default=2, help="processes writing the logs, and each validation's")
    parser.add_argument("--proof", action="store_true", help="then tune, and run the compensators in the axis's loop")
    parser.add_argument("--duration", type=float, default=60.0, help="the proof's runs [s] (judged on the second half)")
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    names = ["cal_chirp", "cal_steps", *(args.only or [n for n in LOGS if not n.startswith("cal_")])]
    start = time.perf_counter()
    with ProcessPoolExecutor(max(args.jobs, 1)) as pool:
        list(pool.map(_log, [out] * len(names), names))
    print(f"{len(names)} logs of the axis (20 s each) in {time.perf_counter() - start:.0f} s\n")
    cal = calibrated(out)
    print("\n| log (hidden truth) | verdict | named effects (fitted) | held-out RMS / budget | wall |")
    print("|---|---|---|---|---|")
    for name in names[2:]:
        answer = out / f"{name}.answer.json"
        start = time.perf_counter()
        _cli("validate", str(out / f"{name}.csv"), "--machine", str(cal), "--json", str(answer), "--quiet",
             "--jobs", str(args.jobs))
        wall = time.perf_counter() - start
        doc = json.loads(answer.read_text())
        named = "; ".join(f"{e['name']} (" + ", ".join(f"{k} = {v['value']:.4g} {v['unit']}"
                                                       for k, v in e["parameters"].items()) + ")"
                          for e in doc["added_effects"]) or "–"
        rms = ", ".join(f"{ch} {v:.2f}" for ch, v in doc["held_out_rms_in_budgets"].items())
        print(f"| {name}: {LOGS[name][2]} | **{doc['verdict']}** | {named} | {rms} | {wall:.0f} s |", flush=True)
    if args.proof:
        proof(out, cal, args.duration, args.jobs)


if __name__ == "__main__":
    main()
