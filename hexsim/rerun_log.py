"""The run as a rerun recording (``.rrd``), written headless: open it with ``rerun out.rrd``.

3D (world frame, z up): base, legs and platform over time (decimated to 50 Hz). Time series: the reversal
bump (the analysed signal minus its fundamental fit) on its own axis, the signal with its fit, piston
positions and setpoints, valve setpoints and compensation voltages, pressures, and the compensator's
parameters for a compensated run. Every run is a recording of its own (:func:`recording_id`). A
default blueprint opens on the 3D view beside the time series.
"""

from __future__ import annotations

import os
import pathlib
import uuid

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from scipy.spatial.transform import Rotation

from hexsim.kinematics import HexapodGeometry, rotation_matrices
from hexsim.metrics import Smoothness
from hexsim.model import load_model
from hexsim.simulation import SimulationResult
from hexsim.tables import write_atomic

VIEW_RATE_HZ = 50.0  # [Hz] rate of the 3D scene in the recording


def _blueprint(compensated: bool, analysis: str) -> rrb.Blueprint:
    """Time series beside the 3D view: the reversal bump (signal minus its fundamental fit) on its own
    axis, then the signal with its fit, positions, valve, pressures and, for a compensated run only,
    the compensator's parameters."""
    panels = [
        rrb.TimeSeriesView(origin="/bump", name=f"reversal bump: {analysis} minus its fundamental"),
        rrb.TimeSeriesView(origin="/acceleration", name=f"{analysis} and its fundamental fit"),
        rrb.TimeSeriesView(origin="/legs", name="piston position and setpoint [m]"),
        rrb.TimeSeriesView(origin="/valve", name="valve setpoint u_v, compensation U_c [V]"),
        rrb.TimeSeriesView(origin="/pressure", name="pressures P1, P_s [bar]"),
    ]
    if compensated:
        panels.append(rrb.TimeSeriesView(origin="/compensator", name="compensator parameters a, b, c, s"))
    return rrb.Blueprint(
        rrb.Horizontal(rrb.Spatial3DView(origin="/world", name="hexapod"), rrb.Vertical(*panels),
                       column_shares=[2, 3]),
        collapse_panels=True,
    )


def recording_id(result: SimulationResult) -> str:
    """A recording id of its own for every run (scenario, compensator, seed and a random suffix), so two
    recordings opened together (``rerun a.rrd b.rrd``) stay two; the application id is ``hexsim``."""
    cfg = result.config
    return f"hexsim-{cfg.scenario.name}-{cfg.compensator_name}-seed{cfg.seed}-{uuid.uuid4().hex[:8]}"


def _scalars(rec: rr.RecordingStream, path: str, times: rr.TimeColumn, values: np.ndarray) -> None:
    rec.send_columns(path, indexes=[times], columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=float)))


def write_rrd(path: str | os.PathLike, result: SimulationResult, sm: Smoothness) -> None:
    """Write the recording of a run to ``path`` (atomically)."""
    write_atomic(path, lambda tmp: _write(tmp, result, sm))


def _write(tmp: pathlib.Path, result: SimulationResult, sm: Smoothness) -> None:
    sc = result.config.scenario
    rec = rr.RecordingStream("hexsim", recording_id=recording_id(result))
    rec.save(tmp, default_blueprint=_blueprint(bool(result.compensator_state), sm.signal))
    rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    times = rr.TimeColumn("time", duration=result.t)
    n = result.n_legs
    for i in range(n):
        leg = f"leg{i + 1}"
        _scalars(rec, f"/legs/{leg}/position", times, result.y[:, i])
        _scalars(rec, f"/legs/{leg}/setpoint", times, result.y_ref[:, i])
        _scalars(rec, f"/valve/{leg}/u_v", times, result.u_v[:, i])
        _scalars(rec, f"/valve/{leg}/U_c", times, result.u_c[:, i])
        _scalars(rec, f"/pressure/{leg}/p1", times, result.p1[:, i] / 1e5)
    _scalars(rec, "/pressure/p_s", times, result.p_s / 1e5)
    for key, values in result.compensator_state.items():
        for i in range(n):
            _scalars(rec, f"/compensator/leg{i + 1}/{key}", times, values[:, i])
    fit_times = rr.TimeColumn("time", duration=sm.t)
    _scalars(rec, "/acceleration/signal", fit_times, sm.fit + sm.noise)
    _scalars(rec, "/acceleration/fundamental", fit_times, sm.fit)
    _scalars(rec, "/bump/noise", fit_times, sm.noise)
    rec.log("/acceleration/signal", rr.SeriesLines(names=f"{sm.signal} [{sm.unit}]", colors=[[40, 90, 170]]),
            static=True)
    rec.log("/acceleration/fundamental", rr.SeriesLines(names="fundamental fit", colors=[[230, 150, 30]]),
            static=True)
    rec.log("/bump/noise", rr.SeriesLines(names=f"signal - fit [{sm.unit}]", colors=[[200, 40, 40]]), static=True)
    for i in range(n):
        for path, label in ((f"/legs/leg{i + 1}/position", "y"), (f"/legs/leg{i + 1}/setpoint", "r"),
                            (f"/valve/leg{i + 1}/u_v", "u_v"), (f"/valve/leg{i + 1}/U_c", "U_c"),
                            (f"/pressure/leg{i + 1}/p1", "P1")):
            rec.log(path, rr.SeriesLines(names=f"leg{i + 1} {label}"), static=True)
    rec.log("/pressure/p_s", rr.SeriesLines(names="P_s", colors=[[20, 20, 20]]), static=True)

    step = max(1, int(round(1.0 / (VIEW_RATE_HZ * np.median(np.diff(result.t))))))
    view_t = rr.TimeColumn("time", duration=result.t[::step])
    if sc.system == "hexapod":
        geom = HexapodGeometry.from_model(load_model("hexapod"))
        pose = result.pose[::step]
        rot = rotation_matrices(pose[:, 3:])
        centre = geom.neutral_position + pose[:, :3]
        tips = centre[:, None, :] + np.einsum("nij,kj->nki", rot, geom.platform)
        base = np.broadcast_to(geom.base, tips.shape)
        quat = Rotation.from_matrix(rot).as_quat()  # x, y, z, w as rerun expects
        rec.log("/world/base", rr.Points3D(geom.base, radii=0.03, colors=[90, 90, 100]), static=True)
        rec.log("/world/platform", rr.Boxes3D(half_sizes=[[0.6, 0.6, 0.03]], centers=[[0, 0, 0.03]],
                                              colors=[40, 90, 170]), static=True)
        rec.send_columns("/world/platform", indexes=[view_t],
                         columns=rr.Transform3D.columns(translation=centre, quaternion=quat))
    else:
        y = result.y[::step, 0]
        base = np.broadcast_to(np.array([0.0, 0.0, 0.05]), (y.size, 1, 3))
        tips = np.stack([np.zeros_like(y), np.zeros_like(y), 0.52 + y], axis=1)[:, None, :]
    strips = np.stack([base, tips], axis=2).reshape(-1, 2, 3)
    rec.send_columns("/world/legs", indexes=[view_t],
                     columns=rr.LineStrips3D.columns(strips=strips).partition([tips.shape[1]] * tips.shape[0]))
    rec.log("/world/legs", rr.LineStrips3D.from_fields(radii=0.015, colors=[200, 200, 210]), static=True)
    rec.flush()
    rec.disconnect()
