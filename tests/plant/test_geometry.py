"""Issue 29: the hexapod's geometry as data, a second geometry, a user's own MJCF, under every command.

The hand calculations here use the machine file's numbers with their own trigonometry (no hexsim
kinematics): a second geometry's statics against the forces MuJoCo needs to hold it, its inverse and
forward kinematics, a user MJCF's heave mode against the oil columns' stiffness.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import pathlib
import re
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from hexsim.errors import InputError
from hexsim.plant.machine import (
    Machine,
    dump,
    load_machine,
    machine_from_document,
    read_machine,
)
from hexsim.plant.model import PlantIndex, load_model, reset_neutral

ROOT = pathlib.Path(__file__).resolve().parents[2]

#: sha256 over the compiled Micro Motion System's geometry and masses (full and platform-only models, the
#: arrays of :data:`FINGERPRINT_FIELDS`) as hexsim compiled it before the geometry was data (commit 0e0246c,
#: MuJoCo 4.0.0): the model from the machine file must be the same to the bit
MICRO_MOTION_SYSTEM_SHA256 = "dedb3b2640570c317f8965bfdb542586eaf23d96eb4805db3cd707b1103b8bd8"
FINGERPRINT_FIELDS = ("body_pos", "body_quat", "body_ipos", "body_iquat", "body_mass", "body_inertia", "jnt_pos",
                      "jnt_axis", "jnt_range", "jnt_solref", "site_pos", "eq_data", "key_qpos", "qpos0", "numeric_data")


def _fingerprint(geometry) -> str:
    h = hashlib.sha256()
    for form in ("full", "platform"):
        m = load_model("hexapod", form, geometry=geometry)
        for name in FINGERPRINT_FIELDS:
            h.update(np.ascontiguousarray(getattr(m, name)).tobytes())
    return h.hexdigest()


def _mms_from_file(tmp_path):
    path = tmp_path / "mms.json"
    path.write_text(dump(Machine().document()))
    return read_machine(path).geometry


def test_micro_motion_system_from_its_machine_file_is_the_default_model_to_the_bit(tmp_path):
    """The built-in's machine file, written and read back, builds every compiled array of both formulations
    equal to the default's."""
    geometry = _mms_from_file(tmp_path)
    for form in ("full", "platform"):
        built, default = load_model("hexapod", form, geometry=geometry), load_model("hexapod", form)
        for name in dir(built):
            value = getattr(built, name)
            if isinstance(value, np.ndarray):
                np.testing.assert_array_equal(value, getattr(default, name), err_msg=f"{form} {name}")


@pytest.mark.skipif(mujoco.__version__ != "4.0.0", reason="the fingerprint was taken with MuJoCo 4.0.0")
def test_micro_motion_system_from_its_machine_file_is_the_model_of_before_to_the_bit(tmp_path):
    """The model from the machine file is the one hexsim compiled before its geometry was data."""
    assert _fingerprint(_mms_from_file(tmp_path)) == MICRO_MOTION_SYSTEM_SHA256


def _hand_joints(g) -> tuple[np.ndarray, np.ndarray, float]:
    """Base joints (world), platform joints (platform frame) and the neutral platform height, from the
    machine file's circle numbers by hand."""
    rad = np.pi / 180.0
    base = np.array([[g.base_radius_m * np.cos(a * rad), g.base_radius_m * np.sin(a * rad), g.base_height_m]
                     for a in g.base_angles_deg])
    plat = np.array([[g.platform_radius_m * np.cos(a * rad), g.platform_radius_m * np.sin(a * rad), 0.0]
                     for a in g.platform_angles_deg])
    length = g.retracted_length_m + g.stroke_m / 2
    dx, dy = plat[0, 0] - base[0, 0], plat[0, 1] - base[0, 1]
    return base, plat, g.base_height_m + np.sqrt(length**2 - dx**2 - dy**2)


