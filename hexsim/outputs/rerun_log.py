"""The run as a rerun recording (``.rrd``), written headless: open it with ``rerun out.rrd``.

3D (world frame, z up): the model's own visual geoms (base, barrels, rods, platform, from the MJCF) at the
run's poses over time (decimated to 50 Hz). Time series: the reversal
bump (the analysed signal minus its fundamental fit) on its own axis, the signal with its fit, piston
positions and setpoints, valve setpoints and compensation voltages, pressures, and the compensator's
parameters for a compensated run. Every run is a recording of its own (:func:`recording_id`). A
default blueprint opens on the 3D view beside the time series.
"""

from __future__ import annotations

import os
import pathlib
import uuid

import mujoco
import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from scipy.spatial.transform import Rotation

from hexsim.control.kinematics import HexapodGeometry, rotation_matrices
from hexsim.engine.config import SimulationResult
from hexsim.plant.model import leg_bodies, load_model
from hexsim.studies.metrics import Smoothness
from hexsim.tables import write_atomic

VIEW_RATE_HZ = 50.0  # [Hz] rate of the 3D scene in the recording


#: the 3D view's camera on the hexapod [m, world]: from the front right, above the platform, looking at
#: the legs' middle (the whole machine in view, 1.3 m across)
HEXAPOD_EYE = rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital, position=[2.3, -2.3, 1.7], look_target=[0.0, 0.0, 0.45],
                                eye_up=[0.0, 0.0, 1.0])


def _eye(scale: float) -> rrb.EyeControls3D:
    """:data:`HEXAPOD_EYE` for a hexapod ``scale`` times the Micro Motion System's size."""
    return rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital, position=[2.3 * scale, -2.3 * scale, 1.7 * scale],
                             look_target=[0.0, 0.0, 0.45 * scale], eye_up=[0.0, 0.0, 1.0])


