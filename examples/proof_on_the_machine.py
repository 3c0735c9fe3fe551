"""Proven on the machine: hexsim's calibrate, tune and commissioning judged on machines hexsim did not write,
each running the tuned file in its own loop (the compensator called exactly as hexsim's 500 Hz P controller
calls it), never on hexsim's model of them.

Machines (their own equations, no hexsim import in the physics):

- ``R1``: the reference plant of ``../shared/reference-plants`` (a spool whose rounded metering edge meets the
  port at 0.9 V, where the flow gain halves; no dead band; 5 µm position noise), calibrated on its shipped
  logs ``cal_chirp`` and ``cal_steps``;
- ``corner``: ``tests/independent_actuator.py``'s port-limited spool off appendix A (flow gain +4 %, return edge
  0.93, overlap 6 µm, 1.4 GPa, 42 kg, its own friction), calibrated on a chirp and steps of its own;
- ``underlap``: its "spool" valve (edges open 6 µm before null and are rounded: no dead band), the same way;
- ``drift``: ``corner`` whose null drifts 0.001 V/s while its oil warms 15 K over the run (calibrated cold).

For each: ``hexsim calibrate`` on the two logs (defaults), ``hexsim tune`` on the calibrated file (defaults:
the ``actuator`` motion, the neighbours with two machines drawn from the calibration's uncertainty), then the tuned file
in the machine's loop on the seed's 50 mm 0.5 Hz sine
(``--duration`` s, judged on the second half: the passenger's view, :func:`hexsim.measured.proof.passenger_view`),
beside hexsim's prediction of the same run (the mean over the calibrated file and the eight machines its
calibration's uncertainty allows, as ``hexsim tune --check`` predicts, their range beside it); then up to
``--runs`` commissioning runs (the runs' logs read back into the model by ``hexsim tune --from-logs``, the
improved file run again; where a run's log shows its file worse than the one before, the step writes that one
back, and the row says "kept").

    python examples/proof_on_the_machine.py [--machines R1,corner,underlap,drift] [--runs 3] [--duration 60] [--floor]

``--floor`` adds, on R1, the floor any static inverse can reach there: the fixed feedforward with R1's own leg
model (its flow curve, friction, oil spring and mass from ``../shared/reference-plants``' equations, not a
calibration) in R1's loop, with its sensors' noise and without; and the tuned file's leg model with R1's own flow
curve in place of the calibrated one (what the curve alone costs). On the independent actuators it adds the fixed
feedforward on the tuned file's leg model as it is, with the actuator's own flow curve, and with its own friction
as well (``tests/independent_actuator.py``'s equations): what each part of the calibrated model costs.

It made the tables of docs/compensation.md ("Proven on the machine").
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import sys
import tempfile
import time

import numpy as np

from compensation import make_compensator
from hexsim.control.scenario import make_scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import simulate
from hexsim.measured.calibration import calibrate
from hexsim.measured.commissioning import commissioning_step
from hexsim.measured.measurement import read_log
from hexsim.measured.null_drift import last_drift, with_drift
from hexsim.measured.proof import passenger_view
from hexsim.measured.records import plausible_machines
from hexsim.measured.reports.commissioning import step_lines
from hexsim.plant.machine import dump, load_machine
from hexsim.studies.tuning import (
    TUNE_DRAWS,
    Candidate,
    neighbours,
    read_tuned,
    tune,
    write_tuned,
)

HERE = pathlib.Path(__file__).resolve().parent
REFERENCE = HERE.parent.parent / "shared" / "reference-plants"
sys.path[:0] = [str(HERE.parent / "tests"), str(REFERENCE)]
from independent_actuator import Actuator, motion, write

#: The seed's sine (eq. 3.10): 50 mm at 0.5 Hz about mid-stroke, faded in over 2 s.
FREQUENCY, AMPLITUDE = 0.5, 0.05
CORNER = Actuator(area="port", flow_gain=1.04, k_at=0.93, overlap=6e-6, bulk=1.4e9, v_pl=8e-7, mass=42.0,
                  coulomb=(72.0, 58.0), viscous=(2500.0, 1900.0), static=(25.0, 35.0))
UNDERLAP = CORNER.replace(area="spool", underlap=6e-6, rounding=8e-6, port_width=0.85)
MACHINES = {"R1": None, "corner": CORNER, "underlap": UNDERLAP,
            "drift": CORNER.replace(null_rate=0.001, warm_rate=0.25)}
NOISE = (5e-6, 2e3, 0.0)  # position as R1's transducer reads it, pressure; the acceleration judged without noise


def chirp(duration: float, stroke: float) -> np.ndarray:
    """0.1 → 3 Hz, amplitude min(60 mm, 12 mm / f), faded in over 2 s, about mid-stroke, a setpoint a ms."""
    t = np.arange(0.0, duration, 1e-3)
    f = 0.1 + 2.9 * t / duration
    phase = 2 * np.pi * (0.1 * t + 0.5 * 2.9 * t * t / duration)
    return stroke / 2 + np.clip(t / 2.0, 0, 1) * np.minimum(0.06, 0.012 / f) * np.sin(phase)


def steps(duration: float, stroke: float) -> np.ndarray:
    """Steps of 10 to 40 mm either side of mid-stroke, each held 2 s, faded in over 2 s."""
    t = np.arange(0.0, duration, 1e-3)
    levels = np.array([0.0, 0.03, -0.02, 0.04, -0.04, 0.01, -0.03, 0.02, 0.0, 0.035])
    return stroke / 2 + np.clip(t / 2.0, 0, 1) * levels[(t / 2.0).astype(int) % len(levels)]


class Truth:
    """One machine: its calibration logs and a run of the seed's sine with a compensator in its own loop."""

    def __init__(self, name: str, folder: pathlib.Path) -> None:
        self.name, self.folder, self.actuator = name, folder, MACHINES[name]

    def calibration_logs(self) -> list[pathlib.Path]:
        if self.actuator is None:
            return [REFERENCE / "r1" / "cal_chirp.csv", REFERENCE / "r1" / "cal_steps.csv"]
        cold = self.actuator.replace(null_rate=0.0, warm_rate=0.0)
        rng = np.random.default_rng(7)
        return [write(motion(cold, 20.0, 1.0, 0.0, rng, noise=(5e-6, 2e3, 0.05), reference=make(20.0, cold.stroke)),
                      self.folder / f"{self.name}_cal_{make.__name__}.csv", f"calibration: {make.__name__}")
                for make in (chirp, steps)]

    def run(self, compensator, duration: float, seed: int, log: pathlib.Path | None = None):
        """(t, ref, acceleration without sensor noise as an accelerometer sampled at 1 kHz averages it over each
        millisecond (what hexsim records), velocity, the instantaneous acceleration where the machine gives it
        (R1; else None)) of the sine with ``compensator`` (None: none) in the machine's loop; the run's
        measurement log written to ``log``."""
        if self.actuator is None:
            import plant
            import r1

            rows, extra = plant.simulate(effects=r1.effects("r1_f"), ref="sine", T=duration, seed=seed,
                                         compensator=compensator)
            if log is not None:
                plant.write(log.stem, rows, r1.META, log.parent)
            return rows[:, 0], rows[:, 1], extra["acc_mean"], extra["v"], extra["acc"]
        hook = None
        if compensator is not None:
            from compensation.leg_model import Reference

            def hook(u_p, y, r, r_dot, r_ddot, r_dddot, p1):
                compensator.observe(Reference(*(np.array([x]) for x in (r, r_dot, r_ddot, r_dddot, p1))))
                return float(compensator.update(np.array([u_p]), np.array([y]))[0])
        cols = motion(self.actuator, duration, FREQUENCY, AMPLITUDE, np.random.default_rng(seed), noise=NOISE,
                      compensate=hook)
        if log is not None:
            write(cols, log, "the seed's sine with the tuned compensator")
        velocity = np.gradient(cols["pos_m"], cols["time_s"])  # judged at the measured reversals (noise-free enough)
        return cols["time_s"], cols["ref_m"], cols["acc_mps2"], velocity, None


