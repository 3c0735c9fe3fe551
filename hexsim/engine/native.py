"""Compiled (numba) runners: the leg plant, the controller and MuJoCo stepped without returning to Python.

The physics is :func:`hexsim.plant.legs.step_legs` (seed eq. 3.2–3.4, 3.7–3.9 and the effects of
:class:`hexsim.plant.effects.Effects`), the same compiled function the Python control callback calls; this
module holds only the loops around it. The loop calls ``mj_step`` of the MuJoCo library the Python
bindings loaded, by symbol name, on the raw ``mjModel*`` / ``mjData*`` (``MjModel._address``), reading
and writing ``qpos``/``qvel``/``ctrl``/``sensordata`` through the bindings' numpy views of the same
memory. tests/engine/test_native.py checks the loops against the Python control callback.
"""

from __future__ import annotations

import math
import os
import pathlib
from typing import NamedTuple

import llvmlite.binding as llvm
import mujoco
import numba
import numpy as np

import compensation.buffered
from compensation import CompensatorSettings
from compensation.base import Compensator, NoCompensator, ReplayedCompensation
from compensation.buffered import BufferedCompensator, buffered_tick
from hexsim import jitcache
from hexsim.control.controller import p_output, valve_setpoint
from hexsim.plant import legs, platform
from hexsim.plant.legs import step_legs
from hexsim.plant.platform import LegGeometry, leg_wrench, read_legs

#: Compensators the compiled controller runs, and its ``comp_mode`` for each (:func:`run_block`: 0 U_c = 0,
#: 1 :func:`compensation.buffered.buffered_tick`, 2 a table row per sample); any other compensator (a
#: user's own included) runs in Python between kernel calls.
COMPILED = {NoCompensator: 0, BufferedCompensator: 1, ReplayedCompensation: 2}


def comp_mode(compensator: Compensator) -> int | None:
    """The kernel's ``comp_mode`` for ``compensator`` (subclasses of the buffered one that keep its
    ``update`` included: they share its tick), or None if only Python can run it."""
    if isinstance(compensator, BufferedCompensator) and type(compensator).update is BufferedCompensator.update:
        return 1
    return COMPILED.get(type(compensator))


def kernel_state(compensator: Compensator, n_legs: int) -> tuple:
    """The records :func:`run_block` hands to the compiled compensator: a buffered one's own (changed
    in place), for the others a placeholder of the same types (so the kernel compiles once)."""
    if isinstance(compensator, BufferedCompensator):
        return compensator.kernel_state()
    return BufferedCompensator(n_legs, 500.0, settings=CompensatorSettings(buffer_time=0.004)).kernel_state()

_lib_path = sorted(pathlib.Path(mujoco.__file__).parent.glob("libmujoco.so*"))
_lib_path = _lib_path or sorted(pathlib.Path(mujoco.__file__).parent.glob("*mujoco*.dylib"))
# mj_step of the MuJoCo library the Python bindings loaded, called by symbol name from compiled code:
# mjModel*, mjData* passed as integers (the same ABI as pointers). Resolved when the kernel is linked,
# so the compiled kernels can be cached on disk (numba's cache=True) and a new process only loads them.
llvm.load_library_permanently(str(_lib_path[0]))
_mj_step = numba.types.ExternalFunction("mj_step", numba.types.void(numba.types.int64, numba.types.int64))

class MjView(NamedTuple):
    """What the runners touch of MuJoCo: the raw ``mjModel*``/``mjData*`` (for ``mj_step``), the
    bindings' numpy views of ``qpos``, ``qvel``, ``ctrl``, ``sensordata``, ``site_xpos`` (the same
    memory), and per leg the addresses of its slide joint (qpos, dof) and actuator; site1/site2 the
    anchor sites of the connect constraints (empty: none); ``xfrc_applied`` and the legs' geometry
    (:class:`hexsim.plant.platform.LegGeometry`: kind 0 slide joints, kind 1 a platform-only model)."""

    model: int
    data: int
    qpos: np.ndarray
    qvel: np.ndarray
    ctrl: np.ndarray
    sensordata: np.ndarray
    site_xpos: np.ndarray
    qpos_adr: np.ndarray
    dof_adr: np.ndarray
    actuator_id: np.ndarray
    site1: np.ndarray
    site2: np.ndarray
    xfrc: np.ndarray
    geo: LegGeometry