def _blueprint(compensated: bool, analysis: str, system: str = "hexapod", scale: float = 1.0,
               perception: bool = False, cueing: bool = False) -> rrb.Blueprint:
    """Time series beside the 3D view: the reversal bump (signal minus its fundamental fit) on its own
    axis, then the signal with its fit, positions, valve, pressures and, for a compensated run only,
    the compensator's parameters. The hexapod's 3D view starts at :data:`HEXAPOD_EYE`."""
    panels = [
        rrb.TimeSeriesView(origin="/bump", name=f"reversal bump: {analysis} minus its fundamental"),
        rrb.TimeSeriesView(origin="/acceleration", name=f"{analysis} and its fundamental fit"),
        rrb.TimeSeriesView(origin="/legs", name="piston position and setpoint [m]"),
        rrb.TimeSeriesView(origin="/valve", name="valve setpoint u_v, compensation U_c [V]"),
        rrb.TimeSeriesView(origin="/pressure", name="pressures P1, P_s [bar]"),
    ]
    if compensated:
        panels.append(rrb.TimeSeriesView(origin="/compensator", name="compensator parameters a, b, c, s"))
    if system == "hexapod":
        panels.append(rrb.TimeSeriesView(origin="/head", name="the occupant's head: specific force [m/s^2], "
                                                                "angular velocity [rad/s]"))
    if perception:
        panels.insert(1, rrb.TimeSeriesView(origin="/perception/seat",
                                            name="seat: ISO 2631-1 weighted false cue and threshold [m/s^2]"))
        panels.insert(2, rrb.TimeSeriesView(origin="/perception/head", name="head: vestibular sensed / threshold"))
    if cueing:
        panels[:0] = [rrb.TimeSeriesView(origin=f"/cueing/{axis}", name=f"sensed cue {axis}: vehicle, ideal platform, "
                                                                           f"simulator") for axis in ("x", "y", "z", "pitch")]
    return rrb.Blueprint(
        rrb.Horizontal(rrb.Spatial3DView(origin="/world", name=system if system == "hexapod" else "single actuator",
                                         eye_controls=(HEXAPOD_EYE if scale == 1.0 else _eye(scale))
                                         if system == "hexapod" else None),
                       rrb.Vertical(*panels),
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


def scene_qpos(m: mujoco.MjModel, result: SimulationResult, rows: np.ndarray) -> np.ndarray:
    """(len(rows), nq) joint positions of the model at the recorded rows ``rows``: each leg's slide at its
    recorded piston position y [m]; on the hexapod the platform's free joint at its recorded pose and
    each leg's base joint turned so that the barrel points from its base joint to the platform anchor
    (:func:`_base_joints`)."""
    qpos = np.tile(m.qpos0, (len(rows), 1))
    for i in range(result.n_legs):
        qpos[:, m.joint(f"leg{i + 1}").qposadr[0]] = result.y[rows, i]
    if result.config.scenario.system != "hexapod":
        return qpos
    pose = result.pose[rows]
    rot = rotation_matrices(pose[:, 3:])
    free = m.jnt_qposadr[m.body_jntadr[m.body("platform").id]]
    qpos[:, free:free + 3] = HexapodGeometry.from_model(m).neutral_position + pose[:, :3]
    qpos[:, free + 3:free + 7] = Rotation.from_matrix(rot).as_quat()[:, [3, 0, 1, 2]]  # w, x, y, z
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)  # the reference pose: the barrels' rest frames and base joints
    slides, rods, barrels = leg_bodies(m, result.n_legs)
    for i, (slide, rod, barrel) in enumerate(zip(slides, rods, barrels)):
        parent = Rotation.from_quat(np.roll(d.xquat[m.body_parentid[barrel]], -1))
        rest = (parent * Rotation.from_quat(np.roll(m.body_quat[barrel], -1))).as_matrix()
        axis = Rotation.from_quat(np.roll(m.body_quat[rod], -1)).apply(m.jnt_axis[slide])  # in the barrel frame
        first = m.body_jntadr[barrel]
        direction = qpos[:, free:free + 3] + rot @ m.site(f"platform_anchor{i + 1}").pos - d.xanchor[first]
        target = direction @ rest  # in the barrel's rest frame
        target /= np.linalg.norm(target, axis=1, keepdims=True)
        _base_joints(m, qpos, first, m.body_jntnum[barrel], axis, target)
    return qpos


def _base_joints(m: mujoco.MjModel, qpos: np.ndarray, first: int, count: int, axis: np.ndarray,
                 target: np.ndarray) -> None:
    """Write into ``qpos`` (rows, nq) the base joint(s) of a leg (joint ``first``: a ball, or two hinges
    h1 then h2) that turn the slide's axis ``axis`` (3,) onto ``target`` (rows, 3), both unit vectors in
    the barrel's rest frame: a ball takes the shortest rotation; two hinges R(h1, a) R(h2, b) axis =
    target, solved by Gauss-Newton from zero (exact in a few steps for a universal joint)."""
    adr = m.jnt_qposadr[first]
    if count == 1:
        cross = np.cross(axis, target)
        angle = np.arctan2(np.linalg.norm(cross, axis=1), target @ axis)
        unit = cross / np.maximum(np.linalg.norm(cross, axis=1, keepdims=True), 1e-15)
        qpos[:, adr:adr + 4] = Rotation.from_rotvec(unit * angle[:, None]).as_quat()[:, [3, 0, 1, 2]]
        return
    h1, h2 = m.jnt_axis[first], m.jnt_axis[first + 1]
    a, b = np.zeros(len(target)), np.zeros(len(target))
    for _ in range(8):
        r1, r2 = Rotation.from_rotvec(a[:, None] * h1), Rotation.from_rotvec(b[:, None] * h2)
        inner = r2.apply(axis)
        v = r1.apply(inner)
        jac = np.stack([np.cross(h1, v), r1.apply(np.cross(h2, inner))], axis=2)  # (rows, 3, 2)
        step = np.linalg.solve(np.einsum("nij,nik->njk", jac, jac), np.einsum("nij,ni->nj", jac, target - v)[..., None])[..., 0]
        a, b = a + step[:, 0], b + step[:, 1]
    qpos[:, adr] = m.qpos0[adr] + a
    qpos[:, m.jnt_qposadr[first + 1]] = m.qpos0[m.jnt_qposadr[first + 1]] + b


def _scene_model(result: SimulationResult) -> mujoco.MjModel:
    """The full model the run was made on (its machine's hexapod, or the single actuator)."""
    hexapod = result.config.scenario.system == "hexapod"
    if hexapod:
        return load_model("hexapod", geometry=result.config.geometry)
    return load_model("actuator", stroke_m=result.config.hydraulics.stroke)


def _log_scene(rec: rr.RecordingStream, m: mujoco.MjModel, result: SimulationResult, rows: np.ndarray,
               times: rr.TimeColumn) -> None:
    """Each moving body's world pose under ``/world/<body>`` at ``result``'s ``rows``, from :func:`scene_qpos`
    and ``mj_kinematics`` (its geoms: :func:`_log_geoms`)."""
    d = mujoco.MjData(m)
    qpos = scene_qpos(m, result, rows)
    xpos, xquat = np.empty((len(rows), m.nbody, 3)), np.empty((len(rows), m.nbody, 4))
    for k, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        xpos[k], xquat[k] = d.xpos, d.xquat
    for body in _moving_bodies(m):
        rec.send_columns(f"/world/{m.body(body).name or 'world'}", indexes=[times], columns=rr.Transform3D.columns(
            translation=xpos[:, body], quaternion=np.roll(xquat[:, body], -1, axis=1)))


def _shown_geoms(m: mujoco.MjModel, body: int) -> list[int]:
    """The body's visual geoms (MJCF groups 0–2)."""
    return [g for g in range(m.ngeom) if m.geom_bodyid[g] == body and m.geom_group[g] <= 2]


def _moving_bodies(m: mujoco.MjModel) -> list[int]:
    """The bodies with visual geoms that are not welded to the world."""
    return [b for b in range(1, m.nbody) if m.body_weldid[b] != 0 and _shown_geoms(m, b)]


def _log_geoms(rec: rr.RecordingStream, m: mujoco.MjModel) -> None:
    """The model's visual geoms (static, in their bodies' frames), and the pose of each body welded to the
    world (static: it does not move)."""
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    for body in range(m.nbody):
        geoms = _shown_geoms(m, body)
        if not geoms:
            continue
        path = f"/world/{m.body(body).name or 'world'}"
        for g in geoms:
            shape = _geom_shape(m, g)
            if shape is not None:
                rec.log(f"{path}/{m.geom(g).name or f'geom{g}'}", shape, static=True)
        if body == 0 or m.body_weldid[body] == 0:  # welded to the world: one pose
            rec.log(path, rr.Transform3D(translation=d.xpos[body], quaternion=np.roll(d.xquat[body], -1)), static=True)


def _geom_shape(m: mujoco.MjModel, g: int):
    """A rerun archetype for geom ``g`` in its body's frame (None for a type rerun has no primitive for)."""
    size, pos, quat = m.geom_size[g], m.geom_pos[g], np.roll(m.geom_quat[g], -1)  # rerun: x, y, z, w
    rgba = m.mat_rgba[m.geom_matid[g]] if m.geom_matid[g] >= 0 else m.geom_rgba[g]
    colors = [np.round(255 * rgba).astype(np.uint8)]
    kind = m.geom_type[g]
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return rr.Boxes3D(half_sizes=[size], centers=[pos], quaternions=[quat], colors=colors, fill_mode="solid")
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:  # MuJoCo and rerun: axis along local z, centred
        return rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], centers=[pos], quaternions=[quat],
                              colors=colors, fill_mode="solid")
    if kind in (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_ELLIPSOID):
        half = np.full(3, size[0]) if kind == mujoco.mjtGeom.mjGEOM_SPHERE else size
        return rr.Ellipsoids3D(half_sizes=[half], centers=[pos], quaternions=[quat], colors=colors, fill_mode="solid")
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:  # rerun's capsule starts at its translation and runs along +z
        start = pos + Rotation.from_quat(quat).apply([0.0, 0.0, -size[1]])
        return rr.Capsules3D(lengths=[2 * size[1]], radii=[size[0]], translations=[start], quaternions=[quat],
                             colors=colors)
    return None