def judged(t, ref, acc, velocity, instantaneous, duration):
    """The passenger's view of a run (1 ms means) and, where the machine gives it, of its instantaneous samples."""
    view = passenger_view(t, acc, ref, FREQUENCY, duration / 2, velocity)
    return view, None if instantaneous is None else passenger_view(t, instantaneous, ref, FREQUENCY, duration / 2,
                                                                   velocity)


def predicted(machine, tuned: pathlib.Path | None, duration: float, candidate: tuple | None = None) -> dict:
    """hexsim's prediction of the same run: the calibrated machine with the tuned file (None: uncompensated), and the
    same on the machines drawn from what its calibration leaves uncertain (``plausible_machines``, as
    ``hexsim tune --check`` predicts): {"view": the calibrated file's passenger view, "models": every model's mean
    reversal peak [m/s^2], the calibrated file's first}. A tuned file whose last commissioning found the valve's null
    drifting in the run before is predicted with that drift (``hexsim tune --check`` does the same). ``candidate``
    (compensator, settings): that compensator on the tuned file's leg model instead of the file's own."""
    options, drift = {}, None
    if tuned is not None:
        name, settings, model = read_tuned(tuned)
        name, settings = candidate or (name, settings)
        options = {"compensator": name, "compensator_settings": settings, "compensator_model": model}
        drift = last_drift(json.loads(tuned.read_text()))
    views = []
    for m in [machine, *plausible_machines(machine)]:
        config = RunConfig.from_machine(m, make_scenario("actuator", duration=duration), **options)
        result = simulate(config if drift is None else with_drift(config, drift, drift.duration))
        setpoint = result.config.scenario.axis_setpoint(result.t)
        views.append(passenger_view(result.t, result.acc[:, 2], setpoint, FREQUENCY, duration / 2, result.ydot[:, 0]))
    return {"view": views[0], "models": [v.mean for v in views]}


