"""Inverse and forward kinematics of the Micro Motion System hexapod."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hexsim.control.kinematics import HexapodGeometry
from hexsim.errors import WorkspaceError
from hexsim.plant.model import PlantIndex, load_model


@pytest.fixture(scope="module")
def geom():
    return HexapodGeometry.from_model(load_model("hexapod"))


def test_neutral_pose_is_mid_stroke(geom):
    np.testing.assert_allclose(geom.inverse(np.zeros(6)), 0.1, atol=1e-9)
    np.testing.assert_allclose(PlantIndex.from_model(load_model("hexapod")).neutral_y, 0.1)


def test_pure_heave_is_symmetric(geom):
    for z in (-0.06, -0.02, 0.03, 0.06):
        y = geom.inverse(np.array([0, 0, z, 0, 0, 0]))
        np.testing.assert_allclose(y, y[0], atol=1e-12)
        assert (y[0] - 0.1) * z > 0  # heave up extends every leg


def test_design_workspace_is_reachable(geom):
    six = math.radians(6)
    poses = np.array([[0, 0, s * 0.06, 0, 0, 0] for s in (-1, 1)]
                     + [[0, 0, 0, s * six, 0, 0] for s in (-1, 1)]
                     + [[0, 0, 0, 0, s * six, 0] for s in (-1, 1)])
    y = geom.inverse(poses)
    assert np.all((y > 0.0) & (y < 0.2))


def test_ik_fk_round_trip_on_random_reachable_poses(geom):
    rng = np.random.default_rng(7)
    scale = np.array([0.04, 0.04, 0.05, math.radians(5), math.radians(5), math.radians(5)])
    checked = 0
    for _ in range(40):
        pose = rng.uniform(-1, 1, 6) * scale
        try:
            y = geom.inverse(pose)
        except WorkspaceError:
            continue
        np.testing.assert_allclose(geom.forward(y), pose, atol=1e-10)
        checked += 1
    assert checked >= 30


def test_unreachable_setpoint_names_the_leg_and_length(geom):
    with pytest.raises(WorkspaceError, match=r"leg\d length 0\.\d+ m.*outside its stroke") as err:
        geom.inverse(np.array([[0, 0, 0.0, 0, 0, 0], [0, 0, 0.15, 0, 0, 0]]), times=np.array([0.0, 1.5]))
    assert "t = 1.500 s" in str(err.value)
