"""``hexsim`` command line: ``hexsim run SCENARIO [options]``.

One module per command (``hexsim/cli/run.py``: ``hexsim run``; ``cue_tune.py``: ``hexsim cue-tune``; …), each
with its parser (``add_<command>``) and its call (``cmd_<command>``: parse, call the package, print); the
options they share in :mod:`hexsim.cli.options`; here the parser of them all and :func:`main`.

Bad options and unreachable setpoints give one line on stderr and exit code 2, never a traceback and
never a half-written output file.
"""

from __future__ import annotations

import os

# One BLAS thread for the hexsim command (unless the user's environment sets one), before numpy loads:
# hexsim's matrices are small, and OpenBLAS's second thread only spins, beside hexsim's own worker
# processes most of all. Measured on 2 cores: R1's calibration (two 20 s logs) 46.6 s wall, 57 s of CPU with
# two BLAS threads, 43.8 s and 42 s with one (the calibrated file the same to 2e-11); a hexapod validation
# with two workers 36.0 -> 30.9 s wall. A notebook importing hexsim keeps its own setting.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import sys  # noqa: E402
import warnings  # noqa: E402

from hexsim import __version__
from hexsim.cli.accept import add_accept, cmd_accept
from hexsim.cli.bench import add_bench, cmd_bench
from hexsim.cli.calibrate import add_calibrate, cmd_calibrate
from hexsim.cli.compare import add_compare, cmd_compare
from hexsim.cli.cue_tune import add_cue_tune, cmd_cue_tune
from hexsim.cli.fmu import add_fmu, cmd_fmu
from hexsim.cli.friction import add_friction, cmd_friction
from hexsim.cli.machine import add_machine, cmd_machine
from hexsim.cli.modes import add_modes, cmd_modes
from hexsim.cli.options import workers
from hexsim.cli.run import add_run, cmd_run
from hexsim.cli.serve import add_serve, cmd_serve
from hexsim.cli.sweep import add_sweep, cmd_sweep
from hexsim.cli.tune import add_tune, cmd_tune
from hexsim.cli.validate import add_validate, cmd_validate
from hexsim.errors import HexsimError, ModelNote
from hexsim.tables import StdoutTarget


def build_parser() -> argparse.ArgumentParser:
    """The command line: ``hexsim run|compare|tune|validate|friction|calibrate|sweep|modes|accept|bench|machine|serve|fmu|cue-tune``
    (``--help`` on each)."""
    parser = argparse.ArgumentParser(
        prog="hexsim",
        description="Six-DOF hydraulic motion platform simulator (Micro Motion System): the reversal bump and its compensation.",
    )
    parser.add_argument("--version", action="version", version=f"hexsim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    add_run(sub)
    add_compare(sub)
    add_tune(sub)
    add_validate(sub)
    add_friction(sub)
    add_calibrate(sub)
    add_sweep(sub)
    add_modes(sub)
    add_accept(sub)
    add_bench(sub)
    add_machine(sub)
    add_serve(sub)
    add_fmu(sub)
    add_cue_tune(sub)
    return parser


def _show_note(message, category, filename, lineno, file=None, line=None) -> None:
    """A :class:`~hexsim.errors.ModelNote` as one line ``hexsim: note: …`` on stderr; other warnings as Python
    shows them."""
    if issubclass(category, ModelNote):
        print("hexsim: note: " + " ".join(str(message).split()), file=sys.stderr)
    else:
        sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    streams = contextlib.nullcontext()
    if str(getattr(args, "json", None)) == "-":  # the JSON document on stdout, the human-readable lines on stderr
        args.json = StdoutTarget(sys.stdout)
        streams = contextlib.redirect_stdout(sys.stderr)
    try:
        with streams, workers(args), warnings.catch_warnings():
            warnings.simplefilter("default", ModelNote)  # each note once
            warnings.showwarning = _show_note
            commands = {"run": cmd_run, "compare": cmd_compare, "validate": cmd_validate, "friction": cmd_friction,
                        "sweep": cmd_sweep, "modes": cmd_modes, "bench": cmd_bench, "machine": cmd_machine,
                        "calibrate": cmd_calibrate, "accept": cmd_accept, "tune": cmd_tune, "serve": cmd_serve,
                        "fmu": cmd_fmu, "cue-tune": cmd_cue_tune}
            return commands[args.command](args)
    except HexsimError as exc:
        # one line, whatever a file put into the message (a key or a value with a line break in it)
        print("hexsim: error: " + " ".join(str(exc).splitlines()), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("hexsim: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # stdout closed early (e.g. piped into head): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0

