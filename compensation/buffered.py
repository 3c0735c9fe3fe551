"""Buffered compensator (seed §5.5, appendix C) and its direction-dependent extension (seed ch. 6).

In this module u_v is the seed's name for what the compensator receives: the P controller's output
(``u_p`` in the code), the valve setpoint before compensation.

Per leg, three buffers are filled over ``buffer_time`` (the seed's 30000 samples of its 10 kHz model =
3 s): UV the valve setpoints, UC "the computed compensation out of the actual difference between u_v
and ẏ/s" (seed §5.5), i.e. u_v - ẏ/s with s the desired slope, and UY the valve setpoints at zero
velocity (|ẏ| < k). Without compensation the maximum of u_v - ẏ/s equals the maximum of the needed
compensation (for the smooth area both are u_max/4, seed eq. 5.1), so the first update sets a; once the
compensation works, u_v - ẏ/s shrinks and, a being only ever increased, the shape is kept: "the global
shape of the compensation is nearly the right one after the first update" (seed §5.5). (We tried
(u_v + U_c) - ẏ/s, whose fixed point is the applied U_c: a then ratchets up on the dynamic lag at the
reversals and the hexapod's heave peaks end 64 % instead of 69 % below the uncompensated ones.)
When the buffers are full (appendix C):

1. each buffer passes appendix C's discrete low-pass (1 - p) / (1 - p z^-1), zero initial state (the
   recursion of ``scipy.signal.lfilter``; its 32 ms time constant re-discretised at the controller rate);
2. UC and UV are weighted by W(i) = 1 / (1 + exp(-10 i / l)), i = 1…l: appendix C's exponent scale. The
   text's eq. (5.4) writes 10 / (2 l), which weights the oldest sample 0.5 and the newest 0.993; appendix
   C's code, which produced Fig. 5.12/5.13, goes from 0.5 to 0.99995. We use the code's;
3. a = max(UC), b = 1/q with q = max|UV| (appendix C's last assignment of q), c = b mean(UY);
   a and b are only ever increased (appendix C: ``if anew > aold``), c follows the data; a is limited to
   q/4 (not in the seed: the exact amplitude for the quadratic flow area, eq. 5.1, the iterative
   compensators' limit too; without it a buffer shorter than the motion's period lets a run away, e.g.
   1 s buffers on a 0.5 Hz heave gave a = 44 V and 72 g peaks);
4. the buffers are cleared, and the function's parameters glide to the new values through a first-order
   low-pass (``fade_time``), never jumping.

The applied compensation is function (2), seed eq. (5.3), with the faded parameters.

The directional compensator keeps two such parameter sets, one fed while u_v rises and one while it
falls, and blends them by tanh(du_v/dt / direction_rate): a flow curve with hysteresis (seed §4.4,
Fig. 4.3, friction depending on the direction of motion) has a different zero-velocity setpoint on the
way up and on the way down, which one curve cannot match (seed ch. 6 recommends this distinction).

Written once, compiled: :func:`buffered_tick` is the compensator's sample; the classes hold its state
as named records (:class:`BufferedParams`, :class:`~compensation.base.ObserverState`,
:class:`Buffers`) and call it from Python; the compiled runner (:mod:`hexsim.engine.native`) calls the same
function on the same records inside its loop.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from compensation.base import (
    Compensator,
    FlowCurveObserver,
    ObserverFilter,
    ObserverState,
    observer_tick,
)
from compensation.functions import function2

#: [V] A full buffer whose valve range q = max|W UV_f| stays below this held no motion and teaches nothing
#: (:func:`update_parameters`): a platform standing still, its P output the position sensor's noise (mV).
STANDSTILL_Q_V = 0.05


class BufferedParams(NamedTuple):
    """Constants of :func:`buffered_tick`: the observer's filter and the controller period; the velocity
    band k [m/s]; the fade gain per sample [-]; appendix C's low-pass pole [-]; the directional blend's
    rate [V/s]."""

    filter: ObserverFilter
    velocity_band: float
    fade: float
    pole: float
    direction_rate: float


class Buffers(NamedTuple):
    """The buffers of D parameter sets (1 buffered, 2 directional) of length L for n legs: UV, UC, UY
    (D, L, n) (UY NaN where the velocity was not near zero); samples in each, fill (D, n) int; the
    (a, b, c) of the last update, abc (D, 3, n); the faded (a, b, c) applied (D, 3, n); appendix C's
    weights W(i) (L,); updates per set (D,) int."""

    uv: np.ndarray
    uc: np.ndarray
    uy: np.ndarray
    fill: np.ndarray
    abc: np.ndarray
    applied: np.ndarray
    weights: np.ndarray
    updates: np.ndarray

    @classmethod
    def empty(cls, sets: int, length: int, n_legs: int) -> "Buffers":
        i = np.arange(1, length + 1)
        return cls(np.zeros((sets, length, n_legs)), np.zeros((sets, length, n_legs)),
                   np.full((sets, length, n_legs), np.nan), np.zeros((sets, n_legs), dtype=np.int64),
                   np.zeros((sets, 3, n_legs)), np.zeros((sets, 3, n_legs)), 1.0 / (1.0 + np.exp(-10.0 * i / length)),
                   np.zeros(sets, dtype=np.int64))


@numba.njit(cache=True)
def lowpass(x, out, pole):
    """Appendix C's discrete low-pass (1 - pole) / (1 - pole z^-1) over x (L,), zero initial state, into
    out: the recursion of ``scipy.signal.lfilter`` for this filter (y = b0 x + z, z = pole y)."""
    z = 0.0
    b0 = 1.0 - pole
    for t in range(x.shape[0]):
        y = x[t] * b0 + z
        z = pole * y
        out[t] = y


@numba.njit(cache=True)
def update_parameters(B, d, i, pole, scratch):
    """Appendix C's update of set d, leg i, from its full buffers (steps 1–3 of the module doc), then
    the buffers of that leg cleared: a = max(W UC_f), b = 1/max|W UV_f|, both only ever increased, a
    limited to 1/(4 b); c = b mean(UY_f) over the samples at zero velocity (kept if there were none).
    A buffer whose range q = max|W UV_f| stays below :data:`STANDSTILL_Q_V` held no motion and changes nothing
    (not in the seed, whose motions all move: with b = 1/q of the sensor's noise, b grew without bound while a
    platform stood still after moving, and the directional compensator's U_c reached 2000 V)."""
    L = B.uv.shape[1]
    w = B.weights
    lowpass(B.uv[d, :, i], scratch, pole)
    q = 0.0
    for t in range(L):
        q = max(q, abs(scratch[t] * w[t]))
    if q < STANDSTILL_Q_V:
        for t in range(L):
            B.uy[d, t, i] = np.nan
        B.fill[d, i] = 0
        return
    lowpass(B.uc[d, :, i], scratch, pole)
    a_new = -np.inf
    for t in range(L):
        a_new = max(a_new, scratch[t] * w[t])
    b_new = 1.0 / max(q, 1e-12) if q > 0 else 0.0
    a = max(B.abc[d, 0, i], a_new)
    b = max(B.abc[d, 1, i], b_new)
    if b > 0:
        a = min(a, 0.25 / max(b, 1e-12))
    B.abc[d, 0, i] = a
    B.abc[d, 1, i] = b
    m = 0
    for t in range(L):
        if math.isfinite(B.uy[d, t, i]):
            scratch[m] = B.uy[d, t, i]
            m += 1
    if m > 0:
        zf = scratch[:m].copy()
        lowpass(zf, scratch, pole)
        total = 0.0
        for t in range(m):
            total += scratch[t]
        B.abc[d, 2, i] = b * (total / m)
    for t in range(L):
        B.uy[d, t, i] = np.nan
    B.fill[d, i] = 0


@numba.njit(cache=True)
def _add_samples(B, d, u_f, v_f, s, u_dot, band, pole):
    """Append this sample of every leg whose slope is known (and, for D = 2, whose u_v moves in set d's
    direction) to set d; update the legs whose buffers are full."""
    n = u_f.shape[0]
    L = B.uv.shape[1]
    full = False
    for i in range(n):
        if s[i] <= 0:
            continue
        if B.uv.shape[0] == 2 and (u_dot[i] >= 0) != (d == 0):
            continue
        row = B.fill[d, i]
        B.uv[d, row, i] = u_f[i]
        B.uc[d, row, i] = u_f[i] - v_f[i] / s[i]
        B.uy[d, row, i] = u_f[i] if abs(v_f[i]) < band else np.nan
        B.fill[d, i] = row + 1
        full = full or row + 1 >= L
    if full:
        scratch = np.empty(L)
        for i in range(n):
            if B.fill[d, i] >= L:
                update_parameters(B, d, i, pole, scratch)
        B.updates[d] += 1


@numba.njit(cache=True)
def buffered_tick(P, obs, B, u_p, y, u_c, stat):
    """One controller sample of the buffered (D = 1) or directional (D = 2) compensator, in place:
    u_p (n,) the P controller's output [V], y (n,) the measured position [m]; writes U_c (n,) [V] and
    the logged state ``stat`` (4, n): a, b, c, s (as :meth:`BufferedCompensator.state`). P a
    :class:`BufferedParams`, obs an :class:`~compensation.base.ObserverState`, B :class:`Buffers`."""
    n = u_p.shape[0]
    D = B.uv.shape[0]
    u_f = np.empty(n)
    v_f = np.empty(n)
    observer_tick(P.filter, obs, u_p, y, u_f, v_f)
    for d in range(D):
        _add_samples(B, d, u_f, v_f, obs.slope, obs.u_dot, P.velocity_band, P.pole)
    for d in range(D):
        for r in range(3):
            for i in range(n):
                B.applied[d, r, i] += P.fade * (B.abc[d, r, i] - B.applied[d, r, i])
    for i in range(n):
        stat[3, i] = obs.slope[i]
        if D == 1:
            u_c[i] = function2(u_p[i], B.applied[0, 0, i], B.applied[0, 1, i], B.applied[0, 2, i])
            for r in range(3):
                stat[r, i] = B.applied[0, r, i]
        else:
            w = 0.5 * (1.0 + math.tanh(obs.u_dot[i] / P.direction_rate))
            u_c[i] = w * function2(u_p[i], B.applied[0, 0, i], B.applied[0, 1, i], B.applied[0, 2, i]) + \
                (1.0 - w) * function2(u_p[i], B.applied[1, 0, i], B.applied[1, 1, i], B.applied[1, 2, i])
            for r in range(3):
                stat[r, i] = w * B.applied[0, r, i] + (1.0 - w) * B.applied[1, r, i]


class BufferedCompensator(Compensator):
    """Seed §5.5 / appendix C: parameters of function (2) from filtered, weighted buffers.

    The state lives in :attr:`params`, :attr:`observer` (its ``state``) and :attr:`buffers`; each
    :meth:`update` runs :func:`buffered_tick`. :meth:`kernel_state` hands the records to a compiled
    runner, which advances them in place."""

    name = "buffered"
    directions = 1

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        st = self.settings
        n = self.n_legs
        self.observer = FlowCurveObserver(n, self.rate_hz, st.velocity_cutoff_hz)
        length = max(2, int(round(st.buffer_time * self.rate_hz / self.directions)))
        self.buffers = Buffers.empty(self.directions, length, n)
        pole = math.exp(-1.0 / (self.rate_hz * st.buffer_filter_tau))
        fade = 1.0 - math.exp(-1.0 / (self.rate_hz * st.fade_time))
        self.params = BufferedParams(self.observer.filter, st.velocity_band, fade, pole, st.direction_rate)
        self._stat = np.zeros((4, n))

    def kernel_state(self) -> tuple[BufferedParams, ObserverState, Buffers]:
        """The records :func:`buffered_tick` reads and changes in place (not copies)."""
        return self.params, self.observer.state, self.buffers

    def update(self, u_p: np.ndarray, y_measured: np.ndarray) -> np.ndarray:
        u_c = np.empty(self.n_legs)
        buffered_tick(*self.kernel_state(), np.asarray(u_p, dtype=float), np.asarray(y_measured, dtype=float), u_c,
                      self._stat)
        return u_c

    def state(self) -> dict[str, np.ndarray]:
        """(a, b, c) applied at the last sample (for the directional one: blended as U_c is) and s."""
        return {key: self._stat[k].copy() for k, key in enumerate(("a", "b", "c", "s"))}


class DirectionalCompensator(BufferedCompensator):
    """Two buffered curves, for rising and for falling u_v, blended by tanh(du_v/dt / direction_rate)."""

    name = "directional"
    directions = 2