def write_rrd(path: str | os.PathLike, result: SimulationResult, sm: Smoothness | None, perception=None,
              cueing=None) -> None:
    """Write the recording of a run to ``path`` (atomically); ``sm`` None (an open-loop or vehicle run): no
    smoothness analysis in it; ``perception`` (a :class:`~hexsim.studies.perception.BumpPerception`):
    the sensed false cue under ``/perception`` with its thresholds; ``cueing`` (a vehicle run's
    :func:`~hexsim.studies.cueing.cue_report`): the sensed cues of vehicle, ideal platform and simulator
    per axis under ``/cueing``."""
    write_atomic(path, lambda tmp: _write(tmp, result, sm, perception, cueing))


def _head(rec, result: SimulationResult, times) -> None:
    """The occupant's head: specific force [m/s^2] and angular velocity [rad/s], head axes (the platform's),
    from the platform's rigid-body state (:func:`hexsim.studies.perception.point_motion`)."""
    from hexsim.plant.geometry import MICRO_MOTION_SYSTEM
    from hexsim.studies.perception import point_motion

    head = point_motion(result, (result.config.geometry or MICRO_MOTION_SYSTEM).head_point)
    for k, axis in enumerate("xyz"):
        _scalars(rec, f"/head/specific_force/{axis}", times, head.specific_force[:, k])
        _scalars(rec, f"/head/angular_velocity/{axis}", times, head.angular_velocity[:, k])


