"""A host computer for ``hexsim serve``: sends setpoint packets at a fixed rate, as a simulator's host does,
and collects the state packets coming back (``hexsim serve --client``, the tests, a user's first try).

A session is a *script*: a function of the host's time t [s] that returns the mode and the six setpoints
to send (or None: send nothing at that frame, a host gone silent). :func:`motion_script` is the usual one:
neutral for ``lead_s``, engage and the motion, neutral again for ``tail_s``.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import socket
import time
from collections.abc import Callable

import numpy as np

from hexsim.errors import InputError
from hexsim.interfaces.packets import (
    DOF,
    HOST_PACKET,
    LEGS,
    STATE_PACKET,
    PacketError,
    PacketLayout,
)

Script = Callable[[float], "tuple[str, np.ndarray] | None"]


def motion_script(motion: Callable[[float], np.ndarray], motion_s: float, lead_s: float = 1.0,
                  tail_s: float = 3.0) -> tuple[Script, float]:
    """The script (neutral for ``lead_s`` [s], then engage with ``motion(t - lead_s)`` (6,) [m, rad] for
    ``motion_s``, then neutral for ``tail_s`` holding the motion's last setpoint) and its length [s]."""

    def script(t: float):
        u = min(max(t - lead_s, 0.0), motion_s)
        return ("engage" if lead_s <= t < lead_s + motion_s else "neutral"), motion(u)

    return script, lead_s + motion_s + tail_s


def scenario_motion(name: str, duration: float | None = None) -> tuple[Callable[[float], np.ndarray], float]:
    """The platform setpoints of a hexapod scenario ``name`` (any ``hexsim run`` accepts: ``heave``,
    ``file:PATH``, ``vehicle:PATH``) as a function of t [s] -> (6,) [m, rad], and its duration [s]. Raises
    InputError for a scenario that is not the hexapod's platform motion."""
    from hexsim.control.scenario import make_scenario

    sc = make_scenario(name, duration=duration)
    if sc.system != "hexapod" or sc.legs is not None or sc.open_loop:
        raise InputError(f"host client: scenario {name!r} gives no platform motion (a hexapod DOF scenario needed)")
    return (lambda t: sc.poses(np.array([t]))[0]), sc.duration


@dataclasses.dataclass
class HostRecord:
    """A session as the host saw it: the frames sent (t [s], frame, mode, setpoint (6,)) and the state packets
    received (t [s] at arrival, fields by name); ``undecodable``: state packets of another size."""

    sent: list = dataclasses.field(default_factory=list)
    states: list = dataclasses.field(default_factory=list)
    undecodable: int = 0

    def series(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(arrival times (N,) [s], values (N,)) of state field ``name``."""
        return (np.array([t for t, _ in self.states]), np.array([s[name] for _, s in self.states], dtype=float))


class HostClient:
    """Sends ``layout`` packets to ``server`` (host, port) at ``rate_hz`` and reads ``state_layout`` packets
    on its own port. Use as a context manager or call :meth:`close`."""

    def __init__(self, server: tuple[str, int], layout: PacketLayout = HOST_PACKET,
                 state_layout: PacketLayout = STATE_PACKET, rate_hz: float = 100.0) -> None:
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise InputError(f"host rate must be a positive number of Hz, got {rate_hz!r}")
        self.server, self.layout, self.state_layout, self.rate_hz = server, layout.check_host(), state_layout, rate_hz
        self.names = DOF if layout.setpoints == "dof" else LEGS
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("0.0.0.0" if server[0] not in ("127.0.0.1", "localhost") else "127.0.0.1", 0))
        self.sock.setblocking(False)
        self.frame = 0

    def __enter__(self) -> HostClient:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self.sock.close()

    def packet(self, mode: str, setpoint: np.ndarray, frame: int | None = None) -> bytes:
        """A host packet of the layout (``frame`` None: the next of the counter)."""
        if frame is None:
            self.frame += 1
            frame = self.frame
        values = {"frame": frame, "mode": self.layout.modes[mode], **dict(zip(self.names, np.asarray(setpoint)))}
        return self.layout.pack(values)

    def send_raw(self, data: bytes) -> None:
        self.sock.sendto(data, self.server)

    def collect(self, record: HostRecord, t: float) -> None:
        """Read every state packet waiting into ``record`` (arrival at ``t`` [s])."""
        while True:
            try:
                data, _ = self.sock.recvfrom(65536)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:  # ICMP port unreachable: no server yet
                continue
            try:
                record.states.append((t, self.state_layout.unpack(data)))
            except PacketError:
                record.undecodable += 1

    def session(self, script: Script, duration: float, record: HostRecord | None = None) -> HostRecord:
        """Run ``script`` (module doc) for ``duration`` [s] at the client's rate, paced to the wall clock
        (a late frame is sent at once, none skipped). Returns the record."""
        record = HostRecord() if record is None else record
        period, t0 = 1.0 / self.rate_hz, time.perf_counter()
        for k in range(int(round(duration * self.rate_hz))):
            while (wait := t0 + k * period - time.perf_counter()) > 0:
                time.sleep(min(wait, 0.002))
                self.collect(record, time.perf_counter() - t0)
            t = k * period
            what = script(t)
            if what is not None:
                mode, setpoint = what
                self.send_raw(self.packet(mode, setpoint))
                record.sent.append((t, self.frame, mode, np.asarray(setpoint, dtype=float).copy()))
            self.collect(record, time.perf_counter() - t0)
        return record


def run_client(scenario: str, server: tuple[str, int], layout: PacketLayout = HOST_PACKET,
               state_layout: PacketLayout = STATE_PACKET, rate_hz: float = 100.0,
               duration: float | None = None) -> HostRecord:
    """``hexsim serve --client SCENARIO``: neutral 1 s, engage and the scenario's motion, neutral 3 s, sent to
    ``server`` at ``rate_hz``. Raises InputError for a scenario without platform motion or a legs layout."""
    if layout.setpoints != "dof":
        raise InputError("hexsim serve --client sends a scenario's platform motion: the layout's setpoints must be 'dof'")
    motion, motion_s = scenario_motion(scenario, duration)
    script, total = motion_script(motion, motion_s)
    with HostClient(server, layout, state_layout, rate_hz) as client:
        return client.session(script, total)


def client_lines(record: HostRecord) -> list[str]:
    """What a client session saw, as a user reads it."""
    from hexsim.interfaces.operating_modes import Status

    lines = [f"sent {len(record.sent)} packets; received {len(record.states)} state packets"
             + (f" ({record.undecodable} of another layout)" if record.undecodable else "")]
    if not record.states:
        lines.append("no state packet came back: is hexsim serve running at that address, and its --reply this host?")
        return lines
    _, status = record.series("status")
    seen = [int(status[0])] + [int(b) for a, b in itertools.pairwise(status) if b != a]
    lines.append("status: " + " -> ".join(Status(s).name.lower() for s in seen if s in iter(Status)))
    if "faults" in record.states[0][1]:
        _, faults = record.series("faults")
        if np.any(faults.astype(int) & 1):
            lines.append("the motion system lost this host at least once (faults bit 1)")
    if "heave" in record.states[0][1]:
        sent_t = np.array([s[0] for s in record.sent])
        sent_heave = np.array([s[3][2] for s in record.sent])
        _, heave = record.series("heave")
        engaged = heave[status == Status.ENGAGED]
        followed = (f"{engaged.min():+.4f}…{engaged.max():+.4f} m engaged, " if engaged.size else "")
        lines.append(f"heave sent {sent_heave.min():+.4f}…{sent_heave.max():+.4f} m, reported {followed}"
                     f"{heave.min():+.4f}…{heave.max():+.4f} m in all (the fade-in and the return to neutral "
                     f"included) over {sent_t[-1] - sent_t[0]:.1f} s")
    if "seat_peak" in record.states[0][1]:
        from hexsim.studies.perception import ISO_PERCEPTION_THRESHOLD

        _, peak = record.series("seat_peak")
        lines.append(f"seat, ISO 2631-1 weighted (the motion and its bumps): largest {peak.max():.4f} m/s² "
                     f"({peak.max() / ISO_PERCEPTION_THRESHOLD:.1f}× the {ISO_PERCEPTION_THRESHOLD:g} m/s² threshold of "
                     "perception)")
    return lines
