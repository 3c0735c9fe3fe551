"""Residual analysis of a replay, as in model validation for system identification (Ljung, *System
Identification*, 2nd ed., §16.6): whiteness (Ljung–Box), cross-correlation with the input u_v, the
residual conditioned on the motion state, and its spectrum.

Inputs are (k, n) arrays of k replay windows of n samples; the first ``settle`` samples of every window
are left out (see :mod:`hexsim.measured.identify`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal, stats

MAX_LAG = 20  # lags [samples] of the whiteness and cross-correlation tests
#: Floors of the noise estimates, per channel [SI]: 0.1 µm, 100 Pa, 100 Pa, 1e-3 m/s^2.
NOISE_FLOOR = {"position": 1e-7, "p1": 100.0, "p2": 100.0, "p_s": 100.0, "acceleration": 1e-3}
#: A noisy channel is clipped at an extreme value that repeats exactly in at least this many samples and
#: this share of the log: white noise of the channel's level repeats a value rarely, a sensor or its
#: converter at the end of its range (the real servo cylinder's position transducer at 10 V, 0.1999756 m,
#: in a quarter of a log's samples) gives the same reading for as long as it stays there.
CLIP_MIN_SAMPLES = 20
CLIP_MIN_SHARE = 0.005


def _acf(x: np.ndarray, max_lag: int) -> np.ndarray:
    """Autocorrelation (max_lag + 1,) pooled over windows (k, n), each window demeaned."""
    x = x - x.mean(axis=1, keepdims=True)
    var = float(np.mean(x * x))
    if var <= 0:
        return np.zeros(max_lag + 1)
    return np.array([1.0] + [float(np.mean(x[:, lag:] * x[:, :-lag])) / var for lag in range(1, max_lag + 1)])


def noise_of(x: np.ndarray, channel: str) -> float:
    """Rms of white noise on ``x`` (any shape; differences along axis 1 for 2-D and 3-D arrays, else
    along the only axis): 1.4826 MAD of the second difference / sqrt(6) (white noise of variance s^2
    gives a second difference of variance 6 s^2). Floored at :data:`NOISE_FLOOR`."""
    d2 = np.diff(x, 2, axis=1 if x.ndim > 1 else 0).ravel()
    mad = float(np.median(np.abs(d2 - np.median(d2))))
    return max(1.4826 * mad / math.sqrt(6.0), NOISE_FLOOR[channel])


def clipped(x: np.ndarray, channel: str) -> np.ndarray:
    """(N,) bool: the samples of a logged signal ``x`` (N,) at an end of its sensor's range: its highest or
    lowest value when that value repeats exactly in at least :data:`CLIP_MIN_SAMPLES` samples and
    :data:`CLIP_MIN_SHARE` of the log while the other samples carry noise (above twice the channel's
    :data:`NOISE_FLOOR`, and above twice the reading's quantisation step). A noise-free signal (a simulated
    log) is never called clipped: a piston resting at a stop repeats its position there physically."""
    out = np.zeros(x.shape, dtype=bool)
    if x.size < 3:
        return out
    ends = [v for v in (float(np.max(x)), float(np.min(x)))
            if np.count_nonzero(x == v) >= max(CLIP_MIN_SAMPLES, CLIP_MIN_SHARE * x.size)]
    if not ends:
        return out
    at_end = np.isin(x, ends)
    rest = x[~at_end]
    steps = np.diff(np.unique(rest))
    quantum = float(steps.min()) if steps.size else 0.0
    if rest.size < 3 or noise_of(rest, channel) <= max(2.0 * NOISE_FLOOR[channel], 2.0 * quantum):
        return out
    return at_end


def effective_n(res: np.ndarray) -> float:
    """Independent samples among residuals (k windows, n samples[, s signals]): N / (1 + 2 sum_k rho_k),
    rho pooled over windows (each demeaned) up to the first non-positive lag (Bartlett /
    Bayley–Hammersley); 0 for residuals without variance. A single series is passed as (1, n)."""
    x = res if res.ndim == 3 else res[..., None]
    x = x - x.mean(axis=1, keepdims=True)
    var = float(np.mean(x * x))
    if var <= 0:
        return 0.0
    s = 0.0
    for lag in range(1, x.shape[1] // 2):
        rho = float(np.mean(x[:, lag:] * x[:, :-lag])) / var
        if rho <= 0:
            break
        s += rho
    return x.size / (1.0 + 2.0 * s)


def ljung_box(res: np.ndarray, max_lag: int = MAX_LAG) -> dict[str, float]:
    """Ljung–Box Q = N (N + 2) sum_k rho_k^2 / (N - k) over lags 1…max_lag, N = all samples, with its
    p-value from chi^2(max_lag). White residuals: p > 0.05."""
    n = res.size
    rho = _acf(res, max_lag)[1:]
    lags = np.arange(1, max_lag + 1)
    q = float(n * (n + 2) * np.sum(rho**2 / (n - lags)))
    return {"Q": q, "p_value": float(stats.chi2.sf(q, max_lag)), "lags": max_lag, "rho_1": float(rho[0])}


def cross_correlation(res: np.ndarray, u: np.ndarray, max_lag: int = MAX_LAG) -> dict[str, float]:
    """Largest |correlation| between residual and input over lags -max_lag…max_lag, and the 95 % bound
    1.96 / sqrt(N) for independence."""
    r = res - res.mean(axis=1, keepdims=True)
    v = u - u.mean(axis=1, keepdims=True)
    den = float(np.sqrt(np.mean(r * r) * np.mean(v * v)))
    if den <= 0:
        return {"max_abs": 0.0, "at_lag": 0, "bound_95": 1.96 / np.sqrt(res.size)}
    best, at = 0.0, 0
    for lag in range(-max_lag, max_lag + 1):
        if lag >= 0:
            c = np.mean(r[:, lag:] * v[:, : v.shape[1] - lag])
        else:
            c = np.mean(r[:, :lag] * v[:, -lag:])
        c = float(c) / den
        if abs(c) > abs(best):
            best, at = c, lag
    return {"max_abs": abs(best), "at_lag": at, "bound_95": float(1.96 / np.sqrt(res.size))}


def conditioned(res: np.ndarray, velocity: np.ndarray, u: np.ndarray, position: np.ndarray,
                near_reversal: np.ndarray) -> dict[str, dict[str, float]]:
    """Mean and RMS of the residual in the classes of the motion state: velocity sign, within 50 ms of a
    reversal or not, |u_v| below 0.2 V / 0.2–1 V / above 1 V, position in the lower/middle/upper third
    of the stroke used, and the direction of the change of u_v. All inputs (k, n)."""
    du = np.diff(u, axis=1, prepend=u[:, :1])
    lo, hi = np.quantile(position, [1 / 3, 2 / 3])
    classes = {
        "velocity > 0": velocity > 0, "velocity < 0": velocity < 0,
        "near reversal": near_reversal, "away from reversals": ~near_reversal,
        "|u_v| < 0.2 V": np.abs(u) < 0.2, "0.2 V <= |u_v| < 1 V": (np.abs(u) >= 0.2) & (np.abs(u) < 1.0),
        "|u_v| >= 1 V": np.abs(u) >= 1.0,
        "position lower third": position < lo, "position middle third": (position >= lo) & (position < hi),
        "position upper third": position >= hi,
        "u_v rising": du > 0, "u_v falling": du < 0,
    }
    out = {}
    for name, mask in classes.items():
        if np.any(mask):
            x = res[mask]
            out[name] = {"mean": float(x.mean()), "rms": float(np.sqrt(np.mean(x * x))), "share": float(mask.mean())}
    return out


def spectrum(res: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Welch power spectral density of the residual (frequencies [Hz], PSD), averaged over windows."""
    nper = min(256, res.shape[1])
    f, p = signal.welch(res, fs=fs, nperseg=nper, axis=1)
    return f, p.mean(axis=0)


def analyse(res: dict[str, np.ndarray], u: np.ndarray, velocity: np.ndarray, position: np.ndarray,
            near_reversal: np.ndarray, fs: float) -> dict[str, dict]:
    """All of the above per channel; the spectrum is summarised by its peak frequency above 2 Hz."""
    out = {}
    for ch, r in res.items():
        f, p = spectrum(r, fs)
        band = f > 2.0
        out[ch] = {
            "ljung_box": ljung_box(r),
            "cross_correlation_u_v": cross_correlation(r, u),
            "conditioned": conditioned(r, velocity, u, position, near_reversal),
            "spectrum_peak_hz": float(f[band][np.argmax(p[band])]) if np.any(band) else float("nan"),
        }
    return out
