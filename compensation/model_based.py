"""Model-based feedforward: the valve command the leg needs to follow its reference, from the inverse of
the calibrated leg model, beside the P loop (seed ch. 6's "model-based" direction; hydraulic motion
control's velocity, pressure and friction feedforward).

The seed's compensators (ch. 5) linearise the *static* flow curve u_v -> ẏ (eq. 5.1) and leave the P loop
to make the velocity: the piston lags its reference by ẏ / (K_p s) and, at a reversal, crosses the
overlap and the friction's flip late. What remains of the bump under the exact static inverse (the
oracle) is dynamics: the chamber pressure must change by the friction's flip, ΔF_f / A1, and that takes
oil, V / E · ΔP1 (seed eq. 3.7). The feedforward gives the valve, per leg and controller sample,

    φ_1 = A1 (ṙ + s LP(u_p)) + V(r) / E · dP1_ref/dt,                    (seed eq. 3.7 solved for φ_1)
    P1_ref = P1_rest + ((M r̈)_i + F_f(ṙ)) / A1,                         (seed eq. 3.8 about the rest load)
    P1 = P1_ref + LP_5Hz(p1 - P1_ref)                                     (the measured p1, where logged)
    u_v = F^-1(φ_1 / A1; P1),    U_c = u_v - u_p,

with F the leg's static flow curve (seed eq. 5.1) from the machine file, at the rest pressure, scaled to
P1 by the orifice law (seed eq. 3.4: flow ∝ sqrt(Δp) of the edge that opens), r the piston
setpoint and its derivatives (the motion computer's reference), LP a low-pass on the P output
(``loop_filter_hz``), s the slope of the linear curve the P loop sees (the machine's chord at
±``oracle_u_ref``, as the oracle's), F_f the friction curve (seed
eq. 3.9, or the machine's table), M the legs' inertia matrix, V(r) = r A1 + V_pl. With a perfect
model and reference the P output stays at the sensor noise; what it still carries is the model's error,
which :class:`AdaptiveFeedforward` learns.

The low-pass matters as much as the model: the position sensor's noise (2 µm rms on the Micro Motion
System) times K_p is white at the controller rate, and the inverse's gain is highest near zero velocity,
where the flow curve is flat. On the built-in 20 s heave (``hexsim run heave --compensator
feedforward``) the feedforward with the filter at 240 Hz (none, in effect) leaves a mean reversal peak of
0.041 m/s² (0.0029 with a noiseless sensor); with the default 20 Hz filter, 0.0051 (none: 0.497). The
filter's phase lag at the loop's crossover (K_p s ≈ 30 rad/s) is about 20°.

What the compensator knows of the machine is a :class:`LegModel`: built by hexsim from a machine file
(:func:`hexsim.control.feedforward.leg_model`) or read from a tuned file (``hexsim tune``), never the
simulator's truth.
"""

from __future__ import annotations

import math
from concurrent.futures import Executor, Future

import numpy as np
from scipy.signal import butter, sosfilt_zi

from compensation.base import Compensator, sos_tick
from compensation.curve_learning import BAND_MPS, CurveLearner, Taken, rest_scale
from compensation.leg_model import LegModel, Reference, open_together
from compensation.settings import CompensatorSettings, SettingsError

#: Low-pass [Hz] on a measured pressure before the feedforward scales its flow curve to it: the leg's
#: load (the pose, the payload, friction at speed) passes, the oil spring's swing (~100 Hz on the Micro
#: Motion System) does not. Unfiltered, the inverse's gain follows P1 and P1 follows the inverse: on a
#: drifting null that loop rang between tank and supply pressure.
PRESSURE_FILTER_HZ = 5.0

#: The smallest footprint [V] at which the adaptive feedforward's guard turns a leg's compensation off (the
#: P output's largest |LP(u_p)| within ±0.1 s of a reversal): on the Micro Motion System's heave the adaptive
#: feedforward's footprint runs at 3 mV, an uncompensated reversal's |u_p| at 0.56 V.
TURN_OFF_FLOOR_V = 0.05

