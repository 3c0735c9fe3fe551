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
residuals' correlation within a group and their misfit's structure (on an earlier calibration of the reference plant
R1 its standard errors were 2–7 times the s² (JᵀJ)⁻¹ ones for the flow gains, the tank pressure, the mass and the
Coulomb levels, whose errors against R1's truth were 8–43 of those (1–6 of the robust ones; the retracting viscous
level, whose error hardly widens, stayed 14 off).
It needs more groups than parameters, and more than in name: its meat Σ_g J_gᵀ r_g r_gᵀ J_g has rank at most G − 1,
and where one or two groups carry nearly all of it (a window the model misses by far more than the others) C is near
rank one, with all of its variance along that window's direction and none across the other k − 1 (on R1's
calibration of 2026-11-29: 32 windows, the largest carrying 56–63 % of the meat, 1.9–2.1 effective windows for 14–17
free parameters, the covariance's second eigenvalue under 1 % of its first; its draws then moved the machine along
one direction only, by 15–22 times the s² (JᵀJ)⁻¹ errors). The effective number of groups (:func:`effective_groups`:
Kish's effective sample size, L. Kish, *Survey Sampling*, 1965, of the groups' shares w_g = r_gᵀ J_g (JᵀJ)⁻¹ J_gᵀ
r_g of tr(C JᵀJ), the sandwich in the data's own metric, invariant to how the parameters are scaled; the
heterogeneity of clusters that shrinks their effective number is Carter, Schnepel & Steigerwald, *Rev. Econ. Stat.*
99, 2017) must therefore exceed the free parameters; else C is s² (JᵀJ)⁻¹ and :attr:`FitStatistics.effective_groups`
says why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FitStatistics:
    """Covariance of a least-squares fit's parameters.

    ``s2``: the residual variance per independent residual; ``covariance`` (f, f) of the ``free`` parameters
    (f of them, in their order); ``std_errors`` (k,) of all k, ``fill`` where not free; ``correlation`` (k, k):
    the free block's, the identity elsewhere. Units: those of the parameters the Jacobian is taken in.
    ``effective_groups``: the residual groups' effective number (:func:`effective_groups`; NaN without groups);
    ``clustered``: whether ``covariance`` is the cluster-robust sandwich (more effective groups than free
    parameters) or s² (JᵀJ)⁻¹."""

    s2: float
    free: np.ndarray
    covariance: np.ndarray
    std_errors: np.ndarray
    correlation: np.ndarray
    effective_groups: float = float("nan")
    clustered: bool = False


def effective_groups(scores: np.ndarray, bread: np.ndarray) -> float:
    """Kish's effective number (Σ w_g)² / Σ w_g² of the groups whose scores J_gᵀ r_g are the rows of ``scores``
    (G, f), with w_g = s_gᵀ ``bread`` s_g each group's share of tr(C JᵀJ), the sandwich C in the data's own
    metric (``bread`` (f, f): (JᵀJ)⁻¹; invariant to how the parameters are scaled);
    G when every group carries the same share, 1 when one carries it all, 0 without any."""
    w = np.einsum("gi,ij,gj->g", scores, bread, scores)
    return float(w.sum() ** 2 / (w @ w)) if np.any(w > 0) else 0.0


def fit_statistics(jac: np.ndarray, fun: np.ndarray, *, free: np.ndarray | None = None,
                   n_independent: float | None = None, n_parameters: int | None = None,
                   fill: float = 0.0, clusters: np.ndarray | None = None) -> FitStatistics:
    """The module's C = s² (Jᵀ J)⁺ for the Jacobian ``jac`` (n, k) and residuals ``fun`` (n,) at the optimum.

    ``free`` (k,) bool: the parameters inside their bounds (default all); ``n_independent``: the independent
    residuals N (default n); ``n_parameters``: the k in N − k (default every column, bound or not);
    N − k is taken as at least 1. ``fill``: the standard error reported for a parameter not free (0, or NaN
    where "none" must not read as "exact"). ``clusters`` (n,): each residual's independent group; with more
    effective groups (:func:`effective_groups`) than free parameters, C is the module's cluster-robust sandwich
    (``n_independent`` then unused).
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
    bread = np.linalg.pinv(jf.T @ jf) if free.any() else np.zeros((0, 0))
    cov = bread * s2
    g_eff, clustered = float("nan"), False
    if clusters is not None and free.any():
        groups, where = np.unique(clusters, return_inverse=True)
        scores = np.zeros((len(groups), jf.shape[1]))
        np.add.at(scores, where.ravel(), jf * fun[:, None])  # each group's J_g^T r_g
        g_eff = effective_groups(scores, bread)
        clustered = len(groups) > 1 and g_eff > jf.shape[1]
        if clustered:
            correction = len(groups) / (len(groups) - 1) * (len(fun) - 1) / max(len(fun) - jf.shape[1], 1)
            cov = correction * bread @ (scores.T @ scores) @ bread
    se_free = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    se = np.full(k, fill)
    se[free] = se_free
    corr = np.eye(k)
    unit = np.where(se_free > 0, se_free, 1.0)
    corr[np.ix_(free, free)] = cov / np.outer(unit, unit)
    return FitStatistics(s2, free, cov, se, corr, g_eff, clustered)
