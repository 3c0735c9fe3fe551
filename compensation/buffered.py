"""Buffered compensator (seed §5.5, appendix C) and its direction-dependent extension (seed ch. 6).

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

1. each buffer passes appendix C's discrete low-pass (``scipy.signal.lfilter``; its 32 ms time constant
   re-discretised at the controller rate);
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
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from compensation.base import Compensator, FlowCurveObserver
from compensation.functions import function2


class ParameterBuffers:
    """UV, UC, UY buffers of ``length`` samples for n legs, and the (a, b, c) they give (appendix C)."""

    def __init__(self, n_legs: int, length: int, rate_hz: float, tau: float) -> None:
        self.length = length
        self.uv = np.zeros((length, n_legs))
        self.uc = np.zeros((length, n_legs))
        self.uy = np.full((length, n_legs), np.nan)  # NaN where the velocity was not near zero
        self.fill = np.zeros(n_legs, dtype=int)
        pole = math.exp(-1.0 / (rate_hz * tau))
        self.num, self.den = [1.0 - pole], [1.0, -pole]
        i = np.arange(1, length + 1)
        self.weights = (1.0 / (1.0 + np.exp(-10.0 * i / length)))[:, None]
        self.abc = np.zeros((3, n_legs))  # (a, b, c) per leg; appendix C: aold, bold, c start at 0
        self.a, self.b, self.c = self.abc  # views
        self.updates = 0

    def add(self, legs: np.ndarray, uv: np.ndarray, uc: np.ndarray, uy: np.ndarray) -> None:
        """Append one sample for the legs selected by the boolean mask ``legs``; update when full."""
        rows = self.fill[legs]
        self.uv[rows, legs] = uv[legs]
        self.uc[rows, legs] = uc[legs]
        self.uy[rows, legs] = uy[legs]
        self.fill[legs] += 1
        if self.fill.max() >= self.length:
            self._update(np.flatnonzero(self.fill >= self.length))

    def _update(self, legs: np.ndarray) -> None:
        uvf = lfilter(self.num, self.den, self.uv[:, legs], axis=0) * self.weights
        ucf = lfilter(self.num, self.den, self.uc[:, legs], axis=0) * self.weights
        a_new = ucf.max(axis=0)
        q = np.abs(uvf).max(axis=0)
        b_new = np.where(q > 0, 1.0 / np.maximum(q, 1e-12), 0.0)
        self.a[legs] = np.maximum(self.a[legs], a_new)
        self.b[legs] = np.maximum(self.b[legs], b_new)
        # safety bound (not in the seed): a <= q/4 = 1/(4 b), the exact amplitude for the seed's quadratic
        # flow area (eq. 5.1), as the iterative compensators limit a (seed §5.4: "parameter a could be
        # limited"); a buffer shorter than the motion's period otherwise ratchets a up without bound
        b = self.b[legs]
        self.a[legs] = np.where(b > 0, np.minimum(self.a[legs], 0.25 / np.maximum(b, 1e-12)), self.a[legs])
        for leg in legs:
            uy = self.uy[:, leg]
            uy = uy[np.isfinite(uy)]
            if uy.size:
                self.c[leg] = self.b[leg] * float(np.mean(lfilter(self.num, self.den, uy)))
        self.uy[:, legs] = np.nan
        self.fill[legs] = 0
        self.updates += 1


class BufferedCompensator(Compensator):
    """Seed §5.5 / appendix C: parameters of function (2) from filtered, weighted buffers."""

    name = "buffered"
    directions = 1

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        st = self.settings
        n = self.n_legs
        self.observer = FlowCurveObserver(n, self.rate_hz, st.velocity_cutoff_hz)
        length = max(2, int(round(st.buffer_time * self.rate_hz / self.directions)))
        self.sets = [ParameterBuffers(n, length, self.rate_hz, st.buffer_filter_tau) for _ in range(self.directions)]
        self.applied = np.zeros((self.directions, 3, n))  # faded (a, b, c) per direction
        self._fade = 1.0 - math.exp(-1.0 / (self.rate_hz * st.fade_time))

    def _direction_weights(self) -> np.ndarray:
        """(directions, n) blend weights, summing to 1 per leg."""
        return np.ones((1, self.n_legs))

    def update(self, u_v: np.ndarray, y_measured: np.ndarray) -> np.ndarray:
        st = self.settings
        u_f, v_f = self.observer.update(u_v, y_measured)
        s = self.observer.slope
        ready = s > 0
        uc_sample = np.where(ready, u_f - v_f / np.where(ready, s, 1.0), 0.0)
        uy_sample = np.where(np.abs(v_f) < st.velocity_band, u_f, np.nan)
        if self.directions == 1:
            masks = [ready]
        else:
            rising = self.observer.u_dot >= 0
            masks = [ready & rising, ready & ~rising]
        for buffers, mask in zip(self.sets, masks):
            if mask.any():
                buffers.add(mask, u_f, uc_sample, uy_sample)
        for k, buffers in enumerate(self.sets):
            self.applied[k] += self._fade * (buffers.abc - self.applied[k])
        if self.directions == 1:
            return function2(u_v, *self.applied[0])
        w = self._direction_weights()
        a, b, c = self.applied[:, 0], self.applied[:, 1], self.applied[:, 2]
        return np.sum(w * function2(u_v[None, :], a, b, c), axis=0)

    def state(self) -> dict[str, np.ndarray]:
        if self.directions == 1:
            a, b, c = self.applied[0].copy()
        else:
            w = self._direction_weights()
            a, b, c = (np.sum(w * self.applied[:, k], axis=0) for k in range(3))
        return {"a": a, "b": b, "c": c, "s": self.observer.slope.copy()}


class DirectionalCompensator(BufferedCompensator):
    """Two buffered curves, for rising and for falling u_v, blended by the direction of u_v's change."""

    name = "directional"
    directions = 2

    def _direction_weights(self) -> np.ndarray:
        rising = 0.5 * (1.0 + np.tanh(self.observer.u_dot / self.settings.direction_rate))
        return np.stack([rising, 1.0 - rising])