def test_second_geometry_statics_equal_jt_f_by_hand():
    """large_motion_base at its neutral pose: the leg forces f that hold the full MuJoCo model at rest
    (hexsim's static solve on the model's own mobility) solve Jᵀ f = w by hand, with J's columns
    (n_i; (a_i - c) × n_i) from the file's joint circles, and w the platform's weight plus what each leg
    hangs on it: its rod's weight along it and (S/L) g⊥ across it (S the barrel's and rod's first moment
    about the base joint; a leg is a two-force member plus its own weight)."""
    from hexsim.engine.config import static_leg_forces

    machine = load_machine("large_motion_base")
    g = machine.geometry
    assert g.base_radius_m > 2 * 0.6 and g.platform_mass_kg > 2 * 600  # a different size, not the built-in
    base, plat, z = _hand_joints(g)
    m = load_model("hexapod", "full", geometry=g)
    d = mujoco.MjData(m)
    reset_neutral(m, d)
    forces = static_leg_forces(m, d, PlantIndex.from_model(m))

    gravity = np.array([0.0, 0.0, -9.81])
    assert np.allclose(m.opt.gravity, gravity)
    anchors = plat + [0.0, 0.0, z]
    com = np.array(g.platform_com_m) + [0.0, 0.0, z]
    legs = anchors - base
    length = np.linalg.norm(legs, axis=1)
    n = legs / length[:, None]
    y = g.stroke_m / 2
    first_moment = g.barrel_mass_kg * g.barrel_com_m + g.rod_mass_kg * (g.retracted_length_m + y - g.rod_com_m)
    carried = np.array([g.rod_mass_kg * (gravity @ u) * u + first_moment / L * (gravity - (gravity @ u) * u)
                        for u, L in zip(n, length)])  # what leg i hangs on the platform besides its force
    jt = np.vstack([n.T, np.cross(anchors - com, n).T])
    w = -np.concatenate([g.platform_mass_kg * gravity + carried.sum(axis=0),
                         np.cross(anchors - com, carried).sum(axis=0)])
    by_hand = np.linalg.solve(jt, w)
    np.testing.assert_allclose(forces, by_hand, rtol=2e-3)
    assert by_hand.min() > 0.0  # every leg pushes


def test_second_geometry_inverse_and_forward_kinematics_round_trip():
    """large_motion_base: the leg lengths of the inverse kinematics are the hand geometry's |p + R b - a|,
    and the forward kinematics recovers each pose from them to 1e-9."""
    from hexsim.control.kinematics import HexapodGeometry, rotation_matrices

    g = load_machine("large_motion_base").geometry
    geom = HexapodGeometry.from_model(load_model("hexapod", geometry=g))
    base, plat, z = _hand_joints(g)
    rng = np.random.default_rng(29)
    poses = np.column_stack([rng.uniform(-0.1, 0.1, (20, 3)), rng.uniform(-0.08, 0.08, (20, 3))])
    y = geom.inverse(poses)
    for pose, legs in zip(poses, y):
        rot = rotation_matrices(pose[3:])[0]
        by_hand = np.linalg.norm(np.array([0.0, 0.0, z]) + pose[:3] + plat @ rot.T - base, axis=1)
        np.testing.assert_allclose(legs + g.retracted_length_m, by_hand, atol=1e-8)
        np.testing.assert_allclose(geom.forward(legs), pose, atol=1e-9)


