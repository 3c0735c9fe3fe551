"""The buffered and directional compensators (:mod:`compensation.buffered`, seed §5.5 and appendix C)
compiled with numba, for the compiled engine's in-kernel controller (:func:`hexsim.native.run_block`).

The classes in :mod:`compensation.buffered` stay the reference: :func:`export_state` copies a
compensator's state into the flat arrays :func:`buffered_tick` reads and writes, :func:`import_state`
copies it back, and tests/test_native.py checks that a run with the compiled compensator follows the
run with the Python one. The only arithmetic that differs is the mean of UY for c (a sequential sum
here, numpy's pairwise sum there): the last bits of c.

State, a tuple of arrays (``D`` = 1 buffered, 2 directional; ``L`` buffer length; ``n`` legs):

* ``cpar`` (10,): Butterworth b0, b1, b2, a1, a2 of the observer (:class:`compensation.base.FlowCurveObserver`),
  controller period [s], velocity band k [m/s], fade gain, appendix C's filter pole, direction_rate [V/s];
* ``cobs`` (13, n): observer filter states z[0] (u_v, velocity), z[1] (u_v, velocity), previous
  measured position [m], running min/max of the filtered u_v [V] and velocity [m/s], previous filtered
  u_v [V], slope s [(m/s)/V], du_v/dt [V/s], and in row 12 whether a previous position exists (1.0);
* ``cbuf`` (D, 3, L, n): buffers UV, UC, UY (NaN where the velocity was not near zero);
* ``cfill`` (D, n) int64: samples in each buffer; ``cabc`` (D, 3, n): (a, b, c) of the last update;
  ``capp`` (D, 3, n): the faded (a, b, c) applied; ``cw`` (L,): appendix C's weights W(i);
  ``cupd`` (D,) int64: updates per direction.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from compensation.base import Compensator, NoCompensator, ReplayedCompensation
from compensation.buffered import BufferedCompensator, DirectionalCompensator

#: Compensators the compiled controller runs, and its ``comp_mode`` for each (:func:`hexsim.native.run_block`:
#: 0 U_c = 0, 1 :func:`buffered_tick`, 2 a table row per sample); the others run in Python between kernel calls.
COMPILED = {NoCompensator: 0, BufferedCompensator: 1, DirectionalCompensator: 1, ReplayedCompensation: 2}


def comp_mode(compensator: Compensator) -> int | None:
    """The kernel's ``comp_mode`` for ``compensator``, or None if only Python can run it."""
    return COMPILED.get(type(compensator))


def export_state(comp: Compensator, n_legs: int) -> tuple:
    """The kernel state of ``comp`` (a copy); for the others a placeholder of the same types."""
    if not isinstance(comp, BufferedCompensator):
        return (np.zeros(10), np.zeros((13, n_legs)), np.zeros((1, 3, 1, n_legs)), np.zeros((1, n_legs), np.int64),
                np.zeros((1, 3, n_legs)), np.zeros((1, 3, n_legs)), np.zeros(1), np.zeros(1, np.int64))
    obs, st = comp.observer, comp.settings
    sets = comp.sets
    pole = -sets[0].den[1]
    cpar = np.array([*obs.b, obs.a[1], obs.a[2], obs.dt, st.velocity_band, comp._fade, pole, st.direction_rate])
    has_prev = obs._y_prev is not None
    cobs = np.stack([obs._z[0, 0], obs._z[0, 1], obs._z[1, 0], obs._z[1, 1],
                     obs._y_prev if has_prev else np.zeros(n_legs), *obs.u_range, *obs.v_range, obs._u_prev,
                     obs.slope, obs.u_dot, np.full(n_legs, float(has_prev))])
    cbuf = np.stack([np.stack([s.uv, s.uc, s.uy]) for s in sets])
    cfill = np.stack([s.fill for s in sets]).astype(np.int64)
    cabc = np.stack([s.abc for s in sets])
    return (cpar, cobs, cbuf, cfill, cabc, comp.applied.copy(), sets[0].weights[:, 0].copy(),
            np.array([s.updates for s in sets], dtype=np.int64))


def import_state(comp: Compensator, state: tuple, ticks: int) -> None:
    """Copy the kernel state back into ``comp`` after ``ticks`` controller samples (a replayed table:
    the row it has reached; nothing for :class:`NoCompensator`)."""
    if isinstance(comp, ReplayedCompensation):
        comp._k += ticks
    if not isinstance(comp, BufferedCompensator):
        return
    _, cobs, cbuf, cfill, cabc, capp, _, cupd = state
    obs = comp.observer
    obs._z[0, 0], obs._z[0, 1], obs._z[1, 0], obs._z[1, 1] = cobs[0:4]
    obs._y_prev = cobs[4].copy() if cobs[12, 0] > 0.5 else None
    obs.u_range[:] = cobs[5:7]
    obs.v_range[:] = cobs[7:9]
    obs._u_prev = cobs[9].copy()
    obs.slope = cobs[10].copy()
    obs.u_dot = cobs[11].copy()
    for k, s in enumerate(comp.sets):
        s.uv[:], s.uc[:], s.uy[:] = cbuf[k]
        s.fill[:] = cfill[k]
        s.abc[:] = cabc[k]
        s.updates = int(cupd[k])
    comp.applied[:] = capp


@numba.njit(cache=True)
def _lowpass_inplace(x, out, pole):
    """Appendix C's discrete low-pass (1 - pole) / (1 - pole z^-1) over x, zero initial state, into out;
    the recursion of scipy.signal.lfilter for this filter (y = b0 x + z, z = pole y)."""
    z = 0.0
    b0 = 1.0 - pole
    for t in range(x.shape[0]):
        y = x[t] * b0 + z
        z = pole * y
        out[t] = y


