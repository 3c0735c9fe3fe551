"""A served session's measurement log and rerun recording, written while the session runs.

``hexsim serve --log FILE.csv --rrd FILE.rrd``: every :data:`STREAM_S` of simulated time the loop hands the
samples recorded since the last stretch (:meth:`Simulator.result` with ``since``, some 0.1–0.3 ms, between
ticks with time to spare) to a writer in a process of its own, which appends them to the measurement log
(:class:`hexsim.outputs.logio.LogStream`: CSV rows flushed to the file, the sidecar from the first stretch)
and to the rerun recording (:class:`hexsim.outputs.rerun_log.RerunStream`). The files therefore hold the
session up to a second or so before now while it runs, and the whole session (not only the last ``keep_s``
in memory) when it ends; a session killed abruptly leaves them readable up to its last stretch.

The writer is a fresh interpreter (``python -m hexsim.interfaces.session_log``, started, with what it needs
imported, before the session's clock starts) at a lower priority than the loop (:data:`WRITER_NICE`): not a
fork (rerun's own threads are not forked with a process that runs them) and not a multiprocessing spawn (which
imports the caller's main module again, a script without a ``__main__`` guard included). It reads
length-prefixed pickles on its standard input — the run's configuration once, with the live scenario's setpoint
table (an hour at 500 Hz: 86 MB) left behind, then the stretches without it, then None — and answers on its
standard output ("ready", then "done" with the paths, or "error" with what went wrong). A thread of the
server's hands the stretches over, so a writer that falls behind never holds up the loop.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import pathlib
import pickle
import queue
import struct
import subprocess
import sys
import tempfile
import threading

from hexsim.engine.config import RunConfig
from hexsim.errors import InputError

#: the stretch of samples handed to the writer at a time [s of the recording]; 0.1 s was no easier on the loop
#: and doubled the rerun recording's size (a chunk per entity and stretch)
STREAM_S = 0.5
#: the writer's niceness (``os.nice``): the loop first
WRITER_NICE = 10
#: the longest wait for the writer to start, or to finish the session's files after it [s]
WRITER_TIMEOUT_S = 120.0
_LENGTH = struct.Struct("<Q")


def _send(stream, obj) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_LENGTH.pack(len(data)) + data)
    stream.flush()


def _receive(stream):
    head = stream.read(_LENGTH.size)
    if len(head) < _LENGTH.size:
        raise EOFError("the stream ended")
    size = _LENGTH.unpack(head)[0]
    body = stream.read(size)
    if len(body) < size:
        raise EOFError("the stream ended within a message")
    return pickle.loads(body)


class SessionLog:
    """The writer of a session's log (``log``: a measurement log .csv, its sidecar beside it) and recording
    (``rrd``) as the session runs (module doc); ``config`` is the session's run configuration (its scenario
    is only named in the files). :meth:`due` says when a stretch is ready, :meth:`send` hands it over,
    :meth:`close` hands over the rest and waits for the files. Raises InputError when the writer cannot
    start, or (at :meth:`close`) could not write a file."""

    def __init__(self, sim, config: RunConfig, log: str | os.PathLike | None = None,
                 rrd: str | os.PathLike | None = None) -> None:
        self.sim = sim
        self.sent = 0  # samples handed over (a count since the start, as sim.rows)
        self.stretch = max(2, int(round(STREAM_S * sim.record_rate)))
        self._errors = tempfile.TemporaryFile()
        # a session of its own: the Ctrl-C that ends the session reaches the server, which ends the files in order
        self._process = subprocess.Popen([sys.executable, "-m", "hexsim.interfaces.session_log"],
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._errors,
                                         start_new_session=True)
        self._answers: queue.Queue = queue.Queue()
        threading.Thread(target=self._read_answers, daemon=True).start()
        self._stretches: queue.Queue = queue.Queue()
        self._feeder = threading.Thread(target=self._feed, daemon=True)
        self._feeder.start()
        self._stretches.put((config, None if log is None else str(log), None if rrd is None else str(rrd)))
        try:
            self._expect("ready")
        except InputError:
            self._process.kill()
            self._errors.close()
            raise

    def due(self) -> bool:
        """Whether a stretch of :data:`STREAM_S` is waiting."""
        return self.sim.rows - self.sent >= self.stretch

    def send(self) -> None:
        """Hand the samples recorded since the last stretch to the writer (the feeding thread sends them)."""
        if self.sim.rows > self.sent:
            result = self.sim.result(since=self.sent)
            self.sent = self.sim.rows
            self._stretches.put(dataclasses.replace(result, config=None))

    def close(self) -> list[pathlib.Path]:
        """Hand over the rest, end the files and wait for them. Returns the paths written (the log's sidecar
        too; none where nothing was recorded). Raises InputError where the writer failed."""
        self.send()
        self._stretches.put(None)
        try:
            written = self._expect("done")
        finally:
            try:
                self._process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self._process.kill()
            self._errors.close()
        return [pathlib.Path(p) for p in written]

    def _feed(self) -> None:
        """The feeding thread: each stretch (and the configuration first, None last) to the writer's input."""
        try:
            while True:
                item = self._stretches.get()
                _send(self._process.stdin, item)
                if item is None:
                    break
            self._process.stdin.close()
        except (BrokenPipeError, OSError):  # the writer is gone: close() says why
            pass

    def _read_answers(self) -> None:
        try:
            while True:
                self._answers.put(_receive(self._process.stdout))
        except (EOFError, OSError, pickle.UnpicklingError):
            self._answers.put(("gone", None))

    def _expect(self, word: str):
        try:
            kind, value = self._answers.get(timeout=WRITER_TIMEOUT_S)
        except queue.Empty:
            self._process.kill()
            raise InputError(f"the session's log writer did not answer in {WRITER_TIMEOUT_S:g} s") from None
        if kind == "gone":
            self._errors.seek(0)
            last = (self._errors.read().decode(errors="replace").strip().splitlines() or ["no message"])[-1]
            raise InputError(f"the session's log writer stopped ({last})")
        if kind == "error":
            raise InputError(f"the session's log: {value}")
        return value