# ------------------------------------------------------------------------------------------- user MJCF
def _ball_hexapod(path, *, legs=6, closed=True, stroke=0.2, offset=0.0, slide_kind="slide") -> None:
    """A small user MJCF written here (not the built-in model): a 90 kg plate on six SPS legs (a ball at
    the base, the slides named ``ram1…``, the plate ``top``), 0.4 m retracted, ``stroke``; ``legs`` of
    them, their loops closed or not, the balls ``offset`` [m] off the slide axes, the slides of ``slide_kind``."""
    rb, rp, zb, length = 0.3, 0.2, 0.05, 0.4 + 0.1
    base = [np.array([rb * np.cos(a), rb * np.sin(a), zb]) for a in np.deg2rad([-20, 20, 100, 140, 220, 260])]
    plat = [np.array([rp * np.cos(a), rp * np.sin(a), 0.0]) for a in np.deg2rad([-40, 40, 80, 160, 200, 280])]
    h = zb + np.sqrt(length**2 - np.sum((plat[0][:2] - base[0][:2]) ** 2))
    bodies, eqs = [], []
    for i in range(legs):
        u = (plat[i] + [0, 0, h] - base[i]) / np.linalg.norm(plat[i] + [0, 0, h] - base[i])
        f = lambda v: " ".join(f"{x:.9f}" for x in v)  # noqa: E731
        bodies.append(f'''<body name="b{i + 1}" pos="{f(base[i])}" zaxis="{f(u)}">
          <joint type="ball"/><geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.02" mass="2"/>
          <body name="r{i + 1}"><joint name="ram{i + 1}" type="{slide_kind}" axis="0 0 1" range="0 {stroke}" ref="0.1"/>
            <geom type="capsule" fromto="0 0 0.2 0 0 {length}" size="0.01" mass="1"/></body></body>''')
        if closed:
            eqs.append(f'<connect body1="r{i + 1}" body2="top" anchor="{offset} 0 {length}"/>')
    path.write_text(f'''<mujoco model="sps"><option timestep="0.001"/><worldbody>
      <body name="top" pos="0 0 {h:.9f}"><freejoint/><geom type="cylinder" size="0.25 0.02" mass="90"/>
        <site name="imu" pos="0 0 0.02"/></body>
      {"".join(bodies)}</worldbody><equality>{"".join(eqs)}</equality></mujoco>''')


def _user_machine(tmp_path, hexapod: dict, name="sps.xml", **keys) -> Machine:
    doc = {"format": "hexsim-machine", "version": 1, "name": "sps", "system": "hexapod",
           "hexapod": {"mjcf": name, **hexapod}, **keys}
    path = tmp_path / "sps.json"
    path.write_text(json.dumps(doc))
    return read_machine(path)


def test_user_mjcf_runs_heave_with_hydraulics_and_gives_its_oil_spring_modes(tmp_path):
    """A user MJCF written in this test (ball joints at the base, slides and platform named in the machine
    file, the step 1 ms and MuJoCo's soft default connects in the file): the heave runs on both
    formulations with the seed's hydraulics and shows the reversal bump; its heave mode is the six oil
    columns E A1² / (y A1 + V_pl) along the legs carrying the plate, by hand within 3 %."""
    from hexsim.engine.config import RunConfig
    from hexsim.engine.runner import simulate
    from hexsim.studies import modes as modes_module
    from hexsim.studies.metrics import run_smoothness

    _ball_hexapod(tmp_path / "sps.xml")
    machine = _user_machine(tmp_path, {"mjcf_legs": [f"ram{i}" for i in range(1, 7)], "mjcf_platform": "top",
                                       "mjcf_sensor_site": "imu"})
    m = load_model("hexapod", "full", geometry=machine.geometry)
    assert m.opt.timestep == pytest.approx(1e-4) and m.nu == 6
    assert np.allclose(m.eq_solref[:, 0], 0.0005)
    runs = {form: simulate(RunConfig.from_machine(machine, "heave", model=form)) for form in ("platform", "full")}
    for form, run in runs.items():
        sm = run_smoothness(run)
        assert sm.peak_noise > 2 * sm.noise_floor, form  # the reversal bump stands out of the noise
        assert np.max(np.abs(run.y - run.y_ref)) < 0.01, form
    np.testing.assert_allclose(runs["platform"].acc[:, 2], runs["full"].acc[:, 2], atol=0.15)

    modes = modes_module.oil_spring_modes(machine.hydraulics, machine.effects, machine.geometry)
    heave = [mode for mode in modes if mode.dominant == "heave"]
    assert len(modes) == 6 and len(heave) == 1
    hyd = machine.hydraulics
    k = hyd.bulk_modulus * hyd.area_bottom**2 / (0.1 * hyd.area_bottom + hyd.pipeline_volume)
    sin2 = (m.key_qpos[0, 2] - 0.05) ** 2 / 0.5**2  # the legs' elevation at the neutral pose
    moving = 90.0 + 6 * 1.0  # the plate and the rods, which move with it along the legs
    assert heave[0].frequency_hz == pytest.approx(np.sqrt(6 * k * sin2 / moving) / (2 * np.pi), rel=0.03)


