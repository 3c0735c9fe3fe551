"""The valve's whole flow curve learned on the machine from what the P loop adds: the seed's buffers and
weighting (§5.5, appendix C) in the model-based frame.

A model-based feedforward (:mod:`compensation.model_based`) commands u = F^-1(w; P1) for the velocity w it wants
(the reference's and the loop's, w = v_d + s LP(u_p)), F the calibrated leg model's static flow curve. Where the
machine's curve is another — a corner where a rounded metering edge meets the port that the calibration
smoothed, a dead band the valve does not have — the piston's velocity is F_true(u) instead, and the P loop
takes up the difference. The loop hides it in its lag (its time constant 1 / (K_p s), 30 ms on the Micro
Motion System, and the loop filter's), so learning from the P output as it comes smears a corner over a few
hundred millivolts of command. The buffers remove the lag: over ``buffer_time`` the compensator keeps what it
commanded and what the loop did, and offline in the buffer (zero phase: the seed's point that the phase does
not matter once the data are buffered) it inverts the loop. With the tracking error e = u_p / K_p (the P
output is K_p times it), ė = ṙ - ẏ, so the piston's velocity is ẏ = ṙ - ė; the flow's velocity adds the oil's
compression, (V / E A1) dP1/dt (from the measured p1 where a transducer is fitted, else the model's), and
against what the model promised at that command, w,

    δ(t) = ṙ - ė + (V / E A1) dP1/dt - w = F_true(u; P1) - F(u; P1)                 (seed eq. 3.7, 5.1)

is the curve's error at the command u(t) itself, no lag left. Scaled back to the rest pressure (the orifice
law of the edge that opens, seed eq. 3.4) and binned by command with the seed's weighting of the buffer's
samples (eq. 5.4: the newest weigh most), it corrects the leg model's curve where the machine went:
F <- F + κ mean_bin(δ). The corrected curve is kept non-decreasing (its inverse unique). A corner the
calibration missed is learned where the motion crosses it; a dead band the valve lacks closes from its edges
inwards as the commands there show the flow the model denied.

What is learned is the curve's *shape*: per side, the share of δ proportional to the model's own curve, δ ≈
g F(u) + b (a flow gain g off, within a valve's tolerance; the offset b, an edge opening early or late, is shape),
is measured by least squares (:meth:`CurveLearner.gain_error`), g F taken out of the evidence before the bins are
fitted and left to the P loop, which takes it up at every speed alike, reversals included. Learned, it could not
be applied where it is not measured: within the reversals' band (:data:`BAND_MPS`) the corrections fall to null's
zero, and the curve's gain stepped by g at the band's edge, 0.1 s either side of every reversal (the null's
learning is told of g too: :class:`compensation.model_based.AdaptiveFeedforward`). On the independent actuators
of ``examples/proof_on_the_machine.py`` (the twenty-fourth stop's tuned files, 60 s sine in their own loops,
second half, seeds 20-22; their calibrated gains some 1 % off) the seat's ISO 2631-1 peak was at those edges.
With the gain learned, then without: ``corner`` 1.05-1.26x the threshold, 0.70-0.75x (its mean reversal peak
0.032-0.033 m/s², 0.031-0.036); ``drift`` 1.32-1.47x, 0.73-0.84x (0.038-0.044, 0.021-0.025); the reference plant
R1 (its corner at 0.89 V, which is kept) 0.92-0.95x, 0.65-0.85x (0.022-0.023, 0.018).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import sparse
from scipy.linalg import solveh_banded
from scipy.signal import savgol_coeffs, savgol_filter

#: Width [V] of the command bins the curve's corrections are kept in: a corner is placed to within it.
BIN_V = 0.02
#: Samples' weight a side of the curve needs in a buffer before it is corrected (at 500 Hz: 20 ms of the motion).
MIN_SAMPLES = 10
#: Weight each earlier buffer keeps in the curve's estimate when a new one arrives: the estimate remembers the
#: last few buffers (1 / (1 - FORGET) of them, 3: some 9 s at the seed's 3 s buffers), so a drifting machine is
#: followed and one buffer's noise is not the curve.
FORGET = 0.67
#: Span [s] of the Savitzky-Golay cubic that differentiates the tracking error and the pressure in a buffer, and
#: smooths the error it gives (the oil spring's ringing, 100 Hz, is no part of the static curve; shorter, the
#: position transducer's noise through the derivative made the learned curve worse on the reference plant R1).
DERIVATIVE_S = 0.021
#: Velocities [m/s] below which a sample teaches nothing: within 0.1 s of a reversal (a 50 mm, 0.5 Hz sine is
#: below 0.05 m/s there) the friction's flip and the oil's compression, not the static curve, make the P loop's
#: work (the seed's velocity band k, §5.3, widened); the null's drift there is the fast null shift's to follow.
BAND_MPS = 0.05
#: Smoothing of the binned corrections across neighbouring bins (a Whittaker smoother, Eilers, Anal. Chem. 75,
#: 2003: the second differences' weight against the bins' sample weights): a bin's noise is no corner.
SMOOTHING = 3.0
#: Shrinkage of the corrections towards none, on the evidence's scale (a ridge): a correction the buffers barely
#: support is not made (on a machine its model describes, the curve's learned noise doubled the bump).
SHRINK = 0.1
#: A second difference of the corrections is a kink the evidence asks for (a rounded metering edge meeting the
#: full port, where the flow gain halves), not noise, where it exceeds this share of the model curve's slope
#: across a bin (the flow gain changing by 1 % within a bin) and :data:`KINK_MEDIAN` times the side's median:
#: its smoothing weight then falls as 1 / |difference| (a Huber penalty; :func:`_smoothed`). Measured on the
#: reference plant R1 (its corner at 0.89 V; the tuned adaptive file in its own loop, 60 s sine, second half):
#: the squared penalty alone rounded the corner's correction 1.3 mm/s short of its tip, and the seat's peak at
#: the corner crossings was 3.95x the perception threshold; with kinks kept 2.91x (3.10x at a knee of 2 %,
#: 3.34x at 5 %). Without the knee (the median alone) 2.87x on R1, but the learned noise then raised the
#: built-in heave's seat peak from 0.45x to 0.79x; with it, unchanged (``hexsim compare heave --duration 60``).
KINK = 0.01
#: See :data:`KINK`: a kink stands out of the side's second differences by at least this factor.
KINK_MEDIAN = 3.0
#: Largest flow-gain error [share of the model's flow] :func:`gain_error` reports: twice a proportional valve's
#: usual ±10 % flow tolerance; beyond it the calibration, not the loop, is what needs mending (a buffer's first
#: few samples on a side cannot move the null's learning by more).
GAIN_LIMIT = 0.2
#: Reweighted solves of the Huber penalty (:func:`_smoothed`; from the squared penalty's solution).
KINK_ITERATIONS = 6


def seed_weights(n: int) -> np.ndarray:
    """The seed's weighting of a buffer's n samples (eq. 5.4, appendix C): 1 / (1 + exp(-10 i / (2 n))), i = 1…n,
    from 0.5 for the oldest to 0.99 for the newest."""
    i = np.arange(1, n + 1)
    return 1.0 / (1.0 + np.exp(-10.0 * i / (2.0 * n)))


class Taken(NamedTuple):
    """A full buffer and the evidence before it (:meth:`CurveLearner.take`): the buffer's arrays (size, n) by
    name, the per-leg normal equations (bins, bins) and their right-hand sides (n, bins), and the flow gain's
    evidence (n, 2, 5) (per leg and side, retracting then extending: :func:`gain_error`)."""

    buffer: dict[str, np.ndarray]
    gram: list
    rhs: np.ndarray
    gain_evidence: np.ndarray


class Taught(NamedTuple):
    """What a buffer taught (:meth:`CurveLearner.teach`): the evidence with it (as :class:`Taken`'s) and the
    corrections (n, bins) [m/s at rest]."""

    gram: list
    rhs: np.ndarray
    correction: np.ndarray
    gain_evidence: np.ndarray


class CurveTeacher:
    """What turns a full buffer into corrections (:meth:`teach`), apart from the learner that records it: its
    command bins ``centres`` (bins,) [V], the kinks' threshold ``knee`` (n, bins) [m/s] (:data:`KINK`), the
    controller period ``dt`` [s], the buffer's ``size`` [samples], the P gain ``kp`` [V/m] (0: fitted) and the leg
    model's curve, its commands ``u`` (G,) [V] and velocities at rest ``base`` (n, G) [m/s] (the flow gain's
    share of the error is measured against it, module doc). Small to pickle (the time filter's matrix is rebuilt
    where it is used), so a buffer can be taught in another process while the controller ticks on
    (:meth:`compensation.model_based.AdaptiveFeedforward.learn_in`)."""

    def __init__(self, centres: np.ndarray, knee: np.ndarray, dt: float, size: int, kp: float, u: np.ndarray,
                 base: np.ndarray) -> None:
        self.centres, self.knee, self.dt, self.size, self.kp = centres, knee, dt, size, kp
        self.u, self.base = u, base
        self.n_legs = knee.shape[0]
        self.window = max(5, int(round(DERIVATIVE_S / dt)) | 1)  # the Savitzky-Golay span [samples], odd
        self._filter: sparse.csr_array | None = None

    @property
    def filter(self) -> sparse.csr_array:
        """The time filter δ is measured with as a (size, size) matrix (:func:`_savgol_matrix`)."""
        if self._filter is None:
            self._filter = _savgol_matrix(self.size, self.window)
        return self._filter

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_filter": None}

    def gain(self, buffer: dict[str, np.ndarray]) -> np.ndarray:
        """K_p [V/m] per leg: the given one, else the least-squares ratio of the ``buffer``'s P output to its
        tracking error (they are K_p apart, the sensor's noise in both)."""
        if self.kp > 0:
            return np.full(self.n_legs, self.kp)
        e, up = buffer["tracking"], buffer["u_p"]
        den = np.sum(e * e, axis=0)
        return np.where(den > 0, np.sum(e * up, axis=0) / np.maximum(den, 1e-30), np.inf)

    def errors(self, buffer: dict[str, np.ndarray]) -> np.ndarray:
        """(size, n) [m/s]: δ at each tick of ``buffer`` (a buffer's arrays (size, n) by name, as
        :class:`CurveLearner` records them) scaled to the rest pressure (module doc)."""
        b, n = buffer, self.window
        e = b["u_p"] / self.gain(b)[None, :]  # the tracking error the controller saw [m]
        e_dot = savgol_filter(e, n, 3, deriv=1, delta=self.dt, axis=0, mode="interp")
        flow = b["ref_rate"] - e_dot
        if not np.isnan(b["p1"]).any():
            p1_dot = savgol_filter(b["p1"], n, 3, deriv=1, delta=self.dt, axis=0, mode="interp")
            flow = flow + b["volume"] * p1_dot
        else:
            flow = flow + b["compression"]
        # the command of tick k acts from tick k to k + 1: its flow is the one measured half way, the mean of the
        # two ticks' (flow at tick k against the command of tick k put the curve's error a tick late: on the
        # Micro Motion System's heave the learned curve then made the bump 6x the model's own)
        flow = 0.5 * (flow + np.concatenate([flow[1:], flow[-1:]]))
        delta = (flow - b["promised"]) / np.maximum(b["scale"], 1e-3)
        return savgol_filter(delta, n, 3, axis=0, mode="interp")

    def teach(self, taken: Taken) -> Taught:
        """The evidence and corrections (n, bins) [m/s] of a :meth:`CurveLearner.take`'s buffer and, fading by
        :data:`FORGET` each, the earlier ones (:meth:`CurveLearner.accept` makes them the learner's). Each sample's
        measured correction (δ plus what the inverse's curve held there) is the correction at its command, seen
        through the time filter δ was measured with: so the bins' corrections are fitted to it as a least-squares
        regression on the same filter's response to each bin (a hat in the command, in time as the command moved;
        the filter's blur along the command, 50 mV at a port's corner, is taken out rather than learned), with the
        seed's weights, from null outwards on each side with the second differences' penalty
        (:func:`_smoothed`), null itself uncorrected; beyond the commands the motion reached, the last bin's
        correction held."""
        b, n_sg = taken.buffer, self.window
        target = self.errors(b) + savgol_filter(b["held"], n_sg, 3, axis=0, mode="interp")
        w = seed_weights(self.size)[:, None] * (np.abs(b["promised"]) >= BAND_MPS)
        evidence, target = self._without_gain(b["u"], w, target, FORGET * taken.gain_evidence)
        bins = len(self.centres)
        grams, rhs, correction = list(taken.gram), FORGET * taken.rhs, np.zeros((self.n_legs, bins))
        ticks = np.arange(self.size)
        for leg in range(self.n_legs):
            # each sample's hat in the command (its two bins' linear interpolation weights), seen through the
            # time filter: the filter matrix times the (size, bins) hats
            pos = np.clip((b["u"][:, leg] - self.centres[0]) / BIN_V, 0.0, bins - 1.0)
            left = np.minimum(np.floor(pos).astype(int), bins - 2)
            frac = pos - left
            hats = sparse.csr_array((np.concatenate([1.0 - frac, frac]),
                                     (np.concatenate([ticks, ticks]), np.concatenate([left, left + 1]))),
                                    shape=(self.size, bins))
            seen = self.filter @ hats
            weighted = seen.multiply(w[:, leg, None]).tocsr()
            grams[leg] = (FORGET * grams[leg] + weighted.T @ seen).tocsr()
            rhs[leg] += weighted.T @ target[:, leg]
        null = int(np.argmin(np.abs(self.centres)))
        for leg in range(self.n_legs):
            gram = grams[leg].tocsc()
            weight, row = gram.diagonal(), np.zeros(bins)
            for side in (np.arange(null, bins), np.arange(null, -1, -1)):  # from null outwards
                seen = np.flatnonzero(weight[side] > 1e-6 * max(float(weight.max()), 1e-30))
                if not seen.size or weight[side].sum() < MIN_SAMPLES:
                    continue
                span = side[:seen[-1] + 1]
                row[span] = _smoothed(gram[span][:, span], rhs[leg, span], self.knee[leg, span[1:-1]])
                row[side[seen[-1] + 1:]] = row[span[-1]]  # beyond the commands the motion reached: held
            correction[leg] = row
        return Taught(grams, rhs, correction, evidence)

    def _without_gain(self, u: np.ndarray, w: np.ndarray, target: np.ndarray,
                      evidence: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The flow gain's evidence (n, 2, 5) with this buffer's (``evidence``: the earlier buffers', faded) and
        the ``target`` (size, n) [m/s] less the gain's share (module doc): per side of the curve the least-squares
        fit δ ≈ g F(u) + b of the model's velocity F(u) at each command ``u`` (size, n) [V] (seen through the time
        filter, as δ is) and an offset b, with the seed's weights ``w`` (size, n); g F is taken out. (The offset
        is a valve edge opening early or late, F(u + Δ) - F(u) ≈ F' Δ: shape, not gain; fitted by g alone, it
        passed for one.)"""
        evidence = evidence.copy()
        flow = np.stack([np.interp(u[:, leg], self.u, self.base[leg]) for leg in range(self.n_legs)], axis=1)
        seen = self.filter @ flow
        extending = flow > 0
        for side, mask in enumerate((~extending, extending)):
            wm = w * mask
            evidence[:, side] += np.stack([np.sum(wm * seen * seen, axis=0), np.sum(wm * seen, axis=0),
                                           np.sum(wm, axis=0), np.sum(wm * seen * target, axis=0),
                                           np.sum(wm * target, axis=0)], axis=1)
        g = gain_error(evidence)
        return evidence, target - seen * np.where(extending, g[None, :, 1], g[None, :, 0])


class CurveLearner:
    """Buffers of one compensator's legs and the corrections they teach (module doc).

    Built with the commands of the leg model's curve ``u`` (G,) [V], its velocities at rest ``velocity`` (n, G)
    [m/s], the controller rate [Hz], the buffer's length ``buffer_time`` [s] and the P gain ``kp`` [V/m] (0: the
    ratio of the P output to the tracking error, fitted in each buffer). :meth:`record` takes a sample per
    controller tick; when the buffer is full, :meth:`learn` returns the corrected curve (n, G)."""

    def __init__(self, u: np.ndarray, velocity: np.ndarray, rate_hz: float, buffer_time: float, kp: float = 0.0):
        self.u = np.asarray(u, dtype=float)
        self.base = np.atleast_2d(np.asarray(velocity, dtype=float))
        self.n_legs = self.base.shape[0]
        self.size = max(int(round(buffer_time * rate_hz)), 4 * int(round(DERIVATIVE_S * rate_hz)))
        self.centres = np.arange(self.u[0], self.u[-1] + BIN_V, BIN_V)
        self.correction = np.zeros((self.n_legs, len(self.centres)))  # [m/s] at the rest pressure
        # a kink (:data:`KINK`): the flow gain changing by KINK of the model curve's own within a bin [m/s]
        self.knee = KINK * BIN_V * np.abs(np.gradient(
            np.stack([np.interp(self.centres, self.u, row) for row in self.base]), BIN_V, axis=1))
        bins = len(self.centres)
        # the evidence, the regression's normal equations per leg: sparse, banded (a sample touches the bins its
        # command passed within the time filter's span), so a sweep across the whole curve costs what a small one
        # does (dense, the 1001 bins of a ±10 V valve took half a second per buffer: 250 ticks at 500 Hz)
        self.gram = [sparse.csr_array((bins, bins)) for _ in range(self.n_legs)]
        self.rhs = np.zeros((self.n_legs, bins))
        self.teacher = CurveTeacher(self.centres, self.knee, 1.0 / rate_hz, self.size, kp, self.u, self.base)
        self.gain_evidence = np.zeros((self.n_legs, 2, 5))  # the flow gain's evidence (:class:`Taken`)
        self._gain = np.zeros((self.n_legs, 2))  # gain_error(gain_evidence), kept as the evidence changes
        names = ("u", "tracking", "u_p", "promised", "ref_rate", "compression", "scale", "p1", "volume", "held")
        self.buffer = {k: np.zeros((self.size, self.n_legs)) for k in names}
        self.filled = 0
        self._restored: set[int] = set()  # legs restored since the last take (accept leaves them)

    def record(self, u: np.ndarray, r: np.ndarray, y: np.ndarray, u_p: np.ndarray, promised: np.ndarray,
               r_dot: np.ndarray, compression: np.ndarray, scale: np.ndarray, p1: np.ndarray | None,
               volume: np.ndarray, held: np.ndarray) -> bool:
        """One tick, each (n,): the command u [V] the model's inverse gave (before the compensator's own
        corrections), the setpoint r and measured position y [m], the P output u_p [V], the velocity the model
        promised at u, w [m/s] at the leg's pressure, ṙ [m/s], the compression's share of w [m/s] (V / E A1
        dP1_ref/dt), the pressure scaling of the curve there ``scale`` (the orifice law's sqrt(Δp / Δp_rest), 1
        without it), the measured p1 [Pa] (None: no transducer), the chamber's V / (E A1) ``volume`` [m/Pa]
        (times dP1/dt, the compression's share of the flow as a velocity) and the correction ``held`` [m/s at
        rest] the inverse's curve had at u (what the compensator had learned and faded in by then). Returns True
        when the buffer is full."""
        k = self.filled
        b = self.buffer
        b["u"][k], b["tracking"][k], b["u_p"][k], b["promised"][k] = u, r - y, u_p, promised
        b["ref_rate"][k], b["compression"][k], b["scale"][k], b["volume"][k] = r_dot, compression, scale, volume
        b["p1"][k] = np.nan if p1 is None else p1
        b["held"][k] = held
        self.filled += 1
        return self.filled >= self.size

    def learn(self) -> np.ndarray:
        """The curve (n, G) [m/s] at rest, non-decreasing, from the evidence of this buffer and, fading by
        :data:`FORGET` each, the earlier ones (:meth:`teach`, at once). The buffer is emptied."""
        return self.accept(self.teach(self.take()))

    def take(self) -> Taken:
        """The full buffer and the evidence so far, copied, for :meth:`teach` (which may then run in another
        process while the next buffer fills); the buffer is emptied."""
        self.filled = 0
        self._restored = set()
        return Taken({k: v.copy() for k, v in self.buffer.items()}, list(self.gram), self.rhs.copy(),
                     self.gain_evidence.copy())

    def accept(self, taught: Taught) -> np.ndarray:
        """A :meth:`teach`'s evidence and corrections made the learner's, except on the legs put back by
        :meth:`restore` since its :meth:`take` (their evidence forgotten, their corrections restored, as the guard
        asked); the curve they give (n, G) [m/s]."""
        for leg in range(self.n_legs):
            if leg not in self._restored:
                self.gain_evidence[leg] = taught.gain_evidence[leg]
                self.gram[leg], self.rhs[leg], self.correction[leg] = taught.gram[leg], taught.rhs[leg], \
                    taught.correction[leg]
        self._gain = gain_error(self.gain_evidence)
        return self.curve()

    def teach(self, taken: Taken) -> Taught:
        """What a :meth:`take`'s buffer teaches (:meth:`CurveTeacher.teach`); the learner is not changed."""
        return self.teacher.teach(taken)

    def gain(self) -> np.ndarray:
        """K_p [V/m] per leg from the buffer filling (:meth:`CurveTeacher.gain`)."""
        return self.teacher.gain(self.buffer)

    def gain_error(self) -> np.ndarray:
        """The flow gain's relative error (n, 2) (retracting, extending) measured so far (:func:`gain_error`):
        left to the P loop, not in :meth:`curve` (module doc). Kept as the evidence changes (:meth:`accept`,
        :meth:`restore`), not solved at each call: the compensator reads it every tick."""
        return self._gain.copy()

    def errors(self) -> np.ndarray:
        """(size, n) [m/s]: δ at each tick of the buffer filling (:meth:`CurveTeacher.errors`)."""
        return self.teacher.errors(self.buffer)

    def curve(self) -> np.ndarray:
        """The leg model's curve with the corrections learned so far (n, G) [m/s], non-decreasing."""
        out = self.base + np.stack([np.interp(self.u, self.centres, c) for c in self.correction])
        return np.maximum.accumulate(out, axis=1)

    def state(self) -> np.ndarray:
        """The corrections learned so far (n, bins) [m/s], a copy."""
        return self.correction.copy()

    def restore(self, leg: int, state: np.ndarray) -> np.ndarray:
        """Leg ``leg``'s corrections back to its row of ``state`` (a :meth:`state`), its evidence forgotten (the
        next buffers measure the correction afresh from there); the curve they give."""
        self.correction[leg] = state[leg]
        self.gram[leg] = sparse.csr_array(self.gram[leg].shape)
        self.rhs[leg] = 0.0
        self.gain_evidence[leg] = 0.0
        self._gain[leg] = 0.0
        self._restored.add(leg)
        return self.curve()

    def held(self, u: np.ndarray) -> np.ndarray:
        """The correction [m/s at rest] each leg's curve holds at its command u (n,) [V]."""
        return np.array([np.interp(u[i], self.centres, self.correction[i]) for i in range(self.n_legs)])


