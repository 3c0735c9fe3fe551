"""Compiled (numba) kernel of the leg hydraulics, stepping MuJoCo without returning to Python.

The same physics as the reference :func:`hexsim.effects.step_plant` + :func:`hexsim.hydraulics.leg_force`
(seed eq. 3.2–3.4, 3.7–3.9 and the effects of :class:`hexsim.effects.Effects`), written per leg in
scalar loops and compiled with numba. The loop calls ``mj_step`` of the MuJoCo library the Python
bindings loaded, by symbol name, on the raw ``mjModel*`` / ``mjData*`` (``MjModel._address``), reading
and writing ``qpos``/``qvel``/``ctrl``/``sensordata`` through the bindings' numpy views of the same
memory. tests/test_native.py checks it against the numpy reference.
"""

from __future__ import annotations

import math
import pathlib

import llvmlite.binding as llvm
import mujoco
import numba
import numpy as np

from compensation.native import buffered_tick
from hexsim.effects import Effects
from hexsim.hydraulics import JACOBIAN_DP_FLOOR
from hexsim.params import HydraulicParams

_lib_path = sorted(pathlib.Path(mujoco.__file__).parent.glob("libmujoco.so*"))
_lib_path = _lib_path or sorted(pathlib.Path(mujoco.__file__).parent.glob("*mujoco*.dylib"))
# mj_step of the MuJoCo library the Python bindings loaded, called by symbol name from compiled code:
# mjModel*, mjData* passed as integers (the same ABI as pointers). Resolved when the kernel is linked,
# so the compiled kernels can be cached on disk (numba's cache=True) and a new process only loads them.
llvm.load_library_permanently(str(_lib_path[0]))
_mj_step = numba.types.ExternalFunction("mj_step", numba.types.void(numba.types.int64, numba.types.int64))

_FLOOR = math.sqrt(JACOBIAN_DP_FLOOR)


def pack(hyd: HydraulicParams, eff: Effects, dt: float = 0.0) -> np.ndarray:
    """Parameters as the flat float array the kernels read (see the index comments below)."""
    t = hyd.stribeck_table
    return np.array([
        hyd.supply_pressure, hyd.tank_pressure, hyd.orifice_constant, hyd.area_bottom, hyd.area_rod,  # 0-4
        hyd.bulk_modulus, hyd.pipeline_volume, hyd.u_v_max, hyd.x_v_max, hyd.overlap,  # 5-9
        hyd.null_offset, math.pi * hyd.spool_diameter, hyd.smooth_area_gain, float(hyd.flow_area == "sharp"),  # 10-13
        hyd.arctan_gain, float(hyd.arctan_normalised), *t[0], *t[1],  # 14-15, 16-19 (ydot < 0), 20-23 (>= 0)
        eff.supply_resistance, eff.supply_time_constant, eff.spool_frequency, eff.spool_damping,  # 24-27
        eff.spool_play, eff.leakage, dt,  # 28-30 (dt: the step [s] of run_block)
        eff.edge_gain_pa, eff.edge_gain_at,  # 31-32
    ])


@numba.njit(cache=True, fastmath=False)
def _areas(x, P):
    if P[13] > 0.5:
        a1 = P[11] * max(x - P[9], 0.0)
        a2 = P[11] * max(-x - P[9], 0.0)
    else:
        a = P[12] * x * x
        a1 = a if x > 0.0 else 0.0
        a2 = a - a1
    return a1, a2


@numba.njit(cache=True, fastmath=False)
def _friction(v, P):
    """Asymmetric Stribeck friction F_f [N] at piston velocity v [m/s] (seed eq. 3.9)."""
    o = 20 if v >= 0.0 else 16
    shape = math.atan(P[14] * v)
    if P[15] > 0.5:
        shape *= 2.0 / math.pi
    return P[o] * v + shape * (P[o + 1] + P[o + 2] * math.exp(-abs(v) / P[o + 3]))