def mj_view(m: mujoco.MjModel, d: mujoco.MjData, idx, site1=None, site2=None) -> MjView:
    """The :class:`MjView` of model ``m`` with data ``d`` and the legs of ``idx``
    (:class:`hexsim.plant.model.PlantIndex`)."""
    none = np.zeros(0, dtype=np.int64)
    return MjView(m._address, d._address, d.qpos, d.qvel, d.ctrl, d.sensordata, d.site_xpos,
                  *(np.asarray(a, dtype=np.int64) for a in (idx.qpos_adr, idx.dof_adr, idx.actuator_id)),
                  none if site1 is None else site1, none if site2 is None else site2, d.xfrc_applied, idx.legs)


class Legs(NamedTuple):
    """The leg plant of a runner: parameters (:func:`hexsim.plant.legs.leg_table`, (n,) records), step dt [s], state
    (:class:`hexsim.plant.legs.PlantState`, changed in place), supply manifold per leg (n,) int, the leg
    forces (n,) [N] of the last step, the ring of measured positions (L, n) that makes the sensor delay,
    the supply flow per manifold (n,) [m^3/s] of the last step (with a supply model)."""

    params: np.ndarray
    dt: float
    state: legs.PlantState
    groups: np.ndarray
    force: np.ndarray
    history: np.ndarray
    supply_flow: np.ndarray


class Control(NamedTuple):
    """The P controller and compensator in the kernel: physics steps per controller sample ``div`` (0:
    the valve setpoints are given), K_p [V/m], piston setpoints and sensor noise per sample (n_ticks, n)
    [m], the compensator ``mode`` (:func:`comp_mode`) with its records ``comp`` or table ``table``
    (n_ticks, n) [V], and the count of samples with a leg saturated (1,)."""

    div: int
    kp: float
    setpoints: np.ndarray
    noise: np.ndarray
    mode: int
    comp: tuple
    table: np.ndarray
    saturated: np.ndarray


class Recorder(NamedTuple):
    """Rows the kernel writes every ``div`` physics steps, ``n_total`` samples in all, kept as a ring of
    len(k) rows (sample r goes to row r % len(k)): step k, sensordata, P1 (n), P_s of leg 0, P2 (n), leg force,
    measured position, piston velocity, connect violation [m], setpoint, u_v, U_c, compensator (a, b, c, s) (rows, 4, n);
    ``status[0]``: the first step whose state is not finite, else -1. The accelerometer's entries of
    sensordata (``acc_adr``) are recorded at t_k as the mean over the sample interval before it, the steps
    k-div … k-1 whose accelerations carried the platform from t_k - T to t_k (Δv/Δt: a boxcar anti-alias
    filter, as an integrating DAQ; the first record, with no interval before it, its own step's):
    ``acc_sum`` holds their running sum and count."""

    div: int
    n_total: int
    k: np.ndarray
    sens: np.ndarray
    p1: np.ndarray
    p_s: np.ndarray
    p2: np.ndarray
    force: np.ndarray
    y: np.ndarray
    ydot: np.ndarray
    viol: np.ndarray
    ref: np.ndarray
    u: np.ndarray
    uc: np.ndarray
    comp: np.ndarray
    status: np.ndarray
    acc_adr: np.ndarray
    acc_sum: np.ndarray


class ReplayOut(NamedTuple):
    """Outputs of :func:`valve_replay`, each (k legs, n rows x sub steps) or (k, n): at every physics step of
    each leg (or at each row's first), the position [m], P1 [Pa], P_s [Pa] and P2 [Pa] (rod side) at its start
    and the acceleration sensor [m/s^2] over it (a row's: the mean over the row before's steps);
    :func:`hexsim.measured.replay.sampled` samples the steps as the log's sensors were."""

    position: np.ndarray
    p1: np.ndarray
    p_s: np.ndarray
    acceleration: np.ndarray
    p2: np.ndarray


