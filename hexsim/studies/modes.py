"""Oil-spring modes of the hexapod: ``hexsim modes``.

Linearised about the neutral pose at rest, each leg is a spring, the oil column of its bottom chamber:
k_i = E A1^2 / (y_i A1 + V_pl) (seed eq. 3.7 with the valve closed: at rest the spool sits in the overlap,
so no flow; the rod side is held at P_s by the supply and adds no stiffness). The inertia is MuJoCo's:
the legs' mobility A (n_legs, n_legs) [1/kg], slide accelerations per unit leg force with the platform,
the legs' own bodies and the closed-loop constraints (:func:`hexsim.engine.config.leg_mobility`). Free
vibration in the leg coordinates, ÿ = -A K y, gives ω^2 = eig(A K). Each mode shape is carried to the
platform's six degrees of freedom through the inverse of the IK Jacobian dy/dpose, and named by the
degree of freedom that holds most of its kinetic energy (the platform's own 6×6 inertia at its
reference point).

The single actuator has one mode, the seed's eigenfrequency (§3.3: about 109 Hz over the stroke).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from hexsim.control.kinematics import HexapodGeometry
from hexsim.control.scenario import DOF_NAMES
from hexsim.engine.config import leg_mobility
from hexsim.errors import InputError
from hexsim.plant.effects import Effects
from hexsim.plant.geometry import Geometry
from hexsim.plant.model import PlantIndex, load_model, reset_neutral
from hexsim.plant.params import HydraulicParams

#: Names of the platform's degrees of freedom in the order of a pose (x, y, z, roll, pitch, yaw).
MOTIONS = ("surge", "sway", "heave", "roll", "pitch", "yaw")


@dataclass(frozen=True)
class Mode:
    """One mode: frequency [Hz], the degree of freedom with the largest share of the platform's kinetic
    energy and that share [-], and the shape as a platform pose (6,) normalised to a largest entry of 1
    (m and rad as a pose: surge, sway, heave, roll, pitch, yaw)."""

    frequency_hz: float
    dominant: str
    share: float
    shape: np.ndarray


def oil_spring_modes(hyd: HydraulicParams | None = None, effects: Effects | None = None,
                     geometry: Geometry | None = None) -> list[Mode]:
    """The hexapod's oil-spring modes at the neutral pose, lowest first (six of them), with the payload of
    ``effects`` (:func:`hexsim.plant.model.apply_load`) and the bulk modulus, areas and pipeline volume of
    ``hyd`` (default the seed's, app. A; with a 4-way valve the rod side's column in parallel), on the
    hexapod of ``geometry`` (a machine file's hexapod section; None: the Micro Motion System). Raises
    InputError for a payload the platform cannot take or a hexapod hexsim cannot build."""
    hyd = hyd or HydraulicParams()
    m = load_model("hexapod", effects=effects or Effects(), geometry=geometry)
    d = mujoco.MjData(m)
    idx = PlantIndex.from_model(m)
    mujoco.set_mjcb_control(None)
    reset_neutral(m, d)
    mobility, _ = leg_mobility(m, d, idx)
    stiffness = hyd.bulk_modulus * hyd.area_bottom**2 / (idx.neutral_y * hyd.area_bottom + hyd.pipeline_volume)
    if hyd.four_way:  # the rod side's oil column is a second spring in parallel
        stiffness = stiffness + hyd.bulk_modulus * hyd.area_rod**2 / (
            (hyd.stroke - idx.neutral_y) * hyd.area_rod + hyd.pipeline_volume_rod)
    w2, vectors = np.linalg.eig(mobility @ np.diag(stiffness))
    if np.any(np.abs(w2.imag) > 1e-9 * np.abs(w2.real)) or np.any(w2.real <= 0):
        raise InputError("the linearised hexapod has modes that are not oscillatory (inertia or stiffness not positive)")
    jac = _ik_jacobian(HexapodGeometry.from_model(m))
    inertia = _platform_inertia(m)
    modes = []
    for k in np.argsort(w2.real):
        pose = np.linalg.solve(jac, vectors[:, k].real)
        energy = inertia * pose**2
        j = int(np.argmax(energy))
        modes.append(Mode(frequency_hz=float(np.sqrt(w2[k].real) / (2 * np.pi)), dominant=MOTIONS[j],
                          share=float(energy[j] / energy.sum()), shape=pose / pose[np.argmax(np.abs(pose))]))
    return modes


def _ik_jacobian(geom: HexapodGeometry, h: float = 1e-7) -> np.ndarray:
    """dy/dpose (6, 6) at the neutral pose by central differences of the inverse kinematics."""
    eye = np.eye(6) * h
    return ((geom.leg_lengths(eye) - geom.leg_lengths(-eye)) / (2 * h)).T


def _platform_inertia(m: mujoco.MjModel) -> np.ndarray:
    """(6,): the platform body's mass [kg] for x, y, z and its moments of inertia [kg m^2] about the axes
    of its frame through the frame's origin (the centre of the upper joint plane; parallel-axis theorem
    from the centre of mass), the diagonal of its free joint's block of the joint-space inertia."""
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "platform")
    mass, c = float(m.body_mass[body]), np.array(m.body_ipos[body])
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, m.body_iquat[body])
    rot = rot.reshape(3, 3)
    about_origin = rot @ np.diag(m.body_inertia[body]) @ rot.T + mass * (c @ c * np.eye(3) - np.outer(c, c))
    return np.concatenate([np.full(3, mass), np.diag(about_origin)])


def modes_table(modes: list[Mode], payload: str) -> str:
    """The modes as the text table ``hexsim modes`` prints."""
    lines = [f"oil-spring modes of the hexapod at the neutral pose ({payload}), linearised:",
             f"{'mode':>4}  {'f [Hz]':>7}  {'dominant':<8}  {'share':>5}  shape ({', '.join(DOF_NAMES)})"]
    for i, mode in enumerate(modes, 1):
        shape = " ".join(f"{v:+.2f}" for v in mode.shape)
        lines.append(f"{i:>4}  {mode.frequency_hz:7.1f}  {mode.dominant:<8}  {mode.share:5.0%}  {shape}")
    return "\n".join(lines)
