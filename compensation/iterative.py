"""Iterative look-up compensator (seed §5.3-5.4, Fig. 5.5-5.10).

A table of ``table_size`` (1001) compensation voltages over ±u_v,max (element 501 = 0 V) is updated once
per visit of an element: U[i] += gain (s u_v - ẏ), the desired minus the actual velocity. The applied
compensation is not the (noisy, stepped) table but an algebraic function whose parameters are read off
the table's shape:

- a: the held maximum of the table, seed §5.3 "keeping the maximum value", in one of two rules
  (``CompensatorSettings.held_maximum``):

  * ``"seed"``: one a, the held maximum of the signed table, as the seed. Where the function
    over-compensates, the table's entries drift to the wrong sign (positive at negative u_v), the held
    maximum picks them up and a ratchets upwards. This is the mechanism behind the seed's Fig. 5.7/5.8
    (function (1) first helps, then diverges); on the hexapod's legs, whose flow curves are asymmetric
    (P_s - P1 ≠ P1 - P_t, and the legs' loads differ up and down), it makes function (2) diverge too
    (heave, after ~17 s).
  * ``"per-side"`` (default): a+ from the entries at u_v > 0, a- from minus those at u_v < 0, each used
    on its side of the function. A wrong-sign entry is a sign of over-compensation, not a need for more,
    and is ignored. For function (2) a is also limited to q/4, the exact amplitude for the seed's
    quadratic flow area (eq. 5.1: U_c = q [sqrt(u/q) - u/q], maximum q/4), the seed's own advice: "to
    prevent the compensation being too large, parameter a could be limited" (§5.4). Without the limit
    the table entries near u_v = 0 keep integrating the plant's lag at every reversal (the velocity
    follows the valve late, so s u_v - ẏ has the same sign on every pass) and a creeps up: on hexapod
    heave the peaks end 70 % above uncompensated after 60 s. Function (1) keeps the valve range as its
    only bound: it over-grows a (its slope near u_v = 0 is 2.3x smaller for the same a) and stays far
    from the linear flow curve.
- b = pi/q (function 1) or 1/q (function 2), q the valve range (running max |u_v|), at least
  ``q_threshold`` (the seed's threshold start value);
- c = b r, r the valve setpoint at zero velocity: here the exponential average of u_v over samples with
  |ẏ| < k (seed: k± = 1e-3 m/s). The seed's text writes r = (u_max - u_min)/2 over that band, which is the
  band's half-width rather than its centre; appendix C uses mean(UY), the centre, as we do.

Seed's finding, reproduced in tests: with function (1) the table keeps growing where (1) cannot give the
needed shape, a grows and the peaks first shrink then grow (Fig. 5.7/5.8); with function (2) it converges
(Fig. 5.9/5.10). Safety bound (not in the seed): a <= u_v,max, so a diverging run stays bounded.
"""

from __future__ import annotations

import numpy as np

from compensation.base import Compensator, FlowCurveObserver
from compensation.functions import FUNCTIONS

#: Time constant [s] of the exponential average of u_v at zero velocity (r).
R_AVERAGE_TIME = 1.0


class IterativeCompensator(Compensator):
    """Seed §5.3 look-up table + algebraic function ``function`` (1 or 2)."""

    function = 2

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        st = self.settings
        n = self.n_legs
        self.observer = FlowCurveObserver(n, self.rate_hz, st.velocity_cutoff_hz)
        self.table = np.zeros((n, st.table_size))
        self._half = st.table_size // 2
        self._du = self.u_v_max / self._half  # [V] per element (0.02 V for 1001 elements over ±10 V)
        self._index_prev = np.full(n, -1)
        self.a_pos = np.zeros(n)  # held maximum of U (compensation for b u_v - c > 0)
        self.a_neg = np.zeros(n)  # held maximum of -U (for b u_v - c < 0)
        self.q = np.zeros(n)
        self.r = np.zeros(n)
        self._alpha_r = 1.0 / (R_AVERAGE_TIME * self.rate_hz)
        self._f = FUNCTIONS[self.function]
        self._b_scale = np.pi if self.function == 1 else 1.0

    @property
    def b(self) -> np.ndarray:
        return self._b_scale / np.maximum(self.q, self.settings.q_threshold)

    @property
    def c(self) -> np.ndarray:
        return self.b * self.r

    def update(self, u_p: np.ndarray, y_measured: np.ndarray) -> np.ndarray:
        st = self.settings
        u_f, v_f = self.observer.update(u_p, y_measured)
        s = self.observer.slope
        rows = np.arange(self.n_legs)
        idx = np.clip(np.rint(u_f / self._du).astype(int) + self._half, 0, st.table_size - 1)
        visit = (idx != self._index_prev) & (s > 0)
        self.table[rows[visit], idx[visit]] += st.iterative_gain * (s[visit] * u_f[visit] - v_f[visit])
        self._index_prev = idx
        if st.held_maximum == "seed":  # one a: the held maximum of the signed table (seed §5.3)
            top = self.table.max(axis=1)
            self.a_pos = self.a_neg = np.minimum(np.maximum(self.a_pos, top), self.u_v_max)
        else:  # per side: only entries with the sign the function gives there count
            pos = self.table[:, self._half + 1:].max(axis=1)
            neg = -self.table[:, : self._half].min(axis=1)
            limit = self.u_v_max if self.function == 1 else np.maximum(self.q, st.q_threshold) / 4.0
            self.a_pos = np.minimum(np.maximum(self.a_pos, pos), limit)
            self.a_neg = np.minimum(np.maximum(self.a_neg, neg), limit)
        self.q = np.maximum(self.q, np.abs(u_f))
        still = np.abs(v_f) < st.velocity_band
        self.r = np.where(still, self.r + self._alpha_r * (u_f - self.r), self.r)
        b, c = self.b, self.c
        a = np.where(b * u_p - c >= 0.0, self.a_pos, self.a_neg)
        return self._f(u_p, a, b, c)

    @property
    def a(self) -> np.ndarray:
        """The larger of the two held maxima [V] (n_legs,)."""
        return np.maximum(self.a_pos, self.a_neg)

    def state(self) -> dict[str, np.ndarray]:
        return {"a": self.a_pos.copy(), "a_neg": self.a_neg.copy(), "b": self.b.copy(), "c": self.c.copy(),
                "s": self.observer.slope.copy()}


class Iterative1(IterativeCompensator):
    """Look-up table + function (1), seed eq. (5.2): diverges (seed Fig. 5.7/5.8)."""

    name = "iterative-1"
    function = 1


class Iterative2(IterativeCompensator):
    """Look-up table + function (2), seed eq. (5.3): converges (seed Fig. 5.9/5.10)."""

    name = "iterative-2"
    function = 2
