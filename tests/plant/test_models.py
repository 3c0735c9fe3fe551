"""Model smoke tests (menagerie model_test style): every MJCF loads, steps 1 s, raises no warning."""

from __future__ import annotations

import importlib.util
import pathlib

import mujoco
import numpy as np
import pytest

from hexsim.plant.model import MODELS, check_warnings, model_path, reset_neutral

MODELS_DIR = pathlib.Path(__file__).resolve().parents[2] / "models"


@pytest.mark.parametrize("xml", sorted(MODELS_DIR.glob("*.xml")), ids=lambda p: p.name)
def test_model_loads_and_steps_one_second_without_warnings(xml):
    m = mujoco.MjModel.from_xml_path(str(xml))
    d = mujoco.MjData(m)
    reset_neutral(m, d)
    mujoco.mj_step(m, d, int(round(1.0 / m.opt.timestep)))
    check_warnings(m, d)
    assert np.all(np.isfinite(d.qpos))
    assert m.opt.timestep == pytest.approx(1e-4)


def test_installed_package_ships_the_models():
    for name in MODELS:
        assert model_path(name).is_file()


def test_hexapod_model_matches_the_design_card():
    m = mujoco.MjModel.from_xml_path(str(model_path("hexapod")))
    assert m.body("platform").mass[0] == pytest.approx(600.0)
    for i in range(1, 7):
        j = m.joint(f"leg{i}")
        assert j.type[0] == mujoco.mjtJoint.mjJNT_SLIDE
        np.testing.assert_allclose(j.range, [0.0, 0.2])
    assert m.neq == 6 and all(m.eq_type == mujoco.mjtEq.mjEQ_CONNECT)
    for s in ("platform_acc", "platform_gyro", "leg1_pos", "leg6_vel"):
        assert m.sensor(s) is not None


def _builder():
    spec = importlib.util.spec_from_file_location("hexapod_builder", MODELS_DIR / "hexapod.py")
    builder = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(builder)
    return builder


def test_committed_hexapod_xml_is_its_builders_and_the_same_model_to_a_micrometre():
    """micro_motion_system.xml is ``build().to_xml()`` of the repository's builder; compiled, it is the
    model hexsim compiles from the builder with its numbers at MuJoCo's 6 significant digits: the same
    elements, the same masses, and every frame, anchor and keyframe value within 2 µm (2e-6)."""
    builder = _builder()
    assert (MODELS_DIR / "micro_motion_system.xml").read_text() == builder.build().to_xml()
    from_xml = mujoco.MjModel.from_xml_path(str(MODELS_DIR / "micro_motion_system.xml"))
    built = builder.build().compile()
    assert from_xml.names == built.names
    for field in ("body_mass", "body_inertia", "jnt_range", "jnt_type", "eq_type", "sensor_type"):
        np.testing.assert_array_equal(getattr(from_xml, field), getattr(built, field), err_msg=field)
    for field in ("body_pos", "body_quat", "site_pos", "body_ipos", "key_qpos", "qpos0", "eq_data"):
        np.testing.assert_allclose(getattr(from_xml, field), getattr(built, field), rtol=0, atol=2e-6,
                                   err_msg=field)


def test_hexsim_compiles_the_builders_model_and_scene_xml_is_the_same_scene():
    """hexsim's hexapod (load_model) is the builder's spec in its scene, and scene.xml (including the
    committed XML) holds the same elements: the floor, light and texture of the scene and the robot."""
    from hexsim.plant.model import load_model

    builder = _builder()
    m = load_model("hexapod")
    expected = builder.scene(builder.build()).compile()
    assert m.names == expected.names and m.nbody == expected.nbody
    np.testing.assert_array_equal(m.body_pos, expected.body_pos)
    viewer = mujoco.MjModel.from_xml_path(str(model_path("hexapod")))
    assert viewer.names == m.names and (viewer.nlight, viewer.ntex, viewer.ngeom) == (m.nlight, m.ntex, m.ngeom)


def test_the_xml_writers_six_digits_leave_the_connects_within_two_micrometres():
    """Why hexsim compiles the builder and not the XML: in the committed XML (6 significant digits) the
    rod tips miss the platform anchors at the neutral pose by about 1 µm; in the builder's model by less
    than 0.1 µm (the 1 nm resolution of its numbers)."""
    def misfit(m):
        d = mujoco.MjData(m)
        reset_neutral(m, d)
        mujoco.mj_kinematics(m, d)
        return max(np.linalg.norm(d.site(f"rod{i}_tip").xpos - d.site(f"platform_anchor{i}").xpos) for i in range(1, 7))

    assert misfit(_builder().build().compile()) < 1e-7
    assert misfit(mujoco.MjModel.from_xml_path(str(MODELS_DIR / "micro_motion_system.xml"))) < 2e-6


def test_a_load_is_a_spec_edit_the_same_as_writing_it_into_the_mjcf():
    """mass_kg, inclination_deg and a payload edit the spec before it compiles: MuJoCo's derived constants
    (subtree mass, M0) follow, as if the MJCF said so."""
    from hexsim.plant.effects import Effects
    from hexsim.plant.model import load_model

    loaded = load_model("actuator", effects=Effects(mass_kg=60.0, inclination_deg=30.0))
    text = model_path("actuator").read_text().replace('mass="40"', 'mass="60"')
    written = mujoco.MjModel.from_xml_string(text)
    np.testing.assert_array_equal(loaded.body_subtreemass, written.body_subtreemass)
    np.testing.assert_array_equal(loaded.dof_M0, written.dof_M0)
    np.testing.assert_allclose(loaded.opt.gravity, [9.81 * 0.5, 0.0, -9.81 * np.sqrt(3) / 2], rtol=1e-15)
    heavier = load_model("hexapod", effects=Effects(payload_kg=200.0, payload_at_m=(0.1, 0.0, 0.2)))
    plain = load_model("hexapod")
    assert heavier.body("platform").subtreemass[0] == pytest.approx(plain.body("platform").subtreemass[0] + 200.0)
    assert heavier.body("platform").ipos[0] == pytest.approx(0.1 * 200.0 / 800.0)


def test_the_replays_batch_is_the_single_actuator_attached_n_times():
    from hexsim.measured.replay import batch_model
    from hexsim.plant.effects import Effects
    from hexsim.plant.model import load_model

    one = load_model("actuator", effects=Effects(mass_kg=55.0))
    batch = batch_model(3, Effects(mass_kg=55.0))
    assert [batch.joint(f"leg{i}").id for i in (1, 2, 3)] == [0, 1, 2] and batch.nu == 3 and batch.nsensor == 6
    np.testing.assert_array_equal(batch.body_mass[1:], [one.body_mass[1]] * 3)
    np.testing.assert_array_equal(batch.jnt_range, [one.jnt_range[0]] * 3)
    np.testing.assert_array_equal(batch.key_qpos[0], [one.key_qpos[0, 0]] * 3)
    assert [batch.sensor(f"leg{i}_acc").type[0] for i in (1, 2, 3)] == [mujoco.mjtSensor.mjSENS_ACCELEROMETER] * 3


def test_the_models_load_when_hexsim_is_imported_from_the_checkout():
    """In the repository's root ``import hexsim`` finds the source tree, whose models live in the
    top-level models/ folder (installed as hexsim.models): they load from there too (CI installs
    without -e, so there this runs the source tree against an installed copy)."""
    import subprocess
    import sys

    code = ("import hexsim.plant.model as m; "
            "print(m.load_model('hexapod').nbody, m.load_model('actuator').nbody, m.model_path('hexapod').name)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=MODELS_DIR.parent)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["15", "2", "scene.xml"]