def prove(name: str, runs: int, duration: float, folder: pathlib.Path) -> list[dict]:
    truth = Truth(name, folder)
    start = time.time()
    prior = load_machine(None)
    logs = [read_log(p, machine=prior) for p in truth.calibration_logs()]
    result = calibrate(logs, prior)
    cal, report = result.machine, result.report
    cal_path = folder / f"{name}_cal.json"
    cal_path.write_text(dump(cal.document()))
    cal = load_machine(cal_path)
    form = report.get("flow_area", {}).get("chosen")
    base = RunConfig.from_machine(cal, make_scenario("actuator", duration=20.0))
    result = tune(base, ("actuator",), neighbours=neighbours(drawn=plausible_machines(cal, TUNE_DRAWS)))
    tuned = folder / f"{name}_tuned_0.json"
    write_tuned(tuned, result, base, ("actuator",))
    print(f"{name}: calibrated ({form}; own logs {report['own_budget']['held_out_rms_in_budgets']}) and tuned "
          f"({result.chosen.label}) in {time.time() - start:.0f} s", flush=True)
    none, none_now = judged(*truth.run(None, duration, 11), duration)
    rows = [{"machine": name, "run": "none", "measured": none, "instantaneous": none_now,
             "predicted": predicted(cal, None, duration)}]
    machine, kept = cal, None
    for k in range(runs + 1):
        name_, settings, model = read_tuned(tuned)
        comp = make_compensator(name_, 1, 500.0, settings=settings, model=model)
        log = folder / f"{name}_run{k}.csv"
        view, now = judged(*truth.run(comp, duration, 20 + k, log), duration)
        label = "tuned" if k == 0 else f"commissioned {k}" + (f" (kept {kept})" if kept else "")
        rows.append({"machine": name, "run": f"{name_} {label}",
                     "measured": view, "instantaneous": now, "predicted": predicted(machine, tuned, duration),
                     "none": none, "none_instantaneous": none_now})
        if k == runs:
            break
        step = commissioning_step([folder / f"{name}_run{j}.csv" for j in range(k + 1)], tuned, cal)
        machine = step.learned.machine
        (folder / f"{name}_cal_{k + 1}.json").write_text(dump(machine.document()))
        nxt = folder / f"{name}_tuned_{k + 1}.json"
        nxt.write_text(json.dumps(step.doc))
        kept = None if step.kept is None else pathlib.Path(step.kept["file"]).name
        print("\n".join(f"{name}: {line}" for line in step_lines(step, str(tuned))), flush=True)
        tuned = nxt
    return rows


def r1_own_model():
    """R1's leg as the feedforward sees a leg (:class:`compensation.leg_model.LegModel`), from the reference plant's
    own equations and R1's values (``plant.SEED`` with ``r1.R1``): the flow curve at the rest pressure on a 10 mV
    grid, the friction curve, A1, E, V_pl, M. What no calibration can beat: the floor of a static inverse."""
    import plant
    import r1

    from compensation.leg_model import LegModel

    p = {**plant.SEED, **r1.R1}
    a1, a2, g = p["A1"], p["A2"], p["g"]
    p_rest = p["Ps"] * a2 / a1 + p["M"] * g / a1
    u = np.linspace(-p["uvmax"], p["uvmax"], 2001)
    x = np.abs(u) * p["xvmax"] / p["uvmax"]
    area = np.array([plant.port_area(xi, **p["area_kw"]) for xi in x])
    drop = np.where(u > 0, p["Ps"] - p_rest, p_rest - p["Pt"])
    velocity = np.sign(u) * p["Cd"] * area * np.sqrt(2 * drop / p["rho"]) / a1
    v = np.linspace(-0.5, 0.5, 2001)
    side = {True: ("sp", "Fcp", "Fsp"), False: ("sm", "Fcm", "Fsm")}
    force = np.array([p[side[vi >= 0][0]] * vi + np.arctan(p["k"] * vi) * (p[side[vi >= 0][1]] + p[side[vi >= 0][2]]
                      * np.exp(-abs(vi) / p["cs"])) for vi in v])
    slope = (np.interp(1.0, u, velocity) - np.interp(-1.0, u, velocity)) / 2.0
    return LegModel(u=u, velocity=velocity[None, :], p_rest=np.array([p_rest]), supply_pressure=p["Ps"],
                    tank_pressure=p["Pt"], area_bottom=a1, bulk_modulus=p["E"], pipeline_volume=p["Vpl"],
                    mass=np.array([[p["M"]]]), friction_v=v, friction_f=force, slope=np.array([slope]), kp=200.0,
                    source="R1's own equations (../shared/reference-plants)")


