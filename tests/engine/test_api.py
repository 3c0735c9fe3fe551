"""The public Python face (hexsim/__init__.py): the README's example runs, a run can be stepped, a user's
own compensator plugs in, and importing hexsim stays cheap."""

from __future__ import annotations

import pathlib
import re
import subprocess
import sys

import numpy as np
import pytest

import hexsim
from hexsim.errors import InputError

README = pathlib.Path(__file__).resolve().parents[2] / "README.md"


def _readme_python_blocks() -> list[str]:
    text = README.read_text()
    section = text[text.index("### Python"):]
    section = section[: section.index("\n## ")]
    return re.findall(r"```python\n(.*?)```", section, re.S)


def test_the_readme_python_examples_run(capsys):
    """The README's Python section, block by block in one namespace: the first prints the buffered
    compensator's noise ratio, the second a user compensator's mean reversal peak."""
    blocks = _readme_python_blocks()
    assert len(blocks) == 2 and len(blocks[0].strip().splitlines()) <= 10
    namespace: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), namespace)
    noise_ratio = float(capsys.readouterr().out.split()[-1])
    assert 0.0 < noise_ratio < 0.2  # buffered: far below the uncompensated 0.38
    exec(compile(blocks[1], "README.md", "exec"), namespace)
    assert float(capsys.readouterr().out.split()[-1]) > 0.0


@pytest.mark.parametrize("engine", ["native", "python"])
def test_a_stepped_run_equals_the_run_in_one_call(engine):
    config = hexsim.RunConfig(hexsim.Scenario.sine("heave", frequency=2.0, duration=1.5), compensator="buffered",
                              engine=engine, compensator_settings=hexsim.CompensatorSettings(buffer_time=0.4))
    whole = hexsim.simulate(config)
    sim = hexsim.Simulator(config)
    sim.step(0.5)
    part = sim.result()
    assert sim.time == pytest.approx(0.5) and part.t.size == 500 and part.t[-1] == pytest.approx(0.499)
    np.testing.assert_array_equal(part.acc, whole.acc[:500])
    sim.step(0.3).step(0.3)
    stepped = sim.run()
    assert sim.done
    for name in ("t", "y", "u_v", "u_c", "p1", "acc", "pose"):
        np.testing.assert_array_equal(getattr(stepped, name), getattr(whole, name), err_msg=name)
    for key, value in whole.compensator_state.items():
        np.testing.assert_array_equal(stepped.compensator_state[key], value, err_msg=key)


class ConstantOffset(hexsim.Compensator):
    """A user's compensator: adds 0.05 V on leg 1 and reports it."""

    name = "constant-offset"

    def update(self, u_v, y_measured):
        u_c = np.zeros(self.n_legs)
        u_c[0] = 0.05
        return u_c

    def state(self):
        return {"offset": np.array([0.05] + [0.0] * (self.n_legs - 1))}


def test_a_user_compensator_class_runs_in_the_loop():
    config = hexsim.RunConfig(hexsim.Scenario.sine("heave", frequency=2.0, duration=1.5), compensator=ConstantOffset)
    result = hexsim.simulate(config)
    assert config.compensator_name == "constant-offset"
    assert np.all(result.u_c[:, 0] == 0.05) and np.all(result.u_c[:, 1:] == 0.0)
    assert np.all(result.compensator_state["offset"][:, 0] == 0.05)
    plain = hexsim.simulate(hexsim.RunConfig(config.scenario))
    # the offset reaches the valve and the P loop takes it out: for the same flow u_p must drop by 0.05 V,
    # so leg 1 settles 0.05 V / K_p = 0.25 mm further out than without it
    shift = np.median(result.y[500:, 0] - plain.y[500:, 0])
    assert shift == pytest.approx(0.05 / config.controller.kp, rel=0.3)
    with pytest.raises(InputError, match="compensator must be a name or a Compensator class"):
        hexsim.RunConfig(config.scenario, compensator=3)


def test_a_scenario_can_be_named_as_on_the_command_line():
    assert hexsim.RunConfig("roll").scenario == hexsim.Scenario.sine("roll")
    assert hexsim.RunConfig("actuator").scenario.system == "actuator"
    with pytest.raises(InputError, match="unknown scenario 'hover'"):
        hexsim.RunConfig("hover")
    with pytest.raises(InputError, match="scenario must be a Scenario or a scenario name, got 3"):
        hexsim.RunConfig(3)


