"""Loading the shipped MJCF models and resolving named elements once (STYLE.md §5).

Python reads rigid-body facts (masses, stroke, timestep, gravity) from ``MjModel`` and never keeps a
second copy (STYLE.md §2).
"""

from __future__ import annotations

import importlib.resources
import pathlib
from dataclasses import dataclass

import mujoco
import numpy as np

from hexsim.errors import InputError, PhysicsError

#: Built-in models: name -> MJCF file inside the ``hexsim.models`` package (sources in ``models/``).
MODELS = {
    "hexapod": "scene.xml",
    "actuator": "single_actuator.xml",
}


def model_path(name: str) -> pathlib.Path:
    """Path of a built-in model's MJCF file. Raises InputError for an unknown name."""
    if name not in MODELS:
        raise InputError(f"unknown model {name!r}; built-in models: {', '.join(MODELS)}")
    return pathlib.Path(str(importlib.resources.files("hexsim.models") / MODELS[name]))


def load_model(name: str) -> mujoco.MjModel:
    """Compile a built-in model (``"hexapod"`` or ``"actuator"``), with island discovery off
    (:func:`no_islands`)."""
    return no_islands(mujoco.MjModel.from_xml_path(str(model_path(name))))


def no_islands(m: mujoco.MjModel) -> mujoco.MjModel:
    """``m`` with MuJoCo's constraint-island discovery switched off (``mjDSBL_ISLAND``, where this MuJoCo
    has it), in place. The hexapod is one island (every leg is tied to the platform) and the single
    actuators are one body each, so discovering islands at every step is work without effect: the
    results are bit-identical (tests/test_hexapod.py) and a hexapod step is about 10 % cheaper."""
    flag = getattr(mujoco.mjtDisableBit, "mjDSBL_ISLAND", None)
    if flag is not None:
        m.opt.disableflags |= int(flag)
    return m


def _id(m: mujoco.MjModel, objtype, name: str) -> int:
    i = mujoco.mj_name2id(m, objtype, name)
    if i < 0:
        raise InputError(f"model {m.names[:40]!r}… has no {objtype.name.removeprefix('mjOBJ_').lower()} {name!r}")
    return i


@dataclass(frozen=True)
class PlantIndex:
    """Addresses of the named elements hexsim drives and reads, resolved once with ``mj_name2id``.

    Legs are the slide joints ``leg1`` … ``legN`` (piston position y [m]) with motors ``leg{i}_force``;
    the platform sensors sit at site ``platform_centre``. Arrays have shape (n_legs,).
    """

    n_legs: int
    qpos_adr: np.ndarray  # (n,) qpos address of each slide joint
    dof_adr: np.ndarray  # (n,) qvel address of each slide joint
    actuator_id: np.ndarray  # (n,) index into data.ctrl
    stroke: np.ndarray  # (n, 2) joint range [m]: 0 … L_s
    neutral_y: np.ndarray  # (n,) piston positions in the `neutral` keyframe [m]
    sensor: dict[str, slice]  # sensor name -> slice of data.sensordata
    dt: float  # physics timestep [s]

    @classmethod
    def from_model(cls, m: mujoco.MjModel) -> "PlantIndex":
        legs = []
        while mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"leg{len(legs) + 1}") >= 0:
            legs.append(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"leg{len(legs) + 1}"))
        if not legs:
            raise InputError("model has no slide joint named leg1")
        joints = np.array(legs)
        acts = np.array([_id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"leg{i + 1}_force") for i in range(len(legs))])
        sensors = {}
        for s in range(m.nsensor):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SENSOR, s)
            adr, dim = m.sensor_adr[s], m.sensor_dim[s]
            sensors[name] = slice(int(adr), int(adr + dim))
        key = _id(m, mujoco.mjtObj.mjOBJ_KEY, "neutral")
        qpos_adr = m.jnt_qposadr[joints].astype(int)
        return cls(
            n_legs=len(legs),
            qpos_adr=qpos_adr,
            dof_adr=m.jnt_dofadr[joints].astype(int),
            actuator_id=acts.astype(int),
            stroke=m.jnt_range[joints].copy(),
            neutral_y=m.key_qpos[key][qpos_adr].copy(),
            sensor=sensors,
            dt=float(m.opt.timestep),
        )


def reset_neutral(m: mujoco.MjModel, d: mujoco.MjData) -> None:
    """Reset ``d`` to the ``neutral`` keyframe and run ``mj_forward``."""
    mujoco.mj_resetDataKeyframe(m, d, _id(m, mujoco.mjtObj.mjOBJ_KEY, "neutral"))
    mujoco.mj_forward(m, d)


def check_warnings(m: mujoco.MjModel, d: mujoco.MjData) -> None:
    """Raise PhysicsError if MuJoCo raised any warning (like dm_control's ``check_invalid_state``).

    The message names the warning, the time and, for bad controls, the actuator (e.g. ``leg3_force``).
    """
    counts = d.warning.number
    if np.any(counts > 0):
        kinds = []
        for i in np.flatnonzero(counts):
            kind = mujoco.mjtWarning(i)
            what = kind.name
            if kind == mujoco.mjtWarning.mjWARN_BADCTRL:
                what += f" ({mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, int(d.warning.lastinfo[i]))})"
            kinds.append(what)
        raise PhysicsError(f"MuJoCo warning {', '.join(kinds)} at t = {d.time:.4f} s")


def apply_load(m: mujoco.MjModel, effects) -> None:
    """Change the moving mass and the inclination of a single-actuator model in place.

    ``effects.mass_kg`` [kg] replaces the mass of the body that slide ``leg1`` carries;
    ``effects.inclination_deg`` [deg] tilts gravity so the actuator axis is that far from vertical: only
    g cos(angle) acts along the axis (the seed's model is vertical, eq. 3.8; the seed notes gravity is
    not along the hexapod's legs, ch. 4). Raises InputError on a model with more than one leg.
    """
    if effects.mass_kg is None and effects.inclination_deg is None:
        return
    idx = PlantIndex.from_model(m)
    if idx.n_legs != 1:
        raise InputError("mass_kg and inclination_deg apply to the single-actuator model only")
    if effects.mass_kg is not None:
        m.body_mass[m.jnt_bodyid[_id(m, mujoco.mjtObj.mjOBJ_JOINT, "leg1")]] = effects.mass_kg
    if effects.inclination_deg is not None:
        g = float(np.linalg.norm(m.opt.gravity))
        angle = np.deg2rad(effects.inclination_deg)
        m.opt.gravity[:] = (g * np.sin(angle), 0.0, -g * np.cos(angle))