@numba.njit(cache=True)
def valve_replay(mj, legs, acc_adr, u_sched, sub, out):
    """Open-loop replay of k independent legs, in the order of :func:`hexsim.measured.replay.replay` (which see):
    row j's setpoints u_sched[:, j] (k, n) [V] drive the ``sub`` steps from row j to row j+1. With ``out``
    (:class:`ReplayOut`) of n sub columns, column j sub + s records the position, P1, P_s and P2 at the start
    of step s of row j and the acceleration (sensordata at ``acc_adr`` (k,)) over it; of n columns, column j
    the state at row j's time and the acceleration averaged over the steps of row j-1 (the boxcar of
    :class:`Recorder`; row 0: its own first step's). ``legs.state`` changes in place. Returns -1, or the first
    row at which P1 is not finite."""
    k, n = u_sched.shape
    m_addr, d_addr, qpos, qvel, ctrl, sens, _, qadr, dadr, aadr, _, _, _, _ = mj  # once: see run_block
    P, dt, force, groups, supply_flow = legs.params, legs.dt, legs.force, legs.groups, legs.supply_flow
    S = legs.state
    fine = out.position.shape[1] == n * sub
    y = np.empty(k)
    yd = np.empty(k)
    acc = np.zeros(k)
    count = 0
    for j in range(n):
        for s in range(sub):
            c = j * sub + s if fine else j
            for i in range(k):
                y[i] = qpos[qadr[i]]
                yd[i] = qvel[dadr[i]]
            if fine or s == 0:
                for i in range(k):
                    out.position[i, c] = y[i]
                    out.p1[i, c] = S.p1[i]
                    out.p_s[i, c] = S.p_s[i]
                    out.p2[i, c] = S.p2[i]
            step_legs(P, dt, u_sched[:, j], y, yd, S, force, groups, supply_flow)
            for i in range(k):
                ctrl[aadr[i]] = force[i]
            _mj_step(m_addr, d_addr)
            if fine:
                for i in range(k):
                    out.acceleration[i, c] = sens[acc_adr[i]]
                continue
            if s == 0:
                for i in range(k):
                    out.acceleration[i, j] = acc[i] / count if count > 0 else sens[acc_adr[i]]
                    acc[i] = 0.0
                count = 0
            for i in range(k):
                acc[i] += sens[acc_adr[i]]
            count += 1
        if not np.isfinite(S.p1).all():
            return j
    return -1