def test_sweep_varies_parameters_by_name_and_refuses_unknown_ones():
    from hexsim.studies.sweeps import vary

    base = hexsim.RunConfig(hexsim.Scenario.sine("heave", frequency=2.0, duration=1.5))
    c = vary(base, {"kp": 250.0, "bulk_modulus": 1.2e9, "frequency": 4.0, "seed": 3, "buffer_time": 1.0})
    assert (c.controller.kp, c.hydraulics.bulk_modulus, c.scenario.frequency, c.seed) == (250.0, 1.2e9, 4.0, 3)
    assert c.compensator_settings.buffer_time == 1.0 and c.scenario.duration == 1.5
    with pytest.raises(InputError, match="'colour' is not a scenario keyword"):
        vary(base, {"colour": "red"})


def test_a_run_holds_its_whole_machine_and_edits_it_one_way(tmp_path):
    """RunConfig carries the Machine (not its parts as loose fields): the parts are read from it, a name or a
    file is read once, ``with_machine`` is the one edit, and the outputs name what the run was on."""
    from hexsim.outputs.logio import sidecar
    from hexsim.plant.machine import dump
    from hexsim.studies.sweeps import vary

    servo = hexsim.load_machine("servo_cylinder")
    by_name = hexsim.RunConfig("actuator", "servo_cylinder")
    assert by_name.machine == servo and by_name.hydraulics is by_name.machine.hydraulics
    assert (by_name.controller, by_name.effects, by_name.geometry) == (servo.controller, servo.effects, None)
    assert by_name.machine_label == by_name.machine_spec == "servo_cylinder"
    path = tmp_path / "rig.json"
    path.write_text(dump(servo.document()))
    from_file = hexsim.RunConfig.from_machine(path, "actuator")
    assert from_file.machine_label == from_file.machine_spec == str(path)
    assert from_file.hydraulics == servo.hydraulics
    # one way to edit it: the run's machine changes, the file it came from does not
    stiffer = by_name.with_machine(hydraulics=by_name.hydraulics.replace(bulk_modulus=1.2e9))
    assert stiffer.hydraulics.bulk_modulus == 1.2e9 and servo.hydraulics.bulk_modulus != 1.2e9
    assert stiffer.machine_label == "servo_cylinder with parameters changed" and stiffer.machine_spec is None
    assert vary(by_name, {"bulk_modulus": 1.2e9}).machine == stiffer.machine
    # the default is the built-in; an edited built-in's log does not claim to be the built-in
    default = hexsim.RunConfig(hexsim.Scenario.sine("heave", frequency=3.0, duration=1.5))
    assert default.machine == hexsim.Machine() and default.machine_label == "micro_motion_system"
    edited = hexsim.simulate(default.with_machine(controller=default.controller.replace(kp=250.0)))
    assert "machine" not in sidecar(edited) and sidecar(edited)["controller"]["kp_V_per_m"] == 250.0
    assert sidecar(hexsim.simulate(default))["machine"] == "micro_motion_system"
    # a leg changed for the run goes on top of the machine's own legs
    legs = (hexsim.LegChange.of(2, leakage=1e-12),)
    assert hexsim.RunConfig("heave", leg_changes=legs).legs == legs
    with pytest.raises(InputError, match="machine must be a Machine, a built-in's name or a machine file, got 3"):
        hexsim.RunConfig("heave", 3)
    with pytest.raises(InputError, match="no such machine file"):
        hexsim.RunConfig("heave", str(tmp_path / "missing.json"))


def test_import_hexsim_is_quick_and_loads_no_simulator():
    code = "import sys, hexsim; print(any(m in sys.modules for m in ('mujoco', 'numba', 'scipy')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
    assert set(hexsim.__all__) >= {"simulate", "Simulator", "RunConfig", "Scenario", "HydraulicParams", "Effects",
                                   "smoothness", "read_log", "validate", "compare", "sweep"}


def test_the_command_line_answers_help_version_and_bad_options_before_loading_the_simulator():
    """`hexsim --help`, `--version` and a refused option never import MuJoCo, numba or scipy (that is
    what made them take 4–10 s); `python -m hexsim` is the same command."""
    from importlib.metadata import version

    code = ("import sys, contextlib, io\n"
            "from hexsim.cli import main\n"
            "err = io.StringIO()\n"
            "with contextlib.redirect_stderr(err):\n"
            "    rc = main(['run', 'bounce'])\n"
            "heavy = [m for m in ('mujoco', 'numba', 'scipy', 'matplotlib', 'rerun') if m in sys.modules]\n"
            "print(rc, heavy, err.getvalue().strip())\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.startswith("2 [] hexsim: error: unknown scenario 'bounce'")
    shown = subprocess.run([sys.executable, "-m", "hexsim", "--version"], capture_output=True, text=True, check=True)
    assert shown.stdout.strip() == f"hexsim {version('hexsim')}" == f"hexsim {hexsim.__version__}"
