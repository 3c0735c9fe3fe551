"""Where the tuned feedforward's leftover on ``underlap`` comes from: the machine (``tests/independent_actuator.py``'s
underlapped spool, examples/proof_on_the_machine.py) beside hexsim's calibrated model of it, the same tuned file in
both loops, read without sensor noise.

It prints, for the uncompensated run and the tuned one, the largest 50-120 Hz ringing after the fade-in (the oil
column's resonance, f_h = sqrt(E A1^2 / (V M)) / 2 pi from the calibrated file at three piston positions); the
calibrated flow curve beside the machine's openings near null; and hexsim's mean reversal peak on the tuned file's
neighbours (each edge 10 and 20 mV earlier and later): how much the prediction hangs on the curve there.

    python examples/proof_on_the_machine.py --machines underlap --runs 0 --keep DIR
    python examples/underlap_leftover.py DIR

It made the paragraph "Where underlap's leftover is" of docs/compensation.md.
"""

from __future__ import annotations

import argparse
import math
import pathlib
import sys

import numpy as np
from scipy.signal import butter, sosfiltfilt

from compensation import make_compensator
from hexsim.control.scenario import make_scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import simulate
from hexsim.measured.proof import passenger_view
from hexsim.plant import hydraulics
from hexsim.plant.machine import load_machine
from hexsim.studies.tuning import neighbours, read_tuned

HERE = pathlib.Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "tests"), str(HERE)]
import independent_actuator as truth_plant  # noqa: E402
from proof_on_the_machine import FREQUENCY, UNDERLAP, Truth  # noqa: E402

DURATION = 20.0  # [s]; the ringing read from 10 s on, the reversal peaks over the second half


def ringing(t: np.ndarray, acc: np.ndarray) -> float:
    """The largest 50-120 Hz departure [m/s^2] of ``acc`` (N,) at 1 kHz from 10 s on (4th-order Butterworth,
    forward and back)."""
    band = sosfiltfilt(butter(4, [50.0, 120.0], btype="band", fs=1000.0, output="sos"), acc)
    return float(np.abs(band[t > 10.0]).max())


def runs(machine, folder: pathlib.Path, name, settings, model) -> None:
    truth = Truth("underlap", folder)
    for label, tuned in (("none", False), (f"tuned {name}", True)):
        comp = make_compensator(name, 1, 500.0, settings=settings, model=model) if tuned else None
        t, _, acc, _, _ = truth.run(comp, DURATION, 20)  # the proof's own loop of the machine, its seed 20
        options = dict(compensator=name, compensator_settings=settings, compensator_model=model) if tuned else {}
        result = simulate(RunConfig.from_machine(machine, make_scenario("actuator", duration=DURATION), **options))
        print(f"{label:<22} 50-120 Hz ringing, largest: machine {ringing(t, acc):.4f}, "
              f"hexsim {ringing(result.t, result.acc[:, 2]):.4f} m/s^2")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=pathlib.Path, help="the proof's --keep folder (underlap_cal.json, "
                                                          "underlap_tuned_0.json)")
    args = parser.parse_args(argv)
    machine = load_machine(args.folder / "underlap_cal.json")
    name, settings, model = read_tuned(args.folder / "underlap_tuned_0.json")
    h, e = machine.hydraulics, machine.effects
    f_h = [math.sqrt(h.bulk_modulus * h.area_bottom ** 2 / ((h.pipeline_volume + h.area_bottom * y) * e.mass_kg))
           / (2 * math.pi) for y in (0.1, 0.15, 0.2)]
    print(f"oil column's resonance at 0.10 / 0.15 / 0.20 m: {f_h[0]:.0f} / {f_h[1]:.0f} / {f_h[2]:.0f} Hz")
    runs(machine, args.folder, name, settings, model)

    packed = truth_plant._pack(UNDERLAP)
    print("command [V]  machine P→A, A→T  /  calibrated P→A, A→T  [mm²]")
    for u in (-0.15, -0.06, 0.0, 0.06, 0.15):
        x = np.array([u / h.u_v_max * h.x_v_max])
        a_pa, a_at = hydraulics.flow_areas(x, h)
        truth = [truth_plant.spool_edge(packed, s * u / UNDERLAP.u_max * UNDERLAP.x_max) * UNDERLAP.flow_gain
                 * (1.0 if s > 0 else UNDERLAP.k_at) for s in (1, -1)]
        print(f"{u:+.2f}        {truth[0] * 1e6:.3f}, {truth[1] * 1e6:.3f}  /  {a_pa[0] * e.edge_gain_pa * 1e6:.3f}, "
              f"{a_at[0] * e.edge_gain_at * 1e6:.3f}")

    base = RunConfig.from_machine(machine, make_scenario("actuator", duration=30.0), compensator=name,
                                  compensator_settings=settings, compensator_model=model)
    shifted = [n for n in neighbours(0.01) if n.name != "drift"] + [
        n for n in neighbours(0.02) if n.name in ("underlap", "overlap")]
    for n in shifted:
        result = simulate(n.apply(base))
        setpoint = result.config.scenario.axis_setpoint(result.t)
        view = passenger_view(result.t, result.acc[:, 2], setpoint, FREQUENCY, 15.0, result.ydot[:, 0])
        print(f"hexsim on {n.name:<10} ({n.open_earlier_V * 1e3:+.0f} mV): mean reversal peak {view.mean:.4f} m/s^2")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