def _cueing(rec, report) -> None:
    """Per axis the sensed cue of the vehicle, the ideal platform and the simulator, and the threshold
    (``report``: a :class:`~hexsim.studies.cueing.CueReport`)."""
    from hexsim.studies.perception import AXES

    times = rr.TimeColumn("time", duration=report.t)
    series = {"vehicle": (report.sensed_vehicle, [40, 90, 170]), "ideal": (report.sensed_ideal, [230, 150, 30]),
              "simulator": (report.sensed_simulator, [200, 40, 40])}
    for k, axis in enumerate(AXES):
        for who, (values, colour) in series.items():
            _scalars(rec, f"/cueing/{axis}/{who}", times, values[:, k])
            rec.log(f"/cueing/{axis}/{who}", rr.SeriesLines(names=f"{axis} sensed, {who}", colors=[colour]),
                    static=True)
        _scalars(rec, f"/cueing/{axis}/threshold", times, np.full(report.t.size, report.axes[axis].sensed_threshold))
        rec.log(f"/cueing/{axis}/threshold", rr.SeriesLines(names="threshold", colors=[[0, 0, 0]]), static=True)


def _perception(rec, p) -> None:
    """The seat's ISO-weighted false cue per axis with the Annex C threshold, and the head's vestibular output
    per axis as a multiple of its sensed threshold."""
    from hexsim.studies.perception import AXES

    times = rr.TimeColumn("time", duration=p.t)
    for k, axis in enumerate("xyz"):
        _scalars(rec, f"/perception/seat/{axis}", times, p.weighted[:, k])
        rec.log(f"/perception/seat/{axis}", rr.SeriesLines(names=f"seat {axis}, ISO 2631-1 weighted [m/s^2]"),
                static=True)
    _scalars(rec, "/perception/seat/threshold", times, np.full(p.t.size, p.seat_threshold))
    rec.log("/perception/seat/threshold", rr.SeriesLines(names=f"threshold {p.seat_threshold:g} m/s^2", colors=[[0, 0, 0]]),
            static=True)
    for k, axis in enumerate(AXES):
        _scalars(rec, f"/perception/head/{axis}", times, np.abs(p.sensed[:, k]) / p.thresholds[axis])
        rec.log(f"/perception/head/{axis}", rr.SeriesLines(names=f"head {axis}, sensed / threshold"), static=True)
    _scalars(rec, "/perception/head/threshold", times, np.ones(p.t.size))
    rec.log("/perception/head/threshold", rr.SeriesLines(names="threshold", colors=[[0, 0, 0]]), static=True)