def _said(exc: Exception) -> str:
    """An error as one line: hexsim's own and the system's as they are, anything else with its kind."""
    return str(exc) if isinstance(exc, (InputError, OSError)) else f"{type(exc).__name__}: {exc}"


def _write_session(source, answers) -> None:
    """The writer: the configuration and paths, then each stretch appended to the files until None; answers
    ("ready", None), then ("done", paths) or ("error", what went wrong)."""
    os.nice(WRITER_NICE)
    config, log, rrd = _receive(source)
    from hexsim.outputs.logio import LogStream
    from hexsim.outputs.rerun_log import RerunStream

    streams = ([LogStream(log)] if log is not None else []) + ([RerunStream(rrd)] if rrd is not None else [])
    _send(answers, ("ready", None))
    failure = None
    while True:
        try:
            result = _receive(source)
        except EOFError:  # the server is gone without its last word: end the files with what came
            break
        if result is None:
            break
        if failure is None:
            try:
                for stream in streams:
                    stream.append(dataclasses.replace(result, config=config))
            except Exception as exc:  # the rest of the stretches still read, so the server's feeder never blocks
                failure = _said(exc)
    for stream in streams:
        try:
            stream.close()
        except Exception as exc:
            failure = failure or _said(exc)
    with contextlib.suppress(OSError):  # a server gone has no one to tell
        _send(answers, ("error", failure) if failure else ("done", [str(p) for s in streams for p in s.written]))


if __name__ == "__main__":
    _answers = os.fdopen(os.dup(1), "wb")  # the answers alone on the standard output: whatever else prints,
    os.dup2(2, 1)  # a library's notice, goes to the standard error
    sys.stdout = sys.stderr
    _write_session(sys.stdin.buffer, _answers)
