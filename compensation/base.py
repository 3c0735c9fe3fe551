"""The compensator interface the per-leg controller calls at its sampling rate (seed §5.1, Fig. 5.3)."""

from __future__ import annotations

import abc
from dataclasses import dataclass, field
from typing import NamedTuple

import numba
import numpy as np
from scipy.signal import butter

from compensation.settings import CompensatorSettings, SettingsError


@dataclass
class PlantTruth:
    """What only the oracle may read: the plant's true hydraulic parameters (updated by the simulator as
    the oil warms), each leg's static bottom-chamber pressure P1 [Pa], shape (n_legs,), and the plant's
    static flow curve ``flow_curve(u_v, p1, params)`` -> piston velocity [m/s] (seed eq. 5.1; the
    simulator passes :func:`hexsim.plant.hydraulics.static_velocity`, so this package imports nothing of it)."""

    params: object
    p1_static: np.ndarray = field(default_factory=lambda: np.zeros(0))
    flow_curve: object = None


class Compensator(abc.ABC):
    """Per-leg compensation voltage U_c [V] from the P controller's output u_p [V] and the measured
    position [m]; the controller sends u_v = sat(u_p + U_c, ±u_v,max) to the valve (seed Fig. 5.3).

    Subclasses implement :meth:`update` (and optionally :meth:`state` and :meth:`observe`, which receives
    the reference's derivatives and measured pressure before each update); a user's class is passed to the
    simulator as ``RunConfig(compensator=cls)`` and built as ``cls(n_legs, rate_hz, u_v_max, settings)``. ``n_legs`` legs, called at ``rate_hz`` [Hz] (the motion
    computer's 500 Hz, seed §2.2.4). A compensator never sees the simulator's true velocity: velocity,
    if needed, comes from differentiating the measured position with a filter (seed §4.4, §5.1).
    """

    name = "base"

    def __init__(self, n_legs: int, rate_hz: float, u_v_max: float = 10.0,
                 settings: CompensatorSettings | None = None, plant: PlantTruth | None = None) -> None:
        self.n_legs = int(n_legs)
        self.rate_hz = float(rate_hz)
        self.u_v_max = float(u_v_max)
        self.settings = settings or CompensatorSettings()

    def observe(self, reference) -> None:
        """What the motion computer knows before this sample's :meth:`update`: a
        :class:`compensation.leg_model.Reference` (the piston setpoints and their derivatives, the
        measured pressures where fitted). The seed's compensators do not use it (default: ignored)."""

    @abc.abstractmethod
    def update(self, u_p: np.ndarray, y_measured: np.ndarray) -> np.ndarray:
        """U_c (n_legs,) [V] for this controller sample; u_p and y_measured are (n_legs,)."""

    def state(self) -> dict[str, np.ndarray]:
        """Parameters worth logging (name -> (n_legs,) array); empty if the compensator has none. Units of
        the built-in names in :data:`STATE_UNITS`."""
        return {}


#: Units of the compensators' logged parameters (seed §5.3, :mod:`compensation.functions`): a the
#: largest U_c, b the inverse of the valve range covered, c the shift (b times the null setpoint), s the
#: slope of the desired linear flow curve s u_v; the adaptive feedforward's null shift, its drift rate and its guard.
STATE_UNITS = {"a": "V", "a_neg": "V", "b": "1/V", "c": "-", "s": "m/(s V)", "null_shift": "V", "null_drift": "V/s",
               "guard": "-"}


class NoCompensator(Compensator):
    """U_c = 0: the uncompensated valve, which shows the reversal bump."""

    name = "none"

    def update(self, u_p: np.ndarray, y_measured: np.ndarray) -> np.ndarray:
        return np.zeros(self.n_legs)


class ReplayedCompensation(Compensator):
    """U_c read from a table (n_ticks, n_legs) [V], one row per controller sample: the compensation a
    logged machine applied, fed forward in a closed-loop replay of its log (hexsim.measured.hexapod_replay). It
    sees nothing; past the table's end it holds the last row."""

    name = "replayed"

    def __init__(self, table: np.ndarray, rate_hz: float, u_v_max: float = 10.0) -> None:
        super().__init__(table.shape[1], rate_hz, u_v_max)
        self.table = table
        self._k = 0

    def update(self, u_p: np.ndarray, y_measured: np.ndarray) -> np.ndarray:
        row = self.table[min(self._k, len(self.table) - 1)]
        self._k += 1
        return row.copy()

    def advance(self, ticks: int) -> None:
        """Skip ``ticks`` rows (a compiled runner read them from :attr:`table` itself)."""
        self._k += int(ticks)


class ObserverFilter(NamedTuple):
    """The observer's 2nd-order Butterworth (b0, b1, b2, 1, a1, a2 of ``scipy.signal.butter``) and the
    controller period dt [s]."""

    b0: float
    b1: float
    b2: float
    a1: float
    a2: float
    dt: float


class ObserverState(NamedTuple):
    """What the observer keeps between samples, for n legs: the filter's delay elements z (2, 2, n)
    [delay, signal (u_v, velocity), leg]; the previous measured position y_prev (n,) [m] and whether
    there is one, started (n,) (1.0); running min/max of the filtered u_v u_range (2, n) [V] and of the
    filtered velocity v_range (2, n) [m/s]; the previous filtered u_v u_prev (n,) [V]; the slope s (n,)
    [(m/s)/V]; du_v/dt u_dot (n,) [V/s]."""

    z: np.ndarray
    y_prev: np.ndarray
    started: np.ndarray
    u_range: np.ndarray
    v_range: np.ndarray
    u_prev: np.ndarray
    slope: np.ndarray
    u_dot: np.ndarray

    @classmethod
    def zeros(cls, n_legs: int) -> "ObserverState":
        z = np.zeros
        return cls(z((2, 2, n_legs)), z(n_legs), z(n_legs), z((2, n_legs)), z((2, n_legs)), z(n_legs), z(n_legs),
                   z(n_legs))