@numba.njit(cache=True)
def run_block(mj, legs, ctl, rec, out, k0, nsteps, r0):
    """``nsteps`` physics steps k0 … k0+nsteps-1 of n legs, in the order of
    :class:`hexsim.engine.config.HydraulicCoupling`. Per step k: read y, ydot; push y into the sensor-delay
    ring (Python pushed it for step k0 before its controller sample); with ``ctl.div`` > 0 and k a
    controller sample, the P controller (:class:`hexsim.control.controller.PController`): u_p = K_p (r_j - y_m),
    r_j = setpoints[j], j = k // div, y_m = the delayed measured position + noise_j; U_c = 0 (mode 0),
    :func:`compensation.buffered.buffered_tick` on (u_p, y_m) (mode 1) or row j of the table (mode 2: a
    logged compensation fed forward); u = sat(u_p + U_c, ±u_v,max) (with ``ctl.div`` = 0 the valve
    setpoints ``out[0]`` (n,) [V] are given and held); every ``rec.div``-th step, a :class:`Recorder` row
    (the state at t_k, the sensors MuJoCo computes at the start of the step, the force applied over it); advance the
    legs (:func:`hexsim.plant.legs.step_legs`), write the forces to ``ctrl``, ``mj_step``. Blocks with the
    controller inside may start between two controller samples: ``out`` = (u_v (n,), U_c (n,), the
    compensator's statistics (4, n), y_m (n,), u_p (n,)) are the caller's, kept from one block to the next
    (the last sample's values hold until the next). Returns the next row; ``rec.status[0]`` = the first
    step whose state is not finite, else -1.

    The controller sample and the two halves of a record are helpers numba inlines into this loop
    (``inline="always"``, in its own IR, before LLVM); what runs at every step reads plain arrays unpacked
    once here (reading them through the records in the per-step loop was 5–15 % slower in alternating heave
    runs)."""
    S = legs.state
    P, dt, force, groups, supply_flow, hist = legs.params, legs.dt, legs.force, legs.groups, legs.supply_flow, \
        legs.history
    m_addr, d_addr, qpos, qvel, ctrl, sens, site_xpos, qadr, dadr, aadr, site1, site2, xfrc, geo = mj
    n = S.p1.shape[0]
    L = hist.shape[0]
    y = np.empty(n)
    yd = np.empty(n)
    u = out[0]
    acc_adr, acc_sum = rec.acc_adr, rec.acc_sum
    n_acc = acc_adr.shape[0]
    div, rec_div, n_total, rows = ctl.div, rec.div, rec.n_total, rec.k.shape[0]
    r = r0
    j = min(k0 // div, ctl.setpoints.shape[0] - 1) if div > 0 else 0  # the last controller sample's row
    for s in range(nsteps):
        k = k0 + s
        _read_legs(geo, qpos, qvel, qadr, dadr, y, yd)
        if s > 0 or div > 0:
            for i in range(n):
                hist[k % L, i] = y[i]
        if div > 0 and k % div == 0:
            j = _control_sample(ctl, P, hist[(k + 1) % L], k, out)
        record = k % rec_div == 0 and r < n_total
        w = r % rows
        if record:
            _record_state(rec, w, k, S, hist[(k + 1) % L], yd, ctl, j, out)
        step_legs(P, dt, u, y, yd, S, force, groups, supply_flow)
        _apply_forces(geo, qpos, ctrl, aadr, xfrc, y, yd, force)
        _mj_step(m_addr, d_addr)
        if not _finite(geo, S.p1, qpos, qvel, qadr, dadr):
            rec.status[0] = k
            return r
        if record:
            _record_sensors(rec, w, sens, site_xpos, site1, site2, force)
            r += 1
        for c in range(n_acc):
            acc_sum[c] += sens[acc_adr[c]]
        acc_sum[n_acc] += 1.0
    rec.status[0] = -1
    return r


@numba.njit(cache=True, inline="always")
def _control_sample(ctl, P, y_meas, k, out):
    """A controller sample at step k (:func:`run_block`): u_p = K_p (r_j - y_m) with y_m = the delayed
    measured position ``y_meas`` (n,) [m] + noise_j, U_c of the compensator mode, u_v = sat(u_p + U_c)
    into ``out`` = (u_v, U_c, compensator statistics (4, n), y_m, u_p); counts a saturated sample.
    Returns j."""
    div, kp, setpoints, noise, mode, comp, table, saturated = ctl
    u, u_c, stat, y_m, u_p = out
    n = u.shape[0]
    j = min(k // div, setpoints.shape[0] - 1)
    for i in range(n):
        y_m[i] = y_meas[i] + noise[j, i]
        u_p[i] = p_output(kp, setpoints[j, i], y_m[i])
    if mode == 1:
        buffered_tick(comp[0], comp[1], comp[2], u_p, y_m, u_c, stat)
    elif mode == 2:
        row = min(k // div, table.shape[0] - 1)
        for i in range(n):
            u_c[i] = table[row, i]
    hit = False
    for i in range(n):
        u[i] = valve_setpoint(u_p[i], u_c[i], P[i].u_v_max)
        hit = hit or u[i] != u_p[i] + u_c[i]
    if hit:
        saturated[0] += 1
    return j


@numba.njit(cache=True, inline="always")
def _record_state(rec, w, k, S, y_meas, yd, ctl, j, out):
    """Row ``w`` of the :class:`Recorder`: the state at t_k (P1, P_s, P2, measured position, ẏ) and, with the
    controller inside, the sample's setpoint, u_v, U_c and the compensator's (a, b, c, s)."""
    u, u_c, stat, _, _ = out
    rec.k[w] = k
    rec.p_s[w] = S.p_s[0]
    for i in range(S.p1.shape[0]):
        rec.p1[w, i] = S.p1[i]
        rec.p2[w, i] = S.p2[i]
        rec.y[w, i] = y_meas[i]
        rec.ydot[w, i] = yd[i]
        if ctl.div > 0:
            rec.ref[w, i] = ctl.setpoints[j, i]
            rec.u[w, i] = u[i]
            rec.uc[w, i] = u_c[i]
            if ctl.mode == 1:
                for c in range(4):
                    rec.comp[w, c, i] = stat[c, i]


@numba.njit(cache=True, inline="always")
def _record_sensors(rec, w, sens, site_xpos, site1, site2, force):
    """Row ``w`` of the :class:`Recorder` after the step: sensordata (the accelerometer's entries as the
    mean over the interval's steps; the first record: its own), the worst connect violation [m] and the
    force applied over the step; the accelerometer's running sum restarts."""
    n_acc = rec.acc_adr.shape[0]
    for c in range(sens.shape[0]):
        rec.sens[w, c] = sens[c]
    if rec.acc_sum[n_acc] > 0.0:
        for c in range(n_acc):
            rec.sens[w, rec.acc_adr[c]] = rec.acc_sum[c] / rec.acc_sum[n_acc]
    for c in range(n_acc + 1):
        rec.acc_sum[c] = 0.0
    worst = 0.0
    for e in range(site1.shape[0]):
        a, b = site1[e], site2[e]
        dx = site_xpos[a, 0] - site_xpos[b, 0]
        dy = site_xpos[a, 1] - site_xpos[b, 1]
        dz = site_xpos[a, 2] - site_xpos[b, 2]
        worst = max(worst, math.sqrt(dx * dx + dy * dy + dz * dz))
    rec.viol[w] = worst
    for i in range(force.shape[0]):
        rec.force[w, i] = force[i]


@numba.njit(cache=True, inline="always")
def _read_legs(geo, qpos, qvel, qadr, dadr, y, yd):
    """Piston positions and velocities (n,) into y, yd: the slide joints' qpos/qvel, or the platform-only
    model's legs from the platform's pose (:func:`hexsim.plant.platform.read_legs`)."""
    if geo.kind == 0:
        for i in range(y.shape[0]):
            y[i] = qpos[qadr[i]]
            yd[i] = qvel[dadr[i]]
    else:
        read_legs(geo, qpos, qvel, y, yd)


@numba.njit(cache=True, inline="always")
def _apply_forces(geo, qpos, ctrl, aadr, xfrc, y, yd, force):
    """The leg forces (n,) [N] onto the model: the motors' ctrl, or the platform's xfrc_applied
    (:func:`hexsim.plant.platform.leg_wrench`)."""
    if geo.kind == 0:
        for i in range(force.shape[0]):
            ctrl[aadr[i]] = force[i]
    else:
        leg_wrench(geo, qpos, y, yd, force, xfrc)


@numba.njit(cache=True, inline="always")
def _finite(geo, p1, qpos, qvel, qadr, dadr):
    """Whether P1 and the legs' (or the platform's) coordinates are finite after a step."""
    ok = True
    for i in range(p1.shape[0]):
        ok = ok and math.isfinite(p1[i])
    if geo.kind == 0:
        for i in range(p1.shape[0]):
            ok = ok and math.isfinite(qpos[qadr[i]]) and math.isfinite(qvel[dadr[i]])
    else:
        for c in range(7):
            ok = ok and math.isfinite(qpos[geo.qadr + c])
        for c in range(6):
            ok = ok and math.isfinite(qvel[geo.dadr + c])
    return ok


def kernels_cached() -> bool:
    """Whether numba's on-disk cache holds the compiled runner (False: the next run compiles it, ~15 s).
    Reads numba's private cache layout; if that changes, answers True (no message rather than a wrong one)."""
    try:
        return run_block.signatures != [] or os.path.exists(run_block._cache._cache_file._index_path)
    except AttributeError:
        return True


# the runners compile in the leg step and the compensator from other files: drop their cache when those change
jitcache.guard((run_block, valve_replay), legs.__file__, platform.__file__, compensation.buffered.__file__,
              compensation.base.__file__, compensation.functions.__file__)