def test_user_mjcf_rerun_scene_closes_every_leg(tmp_path):
    """rerun's 3D view of a user MJCF: the base balls turned so that each rod's tip meets its platform ball
    at every drawn sample (to 0.1 mm)."""
    from hexsim.engine.config import RunConfig
    from hexsim.engine.runner import simulate
    from hexsim.outputs.rerun_log import scene_qpos

    _ball_hexapod(tmp_path / "sps.xml")
    machine = _user_machine(tmp_path, {"mjcf_platform": "top"})
    run = simulate(RunConfig.from_machine(machine, "roll", model="platform"))
    m = load_model("hexapod", geometry=machine.geometry)
    d = mujoco.MjData(m)
    for q in scene_qpos(m, run, np.arange(0, len(run.t), 400)):
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        for i in range(6):
            tip = d.site(f"rod{i + 1}_tip").xpos  # the closure, made site to site by hexsim
            assert np.linalg.norm(tip - d.site(f"platform_anchor{i + 1}").xpos) < 1e-4


@pytest.mark.parametrize("case, words", [
    ({"legs": 5}, "six legs; the model has 5 slide joints"),
    ({"closed": False}, "leg1: no active <connect> ties its rod to the platform"),
    ({"stroke": 0.3}, "range 0…0.3 m must be the piston's stroke 0…0.2 m"),
    ({"offset": 0.03}, "slide axis is 3.43° off the line from its base joint to its platform ball"),
    ({"slide_kind": "hinge"}, "six legs; the model has 0 slide joints"),
])
def test_bad_user_mjcfs_are_refused_with_one_line(tmp_path, case, words):
    _ball_hexapod(tmp_path / "sps.xml", **case)
    machine = _user_machine(tmp_path, {"mjcf_platform": "top"})
    with pytest.raises(InputError) as err:
        load_model("hexapod", geometry=machine.geometry)
    assert words in str(err.value) and "\n" not in str(err.value) and "sps.xml" in str(err.value)


def test_bad_user_mjcf_names_and_files_are_refused_with_one_line(tmp_path):
    _ball_hexapod(tmp_path / "sps.xml")
    for hexapod, words in (({"mjcf_legs": ["ram1", "ram2", "ram3", "ram4", "ram5", "nope"]}, "joint 'nope'"),
                           ({"mjcf_platform": "b1"}, "must move freely"),
                           ({"mjcf_sensor_site": "nope"}, "site 'nope'"),
                           ({"mjcf": "missing.xml"}, "no such MJCF file")):
        machine = _user_machine(tmp_path, {"mjcf_platform": "top", **hexapod})
        with pytest.raises(InputError, match=re.escape(words)):
            load_model("hexapod", geometry=machine.geometry)
    (tmp_path / "broken.xml").write_text("<mujoco><worldbody><body></mujoco>")
    machine = _user_machine(tmp_path, {}, name="broken.xml")
    with pytest.raises(InputError, match="MuJoCo cannot load it") as err:
        load_model("hexapod", geometry=machine.geometry)
    assert "\n" not in str(err.value)