@numba.njit(cache=True, fastmath=False)
def step_legs(P, u, y, ydot, dt, p1, ps, xv, vv, ub, force, groups, demand):
    """One step of every leg, in place: state (p1, ps, xv, vv, ub) and force, arrays (n,)."""
    n = p1.shape[0]
    ng = demand.shape[0]
    for g in range(ng):
        demand[g] = 0.0
    for i in range(n):
        # spool play and spool dynamics
        if P[28] > 0.0:
            ub[i] = min(max(ub[i], u[i] - P[28]), u[i] + P[28])
        else:
            ub[i] = u[i]
        x_set = (ub[i] - P[10]) * (P[8] / P[7])
        if P[26] > 0.0:
            w = 2.0 * math.pi * P[26]
            vv[i] = vv[i] + dt * (w * w * (x_set - xv[i]) - 2.0 * P[27] * w * vv[i])
            xv[i] = xv[i] + dt * vv[i]
            if abs(xv[i]) > P[8]:
                xv[i] = math.copysign(P[8], xv[i])
                vv[i] = 0.0
        else:
            xv[i] = x_set
        # orifice flow (seed eq. 3.4) and linearly implicit P1 (eq. 3.7)
        a1, a2 = _areas(xv[i], P)
        a1 *= P[31]
        a2 *= P[32]
        dp1 = ps[i] - p1[i]
        dp2 = p1[i] - P[1]
        s1 = math.sqrt(abs(dp1))
        s2 = math.sqrt(abs(dp2))
        phi = P[2] * (a1 * math.copysign(s1, dp1) - a2 * math.copysign(s2, dp2))
        dphi = -0.5 * P[2] * (a1 / max(s1, _FLOOR) + a2 / max(s2, _FLOOR))
        if P[29] != 0.0:
            phi += P[29] * dp1
            dphi -= P[29]
        stiff = P[5] / (max(y[i], 0.0) * P[3] + P[6])
        p1[i] = p1[i] + dt * stiff * (phi - ydot[i] * P[3]) / (1.0 - dt * stiff * dphi)
        if P[24] > 0.0:
            dps = ps[i] - p1[i]
            phi_pa = P[2] * a1 * math.copysign(math.sqrt(abs(dps)), dps)
            demand[groups[i]] += phi_pa + P[29] * dps - ydot[i] * P[4]
        force[i] = _friction(ydot[i], P)  # completed to the leg force below, once P_s is final
    if P[24] > 0.0:
        decay = math.exp(-dt / P[25])
        for i in range(n):
            target = P[0] - P[24] * demand[groups[i]]
            ps[i] = max(target + (ps[i] - target) * decay, P[1])
    # leg force with the new P1 and P_s (eq. 3.8 without gravity), as leg_force after step_plant
    for i in range(n):
        force[i] = p1[i] * P[3] - ps[i] * P[4] - force[i]


@numba.njit(cache=True)
def valve_replay(m_addr, d_addr, qpos, qvel, ctrl, sens, qadr, dadr, aadr, acc_adr, P, u_sched, sub, dt,
                 p1, ps, xv, vv, ub, out_pos, out_p1, out_ps, out_acc):
    """Open-loop replay of k independent legs, in the order of :func:`hexsim.replay.replay` (which see):
    row j's setpoints u_sched[:, j] drive the ``sub`` steps from row j to row j+1; row j records the
    position, P1 and P_s at its time and the acceleration MuJoCo computes in the first of those steps.
    Outputs (k, n). Returns -1, or the first row at which P1 is not finite."""
    k, n = u_sched.shape
    y = np.empty(k)
    yd = np.empty(k)
    force = np.empty(k)
    groups = np.arange(k)
    demand = np.empty(k)
    for j in range(n):
        for s in range(sub):
            for i in range(k):
                y[i] = qpos[qadr[i]]
                yd[i] = qvel[dadr[i]]
            if s == 0:
                for i in range(k):
                    out_pos[i, j] = y[i]
                    out_p1[i, j] = p1[i]
                    out_ps[i, j] = ps[i]
            step_legs(P, u_sched[:, j], y, yd, dt, p1, ps, xv, vv, ub, force, groups, demand)
            for i in range(k):
                ctrl[aadr[i]] = force[i]
            _mj_step(m_addr, d_addr)
            if s == 0:
                for i in range(k):
                    out_acc[i, j] = sens[acc_adr[i]]
        if not np.isfinite(p1).all():
            return j
    return -1