def _both_open(model: LegModel, i: int) -> tuple[int, int, np.ndarray, np.ndarray] | None:
    """Leg ``i``'s band of the grid where both edges of its 3-way valve pass flow at rest (each above
    :data:`OPEN_FRACTION` of the curve's largest speed), widened by a point either side: (first index, one past
    the last, v_PA and v_AT there [m/s]); None for a model without ``velocity_at`` or whose edges never open
    together (an overlapped spool)."""
    if model.velocity_at is None:
        return None
    v, at = model.velocity[i], model.velocity_at[i]
    pa = v + at
    both = np.flatnonzero(open_together(v, at)[0])
    if both.size == 0:
        return None
    lo, hi = max(int(both[0]) - 1, 0), min(int(both[-1]) + 2, len(v))
    return lo, hi, pa[lo:hi] + 1e-12 * model.u[lo:hi], at[lo:hi]


class FeedforwardCompensator(Compensator):
    """The model-based feedforward of this module's docstring, per leg, at the controller rate.

    Built as ``cls(n_legs, rate_hz, u_v_max, settings, model=LegModel)``; the simulator hands it each
    sample's :class:`Reference` through :meth:`observe` before :meth:`update`. Without a reference (a
    controller that gives none) it falls back to the static inverse of the oracle's form on its model,
    U_c = F^-1(s u_p) - u_p. ``settings.feedforward_pressure``: ``"reference"`` (P1_ref) or ``"measured"``
    (the transducer's p1, where the reference carries it). Raises SettingsError for a model of another
    number of legs or one :func:`check_model` refuses.
    """

    name = "feedforward"

    def __init__(self, n_legs: int, rate_hz: float, u_v_max: float = 10.0,
                 settings: CompensatorSettings | None = None, plant=None, model: LegModel | None = None) -> None:
        super().__init__(n_legs, rate_hz, u_v_max, settings)
        if model is None:
            raise SettingsError(f"the {self.name} compensator needs the machine's leg model (a machine file or a "
                                "tuned file)")
        if model.n_legs != self.n_legs:
            raise SettingsError(f"the leg model has {model.n_legs} legs, the machine {self.n_legs}")
        self.model = model
        self.reference: Reference | None = None
        self.dt = 1.0 / self.rate_hz
        u, v = model.u, model.velocity
        self._rest_drop = (model.supply_pressure - model.p_rest, model.p_rest - model.tank_pressure)
        # the inverse, per leg: velocity strictly increasing (a vanishing slope inside the overlap)
        self._v = v + 1e-12 * u[None, :]
        self._u = u
        self._null = np.array([_null(u, v[i]) for i in range(self.n_legs)])
        self._edges = [_both_open(model, i) for i in range(self.n_legs)]
        self.feedforward = np.zeros(self.n_legs)
        nyquist = self.rate_hz / 2
        if self.settings.loop_filter_hz >= nyquist:
            raise SettingsError(f"loop_filter_hz {self.settings.loop_filter_hz} must be below the Nyquist rate {nyquist}")
        self._sos = butter(2, self.settings.loop_filter_hz / nyquist, output="sos")
        self._zi = np.zeros((self._sos.shape[0], 2, self.n_legs))
        self._psos = butter(2, min(PRESSURE_FILTER_HZ / nyquist, 0.9), output="sos")
        self._pzi = None

    def observe(self, reference: Reference) -> None:
        self.reference = reference

    def demand(self) -> tuple[np.ndarray, np.ndarray]:
        """(the reference's velocity demand [m/s]: ṙ plus the flow that changes the chamber's pressure, over
        A1; P1_ref [Pa]), each (n_legs,); zeros and the rest pressure without a reference."""
        m, ref = self.model, self.reference
        if ref is None:
            return np.zeros(self.n_legs), m.p_rest.copy()
        a1 = m.area_bottom
        f_now = m.friction(ref.r_dot)
        p1_ref = m.p_rest + (m.mass @ ref.r_ddot + f_now) / a1
        if ref.p1 is not None and self.settings.feedforward_pressure == "measured":
            p1_ref = p1_ref + self.pressure_filter(np.asarray(ref.p1, dtype=float) - p1_ref)
        # dP1_ref/dt: inertia's jerk and the friction's change along the reference (seed eq. 3.8)
        f_next = m.friction(ref.r_dot + ref.r_ddot * self.dt)
        dp1 = (m.mass @ ref.r_dddot + (f_next - f_now) / self.dt) / a1
        volume = np.maximum(ref.r, 0.0) * a1 + m.pipeline_volume
        return ref.r_dot + volume / m.bulk_modulus * dp1 / a1, p1_ref

    def inverse(self, velocity: np.ndarray, p1: np.ndarray) -> np.ndarray:
        """u_v [V] (n_legs,) giving the static ``velocity`` [m/s] at bottom pressure ``p1`` [Pa]: the flow
        curve at rest scaled by sqrt(Δp / Δp_rest) of the edge that opens (seed eq. 3.4), inverted; where the
        model has both edges open together (``velocity_at``), each edge scaled by its own drop there; each
        scale held within 0.5…2 (a chamber near supply or tank pressure would otherwise ask for the whole
        valve). With ``settings.dead_band_margin`` m > 0 the curve is read as opening m earlier on each edge:
        u_v moved m towards the curve's null (the middle of its overlap, or where it crosses zero), never past it."""
        m = self.model
        target = np.asarray(velocity, dtype=float)
        if m.pressure_scaling:
            up = np.sqrt(np.clip((m.supply_pressure - p1) / self._rest_drop[0], 0.25, 4.0))
            down = np.sqrt(np.clip((p1 - m.tank_pressure) / self._rest_drop[1], 0.25, 4.0))
            u = np.array([self._edge_inverse(i, target[i], up[i], down[i]) for i in range(self.n_legs)])
        else:
            u = np.array([np.interp(target[i], self._v[i], self._u) for i in range(self.n_legs)])
        margin = self.settings.dead_band_margin
        if not margin:
            return u
        return np.where(target > 0, np.maximum(u - margin, self._null), np.where(
            target < 0, np.minimum(u + margin, self._null), u))

    def _edge_inverse(self, i: int, target: float, up: float, down: float) -> float:
        """u_v [V] of leg ``i`` giving ``target`` [m/s] with the supply edge's flow scaled by ``up`` and the return
        edge's by ``down`` (each sqrt(Δp / Δp_rest), seed eq. 3.4): outside the band where both edges are open
        (:func:`_both_open`) the curve scaled by the edge the target's sign opens; within it
        v_PA up - v_AT down, plus what the adaptive learner added (scaled by the side's edge)."""
        edges = self._edges[i]
        if edges is None:
            return float(np.interp(target / (up if target >= 0 else down), self._v[i], self._u))
        lo, hi, v_pa, v_at = edges
        learned = self._v[i, lo:hi] - self.model.velocity[i, lo:hi]
        net = v_pa * up - v_at * down + learned * np.where(self._u[lo:hi] >= self._null[i], up, down)
        if target > net[-1]:
            return float(np.interp(target / up, self._v[i], self._u))
        if target < net[0]:
            return float(np.interp(target / down, self._v[i], self._u))
        return float(np.interp(target, np.maximum.accumulate(net), self._u[lo:hi]))

    def pressure_filter(self, p1: np.ndarray) -> np.ndarray:
        """The measured p1's departure from P1_ref [Pa] (n_legs,) low-passed at :data:`PRESSURE_FILTER_HZ`
        (2nd-order Butterworth, started at the first sample): the load the model does not know (the pose,
        the payload, friction that changed), without the oil spring's swing; the fast part (the friction's
        flip, the inertia) stays the reference's."""
        p1 = np.asarray(p1, dtype=float)
        if self._pzi is None:
            self._pzi = sosfilt_zi(self._psos)[:, :, None] * p1[None, None, :]
        out = np.empty(len(p1))
        sos_tick(self._psos, self._pzi, p1, out)
        return out

    def loop_filter(self, u_p: np.ndarray) -> np.ndarray:
        """LP(u_p) [V] (n_legs,): one sample of the 2nd-order Butterworth (``scipy.signal.sosfilt``'s
        recursion, :func:`compensation.base.sos_tick`, state kept)."""
        u_p = np.asarray(u_p, dtype=float)
        out = np.empty(len(u_p))
        sos_tick(self._sos, self._zi, u_p, out)
        return out

    def update(self, u_p: np.ndarray, y_measured: np.ndarray) -> np.ndarray:
        velocity, p1 = self.demand()
        u_v = self.inverse(velocity + self.model.slope * self.loop_filter(u_p), p1)
        self.feedforward = u_v - u_p
        return self.feedforward

    def state(self) -> dict[str, np.ndarray]:
        return {"s": self.model.slope.copy()}


