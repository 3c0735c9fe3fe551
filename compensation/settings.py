"""Settings of the compensators and their error, importable without the compensators themselves (the
command line reads the defaults before it loads anything heavy)."""

from __future__ import annotations

import math
from dataclasses import dataclass


class SettingsError(ValueError):
    """A compensator setting out of range (names the setting and the value)."""


@dataclass(frozen=True)
class CompensatorSettings:
    """Settings of the adaptive compensators, defaults from the seed where it gives one (ch. 5, app. C).

    velocity_cutoff_hz: low-pass [Hz] on the differentiated measured position and, for the same phase
        lag, on u_v (seed §4.4: filter before differentiating; the seed gives no value);
    velocity_band: k± [m/s], |ẏ| below which u_v counts as "at zero velocity" (seed §5.3: 1e-3);
    q_threshold: [V] start value of the valve range q before the measured range exceeds it (seed §5.3's
        threshold for b; no value given: 0.5 V, below the ~0.9 V a 0.05 m / 0.5 Hz motion needs, so the
        measured range takes over; a threshold above the range used fixes b too small, the function's zero
        falls short of the range and the iterative table diverges);
    iterative_gain: [V/(m/s)] look-up table update per visit and velocity error (seed §5.3, no value);
    table_size: elements of the look-up table over ±u_v,max (seed §5.3: 1001, element 501 = 0 V);
    buffer_time: [s] time the buffers UV, UC, UY are filled before an update (seed §5.5: 30000 samples
        of the 10 kHz Simulink model = 3 s);
    buffer_filter_tau: [s] time constant of appendix C's discrete low-pass 0.003137 / (1 - 0.9969 z^-1)
        at 10 kHz (-1 / (10^4 ln 0.9969) = 32 ms), re-discretised at the controller rate;
    fade_time: [s] time constant of the low-pass through which new parameters are faded in (seed §5.5:
        "filtered again with a low-pass filter"; no value given);
    direction_rate: [V/s] rate of change of u_v over which the directional compensator blends its two
        curves (tanh scale);
    oracle_u_ref: [V] valve setpoint at which the oracle's linear flow curve meets the true one;
    held_maximum: how the iterative compensators read a off their table, ``"per-side"`` (default) or the
        seed's ``"seed"`` (see :mod:`compensation.iterative`);
    feedforward_pressure: the pressure the model-based feedforward scales its flow curve to,
        ``"measured"`` (the leg's transducer where the controller has one, default; else the reference's)
        or ``"reference"`` (the P1 the reference needs) (see :mod:`compensation.model_based`);
    loop_filter_hz: [Hz] the model-based feedforward's low-pass (2nd-order Butterworth) on the P output
        before it enters the inverse: the position sensor's noise, through K_p and the inverse's high gain
        near zero velocity, is otherwise most of what is left of the bump (see :mod:`compensation.model_based`);
    adapt_time: [s] time constant with which the adaptive feedforward's correction table follows the
        volts the P loop adds; adapt_rate: [V/s] its largest step rate; adapt_limit: [V] its largest
        correction (a drifting null, a changed flow gain; beyond it the model is wrong, not drifting);
    dead_band_margin: [V] how far short of each valve edge the model-based feedforward's inverse stops (its
        curve read as opening this much earlier, :func:`hexsim.plant.hydraulics.as_curve`'s shift): a dead band
        known to within ± this much is never jumped too far, at the price of that much left to the P loop at
        each reversal (0, default: the calibrated edges taken as exact; ``hexsim tune``'s dead-band tolerance).
    """

    velocity_cutoff_hz: float = 20.0
    velocity_band: float = 1e-3
    q_threshold: float = 0.5
    iterative_gain: float = 2.0
    table_size: int = 1001
    buffer_time: float = 3.0
    buffer_filter_tau: float = -1.0 / (1e4 * math.log(0.9969))
    fade_time: float = 1.0
    direction_rate: float = 0.5
    oracle_u_ref: float = 1.0
    held_maximum: str = "per-side"
    feedforward_pressure: str = "measured"
    loop_filter_hz: float = 20.0
    adapt_time: float = 0.3
    adapt_rate: float = 0.5
    adapt_limit: float = 1.0
    dead_band_margin: float = 0.0

    def __post_init__(self) -> None:
        for name in ("velocity_cutoff_hz", "velocity_band", "q_threshold", "iterative_gain", "buffer_time",
                     "buffer_filter_tau", "fade_time", "direction_rate", "oracle_u_ref", "loop_filter_hz", "adapt_time", "adapt_rate",
                     "adapt_limit"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise SettingsError(f"compensator setting {name} must be a finite positive number, got {value!r}")
        if not (isinstance(self.dead_band_margin, (int, float)) and 0.0 <= self.dead_band_margin <= 0.1):
            raise SettingsError("compensator setting dead_band_margin must be between 0 and 0.1 V, got "
                                f"{self.dead_band_margin!r}")
        if self.held_maximum not in ("per-side", "seed"):
            raise SettingsError(f"compensator setting held_maximum must be 'per-side' or 'seed', got {self.held_maximum!r}")
        if self.feedforward_pressure not in ("reference", "measured"):
            raise SettingsError("compensator setting feedforward_pressure must be 'reference' or 'measured', got "
                                f"{self.feedforward_pressure!r}")
        if self.table_size < 3 or self.table_size % 2 == 0:
            raise SettingsError(f"compensator setting table_size must be an odd number >= 3, got {self.table_size}")
