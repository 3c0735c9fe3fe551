"""Compiled (numba) runners: the leg plant, the controller and MuJoCo stepped without returning to Python.

The physics is :func:`hexsim.plant.step_legs` (seed eq. 3.2–3.4, 3.7–3.9 and the effects of
:class:`hexsim.effects.Effects`), the same compiled function the Python control callback calls; this
module holds only the loops around it. The loop calls ``mj_step`` of the MuJoCo library the Python
bindings loaded, by symbol name, on the raw ``mjModel*`` / ``mjData*`` (``MjModel._address``), reading
and writing ``qpos``/``qvel``/``ctrl``/``sensordata`` through the bindings' numpy views of the same
memory. tests/test_native.py checks the loops against the Python control callback.
"""

from __future__ import annotations

import math
import pathlib

import llvmlite.binding as llvm
import mujoco
import numba
import numpy as np

import compensation.buffered
from compensation import CompensatorSettings
from compensation.base import Compensator, NoCompensator, ReplayedCompensation
from compensation.buffered import BufferedCompensator, buffered_tick
from hexsim import jitcache, plant
from hexsim.plant import step_legs

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

@numba.njit(cache=True)
def valve_replay(m_addr, d_addr, qpos, qvel, ctrl, sens, qadr, dadr, aadr, acc_adr, P, u_sched, sub, dt,
                 S, out_pos, out_p1, out_ps, out_acc):
    """Open-loop replay of k independent legs, in the order of :func:`hexsim.replay.replay` (which see):
    row j's setpoints u_sched[:, j] drive the ``sub`` steps from row j to row j+1; row j records the
    position, P1 and P_s at its time and the acceleration MuJoCo computes in the first of those steps.
    Outputs (k, n); P a :class:`hexsim.plant.LegParams`, S the :class:`hexsim.plant.PlantState` of the
    k legs (in place). Returns -1, or the first row at which P1 is not finite."""
    k, n = u_sched.shape
    y = np.empty(k)
    yd = np.empty(k)
    force = np.empty(k)
    groups = np.arange(k)
    for j in range(n):
        for s in range(sub):
            for i in range(k):
                y[i] = qpos[qadr[i]]
                yd[i] = qvel[dadr[i]]
            if s == 0:
                for i in range(k):
                    out_pos[i, j] = y[i]
                    out_p1[i, j] = S.p1[i]
                    out_ps[i, j] = S.p_s[i]
            step_legs(P, dt, u_sched[:, j], y, yd, S, force, groups)
            for i in range(k):
                ctrl[aadr[i]] = force[i]
            _mj_step(m_addr, d_addr)
            if s == 0:
                for i in range(k):
                    out_acc[i, j] = sens[acc_adr[i]]
        if not np.isfinite(S.p1).all():
            return j
    return -1