def gain_error(evidence: np.ndarray) -> np.ndarray:
    """The flow gain's relative error g (n, 2) from its evidence (n, 2, 5) (:class:`Taken`: per leg and side the
    weighted sums Σ F², Σ F, Σ 1, Σ F δ, Σ δ of the fit δ ≈ g F + b, :meth:`CurveTeacher._without_gain`): the
    least-squares g, 0 where a side's evidence cannot tell it from the offset b, within ±:data:`GAIN_LIMIT`."""
    ff, f1, n1, fy, y1 = np.moveaxis(evidence, -1, 0)
    det = ff * n1 - f1 * f1
    ok = det > 1e-9 * np.maximum(ff * n1, 1e-300)
    return np.clip(np.where(ok, (n1 * fy - f1 * y1) / np.where(ok, det, 1.0), 0.0), -GAIN_LIMIT, GAIN_LIMIT)


def _smoothed(gram: np.ndarray, rhs: np.ndarray, knee: np.ndarray | float = 0.0,
              iterations: int = KINK_ITERATIONS) -> np.ndarray:
    """The corrections (k,) of a side's bins from null outwards from the regression's normal equations ``gram``
    (k, k) and ``rhs`` (k,), with :data:`SMOOTHING` times the second differences' squares (a Whittaker smoother,
    Eilers, Anal. Chem. 75, 2003, on the evidence's scale) and the first bin (null) held at zero: a bin the
    motion passed too fast to weigh, and the reversals' band that teaches nothing, are filled by their
    neighbours, and the correction leaves null as smoothly as it can (a kink there would be a bump at every
    reversal).

    A kink the evidence asks for is kept: a second difference larger than ``knee`` [m/s] ((k - 2,) or a scalar:
    :data:`KINK` of the model curve's slope across a bin) and :data:`KINK_MEDIAN` times their median is
    penalised in proportion to its size rather than its square (a Huber penalty, solved by iteratively
    reweighted least squares, ``iterations`` solves, 1: the squared penalty alone; in the line of l1 trend
    filtering, Kim, Koh, Boyd & Gorinevsky, SIAM Review 51(2), 2009, which keeps a piecewise-linear signal's
    kinks). The squared penalty
    alone rounds a corner of the valve's curve (where a rounded metering edge meets the full port) into a
    hump some 80 mV wide, short of its tip, and every crossing of the corner is then a bump."""
    k = len(rhs)
    g = sparse.csc_array(gram, dtype=float)
    diag = g.diagonal()
    scale = float(np.mean(diag[diag > 0]))
    r = rhs / scale
    c = np.zeros(k)  # c[0], null's, held at zero: the bins beyond it solved for
    if k < 3:
        if k > 1:
            c[1:] = np.linalg.lstsq(g[1:, 1:].toarray() / scale + 1e-9 * np.eye(k - 1), r[1:], rcond=None)[0]
        return c
    # the free bins' normal equations, symmetric positive definite and banded (a sample couples the bins its
    # command passed within the time filter's span), in the upper form of the banded Cholesky factorisation
    upper = sparse.triu(g[1:, 1:], format="coo")
    upper.sum_duplicates()
    width = max(2, int(np.max(upper.col - upper.row, initial=0)))
    band = np.zeros((width + 1, k - 1))
    band[width + upper.row - upper.col, upper.col] = upper.data / scale
    band[width] += SHRINK
    c[1:] = solveh_banded(band + _penalty_band(np.full(k - 2, SMOOTHING), width), r[1:])
    for _ in range(iterations - 1):
        curvature = np.abs(np.diff(c, 2))
        bend = np.maximum(knee, KINK_MEDIAN * float(np.median(curvature)))
        weight = SMOOTHING * np.minimum(1.0, bend / np.maximum(curvature, 1e-15))
        c[1:] = solveh_banded(band + _penalty_band(weight, width), r[1:])
    return c