@numba.njit(cache=True)
def run_block(m_addr, d_addr, qpos, qvel, ctrl, sens, site_xpos, qadr, dadr, aadr, site1, site2, P, u, groups,
              p1, ps, xv, vv, ub, force, demand, hist, k0, nsteps, rec_div, r0, rec_k, rec_sens, rec_p1, rec_ps,
              rec_force, rec_y, rec_viol, status, ctrl_div, kp, setpoints, noise, rec_ref, rec_u, saturated,
              n_total, comp_mode, comp, ff_table, rec_uc, rec_comp):
    """``nsteps`` physics steps k0 … k0+nsteps-1 of n legs with the valve setpoints ``u`` (n,) held (ZOH),
    in the order of :class:`hexsim.simulation.HydraulicCoupling`: read y, ydot; push y into the
    sensor-delay ring ``hist`` (L, n) (Python pushed it for step k0 before the controller sample);
    advance the leg hydraulics by the step ``P[30]`` (:func:`step_legs`); write the leg forces to
    ``ctrl``; ``mj_step``.
    Every step k with k % rec_div == 0 fills row r of the ``rec_*`` arrays with the state at t_k: k,
    P1, P_s of leg 0 and the measured position before the step, the sensor data and site positions
    MuJoCo computed at the start of the step (``rec_viol``: largest distance between the connect
    anchor sites ``site1[i]``/``site2[i]``) and the force applied over the step. Returns the next row;
    ``status[0]`` = the first step whose state is not finite, else -1.

    ``ctrl_div`` > 0: the P controller runs here too (:class:`hexsim.controller.PController`): at every
    step k with k % ctrl_div == 0, u_p = K_p (r_j - y_m) with r_j = setpoints[j], j = k // ctrl_div,
    y_m = y_measured + noise_j; U_c = 0 (``comp_mode`` 0), the compiled buffered/directional
    compensator's :func:`compensation.native.buffered_tick` on (u_p, y_m) with the state tuple ``comp``
    (``comp_mode`` 1), or row min(j, last) of ``ff_table`` (n_ticks, n) (``comp_mode`` 2: a logged
    compensation fed forward, :class:`compensation.base.ReplayedCompensation`); u = sat(u_p + U_c,
    ±P[7]). ``saturated[0]`` counts the samples with a leg saturated; rows also get the setpoint, u_v
    and U_c in force and the compensator's (a, b, c, s) (``rec_ref``, ``rec_u``, ``rec_uc``,
    ``rec_comp`` (rows, 4, n)). Blocks must start at a controller sample (k0 % ctrl_div == 0). 0: ``u``
    is given and held, and Python fills those rows. Rows are a ring: sample r (of ``n_total``) goes to
    row r % len(rec_k), so a long run can keep only its last part."""
    n = p1.shape[0]
    L = hist.shape[0]
    dt = P[30]
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
                buffered_tick(comp, u_p, y_m, u_c, stat)
            elif comp_mode == 2:
                row = min(k // ctrl_div, ff_table.shape[0] - 1)
                for i in range(n):
                    u_c[i] = ff_table[row, i]
            hit = False
            for i in range(n):
                v = u_p[i] + u_c[i]
                u[i] = min(max(v, -P[7]), P[7])
                hit = hit or u[i] != v
            if hit:
                saturated[0] += 1
        record = k % rec_div == 0 and r < n_total
        w = r % rec_k.shape[0]
        if record:
            rec_k[w] = k
            rec_ps[w] = ps[0]
            for i in range(n):
                rec_p1[w, i] = p1[i]
                rec_y[w, i] = hist[(k + 1) % L, i]
                if ctrl_div > 0:
                    rec_ref[w, i] = setpoints[j, i]
                    rec_u[w, i] = u[i]
                    rec_uc[w, i] = u_c[i]
                    if comp_mode == 1:
                        for c in range(4):
                            rec_comp[w, c, i] = stat[c, i]
        step_legs(P, u, y, yd, dt, p1, ps, xv, vv, ub, force, groups, demand)
        for i in range(n):
            ctrl[aadr[i]] = force[i]
        _mj_step(m_addr, d_addr)
        finite = True
        for i in range(n):
            if not (math.isfinite(p1[i]) and math.isfinite(qpos[qadr[i]]) and math.isfinite(qvel[dadr[i]])):
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


def _flush_if_callee_changed() -> None:
    """Drop numba's on-disk cache of :func:`run_block` when :mod:`compensation.native` changed since it
    was written. The cache is keyed on this file's time stamp only, but run_block compiles in
    ``buffered_tick`` from that other file (numba documents that changes to functions in other files
    are not detected); without this an edit there would run with the old compiled compensator. A
    marker next to the cache holds the other file's time stamp and size."""
    import os

    import compensation.native as callee

    cache = getattr(run_block, "_cache", None)  # numba's FunctionCache of the dispatcher (cache=True)
    if cache is None or not hasattr(cache, "flush"):
        return
    try:
        st = os.stat(callee.__file__)
        stamp = f"{st.st_mtime_ns} {st.st_size}"
        marker = pathlib.Path(cache.cache_path) / "native.run_block.callee-stamp"
        if not marker.exists() or marker.read_text() != stamp:
            cache.flush()
            marker.write_text(stamp)
    except OSError:  # a read-only cache directory: numba then keeps no cache to go stale there either
        pass


_flush_if_callee_changed()