def floor(duration: float, none: dict, tuned: pathlib.Path) -> list[dict]:
    """The rows of ``--floor``: the fixed feedforward on R1's own leg model in R1's loop, with its sensors' noise and
    without, and on the ``tuned`` file's leg model with R1's own flow curve (``none``: the uncompensated row, for
    the reductions)."""
    import dataclasses

    import plant
    import r1

    own, calibrated = r1_own_model(), read_tuned(tuned)[2]
    swapped = dataclasses.replace(calibrated, u=own.u, velocity=own.velocity, slope=own.slope)
    rows = []
    for label, model, noise in (("feedforward on R1's own model (floor)", own, None),
                                ("the same, sensors without noise", own, dict(pos=0.0, p=0.0, acc=0.0)),
                                ("feedforward on the tuned file with R1's own curve", swapped, None)):
        comp = make_compensator("feedforward", 1, 500.0, model=model)
        effects = r1.effects("r1_f")
        if noise:
            effects["noise"] = noise
        out, extra = plant.simulate(effects=effects, ref="sine", T=duration, seed=20, compensator=comp)
        view, now = judged(out[:, 0], out[:, 1], extra["acc_mean"], extra["v"], extra["acc"], duration)
        rows.append(_floor_row("R1", label, view, now, none))
    return rows


def _floor_row(machine: str, label: str, view, now, none: dict) -> dict:
    """A row of ``--floor``: a run with no prediction, judged against the uncompensated row ``none``."""
    return {"machine": machine, "run": label, "measured": view, "instantaneous": now, "predicted": None,
            "none": none["measured"], "none_instantaneous": none["instantaneous"]}


def own_parts(truth: Truth, duration: float, none: dict, tuned: pathlib.Path) -> list[dict]:
    """The rows of ``--floor`` on an independent actuator: the fixed feedforward on the ``tuned`` file's leg model in
    the actuator's loop as it is, with the actuator's own flow curve (its net piston velocity at mid-stroke and its
    rest pressure, from ``tests/independent_actuator.py``'s ``leg_at``), and with its own friction curve as well (the
    same ``leg_at``'s) (``none``: the uncompensated row). Raises ValueError for an actuator with entrained air (its chamber's
    stiffness, which the velocity is read through here, is not the oil's)."""
    import dataclasses

    from independent_actuator import _pack, leg_at

    s = truth.actuator
    if s.air > 0:
        raise ValueError(f"{truth.name}: own_parts reads the flow through the oil's bulk modulus; this one has air")
    c = _pack(s)
    a1, a2, y = c[0], c[1], s.stroke / 2
    p_rest = (s.supply * a2 + s.mass * 9.81 * math.cos(math.radians(s.inclination_deg))) / a1
    model = read_tuned(tuned)[2]
    velocity = np.array([leg_at(c, y, 0.0, p_rest, (u - s.null_offset) / s.u_max * s.x_max, s.supply)[0]
                         for u in model.u]) * (a1 * y + s.v_pl) / s.bulk / a1
    # its friction as leg_at has it: the pressure force less the net force at mid-stroke (no end stop there)
    friction = np.array([p_rest * a1 - s.supply * a2 - leg_at(c, y, v, p_rest, 0.0, s.supply)[1]
                         for v in model.friction_v])
    curve = dataclasses.replace(model, velocity=velocity[None, :])
    rows = []
    for label, leg in (("feedforward on the tuned file's model", model),
                       (f"the same with {truth.name}'s own curve", curve),
                       (f"the same with {truth.name}'s own curve and friction", dataclasses.replace(
                           curve, friction_f=friction))):
        comp = make_compensator("feedforward", 1, 500.0, model=leg)
        rows.append(_floor_row(truth.name, label, *judged(*truth.run(comp, duration, 20), duration), none))
    return rows


