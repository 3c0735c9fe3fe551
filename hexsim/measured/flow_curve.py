"""A valve's flow curves read from its logs' own flows: each edge's opening against command, over every
command the logs reach, corners included.

A closed-loop log of a valve-controlled cylinder measures the flow through the valve at every sample, by
continuity (seed eq. 3.6, 3.7): phi_1 = A1 ydot + V1(y) / E dP1/dt (+ the leakage C_l (P_s - P1) the chamber
receives across the piston), and with a 4-way valve phi_2 = -A2 ydot + V2(y) / E dP2/dt. The valve's side of the
same flow is the orifice equation of each edge (seed eq. 3.4): phi_1 = pi d x_v,max (O_PA(u) q(P_s - P1) -
O_AT(-u) q(P1 - P_t)), O_PA and O_AT the edges' openings (fractions of the full opening) at the command that
opens each, q the flow of a unit opening (:func:`hexsim.plant.hydraulics.edge_flow`). That is *linear* in the
openings, so each edge's curve is a linear least-squares problem whose answer does not depend on where a search
starts, and 1/E and V_pl/E are two more linear unknowns.

**The curves** (:func:`fit_flow_curves`): each edge's opening is piecewise linear on a fine grid of commands
(:func:`edge_grid`: 5 mV near null, 2 % of the command beyond, from 0.5 V below null, where the rounded edges
of an underlapped spool still pass flow, to the largest command the logs reach on that edge), rising from zero
(every answer a valve's).
Whether an edge opens before null at all is the held-out windows' answer too: the curves are fitted shut at and
below null and with the knots below null, and the underlap kept only where it predicts the held-out windows
better by more than one standard error (a straight ramp through null costs the slope-change penalty nothing,
so without the choice a valve whose opening rises as x_v^2 from null, where the flows near null say little,
was read as underlapped: on the reference plant R1, 11-23 % of its 0.1 V opening at -0.1 V, which a
compensator inverting the curve then jumped at every reversal).
What picks the shape out of the noise is a penalty on the *changes of slope*, their sum of absolute values
(l1 trend filtering: Kim, Koh, Boyd & Gorinevsky, SIAM Review 51(2), 2009): a few kinks where the flows ask for
them, a rounded metering edge meeting the full port among them, straight lines elsewhere. Its weight is
chosen by held-out windows (each log cut into :data:`FOLDS` contiguous windows, the curve fitted without one at
a time and judged on it: blocked cross-validation, Bergmeir & Benítez, Information Sciences 191, 2012), so the
number of corners is the data's. The absolute values and a robust loss on the flows (the reversals' dP1/dt is
the noisiest term) are iteratively reweighted least squares (Holland & Welsch 1977), each step a bounded
linear least squares on the normal equations.

**Held to the machine** (``toward_machine``: commissioning, :mod:`hexsim.measured.commissioning`): logs of a
compensated machine jump the command across null at every reversal, so near null their flows say little, and
the penalty alone draws a straight line from null there: on R1, 2.4x its opening at 20 mV, and a compensator
inverting it left reversal peaks 1.6x those of the calibrated curve. The openings at the knots are then held
to the calibrated machine's, each relative to its own size (a Gaussian prior: Tikhonov, or ridge, toward the
machine; a shut edge held no tighter than its opening :data:`FLOOR_V` past where it opens), with the strongest
of :data:`STRENGTHS` whose held-out windows are within one standard error of the best: where the flows tell
(a corner the sine crosses slowly), they win; where they do not, the calibration's shape stays. Two more choices
follow the machine there: edges that open before null on the machine (an underlapped valve) are read so unless
the shut ones predict the held-out windows better (the logs' jumps across null cannot show the underlap, and a
dead band read into the curve is jumped by the compensator at every reversal), and the slope-change penalty is the
smoothest within :data:`WIGGLE_MARGIN` of the best where that is wider than a standard error (a compensator
inverts the curve, and a wiggle is a bump at every crossing).

**Into the machine file** (:meth:`FlowCurves.points`): each edge's fitted curve thinned to at most
:data:`hexsim.plant.params.MAX_CURVE_POINTS` points through which the monotone cubic (PCHIP) of flow area
"curve" follows it (:func:`hexsim.plant.params.thin_curve`); beyond the largest command the logs reach, the calibrated
flow-area form's shape (the prior, scaled to meet the curve there) up to the command range.

Continuity is integrated over short intervals (:func:`hexsim.measured.flow_balance.flow_samples`), so no
measured signal is differentiated and a step's fast pressure jump is as much evidence as a slow motion; 1/E and
V_pl/E are two more linear unknowns (the compressed volume), held weakly at the machine's.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse
from scipy.stats import median_abs_deviation

from hexsim.errors import InputError
from hexsim.measured.box_lsq import box_lsq
from hexsim.measured.flow_balance import FOLDS, FlowSamples, flow_samples
from hexsim.measured.measurement import MeasurementLog
from hexsim.plant import hydraulics
from hexsim.plant.machine import Machine, with_keys
from hexsim.plant.params import thin_curve

#: Weights of the penalty on the curves' slope changes tried, as a share of the flows' robust sum of squares
#: per unit of the penalty (:func:`_solve`).
WEIGHTS = (1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2)
#: The grid of each edge's curve: knots below null where an underlapped edge may open [V], then from null a
#: spacing of the larger of GRID_MIN_V and GRID_REL times the command (a corner is placed to within a knot:
#: 18 mV at 0.9 V). Below null as far as 0.5 V (5 % of a 10 V valve's command): a rounded edge that opens 6 µm
#: before null still passes flow 0.2 V below it, and a curve held shut there from 0.2 V had a corner the valve
#: lacks, its flow gain 15 % off either side of it; a compensator inverting it removed 60 % of the independent
#: underlapped spool's bump, and 85-86 % read from 0.5 V (``examples/proof_on_the_machine.py``).
BELOW_NULL_V = (-0.5, -0.4, -0.3, -0.2, -0.12, -0.07, -0.04, -0.02, -0.01)
GRID_MIN_V, GRID_REL = 0.005, 0.02
#: An edge's curve is read up to this quantile of the commands that open it (a few outlying samples do not
#: stretch it over commands the logs barely visit); at least MIN_REACH_V.
REACH_QUANTILE, MIN_REACH_V = 0.998, 0.1
#: A knot is a corner of a fitted curve where its slope changes by more than this share (:func:`_refined`).
CORNER_SHARE = 0.15
#: Bounds of 1/E [1/Pa]: a bulk modulus within 0.1 … 3 GPa (aerated oil … stiff mineral oil in steel).
BETA_BOUNDS = (1.0 / 3.0e9, 1.0 / 1.0e8)
#: Strengths tried for holding a commissioning's curves to the machine's openings (:func:`_machine_openings`),
#: as a share of the flows' weighted sum of squares per knot: none, then from faint to as much as the flows.
STRENGTHS = (0.0, 1e-4, 1e-3, 1e-2, 1e-1, 1.0)
#: ... and the strength the openings within the commands a calibration measured are held with, where only those are
#: (``hold_within``): a hundred times the flows' weight, so there the calibrated curve stays.
HOLD_WITHIN_STRENGTH = 100.0
#: The openings are held relative to the machine's own, but never to less than its opening this far [V] past
#: where its edge opens.
FLOOR_V = 0.02
#: A commissioning's curve (``toward_machine``) is read with the smoothest penalty weight whose held-out flow error
#: (rms) is within this share of the best, where that is wider than one standard error. Long logs of a compensated
#: machine make the standard error small, and the held-out flows then chose weights that let the curve wiggle by
#: ±0.5-1 % every 20 mV at low speed, a wiggle the flows cannot tell from the best fit and a compensator inverting
#: the curve turns into a bump at every crossing: on the independent port-limited actuator the second commissioning
#: chose 1e-7 (1e-5 within 2.5 %) and its reversals went from 0.037 to 0.128 m/s²; on R1 1e-6 (1e-5 within 3.4 %),
#: 0.029 to 0.037.
WIGGLE_MARGIN = 0.05
#: Iterations of the reweighted least squares (robust loss and l1 penalty).
IRLS_STEPS = 6


def edge_grid(reach: float) -> np.ndarray:
    """The knots [V] of one edge's curve up to the command ``reach`` [V]: :data:`BELOW_NULL_V`, null, then a
    spacing of max(:data:`GRID_MIN_V`, :data:`GRID_REL` u) (the last knot at ``reach``)."""
    knots = [*BELOW_NULL_V, 0.0]
    while knots[-1] < reach:
        knots.append(knots[-1] + max(GRID_MIN_V, GRID_REL * knots[-1]))
    knots[-1] = max(reach, knots[-2] + 0.5 * GRID_MIN_V)
    return np.array(knots)


def edge_opening(machine: Machine, side: int, u: np.ndarray) -> np.ndarray:
    """``machine``'s opening of one edge (``side`` 0: P→A, opened by +u; 1: A→T, opened by -u) at the commands ``u``
    [V] at the spool (u_v - u_0), as a fraction of the full opening pi d x_v,max: its flow-area form or curve
    (:func:`hexsim.plant.hydraulics.flow_areas`) times the edge's gain. Shape of ``u``."""
    hyd, eff = machine.hydraulics, machine.effects
    full = math.pi * hyd.spool_diameter * hyd.x_v_max
    gain = eff.edge_gain_pa if side == 0 else eff.edge_gain_at
    return hydraulics.flow_areas((1.0 if side == 0 else -1.0) * u * hyd.x_v_max / hyd.u_v_max, hyd)[side] * gain / full


