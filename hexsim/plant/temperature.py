"""Oil temperature: how warming the oil changes the hydraulic parameters (seed §5.3, §5.5).

The seed warms the oil by 15 °C in its compensation study (§5.5) and names the effects: density and
viscosity change, and the valve needs "a larger or smaller input voltage ... to reach a specific valve
spool position" (§5.3), i.e. the valve null shifts. The model here, per degree above the reference
temperature T0 = 35 °C (seed app. A):

- density ρ(T) = ρ(T0) / (1 + α (T - T0)), α = 6.5e-4 1/K, the volumetric expansion of mineral oil
  (ISO VG 46 oils: 872 kg/m^3 at 15 °C becomes the seed's 860 kg/m^3 at 35 °C with this α);
- kinematic viscosity ν(T) by the Walther equation (ASTM D341) through ν(40 °C) = 46 mm^2/s and
  ν(100 °C) = 7.9 mm^2/s, typical data of Shell Tellus T 46 (the seed's oil, §2.2.2);
- the viscous friction coefficients σ± of the seal friction (seed eq. 3.9) scale with the *dynamic*
  viscosity, μ(T)/μ(T0) with μ = ρ ν: the seal's viscous term is the shear of a full oil film, Newton's
  F = μ A v / h, with the film thickness h taken as constant (hydrodynamic lubrication; e.g. Müller &
  Nau, *Fluid Sealing Technology*, 1998). Elastohydrodynamic seal theory, in which the film
  thickens with μ v, gives F ∝ √(μ v) instead (about half the change in σ: −26 % instead of −45 % for
  +15 K); the seed identifies σ only at 35 °C (§2.3.3), so the simpler law is kept and named here;
- valve null u_0(T) = u_0(T0) + k_null (T - T0) with k_null = 3 mV/K: 45 mV for the seed's 15 °C, the
  size of the overlap in volts (O_l u_v,max / x_v,max = 45 mV). This is an assumed value of the order of
  the zero-point drift proportional-valve datasheets quote (about 1 % of the rated signal over a few tens
  of kelvin); set ``null_drift`` to study others.

The orifice flow (turbulent, seed eq. 3.4) depends on viscosity only through C_d, which is kept.
The bulk modulus is kept constant (its temperature dependence is a few 0.1 %/K).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hexsim.errors import InputError
from hexsim.plant.params import HydraulicParams

REFERENCE_TEMPERATURE = 35.0  # T0 [°C], seed app. A
EXPANSION = 6.5e-4  # α [1/K], volumetric thermal expansion of mineral oil
NU_40, NU_100 = 46.0, 7.9  # [mm^2/s] Shell Tellus T 46, typical data
NULL_DRIFT = 3e-3  # k_null [V/K], assumed (see module doc)


def _walther_coefficients() -> tuple[float, float]:
    t1, t2 = 313.15, 373.15
    z1, z2 = math.log10(math.log10(NU_40 + 0.7)), math.log10(math.log10(NU_100 + 0.7))
    b = (z1 - z2) / (math.log10(t2) - math.log10(t1))
    return z1 + b * math.log10(t1), b


def viscosity(temperature_c: float) -> float:
    """Kinematic viscosity ν [mm^2/s] of the oil at ``temperature_c`` [°C] (Walther / ASTM D341)."""
    a, b = _walther_coefficients()
    return 10 ** (10 ** (a - b * math.log10(temperature_c + 273.15))) - 0.7


def viscosity_ratio(temperature_c: float) -> float:
    """μ(T)/μ(T0): the dynamic viscosity μ = ρ ν at ``temperature_c`` [°C] relative to T0 = 35 °C, with
    the density's thermal expansion (module doc); the factor on the seal's viscous friction."""
    dt = temperature_c - REFERENCE_TEMPERATURE
    return viscosity(temperature_c) / viscosity(REFERENCE_TEMPERATURE) / (1.0 + EXPANSION * dt)


@dataclass(frozen=True)
class WarmUp:
    """Oil temperature rising linearly by ``delta_c`` [°C] from T0 over ``duration_s`` [s], then constant."""

    delta_c: float = 15.0  # seed §5.5
    duration_s: float = 60.0
    null_drift: float = NULL_DRIFT  # k_null [V/K]

    def __post_init__(self) -> None:
        if not (math.isfinite(self.delta_c) and -30.0 <= self.delta_c <= 60.0):
            raise InputError(f"warm-up must be between -30 and 60 °C, got {self.delta_c}")
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise InputError(f"warm-up duration must be positive, got {self.duration_s}")

    def temperature(self, t) -> np.ndarray:
        """Oil temperature [°C] at times t [s]."""
        return REFERENCE_TEMPERATURE + self.delta_c * np.clip(np.asarray(t, dtype=float) / self.duration_s, 0.0, 1.0)

    def params_at(self, base: HydraulicParams, temperature_c: float) -> HydraulicParams:
        """``base`` (valid at T0) moved to ``temperature_c`` [°C]: density, viscous friction (∝ dynamic
        viscosity, :func:`viscosity_ratio`), valve null."""
        dt = temperature_c - REFERENCE_TEMPERATURE
        ratio = viscosity_ratio(temperature_c)
        return base.replace(
            density=base.density / (1.0 + EXPANSION * dt),
            viscous_pos=base.viscous_pos * ratio,
            viscous_neg=base.viscous_neg * ratio,
            null_offset=base.null_offset + self.null_drift * dt,
        )