def candidate_rows(truth: Truth, duration: float, none: dict, tuned: pathlib.Path, specs: list[str]) -> list[dict]:
    """The rows of ``--candidate``: each compensator ``NAME[:KEY=VALUE,…]`` (its settings changed from the defaults) on
    the ``tuned`` file's leg model, in the machine's loop (the run the tuned file had, same seed) and predicted on the
    calibrated file and its draws (``none``: the uncompensated row). What ``hexsim tune``'s choice weighs: on a
    machine whose null stays, a compensator the drifting neighbour refused may leave less at the seat."""
    from compensation import CompensatorSettings

    machine = load_machine(tuned.parent / f"{truth.name}_cal.json")
    model = read_tuned(tuned)[2]
    rows = []
    for spec in specs:
        name, _, rest = spec.partition(":")
        changes = {k: float(v) for k, v in (kv.split("=") for kv in rest.split(",") if kv)}
        settings = CompensatorSettings(**changes)
        comp = make_compensator(name, 1, 500.0, settings=settings, model=model)
        view, now = judged(*truth.run(comp, duration, 20), duration)
        rows.append({"machine": truth.name, "run": f"{Candidate(name, settings).label} on the tuned file's model",
                     "measured": view, "instantaneous": now, "none": none["measured"],
                     "none_instantaneous": none["instantaneous"],
                     "predicted": predicted(machine, tuned, duration, (name, settings))})
    return rows


def table(rows: list[dict]) -> str:
    """Measured (1 ms means, as hexsim records) beside predicted; the instantaneous samples' reduction where the
    machine gives them."""
    head = ("| machine | compensator | mean reversal peak, measured [m/s²] | predicted (its models' range) | "
            "reduction | instantaneous "
            "reduction | worst reversal / none's | seat W_k peak / threshold, measured | predicted |")
    out = [head, "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        m, p, none = r["measured"], r["predicted"], r.get("none")
        red = f"{100 * (1 - m.mean / none.mean):.1f} %" if none else "–"
        now, none_now = r.get("instantaneous"), r.get("none_instantaneous")
        red_now = f"{100 * (1 - now.mean / none_now.mean):.1f} %" if now is not None and none_now is not None else "–"
        worst = f"{m.worst_against(none):.2f}" if none else "–"
        p_mean, p_seat = ((f"{np.mean(p['models']):.4f} ({min(p['models']):.4f}–{max(p['models']):.4f})",
                           f"{p['view'].seat_ratio:.2f}") if p else ("–", "–"))
        out.append(f"| {r['machine']} | {r['run']} | {m.mean:.4f} | {p_mean} | {red} | {red_now} | {worst} | "
                   f"{m.seat_ratio:.2f} | {p_seat} |")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--machines", default=",".join(MACHINES))
    ap.add_argument("--runs", type=int, default=3, help="commissioning runs after the tuned one (default 3)")
    ap.add_argument("--duration", type=float, default=60.0, help="each run on the machine [s] (default 60)")
    ap.add_argument("--keep", type=pathlib.Path, help="keep the logs and files in this folder")
    ap.add_argument("--floor", action="store_true", help="on R1, add the floor: the feedforward on R1's own model; "
                    "on the others, the feedforward on the tuned model with the machine's own curve and friction")
    ap.add_argument("--candidate", action="append", default=[], metavar="NAME[:KEY=VALUE,...]",
                    help="also run this compensator (its settings changed from the defaults) on the tuned file's leg "
                    "model in the machine's loop and on hexsim's model (repeatable)")
    args = ap.parse_args(argv)
    names = [m for m in args.machines.split(",") if m]
    unknown = [m for m in names if m not in MACHINES]
    if unknown:
        ap.error(f"unknown machine {unknown[0]!r}; choose from {', '.join(MACHINES)}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or pathlib.Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for name in names:
            mine = prove(name, args.runs, args.duration, folder)
            rows += mine
            if args.floor and name == "R1":
                rows += floor(args.duration, mine[0], folder / "R1_tuned_0.json")
            elif args.floor:
                rows += own_parts(Truth(name, folder), args.duration, mine[0], folder / f"{name}_tuned_0.json")
            if args.candidate:
                rows += candidate_rows(Truth(name, folder), args.duration, mine[0], folder / f"{name}_tuned_0.json",
                                       args.candidate)
            print(table([r for r in rows if r["machine"] == name]), flush=True)
    print("\n" + table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