def test_machine_file_hexapod_keys_are_checked(tmp_path):
    doc = Machine().document()
    for change, words in (({"mjcf": "x.xml"}, "hexapod.mjcf names the hexapod's model; hexapod.base_radius_m"),
                          ({"base_joints_m": [[0, 0, 0]] * 6}, "hexapod.base_joints_m and hexapod.base_radius_m"),
                          ({"base_angles_deg": [0, 1, 2]}, "hexapod.base_angles_deg: expected six angles"),
                          ({"retracted_length_m": 0.1}, "more than its neutral length"),
                          ({"platform_inertia_kgm2": [1, 1, 5]}, "hexapod.platform_inertia_kgm2"),
                          ({"base_angles_deg": [-12, 12, 108, 132, 228, 250]}, "different lengths at the neutral")):
        bad = {**doc, "hexapod": {**doc["hexapod"], **change}}
        with pytest.raises(InputError, match=re.escape(words)):
            machine_from_document(bad, "m.json")
    single = load_machine("servo_cylinder").document()
    with pytest.raises(InputError, match="describes a hexapod; this machine is a single-actuator"):
        machine_from_document({**single, "hexapod": {"platform_mass_kg": 10.0}})


def test_geometry_as_points_builds_the_same_hexapod_as_its_circle():
    """The Micro Motion System's joints given as coordinates build the model its circles build (to 1 nm)."""
    from hexsim.plant.geometry import MICRO_MOTION_SYSTEM, joint_coordinates

    base, plat, _ = joint_coordinates(MICRO_MOTION_SYSTEM)
    points = dataclasses.replace(MICRO_MOTION_SYSTEM, base_joints_m=tuple(map(tuple, base)),
                                 platform_joints_m=tuple(map(tuple, plat)))
    a, b = load_model("hexapod", geometry=points), load_model("hexapod")
    for name in ("body_pos", "site_pos", "key_qpos", "body_mass"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), atol=1e-9)


# --------------------------------------------------------------------------------- the docs' example
def test_the_docs_user_mjcf_example_runs_as_written(tmp_path):
    """docs/your-hexapod.md's bench-top MJCF and machine file, copied as a user would: ``hexsim run heave``
    and ``hexsim modes`` on it print what the page shows (summary lines but the wall-clock ones); a heave
    logged on it and validated against it is explained by the nominal (verdict none); from a folder
    without the files, one line and exit 2."""
    text = (ROOT / "docs" / "your-hexapod.md").read_text()
    (tmp_path / "bench_top.xml").write_text(re.search(r"```xml\n(.*?)```", text, re.S).group(1))
    (tmp_path / "bench_top.json").write_text(re.search(r"```json\n(.*?)```", text, re.S).group(1))
    for command in (["run", "heave"], ["modes"]):
        out = subprocess.run([sys.executable, "-m", "hexsim", *command, "--machine", "bench_top.json"], cwd=tmp_path,
                             capture_output=True, text=True, timeout=600)
        assert out.returncode == 0, out.stderr
        shown = text.replace("-0.00", "+0.00")  # a mode shape's zero may print with either sign
        for line in out.stdout.replace("-0.00", "+0.00").splitlines():
            if not line.startswith(("realtime_factor", "wrote")):  # a mode's number: equal modes in either order
                assert re.sub(r"^\s+\d\s+", "", line) in shown, line
    hexsim = [sys.executable, "-m", "hexsim"]
    logged = subprocess.run([*hexsim, "run", "heave", "--duration", "8", "--machine", "bench_top.json", "--log",
                             "heave.csv", "--quiet"], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert logged.returncode == 0, logged.stderr
    judged = subprocess.run([*hexsim, "validate", "heave.csv", "--machine", "bench_top.json"], cwd=tmp_path,
                            capture_output=True, text=True, timeout=600)
    assert judged.returncode == 0 and "verdict: none" in judged.stdout, judged.stdout + judged.stderr
    bad = subprocess.run([sys.executable, "-m", "hexsim", "modes", "--machine", "bench_top.json"], cwd=ROOT,
                         capture_output=True, text=True, timeout=600)  # run from elsewhere: the file is not there
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1
