"""A bounded linear least squares on a triangular system, solved the fast way when the bounds it holds are
nearly known (the reweighted steps of :func:`hexsim.measured.flow_curve._solve` each hold almost the same
bounds as the step before), with scipy's bounded-variable least squares as the fallback."""

from __future__ import annotations

import numpy as np
import scipy.linalg
from scipy.optimize import lsq_linear

#: Exchanges of the bounds held tried before a bounded least squares is solved from scratch (:func:`box_lsq`).
#: Each costs a few milliseconds on a curve's 100-400 unknowns, bvls from scratch 0.7 s: at 8, eleven of a 4-way
#: axis' calibration's reweighted steps fell back to bvls (8 of its 63 s); at 32 none did, the file the same to
#: the digit (examples/four_way_axis.py's logs, 54 s).
PIVOTS = 32


def box_lsq(r: np.ndarray, z: np.ndarray, lo: np.ndarray, hi: np.ndarray,
             held: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """argmin |r x - z| over lo <= x <= hi for a square, nonsingular, upper triangular ``r`` (n, n), and the
    bounds it holds (n,) (-1 at lo, +1 at hi, 0 free, as ``lsq_linear``'s ``active_mask``).

    The problem is strictly convex, so a point that meets its optimality (Karush-Kuhn-Tucker) conditions is its
    one minimum. The unconstrained solution is checked first; then, from the bounds ``held`` (those the
    previous reweighting step held, or the warm start sits on; else those the unconstrained solution crosses),
    up to :data:`PIVOTS` exchanges of the bounds held (a free unknown beyond a bound is held at it, a held one
    whose gradient pulls it inside is freed; block principal pivoting, Portugal, Judice & Vicente 1994), each
    the least squares on the free columns (:func:`held_solution`). Only if none is optimal does
    ``scipy.optimize.lsq_linear``'s bounded-variable least squares (bvls) solve it from scratch (its active-set
    iterations each a least squares on the free columns: about 50 of them on a 376-unknown curve, 0.65 s).
    Same minimum either way, to rounding."""
    x = scipy.linalg.solve_triangular(r, z)
    if np.all((x >= lo) & (x <= hi)):
        return x, np.zeros(len(x), dtype=int)
    tol = 1e-10 * max(float(np.linalg.norm(r.T @ z, np.inf)), 1e-300)
    guess = held if np.any(held) else np.where(x < lo, -1, np.where(x > hi, 1, 0))
    for _ in range(PIVOTS):
        x = held_solution(r, z, lo, hi, guess)
        grad = r.T @ (r @ x - z)  # the cost's gradient: >= 0 where x is held at lo, <= 0 at hi
        free = guess == 0
        below, above = free & (x < lo), free & (x > hi)
        inside = ((guess < 0) & (grad < -tol)) | ((guess > 0) & (grad > tol))
        if not (np.any(below) or np.any(above) or np.any(inside)):
            return x, guess
        guess = np.where(below, -1, np.where(above, 1, np.where(inside, 0, guess)))
    result = lsq_linear(r, z, bounds=(lo, hi), method="bvls")
    return result.x, result.active_mask.astype(int)


def held_solution(r: np.ndarray, z: np.ndarray, lo: np.ndarray, hi: np.ndarray, held: np.ndarray) -> np.ndarray:
    """The minimum of |r x - z| (``r`` upper triangular (n, n)) with the unknowns ``held`` (n,) (-1, +1) at their
    lower or upper bound and the others free: the free columns' QR from r's by deleting the held ones
    (``scipy.linalg.qr_delete``, Givens rotations from the identity), then one triangular solve."""
    x = np.where(held < 0, lo, np.where(held > 0, hi, 0.0))
    fixed = np.flatnonzero(held)
    rhs = z - r[:, fixed] @ x[fixed]
    q, rf = np.eye(len(z)), r.copy()
    blocks = np.split(fixed, np.flatnonzero(np.diff(fixed) > 1) + 1) if len(fixed) else []
    for block in blocks[::-1]:  # from the last: the indices before it hold
        q, rf = scipy.linalg.qr_delete(q, rf, int(block[0]), len(block), which="col", overwrite_qr=True,
                                       check_finite=False)
    k = len(z) - len(fixed)
    x[held == 0] = scipy.linalg.solve_triangular(rf[:k, :k], (q.T @ rhs)[:k])
    return x