def _write(tmp: pathlib.Path, result: SimulationResult, sm: Smoothness | None, perception=None,
           cueing=None) -> None:
    rec, m = _open(tmp, result, sm.signal if sm else "acceleration", perception is not None, cueing is not None)
    times = rr.TimeColumn("time", duration=result.t)
    _log_samples(rec, result, times)
    if sm is not None:
        fit_times = rr.TimeColumn("time", duration=sm.t)
        _scalars(rec, "/acceleration/signal", fit_times, sm.fit + sm.noise)
        _scalars(rec, "/acceleration/fundamental", fit_times, sm.fit)
        _scalars(rec, "/bump/noise", fit_times, sm.noise)
        rec.log("/acceleration/signal", rr.SeriesLines(names=f"{sm.signal} [{sm.unit}]", colors=[[40, 90, 170]]),
                static=True)
        rec.log("/acceleration/fundamental", rr.SeriesLines(names="fundamental fit", colors=[[230, 150, 30]]),
                static=True)
        rec.log("/bump/noise", rr.SeriesLines(names=f"signal - fit [{sm.unit}]", colors=[[200, 40, 40]]), static=True)
    else:
        _scalars(rec, "/acceleration/signal", times, result.acc[:, 2])
    if perception is not None:
        _perception(rec, perception)
    if cueing is not None:
        _cueing(rec, cueing)
    rows = np.arange(0, len(result.t), _view_step(result.t))
    _log_scene(rec, m, result, rows, rr.TimeColumn("time", duration=result.t[rows]))
    rec.flush()
    rec.disconnect()


def _view_step(t: np.ndarray) -> int:
    """Samples of the recording (times ``t`` (N,) [s], N >= 2) per sample of the 3D scene (:data:`VIEW_RATE_HZ`)."""
    return max(1, int(round(1.0 / (VIEW_RATE_HZ * np.median(np.diff(t))))))


def _open(path: pathlib.Path, result: SimulationResult, analysis: str = "acceleration", perception: bool = False,
          cueing: bool = False) -> tuple[rr.RecordingStream, mujoco.MjModel]:
    """A recording of ``result``'s run saving to ``path`` with its blueprint and what does not change over
    time: the run's description, the series' names and the model's geoms. Returns it and the scene's model."""
    rec = rr.RecordingStream("hexsim", recording_id=recording_id(result))
    m = _scene_model(result)
    rec.save(path, default_blueprint=_blueprint(bool(result.compensator_state), analysis,
                                                result.config.scenario.system, float(m.stat.extent) / 1.6,
                                                perception, cueing))
    rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    cfg = result.config
    rec.log("/run", rr.TextDocument(f"scenario {cfg.scenario.name}, machine {cfg.machine_label} "
                                    f"({cfg.hydraulics.valve_type} valve), compensator {cfg.compensator_name}"),
            static=True)
    for i in range(result.n_legs):
        for path_, label in ((f"/legs/leg{i + 1}/position", "y"), (f"/legs/leg{i + 1}/setpoint", "r"),
                             (f"/valve/leg{i + 1}/u_v", "u_v"), (f"/valve/leg{i + 1}/U_c", "U_c"),
                             (f"/pressure/leg{i + 1}/p1", "P1"), (f"/pressure/leg{i + 1}/p2", "P2")):
            rec.log(path_, rr.SeriesLines(names=f"leg{i + 1} {label}"), static=True)
    rec.log("/pressure/p_s", rr.SeriesLines(names="P_s", colors=[[20, 20, 20]]), static=True)
    if result.sensor_site is not None:
        for axis in "xyz":
            rec.log(f"/head/specific_force/{axis}", rr.SeriesLines(names=f"head f_{axis} [m/s^2]"), static=True)
            rec.log(f"/head/angular_velocity/{axis}", rr.SeriesLines(names=f"head omega_{axis} [rad/s]"), static=True)
    _log_geoms(rec, m)
    return rec, m