def _penalty_band(weight: np.ndarray, width: int) -> np.ndarray:
    """D' diag(weight) D, D the (k - 2, k) second differences and ``weight`` (k - 2,), on bins 1…k-1 (null's
    dropped, :func:`_smoothed`), in the upper banded form of :func:`scipy.linalg.solveh_banded` with ``width``
    (at least 2) superdiagonals: (width + 1, k - 1)."""
    k = len(weight) + 2
    main, first, second = np.zeros(k), np.zeros(k), np.zeros(k)  # the diagonal and the two above it, by row
    main[:-2] += weight
    main[1:-1] += 4.0 * weight
    main[2:] += weight
    first[:-2] -= 2.0 * weight
    first[1:-1] -= 2.0 * weight
    second[:-2] += weight
    band = np.zeros((width + 1, k - 1))
    band[width] = main[1:]
    band[width - 1, 1:] = first[1:-1]
    band[width - 2, 2:] = second[1:-2]
    return band


def _savgol_matrix(n: int, window: int) -> sparse.csr_array:
    """The (n, n) sparse matrix of :func:`scipy.signal.savgol_filter`'s cubic smoothing over ``window`` samples
    with ``mode="interp"`` (a signal x (n,) filtered is this matrix @ x): the interior rows the window's
    coefficients, the first and last window // 2 rows the cubic fitted to the first and last ``window`` samples."""
    half = window // 2
    inner = savgol_coeffs(window, 3, use="dot")
    rows = [np.repeat(np.arange(half, n - half), window)]
    cols = [(np.arange(half, n - half)[:, None] + np.arange(-half, half + 1)[None, :]).ravel()]
    vals = [np.tile(inner, n - 2 * half)]
    edges = savgol_filter(np.eye(window), window, 3, axis=0, mode="interp")  # rows: outputs, columns: inputs
    for out_rows, offset in ((np.arange(half), 0), (np.arange(n - half, n), n - window)):
        for i in out_rows:
            rows.append(np.full(window, i))
            cols.append(offset + np.arange(window))
            vals.append(edges[i - offset])
    return sparse.csr_array((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))


def rest_scale(model, velocity: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """The orifice law's factor between a 3-way leg's curve at its rest pressure and at ``p1`` [Pa] (n,), for the
    edge that passes ``velocity`` [m/s] (n,): sqrt(Δp / Δp_rest), held within 0.5…2 (seed eq. 3.4; as
    :meth:`compensation.model_based.FeedforwardCompensator.inverse` scales it); 1 where the model does not scale
    (a 4-way valve's curve is its steady motion against the load)."""
    if not model.pressure_scaling:
        return np.ones_like(np.asarray(velocity, dtype=float))
    up = (model.supply_pressure - p1) / (model.supply_pressure - model.p_rest)
    down = (p1 - model.tank_pressure) / (model.p_rest - model.tank_pressure)
    return np.sqrt(np.clip(np.where(velocity >= 0, up, down), 0.25, 4.0))


__all__ = ["BIN_V", "CurveLearner", "CurveTeacher", "Taken", "Taught", "gain_error", "rest_scale", "seed_weights"]