def _basis(u: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """(n, k - 1): the opening at ``u`` per unit rise of the curve over each interval (linear between knots,
    closed at and below the first, flat beyond the last): column j is the opening of a curve that rises by 1
    over the interval from knot j to knot j + 1 (a rise lifts every knot after it)."""
    t = np.clip((u[:, None] - knots[None, :-1]) / np.diff(knots)[None, :], 0.0, 1.0)
    return t


def _slope_changes(knots: np.ndarray) -> np.ndarray:
    """(k - 2, k - 1): the changes of slope [1/V] between neighbouring intervals of a curve given by its rises
    (slope of interval j = rise_j / h_j)."""
    h = np.diff(knots)
    d = np.zeros((len(h) - 1, len(h)))
    idx = np.arange(len(h) - 1)
    d[idx, idx] = -1.0 / h[:-1]
    d[idx, idx + 1] = 1.0 / h[1:]
    return d


@dataclass(frozen=True)
class EdgeCurve:
    """One edge's fitted curve: ``knots`` [V] (k,) and ``openings`` [-] (k,) (fractions of pi d x_v,max, the
    first 0), piecewise linear, read up to ``reach`` [V] (the last knot)."""

    knots: np.ndarray
    openings: np.ndarray

    @property
    def reach(self) -> float:
        return float(self.knots[-1])

    def opening(self, u: np.ndarray) -> np.ndarray:
        return np.interp(u, self.knots, self.openings, left=0.0, right=float(self.openings[-1]))


@dataclass(frozen=True)
class FlowCurves:
    """What :func:`fit_flow_curves` read: the P→A and A→T edges' curves (:class:`EdgeCurve`; the rod side's
    P→B and B→T of a 4-way valve follow the A→T and P→A shapes, with their own gains), the oil's
    ``bulk_modulus`` [Pa] and the cap side's dead volume ``pipeline_volume`` [m^3] (from the compressed
    volume, held weakly at the machine's), the ``weight`` the held-out windows chose for the slope-change
    penalty, their flow error at each weight tried (``held_out``: weight -> rms [m^3/s]; ``held_out_se``:
    weight -> the standard error of its square), the rms flow error of the fit (``rms``) against the measured
    flow's (``flow_rms``), the commands the logs reached (``reached``: lowest, highest [V] at the spool), and
    the strength the openings were held to the machine's with (``prior_strength``, one of :data:`STRENGTHS`;
    0 where they were not held)."""

    pa: EdgeCurve
    at: EdgeCurve
    bulk_modulus: float
    pipeline_volume: float
    weight: float
    held_out: dict
    rms: float
    flow_rms: float
    reached: tuple[float, float]
    held_out_se: dict = dataclasses.field(default_factory=dict)
    prior_strength: float = 0.0

    def points(self, prior: Machine) -> tuple[list[list[float]], list[list[float]]]:
        """Each edge's points for the machine file (``valve.flow_curve_PA``, ``valve.flow_curve_AT``): the curve
        within its reach, then ``prior``'s opening of that edge (its flow-area form and edge gain) scaled to meet
        it, up to the command range, thinned (:func:`hexsim.plant.params.thin_curve`)."""
        out = []
        for side, edge in enumerate((self.pa, self.at)):
            dense = np.unique(np.concatenate([edge.knots, np.linspace(edge.knots[0], prior.hydraulics.u_v_max, 2001)]))
            value = edge.opening(dense)
            beyond = dense > edge.reach
            if beyond.any():
                shape = edge_opening(prior, side, dense)
                at_reach = float(np.interp(edge.reach, dense, shape))
                last = float(edge.openings[-1])
                if at_reach > 0.0:
                    value[beyond] = last * shape[beyond] / at_reach
                else:  # the prior is closed there: the curve's last slope
                    slope = (edge.openings[-1] - edge.openings[-2]) / (edge.knots[-1] - edge.knots[-2])
                    value[beyond] = last + slope * (dense[beyond] - edge.reach)
            value = np.minimum(np.maximum.accumulate(np.maximum(value, 0.0)), 2.0)
            out.append(thin_curve(dense, value))
        return out[0], out[1]


#: The prior on 1/E and V_pl/E: held weakly at the machine's, this share of their value a standard deviation.
BETA_PRIOR_SHARE = 0.5


def intervals(s: FlowSamples) -> tuple[np.ndarray, np.ndarray]:
    """(starts (k,), reach (k, 2)) of ``s``'s intervals: where each begins among its samples, and its largest
    command on each edge (P→A at u, A→T at -u) [V]."""
    starts = np.flatnonzero(np.r_[True, np.diff(s.interval) != 0])
    return starts, np.column_stack([np.maximum.reduceat(s.u, starts), np.maximum.reduceat(-s.u, starts)])


def within_reach(most: np.ndarray, reach: list[float]) -> np.ndarray:
    """(k,) bool: the intervals whose largest commands ``most`` (k, 2) are within each edge's ``reach`` [V] (an
    interval beyond an edge's reach is not its curve's to read)."""
    return (most[:, 0] <= reach[0]) & (most[:, 1] <= reach[1])


def robust_scale(b: np.ndarray) -> float:
    """The flows' scale [m^3] the soft-L1 weights are read on: a twentieth of their robust spread (MAD)."""
    return max(0.05 * float(median_abs_deviation(b, scale="normal")), 1e-9)


def soft_l1(e: np.ndarray) -> np.ndarray:
    """The soft-L1 loss's weights of the residuals ``e`` in units of :func:`robust_scale` (reweighted least
    squares)."""
    return 1.0 / np.sqrt(1.0 + e * e)


def fold_mean(errors: list[float]) -> tuple[float, float]:
    """The blocked held-out windows' mean error over the :data:`FOLDS` windows, and its standard error."""
    return float(np.mean(errors)), float(np.std(errors) / math.sqrt(FOLDS))


def edge_rows(samples: list[FlowSamples], pa: np.ndarray, at: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The linear system of the unknowns (the P→A rises, the A→T rises, 1/E, V_pl/E): (A (k, m), b (k,), block
    (k,), reach (k, 2)) over the intervals, with A x = b the flow balance of every interval (:class:`FlowSamples`):
    the supply edge's unit volume times its opening plus the return edge's, summed over the interval's
    samples, less the compressed volume, equals the displaced volume; ``reach`` the largest command of each
    interval on each edge. A cap side's supply edge is P→A at u, its return A→T at -u; a rod side's supply edge P→B follows
    the A→T curve at -u and its return B→T the P→A curve at u."""
    rows, rhs, blocks, reach = [], [], [], []
    for s in samples:
        on_pa, on_at = _basis(s.u, pa), _basis(-s.u, at)
        if s.mirror:  # rod side: P→B (supply) on the A→T curve, B→T (return) on the P→A curve
            per = np.column_stack([on_pa * s.ret[:, None], on_at * s.supply[:, None]])
        else:
            per = np.column_stack([on_pa * s.supply[:, None], on_at * s.ret[:, None]])
        starts, most = intervals(s)
        rows.append(np.column_stack([np.add.reduceat(per, starts, axis=0), -s.swept_dp, -s.dead_dp]))
        rhs.append(s.displaced)
        blocks.append(s.block)
        reach.append(most)
    return np.vstack(rows), np.concatenate(rhs), np.concatenate(blocks), np.vstack(reach)


def _penalty(pa: np.ndarray, at: np.ndarray) -> scipy.sparse.csr_matrix:
    """(p, m), sparse (two entries a row): the slope changes of both edges' curves as rows on the unknowns
    (none on 1/E and V_pl/E)."""
    dp, da = _slope_changes(pa), _slope_changes(at)
    return scipy.sparse.csr_matrix(scipy.sparse.block_diag([dp, da, np.zeros((0, 2))]))


def _solve(gram: np.ndarray, rhs: np.ndarray, D: scipy.sparse.csr_matrix, weight: float, x0: np.ndarray,
           bounds: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """The unknowns inside ``bounds`` minimising x^T gram x - 2 rhs^T x + weight sum |D x|: the absolute values
    reweighted (:data:`IRLS_STEPS` times), each step a bounded linear least squares on the equilibrated normal
    equations (:func:`hexsim.measured.box_lsq.box_lsq`; the bounds ``x0`` or the step before held are its first guess)."""
    lo, hi = bounds
    x = np.clip(x0, lo, hi)
    held = np.where(x <= lo, -1, np.where(x >= hi, 1, 0))
    for _ in range(IRLS_STEPS):
        d = D @ x
        eps = 1e-3 * max(float(np.median(np.abs(d))), 1e-6)
        g = gram + weight * (D.T @ scipy.sparse.diags(1.0 / (np.abs(d) + eps)) @ D).toarray()
        scale = np.sqrt(np.maximum(np.diag(g), 1e-30 * np.max(np.diag(g))))
        gs = g / np.outer(scale, scale)  # equilibrated
        gs[np.diag_indices_from(gs)] += 1e-10
        r = np.linalg.cholesky(gs).T
        z = scipy.linalg.solve_triangular(r, rhs / scale, trans="T")
        xs, held = box_lsq(r, z, lo * scale, hi * scale, held)
        x = xs / scale
    return x


def fit_flow_curves(logs: list[MeasurementLog], machine: Machine, toward_machine: bool = False,
                    hold_within: tuple[float, float] | None = None, like: FlowCurves | None = None) -> FlowCurves:
    """Each edge's curve read from ``logs``' flow balance on ``machine`` (its areas, null offset, spool loop,
    bulk modulus and dead volume; the curves carry the edges' gains: P→A and A→T read with unit gains, a 4-way
    valve's rod side with its gains relative to them), the slope-change penalty's weight chosen by held-out
    windows, then fitted again with knots added either side of each corner the first fit found
    (:func:`_refined`: the knots go where the flows ask for them); with ``toward_machine`` the openings held to
    ``machine``'s as strongly as the held-out windows allow (module doc: "Held to the machine"); with
    ``hold_within`` (lowest, highest command [V] at the spool), only the openings at knots within those commands, at
    :data:`HOLD_WITHIN_STRENGTH`, the rest read from the flows alone (:mod:`hexsim.measured.envelope`: a log beyond
    the commands its machine's calibration measured). ``like``: an earlier reading of the same logs whose penalty
    weight and choice of edges (opening before null or shut) are kept, not chosen again by the held-out windows (a
    reading through effects refitted since: :func:`hexsim.measured.curve_read.curve_read_from_log`; 0.5 s in place of
    4.8 s on R1's 20 s logs).

    Raises InputError (naming the log) for a log without p1_Pa or of a hexapod, or if fewer than 100 intervals
    away from the stops remain."""
    samples, reach, u_all = balance_samples(logs, unit_gains(machine), machine.sensors.sample_skew)
    grids = (edge_grid(reach[0]), edge_grid(reach[1]))
    strength = None if hold_within is None else HOLD_WITHIN_STRENGTH
    if like is not None:
        opens = like.pa.knots[0] < 0.0 or like.at.knots[0] < 0.0
        first = _fit_on(samples, reach, *(grids if opens else (g[g >= 0.0] for g in grids)), machine, like.weight,
                        toward_machine, strength or like.prior_strength or None, hold_within)
        first = dataclasses.replace(first, held_out=like.held_out, held_out_se=like.held_out_se)
    else:
        opened = _fit_on(samples, reach, *grids, machine, None, toward_machine, strength, hold_within)
        shut = _fit_on(samples, reach, *(g[g >= 0.0] for g in grids), machine, None, toward_machine, strength,
                       hold_within)
        # the simpler shut edges unless the underlap predicts the held-out windows better by one standard error; in
        # a commissioning, the machine's own edges (shut or opening before null) unless the other predicts them better
        if toward_machine and _opens_before_null(machine):
            first = opened if held_out_ms(opened)[0] <= sum(held_out_ms(shut)) else shut
        else:
            first = shut if held_out_ms(shut)[0] <= sum(held_out_ms(opened)) else opened
    second = _fit_on(samples, reach, _refined(first.pa), _refined(first.at), machine, first.weight,
                     toward_machine, first.prior_strength, hold_within)
    return dataclasses.replace(second, held_out=first.held_out, held_out_se=first.held_out_se,
                               reached=(float(u_all.min()), float(u_all.max())))


#: Return-line pressures tried, as shares of the bracket, where the flows choose it (:func:`tank_pressure_from_flows`).
TANK_GRID = np.linspace(0.0, 1.0, 5)
#: ... and the share by which the best must lower the flows' rms error below the machine's own pressure's to be
#: taken: where only one edge is open at a time (a valve with a dead band) the return edge's curve absorbs the
#: pressure, and the rms varies by 0.5 % over the bracket (an underlapped spool's both open edges: by 3x).
TANK_MARGIN = 0.05


def tank_pressure_from_flows(logs: list[MeasurementLog], machine: Machine, lower: float, upper: float
                             ) -> tuple[float, dict[float, float]]:
    """The return line's pressure P_t [Pa] within [``lower``, ``upper``] whose flow balance the curves of
    ``logs`` fit best on ``machine`` (:func:`fit_flow_curves`' system). P_t enters the balance only in the
    return edges' q(P1 - P_t) (seed eq. 3.4), and not linearly: the curves are fitted at each of
    :data:`TANK_GRID` across the bracket, with the slope-change penalty the held-out windows chose at the
    machine's own P_t, the edges allowed to open before null; the smallest rms flow error wins, refined by a
    parabola through it and its neighbours, if it is :data:`TANK_MARGIN` below the machine's own P_t's (else
    the flows cannot tell, and the machine's stays). A form's calibration trades P_t against the curve it cannot follow
    (the underlapped independent actuator: 2.7 bar for a true 0, and its A→T curve read under it 17 % wide at
    10 V); the flows alone do not (their rms 6.0e-9 m^3 at 0 bar, 1.5e-8 at 2 bar). Returns (P_t, {P_t tried,
    the machine's among them: rms [m^3]}). Raises InputError as :func:`fit_flow_curves`."""
    unit = unit_gains(machine)

    def read(tank: float, weight: float | None) -> FlowCurves:
        m = with_keys(unit, {"supply.tank_pressure_Pa": tank})
        samples, reach, _ = balance_samples(logs, m, machine.sensors.sample_skew)
        return _fit_on(samples, reach, edge_grid(reach[0]), edge_grid(reach[1]), m, weight)

    own = float(np.clip(machine.hydraulics.tank_pressure, lower, upper))
    first = read(own, None)
    tried = {float(t): read(float(t), first.weight).rms for t in lower + TANK_GRID * (upper - lower)}
    tanks, rms = np.array(list(tried)), np.array(list(tried.values()))
    best = int(np.argmin(rms))
    tried[own] = first.rms
    if rms[best] > (1.0 - TANK_MARGIN) * first.rms:  # the flows cannot tell: the machine's own
        return own, tried
    if 0 < best < len(tanks) - 1:  # the vertex of the parabola through the best and its neighbours
        a, b, _ = np.polyfit(tanks[best - 1:best + 2], rms[best - 1:best + 2], 2)
        if a > 0.0:
            return float(np.clip(-b / (2.0 * a), tanks[best - 1], tanks[best + 1])), tried
    return float(tanks[best]), tried


def unit_gains(machine: Machine) -> Machine:
    """``machine`` with unit P→A and A→T gains (the curves carry them), a 4-way valve's rod-side gains relative (a
    3-way valve has no rod-side edges: its P→B and B→T gains stay as they were)."""
    eff = machine.effects
    rod = (dict(edge_gain_pb=eff.edge_gain_pb / eff.edge_gain_at, edge_gain_bt=eff.edge_gain_bt / eff.edge_gain_pa)
           if machine.hydraulics.four_way else {})
    return dataclasses.replace(machine, effects=eff.replace(edge_gain_pa=1.0, edge_gain_at=1.0, **rod))


def balance_samples(logs: list[MeasurementLog], machine: Machine, skew: float
             ) -> tuple[list[FlowSamples], list[float], np.ndarray]:
    """The logs' flow balance on ``machine`` (:func:`hexsim.measured.flow_balance.flow_samples`), each edge's
    reach [V] (P→A, A→T: :data:`REACH_QUANTILE` of the commands that open it, at least :data:`MIN_REACH_V`) and
    every sample's command. Raises InputError if fewer than 100 intervals away from the stops remain."""
    samples = [s for log in logs for s in flow_samples(log, machine, skew)]
    if sum(len(s.displaced) for s in samples) < 100:
        raise InputError("a flow curve needs at least 100 intervals away from the stroke's ends; the logs have fewer")
    u_all = np.concatenate([s.u for s in samples])
    reach = [max(float(np.quantile(w[w > 0], REACH_QUANTILE)) if np.count_nonzero(w > 0) > 50 else 0.0,
                 MIN_REACH_V) for w in (u_all, -u_all)]
    return samples, reach, u_all


def _opens_before_null(machine: Machine) -> bool:
    """Whether either edge of ``machine``'s valve opens before null: P→A below it or A→T above it, at
    :data:`FLOOR_V` from null (an underlapped valve, which a commissioning must not read shut: the compensator
    would then jump a dead band the valve does not have at every reversal)."""
    hyd = machine.hydraulics
    x = FLOOR_V * hyd.x_v_max / hyd.u_v_max
    return bool(hydraulics.flow_areas(-x, hyd)[0] > 0.0 or hydraulics.flow_areas(x, hyd)[1] > 0.0)


def held_out_ms(curves: FlowCurves) -> tuple[float, float]:
    """The held-out windows' mean square flow error at the weight they chose best, and its standard error."""
    best = min(curves.held_out, key=curves.held_out.get)
    return curves.held_out[best] ** 2, curves.held_out_se[best]


def _fit_on(samples: list[FlowSamples], reach: list[float], pa: np.ndarray, at: np.ndarray, machine: Machine,
            weight: float | None = None, toward_machine: bool = False, strength: float | None = None,
            hold_within: tuple[float, float] | None = None) -> FlowCurves:
    """The curves on the knots ``pa`` and ``at`` (V, each edge's up to its ``reach``): the flows' robust weights
    (soft-L1 as reweighted least squares, three passes), then the penalty's ``weight`` chosen by the blocked
    held-out windows where it is not given (the smoothest within one standard error of the best: Hastie,
    Tibshirani & Friedman, The Elements of Statistical Learning, 2nd ed., §7.10; a compensator inverts this
    curve, and a wiggle the held-out windows cannot tell from the best fit is a bump at every crossing); with
    ``toward_machine``, the openings held to ``machine``'s with the ``strength`` the held-out windows choose
    where it is not given (:func:`_machine_openings`; the strongest within one standard error of the best), only
    those at knots within the commands ``hold_within`` where it is given."""
    A, b, block, most = edge_rows(samples, pa, at)
    keep = within_reach(most, reach)
    A, b, block = A[keep], b[keep], block[keep]
    D = _penalty(pa, at)
    x = _prior_unknowns(machine, pa, at)
    m = len(x)
    bounds = (np.concatenate([np.zeros(m - 2), [BETA_BOUNDS[0], 0.0]]),
              np.concatenate([np.full(m - 2, np.inf), [BETA_BOUNDS[1], np.inf]]))
    # 1/E and V_pl/E held weakly at the machine's (half their value as a standard deviation): where the logs' pressure
    # changes hardly tell the swept from the dead volume, the two do not wander apart
    prior_gram = np.zeros((m, m))
    prior_gram[m - 2:, m - 2:] = np.diag(1.0 / (BETA_PRIOR_SHARE * x[m - 2:] + 1e-30) ** 2)
    prior_rhs = prior_gram @ x
    c = robust_scale(b)
    unit_penalty = float(np.sum(b * b)) / max(float(np.sum(np.abs(D @ x))), 1e-12) / c**2  # weight 1: data ~ penalty
    w = np.ones(len(b))
    for _ in range(3):
        x = _solve((A.T * (w / c**2)) @ A + prior_gram, (A.T * (w / c**2)) @ b + prior_rhs, D,
                   (weight or WEIGHTS[2]) * unit_penalty, x, bounds)
        e = (A @ x - b) / c
        w = soft_l1(e)
    grams = [((A[block == k].T * (w[block == k] / c**2)) @ A[block == k],
              (A[block == k].T * (w[block == k] / c**2)) @ b[block == k]) for k in range(FOLDS)]
    gram, rhs = sum(g for g, _ in grams) + prior_gram, sum(r for _, r in grams) + prior_rhs
    folds = _Folds(A, b, w, block, grams, D, x, bounds)
    scores: dict = {}
    if weight is None:
        scores = {trial: folds.held_out(gram, rhs, trial * unit_penalty) for trial in WEIGHTS}
        weight = _within_one_se(scores, WIGGLE_MARGIN if toward_machine else 0.0)
    if toward_machine:
        P, t = _machine_openings(machine, pa, at)
        if hold_within is not None:  # each edge's knots (past null) within the commands, A→T's at -u
            keep = np.concatenate([pa[1:] <= hold_within[1], at[1:] <= -hold_within[0]])
            P, t = P[keep], t[keep]
        unit_prior = float(np.sum(w * b * b)) / c**2 / max(len(t), 1)  # strength 1: the openings ~ the flows
        held_gram, held_rhs = unit_prior * (P.T @ P), unit_prior * (P.T @ t)
        if strength is None:
            strength = _within_one_se({k: folds.held_out(gram + k * held_gram, rhs + k * held_rhs,
                                                         weight * unit_penalty) for k in STRENGTHS})
        gram, rhs = gram + strength * held_gram, rhs + strength * held_rhs
    x = _solve(gram, rhs, D, weight * unit_penalty, x, bounds)
    k_pa = len(pa) - 1
    curves = (EdgeCurve(pa, np.concatenate([[0.0], np.cumsum(x[:k_pa])])),
              EdgeCurve(at, np.concatenate([[0.0], np.cumsum(x[k_pa:m - 2])])))
    return FlowCurves(*curves, 1.0 / x[-2], x[-1] / x[-2], weight,
                      {k: math.sqrt(ms) for k, (ms, _) in scores.items()},
                      float(np.sqrt(np.mean((A @ x - b) ** 2))), float(np.sqrt(np.mean(b * b))), (0.0, 0.0),
                      {k: se for k, (_, se) in scores.items()}, strength or 0.0)


@dataclass(frozen=True)
class _Folds:
    """The blocked held-out windows of one fit: its rows ``A`` (n, m), flows ``b`` (n,), robust weights ``w``
    (n,) and windows ``block`` (n,), each window's normal equations ``grams`` ((m, m), (m,)), the penalty's
    rows ``D``, the start ``x`` and the ``bounds``."""

    A: np.ndarray
    b: np.ndarray
    w: np.ndarray
    block: np.ndarray
    grams: list
    D: scipy.sparse.csr_matrix
    x: np.ndarray
    bounds: tuple

    def held_out(self, gram: np.ndarray, rhs: np.ndarray, penalty: float) -> tuple[float, float]:
        """The windows' weighted mean square flow error, each predicted by the fit of the normal equations
        ``gram``, ``rhs`` without it (the slope changes weighted ``penalty``), and its standard error."""
        errors = []
        for k, (gk, rk) in enumerate(self.grams):
            xk = _solve(gram - gk, rhs - rk, self.D, penalty, self.x, self.bounds)
            sel = self.block == k
            errors.append(float(np.sum(self.w[sel] * (self.A[sel] @ xk - self.b[sel]) ** 2) / np.sum(self.w[sel])))
        return fold_mean(errors)


def _within_one_se(scores: dict, margin: float = 0.0) -> float:
    """Of the trials ``scores`` (trial -> (held-out mean square, its standard error)), ordered from the least to
    the most smoothing or holding, the last within one standard error of the best (the one-standard-error rule),
    or within ``margin`` of the best's rms where that is wider."""
    best = min(scores, key=lambda k: scores[k][0])
    ms, se = scores[best]
    return max(k for k, (m, _) in scores.items() if m <= ms + max(se, ((1.0 + margin) ** 2 - 1.0) * ms))


def _refined(edge: EdgeCurve) -> np.ndarray:
    """``edge``'s knots with three more in each interval either side of every corner it found: a knot where the
    slope changes by more than :data:`CORNER_SHARE` of the larger slope beside it (a rounded metering edge
    meeting the port halves it there; a smooth curve's change from one knot to the next is a few percent)."""
    k, f = edge.knots, edge.openings
    slope = np.diff(f) / np.diff(k)
    change = np.abs(np.diff(slope)) > CORNER_SHARE * np.maximum(np.abs(slope[:-1]), np.abs(slope[1:]))
    extra = [k[j] + (k[j + 1] - k[j]) * q for i in np.flatnonzero(change) + 1 for j in (i - 1, i)
             for q in (0.25, 0.5, 0.75)]
    return np.unique(np.concatenate([k, extra]))


def _machine_openings(machine: Machine, pa: np.ndarray, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(P (k, m), t (k,)) with |P x - t|^2 the squared departures of the curves' openings at their knots ``pa``
    and ``at`` (past null) from ``machine``'s (its flow-area form and edge gains), each relative to that
    opening, at least its opening :data:`FLOOR_V` past where the edge opens (so an edge the machine holds shut
    is not held shut: a dead band a calibration gave a valve that has none is still read open)."""
    m = len(pa) + len(at)  # the rises of both edges (k_pa - 1 + k_at - 1), 1/E and V_pl/E
    rows, targets, offset = [], [], 0
    for side, knots in enumerate((pa, at)):
        fine = np.linspace(float(knots[0]), float(knots[-1]) + 2.0 * FLOOR_V, 4001)
        opening = np.maximum.accumulate(edge_opening(machine, side, fine))
        opens = float(fine[np.argmax(opening > 0.0)]) if np.any(opening > 0.0) else float(knots[0])
        o = np.interp(knots[1:], fine, opening)
        scale = np.maximum(o, float(np.interp(opens + FLOOR_V, fine, opening)))
        block = np.zeros((len(o), m))
        block[:, offset:offset + len(o)] = np.tril(np.ones((len(o), len(o)))) / scale[:, None]  # rises -> openings
        rows.append(block)
        targets.append(o / scale)
        offset += len(o)
    return np.vstack(rows), np.concatenate(targets)


def _prior_unknowns(machine: Machine, pa: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The unknowns of ``machine``'s own valve (its form's openings with its edge gains at the knots, as rises;
    1/E, V_pl/E): where the reweighted least squares starts."""
    hyd = machine.hydraulics
    rises = [np.maximum(np.diff(np.maximum.accumulate(edge_opening(machine, side, knots))), 0.0)
             for side, knots in enumerate((pa, at))]
    beta = 1.0 / hyd.bulk_modulus
    return np.concatenate([*rises, [beta, hyd.pipeline_volume * beta]])