@numba.njit(cache=True)
def _update_leg(buf, abc, w, pole, i, scratch):
    """ParameterBuffers._update for leg i of one direction: buf (3, L, n), abc (3, n)."""
    L = buf.shape[1]
    _lowpass_inplace(buf[0, :, i], scratch, pole)
    q = 0.0
    for t in range(L):
        q = max(q, abs(scratch[t] * w[t]))
    _lowpass_inplace(buf[1, :, i], scratch, pole)
    a_new = -np.inf
    for t in range(L):
        a_new = max(a_new, scratch[t] * w[t])
    b_new = 1.0 / max(q, 1e-12) if q > 0 else 0.0
    a = max(abc[0, i], a_new)
    b = max(abc[1, i], b_new)
    if b > 0:
        a = min(a, 0.25 / max(b, 1e-12))
    abc[0, i] = a
    abc[1, i] = b
    m = 0
    for t in range(L):
        if math.isfinite(buf[2, t, i]):
            scratch[m] = buf[2, t, i]
            m += 1
    if m > 0:
        zf = scratch[:m].copy()
        _lowpass_inplace(zf, scratch, pole)
        total = 0.0
        for t in range(m):
            total += scratch[t]
        abc[2, i] = b * (total / m)
    for t in range(L):
        buf[2, t, i] = np.nan


@numba.njit(cache=True)
def _function2(u, a, b, c):
    """Seed eq. (5.3), as compensation.functions.function2."""
    x = b * u - c
    return 4.0 * a * (math.copysign(math.sqrt(abs(x)), x) - x)


@numba.njit(cache=True)
def buffered_tick(state, u_p, y, u_c, stat):
    """One controller sample of :meth:`compensation.buffered.BufferedCompensator.update` (D = 1) or of
    the directional compensator (D = 2): u_p (n,) the P controller's output [V], y (n,) the measured
    position [m]; writes U_c (n,) [V] and the logged state ``stat`` (4, n): a, b, c, s (as ``state()``)."""
    cpar, cobs, cbuf, cfill, cabc, capp, cw, cupd = state
    n = u_p.shape[0]
    D = cbuf.shape[0]
    L = cbuf.shape[2]
    b0, b1, b2, a1, a2, dt, band, fade, pole, rate = cpar[0], cpar[1], cpar[2], cpar[3], cpar[4], cpar[5], \
        cpar[6], cpar[7], cpar[8], cpar[9]
    if cobs[12, 0] < 0.5:
        for i in range(n):
            cobs[4, i] = y[i]
            cobs[12, i] = 1.0
    scratch = np.empty(L)
    for d in range(D):
        full = False
        for i in range(n):
            if d == 0:  # the observer, once per sample (FlowCurveObserver.update)
                x0 = u_p[i]
                x1 = (y[i] - cobs[4, i]) / dt
                cobs[4, i] = y[i]
                o0 = b0 * x0 + cobs[0, i]
                o1 = b0 * x1 + cobs[1, i]
                cobs[0, i] = b1 * x0 - a1 * o0 + cobs[2, i]
                cobs[1, i] = b1 * x1 - a1 * o1 + cobs[3, i]
                cobs[2, i] = b2 * x0 - a2 * o0
                cobs[3, i] = b2 * x1 - a2 * o1
                cobs[11, i] = (o0 - cobs[9, i]) / dt
                cobs[9, i] = o0
                cobs[5, i] = min(cobs[5, i], o0)
                cobs[6, i] = max(cobs[6, i], o0)
                cobs[7, i] = min(cobs[7, i], o1)
                cobs[8, i] = max(cobs[8, i], o1)
                du = cobs[6, i] - cobs[5, i]
                cobs[10, i] = (cobs[8, i] - cobs[7, i]) / max(du, 0.01) if du > 0.01 else 0.0
                stat[0, i] = o0  # the filtered u_v and velocity, until the direction loop is done
                stat[1, i] = o1
            u_f, v_f, s = stat[0, i], stat[1, i], cobs[10, i]
            if s <= 0:
                continue
            if D == 2 and (cobs[11, i] >= 0) != (d == 0):
                continue
            row = cfill[d, i]
            cbuf[d, 0, row, i] = u_f
            cbuf[d, 1, row, i] = u_f - v_f / s
            cbuf[d, 2, row, i] = u_f if abs(v_f) < band else np.nan
            cfill[d, i] = row + 1
            full = full or row + 1 >= L
        if full:
            for i in range(n):
                if cfill[d, i] >= L:
                    _update_leg(cbuf[d], cabc[d], cw, pole, i, scratch)
                    cfill[d, i] = 0
            cupd[d] += 1
    for d in range(D):
        for r in range(3):
            for i in range(n):
                capp[d, r, i] += fade * (cabc[d, r, i] - capp[d, r, i])
    for i in range(n):
        stat[3, i] = cobs[10, i]
        if D == 1:
            u_c[i] = _function2(u_p[i], capp[0, 0, i], capp[0, 1, i], capp[0, 2, i])
            for r in range(3):
                stat[r, i] = capp[0, r, i]
        else:
            w = 0.5 * (1.0 + math.tanh(cobs[11, i] / rate))
            u_c[i] = w * _function2(u_p[i], capp[0, 0, i], capp[0, 1, i], capp[0, 2, i]) + \
                (1.0 - w) * _function2(u_p[i], capp[1, 0, i], capp[1, 1, i], capp[1, 2, i])
            for r in range(3):
                stat[r, i] = w * capp[0, r, i] + (1.0 - w) * capp[1, r, i]