def _log_samples(rec: rr.RecordingStream, result: SimulationResult, times: rr.TimeColumn) -> None:
    """The legs' time series (position, setpoint, u_v, U_c, pressures), P_s, the compensator's parameters and
    the head's motion of ``result``'s samples at ``times``."""
    n = result.n_legs
    for i in range(n):
        leg = f"leg{i + 1}"
        _scalars(rec, f"/legs/{leg}/position", times, result.y[:, i])
        _scalars(rec, f"/legs/{leg}/setpoint", times, result.y_ref[:, i])
        _scalars(rec, f"/valve/{leg}/u_v", times, result.u_v[:, i])
        _scalars(rec, f"/valve/{leg}/U_c", times, result.u_c[:, i])
        _scalars(rec, f"/pressure/{leg}/p1", times, result.p1[:, i] / 1e5)
        if result.config.hydraulics.four_way:
            _scalars(rec, f"/pressure/{leg}/p2", times, result.p2[:, i] / 1e5)
    _scalars(rec, "/pressure/p_s", times, result.p_s / 1e5)
    for key, values in result.compensator_state.items():
        for i in range(n):
            _scalars(rec, f"/compensator/leg{i + 1}/{key}", times, values[:, i])
    if result.sensor_site is not None:
        _head(rec, result, times)


class RerunStream:
    """A rerun recording written while its run goes on: :meth:`append` logs each new stretch of samples (a
    :class:`~hexsim.engine.config.SimulationResult` of the samples since the last), :meth:`close` ends it.
    The file at ``path`` holds what was appended so far (rerun's file sink writes as it goes), so a session
    that ends abruptly leaves its recording up to the last stretch; it is not written atomically. The same
    entities as :func:`write_rrd` without the analyses of a finished run (the bump's fit, the perception):
    the legs, valve, pressures, the compensator's parameters, the head, the platform's acceleration and
    the 3D scene at :data:`VIEW_RATE_HZ`."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = pathlib.Path(path)
        self._rec: rr.RecordingStream | None = None
        self._m: mujoco.MjModel | None = None
        self._step = 1  # samples per scene sample
        self._row = 0  # samples appended so far

    @property
    def written(self) -> list[pathlib.Path]:
        """The file written (none before the first samples)."""
        return [self.path] if self._row else []

    def append(self, result: SimulationResult) -> None:
        if len(result.t) == 0:
            return
        if self._rec is None:
            self._rec, self._m = _open(self.path, result)
            if len(result.t) > 1:
                self._step = _view_step(result.t)
        times = rr.TimeColumn("time", duration=result.t)
        _log_samples(self._rec, result, times)
        _scalars(self._rec, "/acceleration/signal", times, result.acc[:, 2])
        rows = np.arange((-self._row) % self._step, len(result.t), self._step)  # as write_rrd's, across stretches
        self._row += len(result.t)
        if rows.size:
            _log_scene(self._rec, self._m, result, rows, rr.TimeColumn("time", duration=result.t[rows]))

    def close(self) -> None:
        if self._rec is not None:
            self._rec.flush()
            self._rec.disconnect()
            self._rec = None
