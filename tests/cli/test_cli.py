"""The command line as a user runs it: outputs, exit codes, one-line errors, no partial files."""

from __future__ import annotations

import json
import os
import pathlib
import re
import shutil
import statistics
import subprocess
import sys

import numpy as np
import pytest

from hexsim.cli import main
from hexsim.tables import read_numeric_csv


@pytest.fixture(scope="module")
def heave_outputs(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    code = main(["run", "heave", "--frequency", "1", "--duration", "4", "--quiet",
                 "--rrd", str(out / "out.rrd"), "--plot", str(out / "out.png"), "--json", str(out / "out.json"),
                 "--log", str(out / "log.csv")])
    return code, out


def test_run_writes_every_output(heave_outputs):
    code, out = heave_outputs
    assert code == 0
    report = json.loads((out / "out.json").read_text())
    for key in ("scenario", "duration_s", "fundamental", "noise_ratio", "peak_noise_g", "reversal_peaks",
                "max_tracking_error_m", "faults", "engine", "timestep_s"):
        assert key in report
    assert "realtime_factor" not in report and "wall_time_s" not in report  # same command, same bytes
    assert report["scenario"] == "heave" and report["duration_s"] == 4.0
    assert len(report["reversal_peaks"]) >= 2 and report["peak_noise_g"] > 0
    assert (out / "out.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rrd = (out / "out.rrd").stat().st_size
    assert 10_000 < rrd < 50e6 * 4 / 20  # < 50 MB for 20 s, pro rata
    assert not list(out.glob(".*.tmp"))


def test_log_follows_the_measurement_log_format(heave_outputs):
    _, out = heave_outputs
    cols = read_numeric_csv(out / "log.csv")
    side = json.loads((out / "log.json").read_text())
    assert side["system"] == "hexapod" and side["sample_rate_hz"] == pytest.approx(1000.0)
    assert side["controller"]["kp_V_per_m"] == 200.0
    for i in range(1, 7):
        for c in ("ref_m", "valve_cmd_V", "pos_m", "p1_Pa"):
            assert f"leg{i}_{c}" in cols
    assert np.all((cols["leg1_pos_m"] > 0) & (cols["leg1_pos_m"] < 0.2))
    assert np.median(cols["platform_acc_z_mps2"]) == pytest.approx(9.81, abs=0.2)  # specific force incl. g
    assert np.all(cols["ps_Pa"] == 7.0e6)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["run", "heave", "--amplitude", "0.15", "--duration", "30"], r"leg\d length .* outside its stroke"),
        (["run", "heave", "--frequency", "400"], "Nyquist"),
        (["run", "heave", "--duration", "1"], "too short"),
        (["run", "hover"], "unknown scenario 'hover'"),
        (["run", "file:/nonexistent/profile.csv"], "no such file"),
        (["run", "heave", "--duration", "8", "--json", "/nonexistent/dir/out.json"], "does not exist"),
        (["run", "heave", "--duration", "8", "--plot", "out.jpg"], "expected a .png or .pdf or .svg"),
        (["run", "heave", "--duration", "8", "--json", "c.json", "--log", "c.csv"], "overwritten by the sidecar"),
        (["tune", "--check", __file__, "--compensator", "none", "--draws", "-1"], "--draws must be 0 or more, got -1"),
        (["tune", "--out", "tuned.json", "--draws", "-2"], "tune: --draws must be 0 or more, got -2"),
    ],
)
def test_bad_input_gives_one_line_and_exit_2(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("hexsim: error:") and len(err.splitlines()) == 1
    assert re.search(message, err), err


def test_bad_option_value_exits_2_without_traceback(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "hexsim.cli", "run", "heave", "--duration", "abc"],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and "'abc' is not a number" in proc.stderr


def test_bad_scenario_file_names_column_and_row(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("time_s,dof_ref_z_m\n0,0\n0.01,0.001\n0.02,oops\n")
    with pytest.raises(Exception, match=r"column 'dof_ref_z_m', row 4: 'oops' is not a number"):
        main_raise(["run", f"file:{path}"])


def main_raise(argv):
    """Run the CLI's command without the error-to-exit-code translation."""
    from hexsim.cli import build_parser, cmd_run

    return cmd_run(build_parser().parse_args(argv))


def test_rrd_is_a_valid_rerun_recording(heave_outputs):
    _, out = heave_outputs
    rerun = pathlib.Path(sys.executable).with_name("rerun")
    if not rerun.exists():
        rerun = shutil.which("rerun")
    assert rerun, "rerun-sdk installs the rerun executable"
    proc = subprocess.run([str(rerun), "rrd", "verify", str(out / "out.rrd")], capture_output=True, text=True,
                          timeout=120, env={**os.environ, "RERUN_ANALYTICS": "off"})
    assert proc.returncode == 0, proc.stderr
    assert "verified without error" in proc.stdout + proc.stderr


def test_run_with_a_compensator_reports_its_parameters(tmp_path):
    out = tmp_path / "buffered.json"
    assert main(["run", "actuator", "--duration", "8", "--compensator", "buffered", "--warm-up", "15", "--quiet",
                 "--json", str(out), "--plot", str(tmp_path / "b.png")]) == 0
    report = json.loads(out.read_text())
    assert report["compensator"] == "buffered"
    assert set(report["compensator_parameters"]) == {"a", "b", "c", "s"}
    assert report["compensator_parameters"]["a"][0] > 0  # the first 3 s buffer has been used
    assert report["oil_temperature_C"] == pytest.approx([35.0, 50.0], abs=0.1)


def test_compare_prints_a_league_table_and_writes_json_and_png(tmp_path, capsys):
    code = main(["compare", "actuator", "--duration", "6", "--compensators", "buffered,oracle", "--jobs", "2",
                 "--json", str(tmp_path / "league.json"), "--plot", str(tmp_path / "league.png")])
    assert code == 0
    out = capsys.readouterr().out
    for name in ("none", "buffered", "oracle"):
        assert re.search(rf"^{name}\s", out, re.M), out
    league = json.loads((tmp_path / "league.json").read_text())
    assert set(league["compensators"]) == {"none", "buffered", "oracle"}
    assert league["compensators"]["none"]["reversal_peak_reduction_pct"] == 0.0
    assert (tmp_path / "league.png").read_bytes()[:4] == b"\x89PNG"


def test_compare_runs_a_tuned_file_beside_the_built_ins(tmp_path, capsys):
    """A tuned file in --compensators runs with its own settings, labelled by its name: the buffered compensator
    with the built-in's settings gives the built-in's figures to the last digit, one with a 1.5 s buffer others."""
    for name, settings in (("same.json", {}), ("short.json", {"buffer_time": 1.5})):
        (tmp_path / name).write_text(json.dumps({"format": "hexsim-tuned/1", "compensator": "buffered",
                                                 "settings": settings}))
    code = main(["compare", "actuator", "--duration", "6", "--jobs", "2", "--json", str(tmp_path / "league.json"),
                 "--compensators", f"buffered,{tmp_path / 'same.json'},{tmp_path / 'short.json'}"])
    assert code == 0
    assert re.search(r"^short\.json \(buffered\)\s", capsys.readouterr().out, re.M)
    league = json.loads((tmp_path / "league.json").read_text())["compensators"]
    peak = {k: v["mean_reversal_peak"] for k, v in league.items()}
    assert peak["same.json (buffered)"] == peak["buffered"] != peak["short.json (buffered)"]


def test_compare_names_a_tuned_file_it_cannot_read(tmp_path, capsys):
    (tmp_path / "bad.json").write_text(json.dumps({"format": "hexsim-tuned/1", "compensator": "magic"}))
    assert main(["compare", "actuator", "--compensators", f"{tmp_path / 'bad.json'}"]) == 2
    err = capsys.readouterr().err
    assert "bad.json" in err and "'magic'" in err and "Traceback" not in err


def test_compare_refuses_an_unknown_compensator(capsys):
    assert main(["compare", "heave", "--compensators", "buffered,magic"]) == 2
    assert "unknown compensator 'magic'" in capsys.readouterr().err


def test_scenario_file_saved_with_a_byte_order_mark_is_read(tmp_path):
    from helpers import write_heave_pitch_profile

    from hexsim.control.scenario import make_scenario

    path = write_heave_pitch_profile(tmp_path / "excel.csv", 6.0, 0.03)
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    assert make_scenario(f"file:{path}").axis_name == "z"


def test_bench_prints_ratios_against_bare_mj_step(tmp_path, capsys):
    out = tmp_path / "bench.json"
    assert main(["bench", "--duration", "1.5", "--repeats", "1", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert set(doc["cases"]) == {"bare_mj_step", "bare_mj_step_platform", "hexapod_platform",
                                 "hexapod_platform_uncompensated", "hexapod_full", "hexapod_python", "hexapod_uncompensated",
                                 "hexapod_fast", "actuator_full", "actuator_fast", "actuator_bare_fast",
                                 "replay_kernel"}
    cases = doc["cases"]
    assert all(c["wall_per_sim_s"] > 0 and c["realtime_factor"] == 1 / c["wall_per_sim_s"] for c in cases.values())
    # the ratios are of the timings in the same document, each case over the baseline timed right before
    # it (no timing is asserted: it is the machine's)
    for name, c in cases.items():
        assert c["to_bare"] == (1.0 if name == "bare_mj_step" else
                                statistics.median(w / b for w, b in c["walls_with_baseline_s"]))
    assert doc["ratio_hexapod_full_to_bare"] == cases["hexapod_full"]["to_bare"]
    assert doc["ratio_actuator_fast_to_bare_fast"] == (cases["actuator_fast"]["wall_per_sim_s"]
                                                       / cases["actuator_bare_fast"]["wall_per_sim_s"])
    startup = doc["startup"]  # hexsim --help against python -c pass, a ratio (not asserted: the machine's)
    assert startup["ratio"] == startup["help_s"] / startup["python_s"] and startup["python_s"] > 0
    printed = capsys.readouterr().out
    assert "hexapod_full / bare_mj_step" in printed and "actuator_fast / actuator_bare_fast" in printed
    assert "hexsim --help" in printed
    assert main(["bench", "--repeats", "0"]) == 2


def test_same_command_twice_writes_the_same_bytes(tmp_path):
    """Determinism (issue 6): JSON report, CSV log and its sidecar are bit-identical between two runs."""
    outputs = []
    for name in ("a", "b"):
        d = tmp_path / name
        d.mkdir()
        assert main(["run", "actuator", "--duration", "2", "--frequency", "2", "--compensator", "buffered",
                     "--buffer-time", "0.5", "--quiet", "--json", str(d / "run.json"), "--log", str(d / "log.csv")]) == 0
        outputs.append([(d / f).read_bytes() for f in ("run.json", "log.csv", "log.json")])
    assert outputs[0] == outputs[1]


def test_each_run_is_a_recording_of_its_own_with_the_bump_on_its_own_axis(heave_outputs, tmp_path):
    """Two recordings of the same run opened together stay two (`rerun a.rrd b.rrd`); the bump has its
    own entity (and panel); an uncompensated run has no compensator entity. Read back with `rerun rrd
    print`, the format's own tool."""
    _, out = heave_outputs
    rerun = pathlib.Path(sys.executable).with_name("rerun")
    rerun = str(rerun) if rerun.exists() else shutil.which("rerun")
    env = {**os.environ, "RERUN_ANALYTICS": "off"}

    def printed(path):
        proc = subprocess.run([rerun, "rrd", "print", "--verbose", str(path)], capture_output=True, text=True,
                              timeout=120, env=env)
        assert proc.returncode == 0, proc.stderr
        return proc.stdout + proc.stderr

    first = printed(out / "out.rrd")
    ids = set(re.findall(r'"(hexsim-heave-[^"]+)"', first))
    assert len(ids) == 1, ids
    assert "/bump/noise" in first and "/compensator" not in first
    # the 3D view is the MJCF's own geoms at the run's body poses (issue 16), not hard-coded shapes
    assert "/world/platform@Transform3D" in first and "/world/rod6@Transform3D" in first
    assert re.search(r"/world/platform/geom\d+@Boxes3D", first) and re.search(r"/world/rod1/geom\d+@Cylinders3D", first)
    from types import SimpleNamespace

    from hexsim.control.scenario import make_scenario
    from hexsim.engine.config import RunConfig
    from hexsim.outputs.rerun_log import recording_id

    run = SimpleNamespace(config=RunConfig(make_scenario("heave")))
    assert recording_id(run) != recording_id(run)


def test_modes_prints_and_writes_the_oil_spring_modes(tmp_path, capsys):
    out = tmp_path / "modes.json"
    assert main(["modes", "--payload", "200@0.3,0", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "oil-spring modes of the hexapod" in text and "200 kg at (0.3, 0, 0)" in text
    modes = json.loads(out.read_text())["modes"]
    assert len(modes) == 6 and all(m["frequency_hz"] > 0 for m in modes)
    # 200 kg more than the nominal 600 kg lowers every mode (same springs, more inertia)
    assert main(["modes"]) == 0
    nominal = [float(line.split()[1]) for line in capsys.readouterr().out.splitlines()[2:]]
    assert all(m["frequency_hz"] < f for m, f in zip(modes, nominal))


def test_json_dash_writes_the_document_to_stdout_and_the_summary_to_stderr(capsys):
    # issue 16: `--json -` for pipes (`hexsim modes --json - | jq`); the JSON carries the software versions
    assert main(["modes", "--json", "-"]) == 0
    out, err = capsys.readouterr()
    doc = json.loads(out)
    assert len(doc["modes"]) == 6
    assert set(doc["software"]) >= {"hexsim", "mujoco", "numpy", "python"}
    assert "oil-spring modes of the hexapod" in err and "wrote <stdout>" in err


@pytest.mark.parametrize("suffix, magic", [(".svg", b"<?xml"), (".pdf", b"%PDF")])
def test_plot_writes_the_format_its_suffix_names(heave_run, tmp_path, suffix, magic):
    from hexsim.outputs.plotting import plot_run
    from hexsim.studies.metrics import run_smoothness

    path = tmp_path / f"run{suffix}"
    plot_run(path, heave_run, run_smoothness(heave_run))
    assert path.read_bytes()[:len(magic)] == magic


def test_importing_hexsim_never_switches_the_matplotlib_backend():
    # issue 16: a notebook user's backend stays what they chose; the figures are drawn without pyplot
    code = ("import matplotlib; matplotlib.use('svg'); "
            "import hexsim.outputs.plotting, hexsim.measured.validation, hexsim.measured.friction_id, hexsim.cli, hexsim.outputs.rerun_log; "
            "assert matplotlib.get_backend() == 'svg', matplotlib.get_backend()")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_the_3d_scene_closes_every_leg_at_its_platform_anchor(heave_run):
    # the recording's body poses: platform from the recorded pose, legs turned towards their anchors and
    # extended by the recorded piston positions; forward kinematics must land each rod tip on its anchor
    import mujoco

    from hexsim.outputs.rerun_log import scene_qpos
    from hexsim.plant.model import load_model

    m = load_model("hexapod")
    d = mujoco.MjData(m)
    rows = np.arange(0, len(heave_run.t), 250)
    gaps = []
    for q in scene_qpos(m, heave_run, rows):
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        gaps += [np.linalg.norm(d.site(f"rod{i}_tip").xpos - d.site(f"platform_anchor{i}").xpos) for i in range(1, 7)]
    assert max(gaps) < 1e-6  # the connect constraints hold to ~0.01 µm in the run itself
