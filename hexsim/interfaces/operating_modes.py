"""A motion controller's operating modes: the piston setpoints the legs follow, from the host's packets.

The conventions of a hydraulic motion system's controller (docs/serve.md):

* it starts **neutral** (settled at the neutral pose, as after its raise), holding the pose whatever the host
  sends until the host asks to **engage**; the host's motion is then faded in over ``engage_s``
  (setpoint = neutral + s(t) (host - neutral), s a quintic from 0 to 1 with zero slope and curvature at both
  ends: no step in position, velocity or acceleration), then followed (**engaged**);
* asked for **neutral** (or **park**) while engaged, or when the host goes silent for ``host_timeout_s``
  while engaged (**host lost**, a latched fault: engage is refused until the host has sent another mode), it
  returns to neutral on a quintic from the setpoint, its velocity and its acceleration at that instant to rest
  at neutral, over ``return_s`` or longer where the legs' ``move_speed`` asks for it (no step in position,
  velocity or acceleration);
* **park** lowers each leg to ``park_m`` above its retracted end, and leaving park raises it again, on the
  same quintic (from rest), at most ``move_speed``; a move is finished before the next request is taken.

A host packet is rejected, counted by reason and leaves the platform undisturbed when its frame counter
is not newer than the last accepted one (modulo the counter's range: "order"; after a silence longer than
the timeout any counter starts a new timeline), or when its setpoint needs a
leg beyond its stroke less ``margin_m`` ("envelope").

Between packets the host's setpoints are interpolated linearly on the host's own timeline, not on the
arrival times: each accepted packet sits at its frame counter (unwrapped) counted from the first packet's times
the host period, the period and where the first packet's frame sits are learned from the arrivals by slow averages
(:data:`LEARN`; the period, until 1 / LEARN frames have come, the mean of the lines from the first packet to each;
the offset from late arrivals more slowly still, :data:`LEARN_LATE`: it follows the earliest), and the setpoint
is played ``delay_frames`` frames behind the newest (1.5: a packet may arrive up to half a period late without
the setpoints noticing). Arrival jitter then moves the offset a little, not the setpoints' velocity, which
would be acceleration spikes of the size jitter x velocity / period^2. A packet later than that is
bridged: past the newest packet the setpoints go on along the last two packets' line for up to
:data:`EXTRAPOLATE_FRAMES` frames (a motion computer's dead reckoning), so the late packet, when it comes,
continues the line instead of ending a hold with a jump (held, a served session's 8 ms late packet stopped the
setpoint for four ticks and then stepped it 0.85 mm: 4 g at the platform with the feedforward on). A host that
stops is held after that, the setpoint stopping on a quintic from its velocity over :data:`REJOIN_FLOOR_S`;
when its packets come again (within ``host_timeout_s``: a host, or the
network, that stalled), the setpoint **rejoins** the host's line on a quintic correction from where it stood,
its velocity and acceleration to nothing, at most ``move_speed`` faster than the line and over
:data:`REJOIN_FLOOR_S` at least, instead of jumping to it (a host silent from 2.5 to 2.8 s on a 0.5 Hz, 40 mm
sine: one tick jumped 10.3 mm; a served session stopped three times 0.3 s jerked the platform at -4.5...35 m/s^2,
its p1 at the cavitation pressure).

A stall is told from a lost host by the frames: after a silence longer than ``host_timeout_s`` the next frame
means the packets waited in a queue (the controller's socket while it stalled, or the host's): the timeline goes
on, every packet not yet played is kept for the controller to catch up through (:data:`MOST_KEPT`), and those
queued or a period late teach the timeline nothing (:meth:`OperatingModes._learn`), unless :data:`LATE_IN_A_ROW`
late ones come in a row, regularly spaced and late by the same: a route that got longer, on whose earliest packet
the timeline is then placed at once, the setpoint rejoining the later line. Frames skipped over the
silence mean a lost host (restarted, or silent itself): followed, the platform returns to neutral, host lost,
though no tick saw the silence.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Callable

import numpy as np

from hexsim.errors import InputError


class Status(enum.IntEnum):
    """The state the motion system reports (the state packet's ``status``)."""

    PARKED = 0
    NEUTRAL = 1
    ENGAGED = 2
    ENGAGING = 3
    RETURNING = 4
    PARKING = 5
    RAISING = 6


#: the weight of each arrival in the averages of the host period and its timeline's offset
LEARN = 0.02
#: ... of an arrival later than the timeline has it, in the offset's: a network delays packets, it never sends one
#: early, so the timeline follows the earliest arrivals and a burst of late ones barely moves it (at LEARN each,
#: a served session's three packets 30 ms late stepped the setpoint back 0.24 mm in one tick: 2 g)
LEARN_LATE = 0.001
#: late arrivals in a row that say the host's timeline is late, and place it on them (:meth:`OperatingModes._learn`)
LATE_IN_A_ROW = 8
#: the most host packets kept for the interpolation: those not yet played, and the one before (a controller that
#: stalled catches up through every packet that waited in its socket; the last eight only, it jumped 12 mm to the
#: eighth last and held there until its ticks reached it)
MOST_KEPT = 4096
#: how far past the newest packet [frames] the setpoints go on along the last two packets' line (module doc): a
#: burst of three packets 30 ms late is bridged (two frames held the setpoint for a tick, then doubled its step)
EXTRAPOLATE_FRAMES = 5.0

#: The shortest rejoin of the host's line after a hold, and the stop when it is held (module doc) [s]
REJOIN_FLOOR_S = 0.2

#: The time constant [s] of the low pass the setpoints' acceleration is read through for a move's start: the
#: host's setpoints, linear between its packets, change their velocity in steps at each packet (their second
#: difference is a train of spikes); two of its 100 Hz periods smooth that to the motion's own acceleration.
ACCELERATION_TAU_S = 0.02

#: fault bits of the state packet's ``faults``
HOST_LOST, REJECTED, OVERRUN, ENVELOPE = 1, 2, 4, 8


@dataclasses.dataclass(frozen=True)
class ModeSettings:
    """engage_s [s]: the fade-in of the host's motion; return_s [s]: the shortest return to neutral;
    move_speed [m/s]: the largest leg speed of a return, park or raise; host_timeout_s [s]: silence after which
    the host is lost; margin_m [m]: the envelope's distance from each end of the stroke; park_m [m]: the park
    position above the retracted end; delay_frames: how far behind the newest packet the host's setpoints are
played (module doc). Raises InputError for a value that is not positive (margin_m and park_m:
    not negative)."""

    engage_s: float = 2.0
    return_s: float = 2.0
    move_speed: float = 0.05
    host_timeout_s: float = 0.5
    margin_m: float = 0.005
    park_m: float = 0.005
    delay_frames: float = 1.5

    def __post_init__(self) -> None:
        for name in ("engage_s", "return_s", "move_speed", "host_timeout_s"):
            if not getattr(self, name) > 0:
                raise InputError(f"{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("margin_m", "park_m", "delay_frames"):
            if not getattr(self, name) >= 0:
                raise InputError(f"{name} must be >= 0, got {getattr(self, name)!r}")


def quintic(s: float) -> float:
    """0 at s <= 0, 1 at s >= 1, between them 10 s^3 - 15 s^4 + 6 s^5 (zero slope and curvature at both ends)."""
    s = min(max(s, 0.0), 1.0)
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


#: A move from rest on :class:`_Move`'s quintic peaks at this many times its mean speed (15/8).
QUINTIC_PEAK_SPEED = 1.875
#: The shortest a move is made to keep a leg that was moving inside its envelope [s]: from 0.2 m/s, 1.6 m/s^2 at most.
SHORTEST_MOVE_S = 0.5


@dataclasses.dataclass
class _Move:
    """A quintic from (y0, v0, a0) at t0 to rest at y1 at t0 + T (arrays (n,) [m], [m/s], [m/s^2]): the
    quintic Hermite polynomial, so position, velocity and acceleration are continuous where it starts and
    it ends with no velocity and no acceleration."""

    t0: float
    T: float
    y0: np.ndarray
    v0: np.ndarray
    a0: np.ndarray
    y1: np.ndarray
    then: Status

    def at(self, t: float) -> np.ndarray:
        s = min(max((t - self.t0) / self.T, 0.0), 1.0)
        s3, s4, s5 = s**3, s**4, s**5
        rise = 10 * s3 - 15 * s4 + 6 * s5  # 0 -> 1, flat at both ends
        h_v = s - 6 * s3 + 8 * s4 - 3 * s5  # slope 1 at the start, nothing else at either end
        h_a = 0.5 * s * s - 1.5 * s3 + 1.5 * s4 - 0.5 * s5  # curvature 1 at the start
        T = self.T
        return (1 - rise) * self.y0 + rise * self.y1 + h_v * T * self.v0 + h_a * T * T * self.a0

    def done(self, t: float) -> bool:
        return t >= self.t0 + self.T


class OperatingModes:
    """The piston setpoints (n_legs,) [m] a motion controller hands its P loops (module doc).

    ``neutral`` (n,) [m] and ``stroke`` (n, 2) [m]: the legs' neutral positions and ends; ``to_legs``: the
    host's six setpoints [m, rad] (a DOF pose, or the legs themselves) -> piston positions (n,) [m] (NaN where
    the pose has none); ``frame_range``: the frame counter's modulus (2^bits). :meth:`receive` takes a host
    packet's fields, :meth:`setpoint` advances to a controller tick."""

    def __init__(self, neutral: np.ndarray, stroke: np.ndarray, to_legs: Callable[[np.ndarray], np.ndarray],
                 settings: ModeSettings = ModeSettings(), frame_range: int = 1 << 32) -> None:
        self.neutral = np.asarray(neutral, dtype=float)
        self.stroke = np.asarray(stroke, dtype=float)
        self.park = self.stroke[:, 0] + settings.park_m
        self.lo, self.hi = self.stroke[:, 0] + settings.margin_m, self.stroke[:, 1] - settings.margin_m
        self.to_legs, self.settings, self.frame_range = to_legs, settings, frame_range
        self.status = Status.NEUTRAL
        self.requested = "neutral"
        self.latched = False  # host lost: engage refused until another mode is asked
        self.faults = 0  # HOST_LOST while latched, the others until read (:meth:`take_faults`)
        self.cmd, self.vel, self.acc = self.neutral.copy(), np.zeros_like(self.neutral), np.zeros_like(self.neutral)
        self._t = 0.0
        self._move: _Move | None = None
        self._fade_t0 = 0.0
        self._frames: list[int] = []  # the accepted packets not yet played, and the one before: frames
        self._legs: list[np.ndarray] = []  # and their piston setpoints
        self._arrived = -np.inf  # the newest accepted packet's arrival [s]
        self._first = (0.0, 0)  # the first accepted packet's (arrival [s], frame)
        self.host_period: float | None = None  # [s], learned
        self._offset = 0.0  # where the host's timeline puts the first packet's frame on our clock [s], learned
        self._lost = False  # the host was lost while followed, seen by :meth:`receive`
        self._late: list[float] = []  # late arrivals in a row [s late], which taught the timeline nothing yet
        self._replaced = False  # the timeline was re-placed on late arrivals (:meth:`_learn`), not yet rejoined
        self.last_frame: int | None = None
        self.rejected: dict[str, int] = {}
        # the host's line as played while following (:meth:`_played_host`): held past its dead reckoning at the
        # last tick, the correction that rejoins it, the last value played [m] with its velocity [m/s] and time [s]
        self._held = False
        self._rejoin: _Move | None = None
        self._stopping: _Move | None = None
        self._played: tuple[np.ndarray, np.ndarray, float] | None = None

    # ------------------------------------------------------------------ packets
    def reject(self, reason: str) -> None:
        """Count a rejected packet under ``reason`` (the fault bit REJECTED, ENVELOPE for "envelope")."""
        self.rejected[reason] = self.rejected.get(reason, 0) + 1
        self.faults |= ENVELOPE if reason == "envelope" else REJECTED

    def receive(self, t: float, fields: dict) -> bool:
        """Take a host packet's ``fields`` (:meth:`~hexsim.interfaces.packets.PacketLayout.unpack`: frame, mode,
        the six setpoints in ``setpoint`` (6,)) arrived at ``t`` [s]. Returns whether it was accepted (else it is
        counted under its reason and changes nothing)."""
        frame = int(fields["frame"])
        queued = self.last_frame is not None and (frame - self.last_frame) % self.frame_range == 1
        if t - self._arrived > self.settings.host_timeout_s and not queued:  # a host back after silence: a new
            # timeline; followed, it was lost, though no tick saw the silence (the controller stalled with it, its
            # ticks behind the packets' clock): the next tick returns to neutral, as it would have. The next frame
            # after a silence is not a new host: its packets waited in a queue (the controller's socket while it
            # stalled, or the host's) and the timeline goes on (a served session whose process stopped 0.8 s had
            # jumped to the new timeline's newest packet, 8 mm in a tick)
            self._lost = self.status in (Status.ENGAGED, Status.ENGAGING)
            self.last_frame, self._frames, self._legs, self.host_period, self._late = None, [], [], None, []
        if self.last_frame is not None:
            ahead = (frame - self.last_frame) % self.frame_range
            if ahead == 0 or ahead >= self.frame_range // 2:
                self.reject("order")
                return False
        legs = np.asarray(self.to_legs(np.asarray(fields["setpoint"], dtype=float)), dtype=float)
        if not np.all(np.isfinite(legs)) or np.any(legs < self.lo) or np.any(legs > self.hi):
            self.reject("envelope")
            return False
        self._learn(t, frame)
        self.last_frame = frame
        self._legs = [*self._legs[-(MOST_KEPT - 1):], legs]
        if fields["mode"] != "engage":
            self.latched = False
            self.faults &= ~HOST_LOST
        self.requested = fields["mode"]
        return True

    def take_faults(self) -> int:
        """The fault bits since the last call (HOST_LOST stays while it is latched)."""
        out, self.faults = self.faults, self.faults & HOST_LOST
        return out

    def _learn(self, t: float, frame: int) -> None:
        """Place the accepted packet (arrival ``t`` [s], counter ``frame``) on the host's timeline: its unwrapped
        frame, and the averages of the host period and the timeline's offset (module doc). A stall's packets teach
        neither (those arriving a period or more late, and those queued behind them, within a quarter period of the
        one before: their arrival times are the queue's, not the host's; a burst of 30, 0-0.3 s late, pulled the
        period 2.4 % long and the offset 5 ms late, and the played line stepped at each packet after it, up to
        3.7 m/s^2). :data:`LATE_IN_A_ROW` late ones in a row, each a quarter period or more after the one before and
        all late by the same within a period, say the host's timeline is late (a route that got longer; a controller
        catching up after a stall reads its backlog ever less late): it is placed on the earliest of them at once and
        the played line rejoins it (``_replaced``; learned slowly instead, a route 80 ms longer held the setpoint at
        its dead reckoning's end for seconds, stepping at each packet: 315 m/s^2)."""
        n = frame if not self._frames else self._frames[-1] + (frame - self.last_frame) % self.frame_range
        self._frames = [*self._frames[-(MOST_KEPT - 1):], n]
        previous, self._arrived = self._arrived, t
        if len(self._frames) == 1:
            self._first = (t, n)
            return
        t0, n0 = self._first
        if self.host_period is None:
            self.host_period = (t - t0) / (n - n0)
            self._offset = t0
            return
        if t - previous < 0.25 * self.host_period:  # queued behind the one before
            return
        late = t - self._on_timeline(n)
        if late >= self.host_period:
            self._late = [*self._late[-(LATE_IN_A_ROW - 1):], late]
            if len(self._late) < LATE_IN_A_ROW:
                return
            if max(self._late) - min(self._late) < self.host_period:
                # the host's timeline is late by the least of them (a route that got longer): placed there at
                # once, the first packet with it (the period's estimate is not biased by the step), the line rejoined
                jump, self._late, self._replaced = min(self._late), [], True
                self._offset += jump
                self._first = (t0 + jump, n0)
                return
        else:
            self._late = []
        self.host_period += max(LEARN, 1.0 / (n - n0)) * ((t - t0) / (n - n0) - self.host_period)
        late = t - self._on_timeline(n)
        self._offset += (LEARN_LATE if late > 0 else LEARN) * late

    def host_setpoint(self, t: float) -> np.ndarray:
        """The host's piston setpoints at ``t`` [s]: linear on the host's timeline, ``delay_frames`` behind
        the newest packet (module doc); past the newest along the last two packets' line for up to
        :data:`EXTRAPOLATE_FRAMES`, then held there."""
        return self._line(t)[0]

    def _line(self, t: float) -> tuple[np.ndarray, np.ndarray, bool]:
        """:meth:`host_setpoint` at ``t`` [s], its velocity on the host's line [m/s] and whether it is held
        (past the newest packet's dead reckoning)."""
        still = np.zeros_like(self._legs[-1])
        f = self._played_frame(t)
        if f is None:
            return self._legs[-1], still, False
        frames = self._frames
        if f >= frames[-1]:
            if len(frames) < 2:
                return self._legs[-1], still, False
            slope = (self._legs[-1] - self._legs[-2]) / (frames[-1] - frames[-2])  # per frame
            held = f - frames[-1] > EXTRAPOLATE_FRAMES
            ahead = min(f - frames[-1], EXTRAPOLATE_FRAMES)
            return self._legs[-1] + ahead * slope, still if held else slope / self.host_period, held
        if f <= frames[0]:
            return self._legs[0], still, False
        k = int(np.searchsorted(frames, f, side="right"))  # frames[k - 1] <= f < frames[k]
        s = (f - frames[k - 1]) / (frames[k] - frames[k - 1])
        step = self._legs[k] - self._legs[k - 1]
        return self._legs[k - 1] + s * step, step / ((frames[k] - frames[k - 1]) * self.host_period), False

    def _played_frame(self, t: float) -> float | None:
        """The (unwrapped, fractional) host frame played at ``t`` [s]: ``delay_frames`` behind the frame the host's
        timeline puts there; None before the host period is learned."""
        if self.host_period is None or self.host_period <= 0:
            return None
        return self._first[1] + (t - self._offset) / self.host_period - self.settings.delay_frames

    def _on_timeline(self, n: float) -> float:
        """Where the host's timeline puts its (unwrapped) frame ``n`` on our clock [s]: a line through the first
        packet's frame, so that the period's learning turns it about there (anchored at frame 0, a host whose
        counter stood at 60000 when it began, its arrivals jittering by 3 ms, was played 8-95 mm off its line)."""
        return self._offset + (n - self._first[1]) * self.host_period

    def _forget(self, t: float) -> None:
        """Drop the packets the host's line has passed at the tick ``t`` [s], keeping the one it is on (and two at
        least: the bridge's line)."""
        f = self._played_frame(t)
        if f is None or len(self._frames) < 3:
            return
        k = min(int(np.searchsorted(self._frames, f, side="right")) - 1, len(self._frames) - 2)
        if k > 0:
            del self._frames[:k], self._legs[:k]

    def _played_host(self, t: float) -> np.ndarray:
        """The host's line at ``t`` [s] as the engaged platform plays it: :meth:`host_setpoint`, except that where
        the line is held (past its dead reckoning) the setpoint stops on a quintic from the last value played and
        its velocity (:meth:`_stop`), and where it was held and is not now (its packets came again) or the
        timeline was re-placed, a quintic correction rejoins it from the last value played, its velocity and no
        acceleration (:meth:`_rejoin_line`; module doc)."""
        line, velocity, held = self._line(t)
        if held and not self._held and self._played is not None:
            self._stopping, self._rejoin = self._stop(), None
        if self._played is not None and ((self._held and not held) or self._replaced):
            self._rejoin, self._stopping = self._rejoin_line(t, line, velocity), None
        self._held, self._replaced = held, False
        y = line
        if self._stopping is not None:
            y = np.clip(self._stopping.at(t), self.lo, self.hi)
        elif self._rejoin is not None:
            y = np.clip(line + self._rejoin.at(t), self.lo, self.hi)
            if self._rejoin.done(t):
                self._rejoin = None
        if self._played is not None and t > self._played[2]:
            self._played = (y, (y - self._played[0]) / (t - self._played[2]), t)
        elif self._played is None:
            self._played = (y, velocity, t)
        return y

    def _stop(self) -> _Move:
        """The stop when the host's line is held: from the last value played and its velocity at that tick, no
        acceleration, to rest over :data:`REJOIN_FLOOR_S` (the quintic's braking is then monotone: it ends half
        that time times the velocity further on, its largest deceleration 1.5 v / T). Held at once, the setpoint's
        velocity stepped to nothing in a tick: 31 m/s^2 of setpoint acceleration, a host's 0.5 Hz, 40 mm sine
        held at its full speed."""
        last, velocity, t_last = self._played
        return _Move(t_last, REJOIN_FLOOR_S, last, velocity, np.zeros_like(last),
                     last + 0.5 * REJOIN_FLOOR_S * velocity, self.status)

    def _rejoin_line(self, t: float, line: np.ndarray, velocity: np.ndarray) -> _Move:
        """The correction (added to the host's ``line`` (n,) [m] with its ``velocity`` [m/s] at ``t`` [s]) from the
        last value played, its velocity and no acceleration to the line, over :data:`REJOIN_FLOOR_S` at least and
        at most ``move_speed`` faster than the line (:data:`QUINTIC_PEAK_SPEED`)."""
        last, last_velocity, t_last = self._played
        gap = last + last_velocity * (t - t_last) - line
        T = max(REJOIN_FLOOR_S, QUINTIC_PEAK_SPEED * float(np.max(np.abs(gap))) / self.settings.move_speed)
        return _Move(t, T, gap, last_velocity - velocity, np.zeros_like(gap), np.zeros_like(gap), self.status)

    # ------------------------------------------------------------------ ticks
    def _start_move(self, target: np.ndarray, then: Status, status: Status, floor: float) -> None:
        """A quintic (:class:`_Move`) to rest at ``target`` over at least ``floor`` [s] and long enough that no
        leg passes ``move_speed`` from rest (:data:`QUINTIC_PEAK_SPEED`), from the last tick's setpoint with its
        velocity and acceleration: the tick that starts the move is already on it, without a step in the
        acceleration. (Started at this tick from the last one's setpoint, the setpoint stood still for a tick at
        the switch: a served host moving at 0.13 m/s that asked for neutral shook the platform at 2.2 g, 5 m/s^2
        at the seat; a cubic from the setpoint and its velocity stepped the acceleration by 4 v0 / T, 0.5 m/s^2
        at the seat.)"""
        distance = float(np.max(np.abs(target - self.cmd)))
        T = max(floor, QUINTIC_PEAK_SPEED * distance / self.settings.move_speed, 1e-3)
        move = _Move(self._t, T, self.cmd.copy(), self.vel.copy(), self.acc.copy(), target.copy(), then)
        self._move = self._within_stroke(move)
        self.status = status

    def _within_stroke(self, move: _Move) -> _Move:
        """``move``, or a shorter one where its path would carry a leg beyond the envelope (the stroke less
        ``margin_m``): a move that starts at speed goes on past where it started, by up to 0.19 v0 T, before
        it turns (a leg at 0.2 m/s over 2 s: 77 mm). The longest of T, T/1.5, T/1.5^2 … (not below
        :data:`SHORTEST_MOVE_S`) whose path stays inside, else the shortest."""
        s = np.linspace(0.0, 1.0, 41)
        for _ in range(12):
            path = np.array([move.at(move.t0 + x * move.T) for x in s])
            if (np.all(path >= self.lo - 1e-12) and np.all(path <= self.hi + 1e-12)) or move.T <= SHORTEST_MOVE_S:
                return move
            move = dataclasses.replace(move, T=max(move.T / 1.5, SHORTEST_MOVE_S))
        return move

    def setpoint(self, t: float) -> np.ndarray:
        """Advance to the controller tick at ``t`` [s] (increasing): the modes' transitions, then the piston
        setpoints (n,) [m] (a copy)."""
        s = self.settings
        host_ok = t - self._arrived <= s.host_timeout_s and not self._lost
        self._lost = False
        following = self.status in (Status.ENGAGED, Status.ENGAGING)
        if following and not host_ok:
            self.latched = True
            self.faults |= HOST_LOST
            self._start_move(self.neutral, Status.NEUTRAL, Status.RETURNING, s.return_s)
        elif following and self.requested != "engage":
            self._start_move(self.neutral, Status.NEUTRAL, Status.RETURNING, s.return_s)
        elif self._move is not None and self._move.done(t):
            self.status, self._move = self._move.then, None
        if self.status == Status.NEUTRAL:
            if self.requested == "park":
                self._start_move(self.park, Status.PARKED, Status.PARKING, 0.0)
            elif self.requested == "engage" and host_ok and not self.latched:
                self.status, self._fade_t0 = Status.ENGAGING, t
        elif self.status == Status.PARKED and self.requested != "park" and host_ok:
            self._start_move(self.neutral, Status.NEUTRAL, Status.RAISING, 0.0)
        if self.status == Status.ENGAGING and t - self._fade_t0 >= s.engage_s:
            self.status = Status.ENGAGED
        if self.status == Status.ENGAGED:
            y = self._played_host(t)
        elif self.status == Status.ENGAGING:
            y = self.neutral + quintic((t - self._fade_t0) / s.engage_s) * (self._played_host(t) - self.neutral)
        else:
            self._held, self._rejoin, self._stopping, self._played = False, None, None, None  # a new line to follow
            if self._move is not None:
                y = self._move.at(t)
            else:
                y = self.park if self.status == Status.PARKED else self.neutral
        self._forget(t)
        dt = t - self._t
        vel = (y - self.cmd) / dt if dt > 0 else np.zeros_like(y)
        if dt > 0:  # the setpoint's acceleration, smoothed over the host's packets' kinks (ACCELERATION_TAU_S)
            self.acc += (1.0 - math.exp(-dt / ACCELERATION_TAU_S)) * ((vel - self.vel) / dt - self.acc)
        self.vel, self.cmd, self._t = vel, np.array(y, dtype=float), t
        return self.cmd.copy()
