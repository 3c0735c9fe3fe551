"""Motion acceptance tests on measured logs: the same figures from a log of the test as from the simulated
machine, side by side (:mod:`hexsim.studies.acceptance`).

A hexapod log (``docs/measurement-log.md``) of a test motion carries the platform setpoint (``dof_ref_*``) and
the legs' measured positions; the degree of freedom that moves most is the test's, its dominant frequency
the test frequency. From the log: the platform's measured pose (forward kinematics of the leg positions,
seed §2.2.3), its fundamental against the setpoint's (gain, phase: the frequency-response point), and,
where the accelerometer is logged and the motion is a translation, the largest reversal bump (the
turn-around check). The simulated machine then runs the log's own setpoints and gives the same figures.
Both are checked against the tolerance file's bands.
"""

from __future__ import annotations

import dataclasses
import math
import pathlib

import numpy as np

from hexsim.control.kinematics import HexapodGeometry
from hexsim.control.scenario import DOF_NAMES, FILE_COLUMNS, Scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import simulate
from hexsim.errors import InputError
from hexsim.measured.measurement import read_log
from hexsim.plant.model import load_model
from hexsim.signals import dominant_frequency, fit_fundamental
from hexsim.studies.acceptance import (
    AcceptanceResult,
    Tolerances,
    at_most,
    within,
    wrap_deg,
)
from hexsim.studies.metrics import STANDARD_GRAVITY, smoothness

#: a sine DOF's name by its index in a pose (acceptance's names)
_DOF_BY_AXIS = ("surge", "sway", "heave", "roll", "pitch", "yaw")


def _figures(t: np.ndarray, ref: np.ndarray, pose: np.ndarray, acc: np.ndarray | None, axis: int,
             frequency: float) -> dict:
    """Gain [dB], phase [deg] and (translations with an accelerometer) the largest reversal bump [g] of one
    test motion: ``ref``, ``pose`` (N, 6), ``acc`` (N, 3) or None, from two periods on."""
    sel = t >= t[0] + 2.0 / frequency
    _, a_out, ph_out, _ = fit_fundamental(t[sel], pose[sel, axis], frequency)
    _, a_in, ph_in, _ = fit_fundamental(t[sel], ref[sel, axis], frequency)
    out = {"gain_db": 20 * math.log10(a_out / a_in), "phase_deg": wrap_deg(math.degrees(ph_out - ph_in)),
           "bump_g": None}
    if acc is not None and axis < 3:
        sm = smoothness(t, acc[:, axis], frequency, t[0] + 2.0 / frequency, ref[:, axis], name="log", unit="m/s^2",
                        velocity=np.gradient(pose[:, axis], t))
        if sm.reversal_peaks.size:
            out["bump_g"] = float(np.max(sm.reversal_peaks)) / STANDARD_GRAVITY
    return out


def read_test_log(path: pathlib.Path, base: RunConfig):
    """A log of a test motion, checked (module doc): (the log, times (N,) [s] from 0, the setpoint (N, 6), the
    test's pose axis, its frequency [Hz]). Raises InputError naming the log for a single-actuator log, one
    without a ``dof_ref_*`` column or leg positions, a setpoint that does not move, or fewer than three
    periods of it."""
    log = read_log(path, base.machine, needs=("pos_m",))
    if log.system != "hexapod":
        raise InputError(f"{path}: a single actuator's log; the motion tests are a hexapod's")
    present = [c for c in FILE_COLUMNS if c in log.columns]
    if not present:
        raise InputError(f"{path}: no dof_ref_* column (the platform setpoint of the test; docs/measurement-log.md)")
    t = log.time - log.time[0]
    ref = np.zeros((t.size, 6))
    for c in present:
        ref[:, FILE_COLUMNS[c]] = log.columns[c]
    axis = int(np.argmax(np.ptp(ref, axis=0) * np.array([1, 1, 1, 0.5, 0.5, 0.5])))
    try:
        frequency = dominant_frequency(t, ref[:, axis])
    except ValueError:
        raise InputError(f"{path}: the platform setpoint does not move") from None
    if t[-1] < 3.0 / frequency:
        raise InputError(f"{path}: {t[-1]:.3g} s hold less than three periods of its {frequency:.3g} Hz test motion")
    return log, t, ref, axis, frequency


def log_test(path: pathlib.Path, base: RunConfig) -> dict:
    """One log's test figures, measured and simulated (module doc): {"log", "dof", "frequency_hz",
    "amplitude", "measured": figures, "simulated": figures}. Raises InputError as :func:`read_test_log`."""
    log, t, ref, axis, frequency = read_test_log(path, base)
    geo = HexapodGeometry.from_model(load_model("hexapod", base.model, base.effects, base.geometry))
    y = log.leg_array("pos_m")
    pose = np.empty_like(ref)
    guess = np.zeros(6)
    for k in range(t.size):
        guess = pose[k] = geo.forward(y[k], guess)
    acc_cols = [f"platform_acc_{a}_mps2" for a in "xyz"]
    acc = np.column_stack([log.columns[c] for c in acc_cols]) if all(c in log.columns for c in acc_cols) else None
    measured = _figures(t, ref, pose, acc, axis, frequency)
    sc = Scenario(f"log:{path.name}", "hexapod", float(t[-1]), axis, frequency, 1.0 / frequency, None, (t, ref))
    r = simulate(dataclasses.replace(base, scenario=sc, progress=False))
    simulated = _figures(r.t, r.pose_ref, r.pose, r.acc, axis, frequency)
    return {"log": str(path), "dof": _DOF_BY_AXIS[axis], "axis": DOF_NAMES[axis], "frequency_hz": frequency,
            "amplitude": float(np.ptp(ref[:, axis]) / 2), "measured": measured, "simulated": simulated}


def add_log_tests(result: AcceptanceResult, logs: list[pathlib.Path], base: RunConfig, tol: Tolerances) -> None:
    """Each log's test (:func:`log_test`) into ``result``: its figures under ``result.logs`` and, measured and
    simulated, its checks against the frequency-response band and the turn-around limit."""
    band = tol.frequency_response
    limit = (tol.turn_around or {}).get("max_bump_g")
    for path in logs:
        fig = log_test(pathlib.Path(path), base)
        result.logs.append(fig)
        name, f = pathlib.Path(path).name, fig["frequency_hz"]
        inside = band is not None and band.from_hz <= f <= band.to_hz
        for source in ("measured", "simulated"):
            values = fig[source]
            item = f"{fig['dof']} at {f:.3g} Hz ({name}, {source})"
            result.checks.append(within("log", f"{item}, gain", values["gain_db"], "dB",
                                         band.gain_db if inside else None))
            result.checks.append(within("log", f"{item}, phase", values["phase_deg"], "deg",
                                         band.phase_deg if inside else None))
            if values["bump_g"] is not None:
                result.checks.append(at_most("log", f"{item}, largest bump", values["bump_g"], "g", limit))
