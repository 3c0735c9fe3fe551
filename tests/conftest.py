"""Shared simulation runs (each is seconds of wall time, so they are computed once per session)."""

from __future__ import annotations

import os

# One BLAS thread per test process, set before numpy loads (here, in the controller, and inherited by the
# xdist workers it starts): the suite runs two workers on two cores, and OpenBLAS's extra threads spin
# waiting for work hexsim's small matrices do not split. Measured on a hexapod validation: 63 s of CPU
# with two BLAS threads, 44 s with one, the same wall time.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import pytest  # noqa: E402

from hexsim.control.scenario import make_scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import simulate
from hexsim.plant.machine import Machine
from hexsim.plant.params import ControllerParams, HydraulicParams


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config):
    """Two pytest-xdist workers, one test file each, when xdist is installed and no ``-n`` was given: the
    long compensation runs overlap with the rest on the 2-core CI machine. Without xdist (or with
    ``-n 0``, or ``-p no:xdist``) the suite runs in one process; nothing is forced on the command line."""
    if (hasattr(config, "workerinput") or getattr(config.option, "numprocesses", 0) is not None
            or config.getoption("usepdb", False)):
        return None
    config.option.numprocesses, config.option.dist = 2, "loadfile"
    config.option.loadscopereorder = False  # the files in the order below, not by their number of tests
    return None


#: The longest test files, longest first (their setups and calls summed, `pytest --durations=0` on 2 cores at
#: 27f3f4f: the independent hexapod's calibration 225 s, the hexapod validations 163, the transients' calibration
#: 149, feedforward 117, the curve calibration 101, calibration 70, validation 34, verdicts 31, the command line 27,
#: commissioning 27, the flow curves 4; the tuning on the 4-way axis, added later, 40; the whole suite 20 CPU minutes
#: on two workers that finish within a minute of each other). Handed out first, the two workers finish together; in
#: the alphabetical order the validation files came last and one worker ran them alone for minutes. They are also the
#: files marked ``slow``. The transients' calibration goes before the hexapod's: the other worker starts with
#: test_serve.py (:data:`REAL_TIME_FIRST`), which compiles the hexapod's kernel (numba, some 20 s on a fresh
#: install); beside it this one compiles the single actuator's replay, and each then loads the other's from numba's
#: cache, where both had compiled the hexapod's kernel at once.
LONGEST_FIRST = ("test_calibration_transients.py", "test_calibration_hexapod.py", "test_hexapod_validation.py",
                 "test_feedforward.py", "test_calibration_curve.py", "test_calibration.py",
                 "test_tuning_on_the_machine.py", "test_validation.py", "test_verdicts.py", "test_cli.py",
                 "test_commissioning.py", "test_flow_curves.py")


#: Files that run a session paced to the wall clock (hexsim serve on localhost), handed out before the longest: the
#: other worker then starts the independent hexapod's calibration, one process. Later, beside a validation's two
#: worker processes, a served session fell behind the clock and the host saw the catch-up's jerks (the specific
#: force's correlation with the heave 0.32 in one CI run of ten; 0.38 with four busy processes beside it, 0.95 with
#: two). Since the controller catches up through the packets queued in a stall (hexsim.interfaces.operating_modes),
#: SIGSTOPs of the whole process of up to 0.8 s leave the served motion as it was without them.
REAL_TIME_FIRST = ("test_serve.py",)


def pytest_collection_modifyitems(config, items):
    """The files of :data:`REAL_TIME_FIRST`, then those of :data:`LONGEST_FIRST`, in that order, then the rest as
    collected (a stable sort: each file's tests keep their order); the longest files' tests marked ``slow``
    (``pytest -m "not slow"`` leaves them out)."""
    rank = {name: i for i, name in enumerate(REAL_TIME_FIRST + LONGEST_FIRST)}
    for item in items:
        if item.path.name in LONGEST_FIRST:
            item.add_marker(pytest.mark.slow)
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


#: The seed's Simulink model (seed Fig. 3.3) has a continuous-time P controller and no sensor noise;
#: the seed checks run the controller at the 10 kHz physics rate to match it.
SEED_CONTROLLER = ControllerParams(rate_hz=10_000.0, position_noise=0.0)


@pytest.fixture(scope="session")
def actuator_sharp():
    sc = make_scenario("actuator", duration=6.0)
    machine = Machine(hydraulics=HydraulicParams(flow_area="sharp"), controller=SEED_CONTROLLER)
    return simulate(RunConfig(sc, machine, record_rate_hz=10_000.0))


@pytest.fixture(scope="session")
def actuator_smooth():
    sc = make_scenario("actuator", duration=6.0)
    machine = Machine(hydraulics=HydraulicParams(flow_area="smooth"), controller=SEED_CONTROLLER)
    return simulate(RunConfig(sc, machine, record_rate_hz=10_000.0))


@pytest.fixture(scope="session")
def heave_run():
    """Uncompensated hexapod heave, the product's default controller (500 Hz, ZOH, 1 µm sensor noise)."""
    return simulate(RunConfig(make_scenario("heave", duration=8.0)))

