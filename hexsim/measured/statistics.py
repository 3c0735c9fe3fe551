"""The statistics of a least-squares fit, in one place for every fit hexsim makes: the machine's calibration
(:mod:`hexsim.measured.calibration`), an effect's parameters (:mod:`hexsim.measured.identify`), the friction
map (:mod:`hexsim.measured.friction_id`) and the discovery's sparse terms (:mod:`hexsim.measured.discovery`).

At a least-squares optimum with residuals r (n,) and Jacobian J (n, k) the parameters' covariance is

    C = s² (Jᵀ J)⁻¹,   s² = rᵀr / (N − k),

the linearised (Gauss–Newton) estimate (Seber & Wild, *Nonlinear Regression*, 1989, §2.1; the same as
``scipy.optimize.curve_fit``'s ``pcov`` with ``absolute_sigma=False``). N is the number of *independent*
residuals: a replayed log's residuals are not white, and N is then fewer than n (:func:`effective_n` of
:mod:`hexsim.measured.residuals`, or a share of n). The pseudo-inverse answers a direction the data does not
see (a zero column of J) with a variance of 0; the callers check for that before they trust a standard error.
Only the parameters a fit left inside their bounds enter (``free``): at an active bound a parameter is not
a free variable of the optimum (scipy's trf also zeroes its Jacobian column).

Where the residuals fall into independent groups (``clusters``: a replayed log's windows, each its own replay
from its own measured start), the covariance is the cluster-robust sandwich instead,

    C = G/(G − 1) (n − 1)/(n − k) (Jᵀ J)⁻¹ [Σ_g J_gᵀ r_g r_gᵀ J_g] (Jᵀ J)⁻¹

(Liang & Zeger 1986; Cameron & Miller, *J. Human Resources* 50, 2015, the CR1 form), which holds whatever the
residuals' correlation within a group and their misfit's structure: on the reference plant R1's calibration
its standard errors are 2–7 times the s² (JᵀJ)⁻¹ ones for the flow gains, the tank pressure, the mass and the
Coulomb levels, whose errors against R1's truth were 8–43 of those (1–6 of the robust ones; the retracting
viscous level, whose error hardly widens, stays 14 off).
It needs more groups than parameters (with fewer, s² (JᵀJ)⁻¹).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FitStatistics:
    """Covariance of a least-squares fit's parameters.

    ``s2``: the residual variance per independent residual; ``covariance`` (f, f) of the ``free`` parameters
    (f of them, in their order); ``std_errors`` (k,) of all k, ``fill`` where not free; ``correlation`` (k, k):
    the free block's, the identity elsewhere. Units: those of the parameters the Jacobian is taken in."""

    s2: float
    free: np.ndarray
    covariance: np.ndarray
    std_errors: np.ndarray
    correlation: np.ndarray


def fit_statistics(jac: np.ndarray, fun: np.ndarray, *, free: np.ndarray | None = None,
                   n_independent: float | None = None, n_parameters: int | None = None,
                   fill: float = 0.0, clusters: np.ndarray | None = None) -> FitStatistics:
    """The module's C = s² (Jᵀ J)⁺ for the Jacobian ``jac`` (n, k) and residuals ``fun`` (n,) at the optimum.

    ``free`` (k,) bool: the parameters inside their bounds (default all); ``n_independent``: the independent
    residuals N (default n); ``n_parameters``: the k in N − k (default every column, bound or not);
    N − k is taken as at least 1. ``fill``: the standard error reported for a parameter not free (0, or NaN
    where "none" must not read as "exact"). ``clusters`` (n,): each residual's independent group; with more
    groups than free parameters, C is the module's cluster-robust sandwich (``n_independent`` then unused).
    Raises ValueError if the shapes disagree."""
    jac, fun = np.asarray(jac, dtype=float), np.asarray(fun, dtype=float)
    if jac.ndim != 2 or fun.shape != (jac.shape[0],):
        raise ValueError(f"the Jacobian {jac.shape} and the residuals {fun.shape} do not match")
    if clusters is not None and np.shape(clusters) != fun.shape:
        raise ValueError(f"the clusters {np.shape(clusters)} and the residuals {fun.shape} do not match")
    k = jac.shape[1]
    free = np.ones(k, dtype=bool) if free is None else np.asarray(free, dtype=bool)
    n = len(fun) if n_independent is None else n_independent
    s2 = float(fun @ fun) / max(n - (k if n_parameters is None else n_parameters), 1.0)
    jf = jac[:, free]
    cov = np.linalg.pinv(jf.T @ jf) * s2 if free.any() else np.zeros((0, 0))
    groups, where = np.unique(clusters, return_inverse=True) if clusters is not None else (np.zeros(0), None)
    if free.any() and len(groups) > jf.shape[1]:
        bread = np.linalg.pinv(jf.T @ jf)
        scores = np.zeros((len(groups), jf.shape[1]))
        np.add.at(scores, where, jf * fun[:, None])  # each group's J_g^T r_g
        correction = len(groups) / (len(groups) - 1) * (len(fun) - 1) / max(len(fun) - jf.shape[1], 1)
        cov = correction * bread @ (scores.T @ scores) @ bread
    se_free = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    se = np.full(k, fill)
    se[free] = se_free
    corr = np.eye(k)
    unit = np.where(se_free > 0, se_free, 1.0)
    corr[np.ix_(free, free)] = cov / np.outer(unit, unit)
    return FitStatistics(s2, free, cov, se, corr)
