"""What a fit says of one parameter, in one vocabulary for the calibration of a machine's nominal
(:mod:`hexsim.measured.calibration`), the identifier's candidates (:mod:`hexsim.measured.identify`) and the
friction map (:mod:`hexsim.measured.friction_id`): an :class:`Estimate` (value, standard error, status and
why), and one rule for "at a bound" (:func:`at_bound`).

A bound is where the optimizer stopped (``scipy.optimize.least_squares``' trf keeps a parameter strictly
inside and leaves it within a small share of its range of an active bound, its Jacobian column no longer a
free direction): a value there has no standard error of its own and says only that the data asked for more
than the range allows. Whether a value is *plausible* is another question, the identifier's
(:func:`hexsim.measured.candidates.plausibility`: the edge of a plausible range, the value that means no
effect, the log's resolution).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hexsim.errors import InputError

FITTED = "fitted"
AT_A_BOUND = "at a bound"
AT_LIMIT = "at its physical limit"
HELD = "held at its prior"
FROM_LOGS = "from the logs"
UNIDENTIFIABLE = "unidentifiable"
#: The statuses an estimate takes.
STATUSES = (FITTED, AT_A_BOUND, AT_LIMIT, HELD, FROM_LOGS, UNIDENTIFIABLE)

#: A value within this share of its scale (its range, or for a range that is only a physical limit, its
#: typical size) of a bound is at that bound.
AT_BOUND = 1e-3

#: Why a value at a bound of a bracket is no finding.
BOUND_WHY = ("the fit ran into the bound: the data asks for more than the bracket allows, a hint that the model "
             "lacks an effect or the bracket is wrong")


def at_bound(value: float, lower: float, upper: float, scale: float | None = None) -> float | None:
    """The bound (``lower`` or ``upper``) ``value`` lies within :data:`AT_BOUND` x ``scale`` of, or None.
    ``scale``: default the range ``upper - lower``; a fit whose bounds are physical limits with no upper
    bracket (friction's forces are at least 0) passes the parameter's typical size; an unbounded range
    without one: only a value on a bound is at it."""
    tol = AT_BOUND * ((upper - lower) if scale is None else scale)
    if not math.isfinite(tol):
        tol = 0.0
    if value - lower <= tol:
        return lower
    if upper - value <= tol:
        return upper
    return None


@dataclass(frozen=True)
class Estimate:
    """One parameter as a fit leaves it: its ``key`` (a machine-file key, or a candidate's or friction's
    parameter name), ``value`` and ``std_error`` in ``unit`` (the error 0 or NaN where the fit gives none: held,
    at a bound), ``status`` (one of :data:`STATUSES`), ``why`` (for every status but fitted) and the range
    [``lower``, ``upper``] it was fitted in."""

    key: str
    value: float
    std_error: float
    unit: str
    status: str = FITTED
    why: str = ""
    lower: float = -math.inf
    upper: float = math.inf

    @classmethod
    def judged(cls, key: str, value: float, std_error: float, unit: str, lower: float, upper: float, *,
               held: str | None = None, limit: str = "", scale: float | None = None) -> Estimate:
        """The estimate of a parameter fitted in [``lower``, ``upper``]: ``held`` (why) at its prior, at its
        physical ``limit`` (what the lower bound is, e.g. "the tank at atmosphere") when there, at a bound
        (:func:`at_bound`, with ``scale``) or fitted. A parameter's own
        :meth:`~hexsim.measured.parameters.Parameter.estimate` calls this with its declaration."""
        common = {"key": key, "value": float(value), "std_error": float(std_error), "unit": unit,
                  "lower": float(lower), "upper": float(upper)}
        if held:
            return cls(**common, status=HELD, why=held)
        reached = at_bound(value, lower, upper, scale)
        if limit and reached == lower:
            return cls(**common, status=AT_LIMIT, why=limit)
        if reached is not None:
            return cls(**common, status=AT_A_BOUND, why=BOUND_WHY)
        return cls(**common)

    @property
    def identified(self) -> bool:
        """Fitted inside its range with a finite, positive standard error: a value whose uncertainty can be
        propagated (:func:`hexsim.measured.scoring.calibration_uncertainty`)."""
        return self.status == FITTED and math.isfinite(self.std_error) and self.std_error > 0

    def as_row(self) -> dict:
        """The row of a report or a machine file's ``calibration.parameters``: key, unit, value, std_error,
        lower, upper, status and (but for fitted) why."""
        row = {"key": self.key, "unit": self.unit, "value": self.value, "std_error": self.std_error,
               "lower": self.lower, "upper": self.upper, "status": self.status}
        return row | ({"why": self.why} if self.status != FITTED else {})

    @classmethod
    def from_row(cls, row: dict, where: str = "calibration.parameters") -> Estimate:
        """The estimate a row of :meth:`as_row` (a machine file's) holds. Raises InputError naming ``where``
        and the key for a row without key, value or status, or an unknown status."""
        if not isinstance(row, dict) or not {"key", "value", "status"} <= set(row):
            raise InputError(f"{where}: a parameter row needs key, value and status, got {row!r:.120}")
        if row["status"] not in STATUSES:
            raise InputError(f"{where}: {row['key']}: unknown status {row['status']!r} (expected one of "
                             f"{', '.join(STATUSES)})")
        try:
            return cls(str(row["key"]), float(row["value"]), float(row.get("std_error", 0.0)), str(row.get("unit", "")),
                       row["status"], str(row.get("why", "")), float(row.get("lower", -math.inf)),
                       float(row.get("upper", math.inf)))
        except (TypeError, ValueError) as exc:
            raise InputError(f"{where}: {row['key']}: {exc}") from None