class AdaptiveFeedforward(FeedforwardCompensator):
    """The feedforward with an inverse that learns the machine's own curve and follows it as it drifts (oil
    temperature, wear, a drifting null), under a guard that falls back rather than make a bump worse.

    Learning, on two time scales:

    - **the whole curve** (:class:`compensation.curve_learning.CurveLearner`): the seed's buffers and weighting
      (§5.5, appendix C) in the model-based frame. Over ``buffer_time`` the compensator keeps what it commanded
      and what the P loop did; offline in the buffer it inverts the loop (the piston's velocity is ṙ - ė, e the
      tracking error the P output is K_p times) and so measures the curve's error at each command without the
      loop's lag, and corrects the leg model's curve where the motion went, faded in over ``fade_time``. A
      corner where a rounded metering edge meets the port, which a calibration smoothed, is learned where the
      motion crosses it (docs/compensation.md: the reference plant R1's corner crossings from 11x to about 3x
      the seat's perception threshold within a minute, the corner's kink kept).
    - **the null**: a shift c [V] of the inverse, u_v = F^-1(v + s LP(u_p)) + c, moved towards the volts the P
      loop adds, e = F^-1(v + s LP(u_p)) - F^-1(v), by least mean squares, Δc = dt / ``adapt_time`` e (in the
      line of Tao & Kokotović's adaptive dead-band inverse, *Adaptive control of systems with actuator and
      sensor nonlinearities*, Wiley 1996, ch. 3): a drifting null is followed in a fraction of a second, where
      a buffer takes seconds. (One c for both sides: learned per side, the two breakpoints split on the
      asymmetry of the P loop's lag and the jump between them at every reversal was itself a bump. A slope
      correction per side beside it, as the curve's learning began, fought the curve on a drifting machine.)
      The null is learned where the curve is not: below the curve learner's band
      (:data:`compensation.curve_learning.BAND_MPS`), near the reversals, where a null shift matters most;
      learned at every speed, it took up the curve's own error (a corner's) within each period and carried it
      into the next reversal (on the reference plant R1 the mean reversal peak 0.078 m/s² with it, 0.047
      without). The flow gain's error the curve's learner measures (g per side,
      :meth:`~compensation.curve_learning.CurveLearner.gain_error`; the curve learns its shape and leaves the
      gain to the P loop) is not the null's either: the loop's volts are read against F^-1(w + g v), what the
      loop adds for the gain taken out (at the band's edge a gain 1 % off is 0.5 mm/s, some 3 mV on a valve of
      0.16 m/s per volt, and c flipped by it at every reversal; ``tests/compensators/test_feedforward.py``).
      What it learns there flips with the direction (the loop's work at a reversal), so beyond the band the
      inverse moves by the mean of the shifts the two sides last held (:meth:`shift`): a drift moves the whole
      curve, a flip would move a corner of it. The seed's safety principles (§5.5): no learning below the
      velocity band k, e clipped to ±0.25 V per sample, steps bounded to ``adapt_rate`` [V/s], c to
      ±``adapt_limit``, faded in over ``fade_time``.
    - **the null's drift rate**: c also moves at a learned rate ċ [V/s] at every sample, and each step the loop
      teaches c teaches ċ 1 / (:data:`DRIFT_RATIO` ``adapt_time``) of it (a second integrator: the type-2 loop of
      a tracking filter, which follows a ramp without lag, where c alone lags a drift r by r times its time
      constant, and learns only near the reversals, a fifth of the time on the seed's sine). A warming valve's
      null drifts steadily for minutes; learned only as c, the lag is paid at every reversal. On the
      independent actuators of ``examples/proof_on_the_machine.py`` (60 s sine, second half; the tuned file's
      model; ``adapt_time`` 1 s): ``drift`` (its null 1 mV/s, its oil warming 15 K) 0.141 m/s² and the seat 3.27x
      the ISO 2631-1 threshold without the rate, 0.037 and 1.54x with it (it learned 1.06 mV/s); ``corner`` (no
      drift) and the reference plant R1 the same either way (0.040 and 0.0294 m/s²). ċ is bounded to
      ±:data:`DRIFT_LIMIT`.

    Guard: at each reversal of the reference (per leg), the largest |LP(u_p)| within ±0.1 s, less the volts the
    loop adds for the flow gain's measured error (as the null reads them; on the 4-way axis of
    ``examples/four_way_axis.py`` the gain's volts alone took its footprint over the floor below), is the bump's
    footprint in the loop (a leg that stalls in the dead band makes the P output climb across it).
    A footprint more than twice its running level (an exponential mean over the last reversals, which
    follows a slow drift) on two reversals running restores the last null and curve that did not, and learning
    pauses for four reversals. A footprint as large as the P output an uncompensated reversal needs — the
    flow curve's dead band, and at least :data:`TURN_OFF_FLOOR_V` (some fifteen times a working
    feedforward's footprint on the Micro Motion System, a tenth of an uncompensated reversal's there) — on two reversals
    running fades the leg's compensation out (U_c -> 0, logged as ``guard`` = 1): the leg runs
    uncompensated rather than worse.
    """

    name = "adaptive"
    WINDOW_S = 0.1
    #: The drift rate's time constant over the null's (``adapt_time``): the tracker's two poles real (damping
    #: 0.5 sqrt(DRIFT_RATIO) = 1.6). Measured on ``corner`` and ``drift`` (60 s; ``adapt_time`` 0.3 s): at 33 (the
    #: rate's time constant 10 s) 0.042 and 0.045 m/s² left, at 10 0.039 and 0.042, though the rate then wandered
    #: to 0.8 mV/s on ``corner``, whose null does not drift (at ``adapt_time`` 1 s: 0.06 mV/s).
    DRIFT_RATIO = 10.0
    #: Largest drift rate [V/s] learned: ten times the 1 mV/s a warming valve's null is judged against
    #: (``hexsim tune``'s drifting neighbour).
    DRIFT_LIMIT = 0.01
    #: Delay [s] between a buffer filling and its curve taking effect: time to teach it beside the loop
    #: (:meth:`learn_in`; some 20 ms a buffer, 0.1 s across a ±10 V curve) while the controller ticks on. The same
    #: in a batch run, which teaches at once and holds the result, so the two give the same commands.
    LEARN_DELAY_S = 0.2

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        st, n, m = self.settings, self.n_legs, self.model
        self.null = np.zeros(n)  # c [V]
        self.drift = np.zeros(n)  # ċ [V/s]
        self._held = np.full((n, 2), np.nan)  # c as each side (retracting, extending) last left the band [V]
        self.learner = CurveLearner(m.u, m.velocity, self.rate_hz, st.buffer_time, kp=m.kp)
        self._v_target = None  # the curve the inverse is fading to (_set_curve)
        self.good = (self.null.copy(), self.learner.state(), self.drift.copy())
        half = self.WINDOW_S * self.rate_hz
        self._ring = np.zeros((int(2 * half) + 1, n))
        self._k = 0
        self._since = np.full(n, -1)  # samples since the last reversal, -1: none pending
        self._last_sign = np.zeros(n)
        self.level = np.full(n, np.nan)  # the footprint's running level [V]
        self._strikes = np.zeros(n, dtype=int)
        self._outside = np.zeros(n, dtype=int)
        self._pause = np.zeros(n, dtype=int)
        self.off = np.zeros(n, dtype=bool)
        self._scale = np.ones(n)  # 1: compensating, fading to 0 once the guard turns a leg off
        self._fade = 1.0 - math.exp(-self.dt / st.fade_time)
        self._applied = 0.0
        # the footprint an uncompensated reversal leaves [V]: the dead band, at least the floor
        self.turn_off = np.maximum([_dead_band(m.u, row) for row in m.velocity], TURN_OFF_FLOOR_V)
        self._tick = 0
        self._teaching: tuple[int, Future] | None = None  # (the tick it takes effect, what the buffer taught)
        self._executor: Executor | None = None

    def learn_in(self, executor: Executor | None) -> None:
        """Teach each full buffer in ``executor`` (:meth:`compensation.curve_learning.CurveTeacher.teach`; e.g. a
        worker process for a real-time loop, which must not stall for it; None: at once, in the tick). Either way
        its curve takes effect :data:`LEARN_DELAY_S` after the buffer filled, or, taught in ``executor``, at the
        first tick after that it is ready (the loop does not wait for it unless the next buffer is full). An empty
        buffer is taught in it at once, so the first real one does not pay for the libraries' first calls (some
        10 ms); the learner's own buffer is not touched."""
        self._executor = executor
        if executor is not None:
            learner = self.learner
            empty = Taken({k: np.ones_like(v) if k == "scale" else np.zeros_like(v) for k, v in learner.buffer.items()},
                          list(learner.gram), learner.rhs.copy(), learner.gain_evidence.copy())
            executor.submit(learner.teacher.teach, empty).result()

    def update(self, u_p: np.ndarray, y_measured: np.ndarray) -> np.ndarray:
        self._tick += 1
        if self._teaching is not None and self._tick >= self._teaching[0] and (
                self._executor is None or self._teaching[1].done()):
            self._take_lesson()
        self._follow_curve()
        velocity, p1 = self.demand()
        loop = self.loop_filter(u_p)
        static = self.inverse(velocity, p1)
        promised = velocity + self.model.slope * loop
        u_v = self.inverse(promised, p1)
        if self.reference is not None:
            self._drift()
            g = self.learner.gain_error()
            explained = self.inverse(promised + np.where(velocity > 0, g[:, 1], g[:, 0]) * velocity, p1) \
                if g.any() else u_v
            self._learn(np.clip(explained - static, -0.25, 0.25), velocity)
            self._guard(loop + (explained - u_v), self.reference.r_dot)
            self._buffer(u_v, y_measured, u_p, promised, velocity, p1)
        self._applied += self._fade * (1.0 - self._applied)
        u_v = u_v + self._applied * self.shift(velocity)
        self._scale += self._fade * (np.where(self.off, 0.0, 1.0) - self._scale)
        self.feedforward = self._scale * (u_v - u_p)
        return self.feedforward

    def _buffer(self, u_v, y, u_p, promised, velocity, p1) -> None:
        """This tick into the curve's buffers (:class:`compensation.curve_learning.CurveLearner`); with a full buffer,
        the legs that learn (not paused by the guard, not turned off) take its corrections."""
        m, ref = self.model, self.reference
        volume = (np.maximum(ref.r, 0.0) * m.area_bottom + m.pipeline_volume) / (m.bulk_modulus * m.area_bottom)
        measured = None if ref.p1 is None else np.asarray(ref.p1, dtype=float)
        at = p1 if measured is None else measured  # the orifice's pressure now: the measured one where fitted
        held = np.array([np.interp(u_v[i], self._u, self._v[i] - m.velocity[i]) for i in range(self.n_legs)])
        if not self.learner.record(u_v, ref.r, np.asarray(y, dtype=float), u_p, promised, ref.r_dot,
                                   velocity - ref.r_dot, rest_scale(m, promised, at), measured, volume, held):
            return
        if self._teaching is not None:  # a buffer shorter than the delay: the last one's lesson first
            self._take_lesson()
        taken = self.learner.take()
        if self._executor is None:
            lesson: Future = Future()
            lesson.set_result(self.learner.teach(taken))
        else:
            lesson = self._executor.submit(self.learner.teacher.teach, taken)
        self._teaching = (self._tick + max(1, round(self.LEARN_DELAY_S * self.rate_hz)), lesson)

    def _take_lesson(self) -> None:
        """The last buffer's corrections into the learner (waiting for them if still being taught), but for the
        legs the guard pauses or turned off; the curve they give to fade in."""
        lesson, self._teaching = self._teaching[1], None
        before = self.learner.state()
        self.learner.accept(lesson.result())
        for i in np.flatnonzero((self._pause > 0) | self.off):
            self.learner.restore(i, before)
        self._set_curve(self.learner.curve())

    def _set_curve(self, velocity: np.ndarray) -> None:
        """The curve (n_legs, G) [m/s at rest] the inverse moves to: what the buffers taught (strictly increasing
        for the inverse, as the model's), faded in over ``fade_time`` (:meth:`_follow_curve`; the seed fades new
        parameters in, §5.5: a curve changed at once would jump the valve)."""
        self._v_target = velocity + 1e-12 * self._u[None, :]

    def _follow_curve(self) -> None:
        """One tick of the inverse's curve towards what the buffers taught (the fade of ``fade_time``)."""
        if self._v_target is None:
            return
        self._v += self._fade * (self._v_target - self._v)
        if np.max(np.abs(self._v_target - self._v)) < 1e-9:
            self._v, self._v_target = self._v_target, None

    def shift(self, v: np.ndarray) -> np.ndarray:
        """The null shift [V] (n_legs,) the inverse is moved by at the demanded velocity v [m/s] (n_legs,): c within
        the band it is learned in (below :data:`~compensation.curve_learning.BAND_MPS`), and beyond twice that band
        the mean of the c each side held as it last left the band (linearly between; c itself until both sides
        have): a null that drifts moves the whole curve, but what the loop adds near a reversal flips with the
        direction and belongs to the reversal alone. Applied at every speed, that flip (±1.7 mV on the
        independent actuator ``corner``, the tuned file on its calibrated model) moved the valve curve's corner at
        0.9 V by as much at every crossing, and each was felt at the seat (1.39x the ISO 2631-1 threshold where
        the fixed feedforward gave 0.79x; docs/compensation.md)."""
        both = ~np.isnan(self._held).any(axis=1)
        mean = np.where(both, self._held.mean(axis=1), self.null)
        near = np.clip(2.0 - np.abs(v) / BAND_MPS, 0.0, 1.0)
        return mean + near * (self.null - mean)

    def _drift(self) -> None:
        """One sample of the null's learned drift (the class docstring) on the legs that learn: c and the shifts
        each side last held move by ċ dt."""
        live = (self._pause == 0) & ~self.off
        moved = np.where(live, self.drift * self.dt, 0.0)
        self.null = np.clip(self.null + moved, -self.settings.adapt_limit, self.settings.adapt_limit)
        self._held += moved[:, None]

    def _learn(self, error: np.ndarray, v: np.ndarray) -> None:
        """One normalised LMS step of the null shift c towards the loop's volts ``error`` (n_legs,) at velocity v
        [m/s] (n_legs,), and of its drift rate by the step over :data:`DRIFT_RATIO` ``adapt_time``."""
        st = self.settings
        slow = (np.abs(v) >= st.velocity_band) & (np.abs(v) < BAND_MPS)
        legs = np.flatnonzero(slow & (self._pause == 0) & ~self.off)
        step = np.clip(self.dt / st.adapt_time * error[legs], -st.adapt_rate * self.dt, st.adapt_rate * self.dt)
        self.null[legs] = np.clip(self.null[legs] + step, -st.adapt_limit, st.adapt_limit)
        self.drift[legs] = np.clip(self.drift[legs] + step / (self.DRIFT_RATIO * st.adapt_time), -self.DRIFT_LIMIT,
                                   self.DRIFT_LIMIT)
        out = np.flatnonzero(np.abs(v) >= BAND_MPS)
        self._held[out, (v[out] > 0).astype(int)] = self.null[out]

    def _guard(self, loop: np.ndarray, r_dot: np.ndarray) -> None:
        ring = self._ring
        ring[self._k % len(ring)] = np.abs(loop)
        self._k += 1
        sign = np.sign(r_dot)
        turned = (sign != 0) & (self._last_sign != 0) & (sign != self._last_sign)
        self._last_sign = np.where(sign != 0, sign, self._last_sign)
        self._since[turned] = 0
        pending = self._since >= 0
        self._since[pending & ~turned] += 1
        for i in np.flatnonzero(self._since >= len(ring) // 2):
            self._since[i] = -1
            self._judge(i, float(ring[:, i].max()))

    def _judge(self, i: int, footprint: float) -> None:
        """One reversal's footprint [V] on leg i: keep, restore or turn off (the class docstring)."""
        self._pause[i] = max(self._pause[i] - 1, 0)
        self._outside[i] = self._outside[i] + 1 if footprint >= self.turn_off[i] else 0
        if self._outside[i] >= 2:
            self.off[i] = True
        level = self.level[i]
        if np.isnan(level) or footprint <= 2.0 * level:
            self._strikes[i] = 0
            self.good[0][i], self.good[1][i], self.good[2][i] = self.null[i], self.learner.correction[i], self.drift[i]
        else:
            self._strikes[i] += 1
            if self._strikes[i] >= 2:
                self.null[i], self.drift[i] = self.good[0][i], self.good[2][i]
                self._set_curve(self.learner.restore(i, self.good[1]))
                self._strikes[i], self._pause[i] = 0, 4
        self.level[i] = footprint if np.isnan(level) else level + 0.25 * (min(footprint, 2.0 * level) - level)

    def state(self) -> dict[str, np.ndarray]:
        """s, the learned null shift c [V], its learned drift rate ċ [V/s], and the guard (0 compensating, 1
        turned off)."""
        return {"s": self.model.slope.copy(), "null_shift": self.null.copy(), "null_drift": self.drift.copy(),
                "guard": self.off.astype(float)}


def _flat(u: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """The commands [V] of a flow curve's flat part around null (its overlap): those whose speed is within 1e-6
    of the largest; empty for an underlapped valve."""
    return u[np.abs(velocity) <= 1e-6 * np.max(np.abs(velocity))]


def _null(u: np.ndarray, velocity: np.ndarray) -> float:
    """The command [V] at the middle of a non-decreasing flow curve's flat part around null (:func:`_flat`), or
    where it crosses zero where it has none."""
    flat = _flat(u, velocity)
    return float(0.5 * (flat[0] + flat[-1])) if flat.size else float(np.interp(0.0, velocity, u))


def _dead_band(u: np.ndarray, velocity: np.ndarray) -> float:
    """Width [V] of the flow curve's flat part around null (:func:`_flat`); 0 for an underlapped valve."""
    flat = _flat(u, velocity)
    return float(flat[-1] - flat[0]) if flat.size else 0.0


__all__ = ["AdaptiveFeedforward", "FeedforwardCompensator"]
