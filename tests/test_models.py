"""Model smoke tests (menagerie model_test style): every MJCF loads, steps 1 s, raises no warning."""

from __future__ import annotations

import importlib.util
import pathlib

import mujoco
import numpy as np
import pytest

from hexsim.plant.model import MODELS, check_warnings, model_path, reset_neutral

MODELS_DIR = pathlib.Path(__file__).resolve().parents[1] / "models"


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


def test_committed_hexapod_xml_matches_its_generator():
    spec = importlib.util.spec_from_file_location("generate_hexapod", MODELS_DIR / "generate_hexapod.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    assert (MODELS_DIR / "micro_motion_system.xml").read_text() == gen.render()