@numba.njit(cache=True)
def run_block(m_addr, d_addr, qpos, qvel, ctrl, sens, site_xpos, qadr, dadr, aadr, site1, site2, P, dt, u, groups,
              S, force, hist, k0, nsteps, rec_div, r0, rec_k, rec_sens, rec_p1, rec_ps,
              rec_force, rec_y, rec_viol, status, ctrl_div, kp, setpoints, noise, rec_ref, rec_u, saturated,
              n_total, comp_mode, comp, ff_table, rec_uc, rec_comp):
    """``nsteps`` physics steps k0 … k0+nsteps-1 of n legs with the valve setpoints ``u`` (n,) held (ZOH),
    in the order of :class:`hexsim.simulation.HydraulicCoupling`: read y, ydot; push y into the
    sensor-delay ring ``hist`` (L, n) (Python pushed it for step k0 before the controller sample);
    advance the leg hydraulics (:class:`hexsim.plant.LegParams` P, :class:`hexsim.plant.PlantState` S)
    by the step ``dt`` [s] (:func:`hexsim.plant.step_legs`); write the leg forces to
    ``ctrl``; ``mj_step``.
    Every step k with k % rec_div == 0 fills row r of the ``rec_*`` arrays with the state at t_k: k,
    P1, P_s of leg 0 and the measured position before the step, the sensor data and site positions
    MuJoCo computed at the start of the step (``rec_viol``: largest distance between the connect
    anchor sites ``site1[i]``/``site2[i]``) and the force applied over the step. Returns the next row;
    ``status[0]`` = the first step whose state is not finite, else -1.

    ``ctrl_div`` > 0: the P controller runs here too (:class:`hexsim.controller.PController`): at every
    step k with k % ctrl_div == 0, u_p = K_p (r_j - y_m) with r_j = setpoints[j], j = k // ctrl_div,
    y_m = y_measured + noise_j; U_c = 0 (``comp_mode`` 0), the compiled buffered/directional
    compensator's :func:`compensation.buffered.buffered_tick` on (u_p, y_m) with the records ``comp``
    (``comp_mode`` 1), or row min(j, last) of ``ff_table`` (n_ticks, n) (``comp_mode`` 2: a logged
    compensation fed forward, :class:`compensation.base.ReplayedCompensation`); u = sat(u_p + U_c,
    ±u_v,max). ``saturated[0]`` counts the samples with a leg saturated; rows also get the setpoint, u_v
    and U_c in force and the compensator's (a, b, c, s) (``rec_ref``, ``rec_u``, ``rec_uc``,
    ``rec_comp`` (rows, 4, n)). Blocks must start at a controller sample (k0 % ctrl_div == 0). 0: ``u``
    is given and held, and Python fills those rows. Rows are a ring: sample r (of ``n_total``) goes to
    row r % len(rec_k), so a long run can keep only its last part."""
    n = S.p1.shape[0]
    L = hist.shape[0]
    y = np.empty(n)
    yd = np.empty(n)
    y_m = np.empty(n)
    u_p = np.empty(n)
    u_c = np.zeros(n)
    stat = np.zeros((4, n))
    r = r0
    j = 0
    for s in range(nsteps):
        k = k0 + s
        for i in range(n):
            y[i] = qpos[qadr[i]]
            yd[i] = qvel[dadr[i]]
        if s > 0 or ctrl_div > 0:
            for i in range(n):
                hist[k % L, i] = y[i]
        if ctrl_div > 0 and k % ctrl_div == 0:
            j = min(k // ctrl_div, setpoints.shape[0] - 1)
            for i in range(n):
                y_m[i] = hist[(k + 1) % L, i] + noise[j, i]
                u_p[i] = kp * (setpoints[j, i] - y_m[i])
            if comp_mode == 1:
                buffered_tick(comp[0], comp[1], comp[2], u_p, y_m, u_c, stat)
            elif comp_mode == 2:
                row = min(k // ctrl_div, ff_table.shape[0] - 1)
                for i in range(n):
                    u_c[i] = ff_table[row, i]
            hit = False
            for i in range(n):
                v = u_p[i] + u_c[i]
                u[i] = min(max(v, -P.u_v_max), P.u_v_max)
                hit = hit or u[i] != v
            if hit:
                saturated[0] += 1
        record = k % rec_div == 0 and r < n_total
        w = r % rec_k.shape[0]
        if record:
            rec_k[w] = k
            rec_ps[w] = S.p_s[0]
            for i in range(n):
                rec_p1[w, i] = S.p1[i]
                rec_y[w, i] = hist[(k + 1) % L, i]
                if ctrl_div > 0:
                    rec_ref[w, i] = setpoints[j, i]
                    rec_u[w, i] = u[i]
                    rec_uc[w, i] = u_c[i]
                    if comp_mode == 1:
                        for c in range(4):
                            rec_comp[w, c, i] = stat[c, i]
        step_legs(P, dt, u, y, yd, S, force, groups)
        for i in range(n):
            ctrl[aadr[i]] = force[i]
        _mj_step(m_addr, d_addr)
        finite = True
        for i in range(n):
            if not (math.isfinite(S.p1[i]) and math.isfinite(qpos[qadr[i]]) and math.isfinite(qvel[dadr[i]])):
                finite = False
        if not finite:
            status[0] = k
            return r
        if record:
            for c in range(sens.shape[0]):
                rec_sens[w, c] = sens[c]
            worst = 0.0
            for e in range(site1.shape[0]):
                dx = site_xpos[site1[e], 0] - site_xpos[site2[e], 0]
                dy = site_xpos[site1[e], 1] - site_xpos[site2[e], 1]
                dz = site_xpos[site1[e], 2] - site_xpos[site2[e], 2]
                worst = max(worst, math.sqrt(dx * dx + dy * dy + dz * dz))
            rec_viol[w] = worst
            for i in range(n):
                rec_force[w, i] = force[i]
            r += 1
    status[0] = -1
    return r


# the runners compile in the leg step and the compensator from other files: drop their cache when those change
jitcache.guard((run_block, valve_replay), plant.__file__, compensation.buffered.__file__,
              compensation.base.__file__, compensation.functions.__file__)