@numba.njit(cache=True)
def observer_tick(f, S, u_p, y, u_f, v_f):
    """One sample of :class:`FlowCurveObserver` for every leg, in place: the P output u_p (n,) [V] (the
    valve setpoint before compensation) and measured position y (n,) [m] in, filtered u_p and velocity
    out in u_f, v_f (n,). The filter is the
    transposed direct form II of ``scipy.signal.lfilter`` (out = b0 x + z0; z0 = b1 x - a1 out + z1;
    z1 = b2 x - a2 out); the slope s = (max v - min v) / (max u - min u) once u has moved by 10 mV
    (seed §5.3), else 0."""
    for i in range(u_p.shape[0]):
        if S.started[i] < 0.5:
            S.y_prev[i] = y[i]
            S.started[i] = 1.0
        x0 = u_p[i]
        x1 = (y[i] - S.y_prev[i]) / f.dt
        S.y_prev[i] = y[i]
        o0 = f.b0 * x0 + S.z[0, 0, i]
        o1 = f.b0 * x1 + S.z[0, 1, i]
        S.z[0, 0, i] = f.b1 * x0 - f.a1 * o0 + S.z[1, 0, i]
        S.z[0, 1, i] = f.b1 * x1 - f.a1 * o1 + S.z[1, 1, i]
        S.z[1, 0, i] = f.b2 * x0 - f.a2 * o0
        S.z[1, 1, i] = f.b2 * x1 - f.a2 * o1
        S.u_dot[i] = (o0 - S.u_prev[i]) / f.dt
        S.u_prev[i] = o0
        S.u_range[0, i] = min(S.u_range[0, i], o0)
        S.u_range[1, i] = max(S.u_range[1, i], o0)
        S.v_range[0, i] = min(S.v_range[0, i], o1)
        S.v_range[1, i] = max(S.v_range[1, i], o1)
        du = S.u_range[1, i] - S.u_range[0, i]
        S.slope[i] = (S.v_range[1, i] - S.v_range[0, i]) / max(du, 0.01) if du > 0.01 else 0.0
        u_f[i] = o0
        v_f[i] = o1


@numba.njit(cache=True)
def sos_tick(sos, zi, x, out):
    """One sample of ``scipy.signal.sosfilt``'s cascade of second-order sections for each of n channels, in
    place: ``sos`` (k, 6) (a0 = 1, as ``scipy.signal.butter(..., output="sos")`` gives), the state ``zi``
    (k, 2, n) (``sosfilt``'s ``zi`` along axis 0), the sample ``x`` (n,) in, the filtered sample in ``out``
    (n,). Each section is ``sosfilt``'s transposed direct form II (y = b0 x + z0; z0 = b1 x - a1 y + z1;
    z1 = b2 x - a2 y), in its order of operations: the outputs equal ``sosfilt``'s
    (tests/compensators/test_compensation_functions.py). A controller filters one sample per tick; ``sosfilt`` called per
    sample spends ~80 µs checking its arguments."""
    for i in range(x.shape[0]):
        v = x[i]
        for s in range(sos.shape[0]):
            y = sos[s, 0] * v + zi[s, 0, i]
            zi[s, 0, i] = sos[s, 1] * v - sos[s, 4] * y + zi[s, 1, i]
            zi[s, 1, i] = sos[s, 2] * v - sos[s, 5] * y
            v = y
        out[i] = v


class FlowCurveObserver:
    """The flow curve a motion computer can see: filtered u_v and velocity from the measured position.

    Velocity = backward difference of the measured position, low-passed by a 2nd-order Butterworth at
    ``cutoff_hz`` (``scipy.signal.butter``); u_v passes the same filter so the pair keeps the same phase
    (seed §4.4 filters the valve setpoint "with the same filter to obtain a flow-curve as realistic as
    possible"). The filter runs one sample per controller tick (:func:`observer_tick`, compiled; the
    same recursion as ``scipy.signal.lfilter``, which tests/compensators/test_compensation_functions.py checks).
    Also keeps the seed's online estimate of the desired slope s = (max ẏ - min ẏ) / (max u_v - min u_v)
    (§5.3) in :attr:`slope`. Arrays (n_legs,). Raises SettingsError for a cutoff at or above Nyquist.
    """

    def __init__(self, n_legs: int, rate_hz: float, cutoff_hz: float) -> None:
        if cutoff_hz >= rate_hz / 2:
            raise SettingsError(f"velocity_cutoff_hz {cutoff_hz} must be below the Nyquist rate {rate_hz / 2}")
        self.dt = 1.0 / rate_hz
        self.b, self.a = butter(2, cutoff_hz / (rate_hz / 2))
        self.filter = ObserverFilter(*map(float, self.b), float(self.a[1]), float(self.a[2]), self.dt)
        self.state = ObserverState.zeros(n_legs)

    @property
    def slope(self) -> np.ndarray:
        """s [(m/s)/V] per leg (n_legs,); 0 until u_v has moved by 10 mV."""
        return self.state.slope

    @property
    def u_dot(self) -> np.ndarray:
        """Rate of change of the filtered u_v [V/s] (n_legs,)."""
        return self.state.u_dot

    def update(self, u_p: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(u_f, ydot_f): filtered valve setpoint [V] and filtered velocity [m/s], each (n_legs,)."""
        u_f, v_f = np.empty(len(self.state.slope)), np.empty(len(self.state.slope))
        observer_tick(self.filter, self.state, np.asarray(u_p, dtype=float), np.asarray(y, dtype=float), u_f, v_f)
        return u_f, v_f
