"""Writing a run in the measurement-log format (``docs/measurement-log.md``): CSV + JSON sidecar.

Simulated runs are written in the same format hexsim reads measured data in, so both can be compared
with the same tools.
"""

from __future__ import annotations

import json
import os
import pathlib

import numpy as np

from hexsim.engine.config import SimulationResult
from hexsim.tables import write_atomic


def log_columns(result: SimulationResult) -> dict[str, np.ndarray]:
    """Columns (name -> (N,) array) of the measurement log for this run, SI units, names per the format."""
    cols: dict[str, np.ndarray] = {"time_s": result.t}
    closed = not result.config.scenario.open_loop  # open loop: no setpoint column
    four_way = result.config.hydraulics.four_way  # the rod side's pressure, p2_Pa
    if result.config.scenario.system == "actuator":
        cols.update({**({"ref_m": result.y_ref[:, 0]} if closed else {}), "valve_cmd_V": result.u_v[:, 0],
                     "pos_m": result.y[:, 0], "p1_Pa": result.p1[:, 0],
                     **({"p2_Pa": result.p2[:, 0]} if four_way else {}), "ps_Pa": result.p_s,
                     "acc_mps2": result.acc[:, 2]})
        return cols
    for i in range(result.n_legs):
        n = i + 1
        if closed:
            cols[f"leg{n}_ref_m"] = result.y_ref[:, i]
        cols[f"leg{n}_valve_cmd_V"] = result.u_v[:, i]
        cols[f"leg{n}_pos_m"] = result.y[:, i]
        cols[f"leg{n}_p1_Pa"] = result.p1[:, i]
        if four_way:
            cols[f"leg{n}_p2_Pa"] = result.p2[:, i]
    cols["ps_Pa"] = result.p_s
    for k, name in enumerate(("x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad")):
        if result.pose_ref is not None:  # None: a run of leg setpoints (a replayed log) has no DOF reference
            cols[f"dof_ref_{name}"] = result.pose_ref[:, k]
    for k, axis in enumerate("xyz"):
        cols[f"platform_acc_{axis}_mps2"] = result.acc[:, k]
    for k, axis in enumerate("xyz"):
        cols[f"platform_gyro_{axis}_radps"] = result.gyro[:, k]
    from hexsim.plant.geometry import MICRO_MOTION_SYSTEM
    from hexsim.studies.perception import point_motion

    head = point_motion(result, (result.config.geometry or MICRO_MOTION_SYSTEM).head_point)
    for k, axis in enumerate("xyz"):
        cols[f"head_f_{axis}_mps2"] = head.specific_force[:, k]
    for k, axis in enumerate("xyz"):
        cols[f"head_omega_{axis}_radps"] = head.angular_velocity[:, k]
    return cols


def sidecar(result: SimulationResult, folder: pathlib.Path | None = None) -> dict:
    """The JSON sidecar: system, sample rate, controller (``none`` for an open-loop run), machine (the
    machine file relative to ``folder``, the log's, or a built-in's name), parameters, acquisition (how
    each channel was sampled), description."""
    cfg = result.config
    rate = 1.0 / float(np.median(np.diff(result.t)))
    controller = ({"type": "none"} if cfg.scenario.open_loop else
                  {"type": "P", "kp_V_per_m": cfg.controller.kp, "rate_hz": cfg.controller.rate_hz})
    machine = {}
    if cfg.machine_spec is not None:
        given = pathlib.Path(cfg.machine_spec)
        machine = {"machine": os.path.relpath(given.resolve(), (folder or pathlib.Path()).resolve())
                   if given.suffix == ".json" else cfg.machine_spec}
    return {
        "system": "single-actuator" if cfg.scenario.system == "actuator" else "hexapod",
        "sample_rate_hz": round(rate, 6),
        "controller": controller,
        **machine,
        "parameters": ("seed appendix A (nominal)" if cfg.hydraulics == type(cfg.hydraulics)()
                       and cfg.effects == type(cfg.effects)() and not cfg.legs
                       else "hexsim with parameters other than the seed's (not stated here)"),
        "oil_temperature_C": 35.0,
        "acquisition": {"accelerometer": "mean over each sample interval (boxcar anti-alias filter)",
                        "other channels": "value at the sample instant"},
        "description": f"hexsim simulation: scenario {cfg.scenario.name}, compensator {cfg.compensator_name}, seed {cfg.seed}",
    }


