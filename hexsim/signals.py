"""Small signal helpers shared by scenarios, metrics and replays: fundamental fit, zero crossings,
zero-order hold, Savitzky–Golay smoothing and derivatives, continuous linear models run on samples."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal
from scipy.optimize import minimize_scalar
from scipy.signal import savgol_filter


def savgol_length(fs: float, window_s: float) -> int:
    """Samples of a Savitzky–Golay window of ``window_s`` [s] at ``fs`` [Hz]: odd, at least 5."""
    return max(5, int(round(window_s * fs)) | 1)


def savgol(x: np.ndarray, fs: float, window_s: float, deriv: int = 0, axis: int = -1) -> np.ndarray:
    """Cubic Savitzky–Golay smoothing (``deriv`` 0) or derivative of samples ``x`` at ``fs`` [Hz] over
    a window of ``window_s`` [s] (:func:`savgol_length`), along ``axis`` (scipy.signal.savgol_filter)."""
    return savgol_filter(x, savgol_length(fs, window_s), 3, deriv=deriv, delta=1.0 / fs, axis=axis)


def fit_fundamental(t: np.ndarray, x: np.ndarray, frequency: float) -> tuple[float, float, float, np.ndarray]:
    """Least-squares fit x ≈ c0 + c1 sin(wt) + c2 cos(wt), w = 2 pi frequency [Hz].

    t, x: (N,). Returns (offset, amplitude, phase [rad], fit (N,)).
    """
    w = 2 * np.pi * frequency
    basis = np.column_stack([np.ones_like(t), np.sin(w * t), np.cos(w * t)])
    coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
    return float(coef[0]), float(np.hypot(coef[1], coef[2])), float(np.arctan2(coef[2], coef[1])), basis @ coef


def dominant_frequency(t: np.ndarray, x: np.ndarray) -> float:
    """Frequency [Hz] of the largest sinusoid in x(t) (N,): the peak of the Hann-windowed spectrum of the
    uniformly resampled signal, refined by minimising the residual of :func:`fit_fundamental` within
    ±1 bin. Raises ValueError if x does not move."""
    if np.ptp(x) == 0:
        raise ValueError("the signal does not move")
    n = max(256, t.size)
    tu = np.linspace(t[0], t[-1], n)
    xu = np.interp(tu, t, x)
    spectrum = np.abs(np.fft.rfft((xu - xu.mean()) * np.hanning(n)))
    freqs = np.fft.rfftfreq(n, tu[1] - tu[0])
    k = 1 + int(np.argmax(spectrum[1:]))
    df = freqs[1]
    best = minimize_scalar(lambda f: np.sum((xu - fit_fundamental(tu, xu, f)[3]) ** 2),
                           bounds=(max(freqs[k] - df, df / 2), freqs[k] + df), method="bounded",
                           options={"xatol": 1e-6 * freqs[k]})
    return float(best.x)


def zero_crossings(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Times [s] where x (N,) changes sign, linearly interpolated between the nonzero samples around it."""
    nz = np.flatnonzero(x != 0)
    t, x = t[nz], x[nz]
    idx = np.flatnonzero(np.sign(x[:-1]) != np.sign(x[1:]))
    frac = x[idx] / (x[idx] - x[idx + 1])
    return t[idx] + frac * (t[idx + 1] - t[idx])


def zero_order_hold(times: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """values (N, ...) at sample times (N,) [s], each held until the next sample, read at times t (M,):
    (M, ...). Before the first sample the first value."""
    rows = np.clip(np.searchsorted(times, t + 1e-9, side="right") - 1, 0, len(times) - 1)
    return values[rows]


def near_reversals(t: np.ndarray, velocity: np.ndarray, half_width: float = 0.05) -> np.ndarray:
    """(N,) True within ``half_width`` [s] of a velocity reversal."""
    near = np.zeros(len(t), bool)
    for tr in zero_crossings(t, velocity):
        near |= np.abs(t - tr) < half_width
    return near


def polynomial_product(*factors) -> tuple[float, ...]:
    """The product of polynomials (coefficients, highest power first; numpy.polymul), as floats: a
    :class:`LinearModel`'s numerator or denominator from its factors."""
    out = np.array([1.0])
    for f in factors:
        out = np.polymul(out, f)
    return tuple(float(c) for c in out)


@dataclass(frozen=True)
class LinearModel:
    """A continuous linear model ``num(s)/den(s)`` (polynomial coefficients, highest power first) with the
    source of its form and numbers; ``unit`` of its input and output."""

    name: str
    num: tuple[float, ...]
    den: tuple[float, ...]
    unit: str
    source: str

    def response(self, f_hz) -> np.ndarray:
        """Complex frequency response at ``f_hz`` (M,) [Hz] (scipy.signal.freqs)."""
        _, h = signal.freqs(self.num, self.den, worN=2 * np.pi * np.atleast_1d(np.asarray(f_hz, dtype=float)))
        return h

    def sos(self, fs: float) -> np.ndarray:
        """Second-order sections of the model discretised at ``fs`` [Hz] by the bilinear transform."""
        z, p, k = signal.tf2zpk(self.num, self.den)
        zd, pd, kd = signal.bilinear_zpk(z, p, k, fs)
        return signal.zpk2sos(zd, pd, kd)

    def apply(self, x: np.ndarray, fs: float) -> np.ndarray:
        """The model's output to ``x`` (N,) or (N, k) sampled at ``fs`` [Hz] from rest (zero state), along
        axis 0 (scipy.signal.sosfilt)."""
        return signal.sosfilt(self.sos(fs), np.asarray(x, dtype=float), axis=0)