#: Sensor noise (rms, SI units) that :func:`add_sensor_noise` puts on simulated logs so they look like
#: measurements: position transducer 2 µm (resolution, "a few µm"), pressure transducers 0.02 bar
#: (0.1 % of a 250 bar range, hexsim's assumption), accelerometer 0.02 m/s^2.
SENSOR_NOISE = {"pos_m": 2e-6, "p1_Pa": 2e3, "p2_Pa": 2e3, "ps_Pa": 2e3, "_mps2": 0.02}


def add_sensor_noise(cols: dict[str, np.ndarray], rng: np.random.Generator) -> dict[str, np.ndarray]:
    """A copy of the log columns with white Gaussian noise of :data:`SENSOR_NOISE` on every measured column
    (leg and platform columns of the hexapod too); setpoints, valve commands and time are left exact."""
    out = {}
    for name, values in cols.items():
        level = next((v for k, v in SENSOR_NOISE.items() if name.endswith(k)), None)
        out[name] = values + rng.normal(0.0, level, values.shape) if level else values
    return out


def write_log(path: str | os.PathLike, result: SimulationResult,
              noise: np.random.Generator | None = None) -> tuple[pathlib.Path, pathlib.Path]:
    """Write ``path`` (CSV) and its sidecar (same stem, .json), each atomically. Returns both paths.

    ``noise``: a generator to add :data:`SENSOR_NOISE` (:func:`add_sensor_noise`); default exact values.
    """
    path = pathlib.Path(path)
    header, table = _table(result, noise)

    def write_csv(tmp: pathlib.Path) -> None:
        np.savetxt(tmp, table, delimiter=",", header=header, comments="", fmt=CSV_FORMAT)

    side = path.with_suffix(".json")
    write_atomic(path, write_csv)
    write_atomic(side, lambda tmp: tmp.write_text(json.dumps(sidecar(result, path.parent), indent=2) + "\n"))
    return path, side


#: the CSV's number format: nine significant digits (a nanometre in a metre, a pascal in 100 bar)
CSV_FORMAT = "%.9g"


def _table(result: SimulationResult, noise: np.random.Generator | None = None) -> tuple[str, np.ndarray]:
    """The CSV's header line and its rows (N, columns) for ``result``."""
    cols = log_columns(result)
    if noise is not None:
        cols = add_sensor_noise(cols, noise)
    return ",".join(cols), np.column_stack(list(cols.values()))


class LogStream:
    """A measurement log written while its run goes on: :meth:`append` adds each new stretch of samples (a
    :class:`~hexsim.engine.config.SimulationResult` of the samples since the last) to the CSV at ``path``,
    flushed to the file, the first one after the sidecar (same stem, .json, written atomically from it);
    :meth:`close` ends it. The CSV holds whole rows up to the last stretch appended, so a session that ends
    abruptly leaves a log that reads up to there; it is not written atomically. Raises InputError for a folder
    that does not exist, OSError where the files cannot be written."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = pathlib.Path(path)
        self.sidecar = self.path.with_suffix(".json")
        self._file = None
        self._described = False
        self.rows = 0

    def append(self, result: SimulationResult) -> None:
        if len(result.t) == 0:
            return
        header, table = _table(result)
        if not self._described and len(result.t) > 1:  # the sidecar's sample rate needs two samples
            side = sidecar(result, self.path.parent)
            write_atomic(self.sidecar, lambda tmp: tmp.write_text(json.dumps(side, indent=2) + "\n"))
            self._described = True
        if self._file is None:
            self._file = open(self.path, "w", encoding="utf-8")  # noqa: SIM115 (open across appends)
            self._file.write(header + "\n")
        np.savetxt(self._file, table, delimiter=",", fmt=CSV_FORMAT)
        self._file.flush()
        self.rows += len(table)

    @property
    def written(self) -> list[pathlib.Path]:
        """The files written so far (the CSV and its sidecar; none before the first samples)."""
        return [p for p, done in ((self.path, self.rows > 0), (self.sidecar, self._described)) if done]

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
