"""Loading the shipped MJCF models and resolving named elements once (STYLE.md §5).

Python reads rigid-body facts (masses, stroke, timestep, gravity) from ``MjModel`` and never keeps a
second copy (STYLE.md §2).
"""

from __future__ import annotations

import functools
import importlib.resources
import importlib.util
import math
import pathlib
import sys
from dataclasses import dataclass

import mujoco
import numpy as np

from hexsim.errors import InputError, PhysicsError


def _models_package() -> None:
    """Make ``hexsim.models`` importable when hexsim runs from a source checkout that is not installed
    (``python -c "import hexsim"`` in the repository's root after a non-editable install): the
    installed package is the checkout's top-level ``models/`` (pyproject's package-dir), so there it is
    loaded from that folder under the same name."""
    if importlib.util.find_spec("hexsim.models") is not None:
        return
    folder = pathlib.Path(__file__).resolve().parents[2] / "models"
    spec = importlib.util.spec_from_file_location("hexsim.models", folder / "__init__.py",
                                                  submodule_search_locations=[str(folder)])
    if spec is None:
        raise ModuleNotFoundError(f"hexsim.models: neither installed nor a models/ folder at {folder}")
    module = importlib.util.module_from_spec(spec)
    sys.modules["hexsim.models"] = module
    spec.loader.exec_module(module)


_models_package()

from hexsim.models import hexapod  # noqa: E402
from hexsim.plant.platform import (  # noqa: E402
    LegGeometry,
    add_point_masses,
    is_platform_model,
    joint_legs,
    leg_bodies,
    leg_geometry,
    platform_spec,
    read_legs,
)

#: Built-in models: name -> MJCF file inside the ``hexsim.models`` package (sources in ``models/``); the
#: hexapod's is written by its builder (:mod:`hexsim.models.hexapod`), which :func:`load_model` compiles.
MODELS = {
    "hexapod": "scene.xml",
    "actuator": "single_actuator.xml",
}


def model_path(name: str) -> pathlib.Path:
    """Path of a built-in model's MJCF file. Raises InputError for an unknown name."""
    if name not in MODELS:
        raise InputError(f"unknown model {name!r}; built-in models: {', '.join(MODELS)}")
    return pathlib.Path(str(importlib.resources.files("hexsim.models") / MODELS[name]))


#: formulations of the hexapod: the full multi-body MJCF, or the platform-only model built from it
FORMULATIONS = ("full", "platform")


def check_formulation(model: str) -> None:
    """Raise InputError unless ``model`` names a formulation of the hexapod (:data:`FORMULATIONS`)."""
    if model not in FORMULATIONS:
        raise InputError(f"model must be one of {', '.join(FORMULATIONS)}, got {model!r}")


def model_spec(name: str, formulation: str = "full", effects=None, geometry=None,
               stroke_m: float | None = None) -> mujoco.MjSpec:
    """The ``MjSpec`` of a model (``"hexapod"`` or ``"actuator"``) with the load of ``effects``
    (:func:`apply_load`; None: none). The single actuator's slide travels ``stroke_m`` [m] (the machine file's
    ``cylinder.stroke_m``, :func:`set_actuator_stroke`; None: the MJCF's 0.2 m). The hexapod is the one
    ``geometry`` describes (:class:`hexsim.plant.geometry.Geometry`, a machine file's ``hexapod`` section; None:
    the built-in Micro Motion System): built by :func:`hexsim.models.hexapod.build` in its scene, to the full precision
    of its numbers (``scene.xml`` is the Micro Motion System for viewers), or a user's MJCF adapted by
    :func:`hexsim.plant.user_model.user_spec`; ``formulation="platform"`` edits it into the platform-only
    model (:func:`hexsim.plant.platform.platform_spec`), except for a user MJCF whose cardans keep their hinges
    apart, which stays full (a note says so); the single actuator has one formulation. Raises
    InputError for an unknown name or formulation, a user MJCF hexsim cannot drive, or a load the model
    cannot take."""
    check_formulation(formulation)
    if name == "hexapod":
        if geometry is not None and geometry.is_mjcf:
            from hexsim.plant.user_model import cardan_spreads, user_spec

            spec = user_spec(geometry)
            spreads = cardan_spreads(spec)
            if formulation == "platform" and np.any(spreads > 0):
                _say_full_model(geometry, spreads)
                formulation = "full"
        else:
            geometry = geometry or hexapod.MICRO_MOTION_SYSTEM
            spec = hexapod.scene(hexapod.build(geometry), geometry.scale)
        if formulation == "platform":
            platform_spec(spec)
    else:
        spec = mujoco.MjSpec.from_file(str(model_path(name)))
        if stroke_m is not None:
            set_actuator_stroke(spec, stroke_m)
    if effects is not None:
        apply_load(spec, effects)
    return spec


def set_actuator_stroke(spec: mujoco.MjSpec, stroke_m: float) -> None:
    """The single actuator's slide ``leg1`` made to travel 0 … ``stroke_m`` [m] (the machine file's
    ``cylinder.stroke_m``; MJCF: ``range="0 0.2"``), its neutral keyframe at mid-stroke, in place. Raises
    InputError for a stroke that is not a positive finite number."""
    if not (isinstance(stroke_m, (int, float)) and math.isfinite(stroke_m) and stroke_m > 0):
        raise InputError(f"cylinder stroke_m must be a positive number of metres, got {stroke_m!r}")
    stroke = float(stroke_m)
    joint = spec.joint("leg1")
    joint.range = [0.0, stroke]
    joint.ref = 0.5 * stroke
    spec.key("neutral").qpos = [0.5 * stroke]


#: the swing [deg] of a leg against the platform at which the notes state what a cardan's offset costs
CARDAN_SWING_DEG = 10.0


def _say_full_model(geometry, spreads: np.ndarray) -> None:
    """Say (a :class:`~hexsim.errors.ModelNote`) that the hexapod of a user's MJCF whose platform-side cardans
    keep their hinges apart (``spreads`` (n,) [m] per leg) runs on the full model, and what the offset costs."""
    from hexsim.plant.user_legs import BALL_TOLERANCE_M, note

    worst = float(np.max(spreads))
    legs = ", ".join(str(i + 1) for i in np.flatnonzero(spreads > 0))
    error = worst * (1.0 - np.cos(np.deg2rad(CARDAN_SWING_DEG)))
    note(f"{geometry.mjcf} (hexapod.mjcf): legs {legs}: the platform joints' hinges sit up to {worst * 1e3:.1f} mm "
         f"apart (a point leg allows {BALL_TOLERANCE_M * 1e3:g} mm): the full model runs, with each cardan's joint "
         f"chain, not the platform-only model (whose legs are straight lines between two points): a run takes about "
         f"7x as long (docs/your-hexapod.md). hexsim's inverse kinematics take each leg to its last hinge: a "
         f"setpoint is off by up to {error * 1e3:.2f} mm at {CARDAN_SWING_DEG:g} deg of swing about the others")


def load_model(name: str, formulation: str = "full", effects=None, geometry=None,
               stroke_m: float | None = None) -> mujoco.MjModel:
    """Compile :func:`model_spec` (the same arguments and errors), with island discovery off
    (:func:`no_islands`)."""
    return no_islands(model_spec(name, formulation, effects, geometry, stroke_m).compile())


@functools.cache
def gravity(name: str = "actuator") -> float:
    """|g| [m/s^2] of a built-in model (both are 9.81): the one value of gravity hexsim uses, read from
    the MJCF (the identifier, ``hexsim friction`` and the reports included). Raises InputError for an
    unknown model name."""
    return float(np.linalg.norm(load_model(name).opt.gravity))


@functools.cache
def moving_mass() -> float:
    """Moving mass M [kg] of the built-in single actuator (the body slide ``leg1`` carries; seed app. A:
    40 kg), read from the MJCF."""
    m = load_model("actuator")
    return float(m.body_mass[m.jnt_bodyid[_id(m, mujoco.mjtObj.mjOBJ_JOINT, "leg1")]])


def no_islands(m: mujoco.MjModel) -> mujoco.MjModel:
    """``m`` with MuJoCo's constraint-island discovery switched off (``mjDSBL_ISLAND``, where this MuJoCo
    has it), in place. The hexapod is one island (every leg is tied to the platform) and the single
    actuators are one body each, so discovering islands at every step is work without effect: the
    results are bit-identical (tests/engine/test_hexapod.py) and a hexapod step is about 10 % cheaper."""
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
    legs: LegGeometry  # kind 0: slide joints (the fields above); kind 1: a platform-only model

    @property
    def platform_only(self) -> bool:
        return self.legs.kind == 1

    def positions(self, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Piston positions y (n,) [m] and velocities ẏ (n,) [m/s] in the state of ``d``."""
        if self.legs.kind == 0:
            return d.qpos[self.qpos_adr].copy(), d.qvel[self.dof_adr].copy()
        y, yd = np.empty(self.n_legs), np.empty(self.n_legs)
        read_legs(self.legs, d.qpos, d.qvel, y, yd)
        return y, yd

    @classmethod
    def from_model(cls, m: mujoco.MjModel) -> "PlantIndex":
        if is_platform_model(m):
            return cls._platform(m)
        legs = []
        while mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"leg{len(legs) + 1}") >= 0:
            legs.append(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"leg{len(legs) + 1}"))
        if not legs:
            raise InputError("model has no slide joint named leg1")
        joints = np.array(legs)
        acts = np.array([_id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"leg{i + 1}_force") for i in range(len(legs))])
        key = _id(m, mujoco.mjtObj.mjOBJ_KEY, "neutral")
        qpos_adr = m.jnt_qposadr[joints].astype(int)
        return cls(
            n_legs=len(legs),
            qpos_adr=qpos_adr,
            dof_adr=m.jnt_dofadr[joints].astype(int),
            actuator_id=acts.astype(int),
            stroke=m.jnt_range[joints].copy(),
            neutral_y=m.key_qpos[key][qpos_adr].copy(),
            sensor=_sensors(m),
            dt=float(m.opt.timestep),
            legs=joint_legs(len(legs)),
        )

    @classmethod
    def _platform(cls, m: mujoco.MjModel) -> "PlantIndex":
        legs = leg_geometry(m)
        n = len(legs.l_min)
        key = _id(m, mujoco.mjtObj.mjOBJ_KEY, "neutral")
        y, yd = np.empty(n), np.empty(n)
        read_legs(legs, m.key_qpos[key], np.zeros(m.nv), y, yd)
        none = np.zeros(0, dtype=int)
        return cls(n_legs=n, qpos_adr=none, dof_adr=none, actuator_id=none, stroke=np.tile(legs.stroke, (n, 1)),
                   neutral_y=y, sensor=_sensors(m), dt=float(m.opt.timestep), legs=legs)


def _sensors(m: mujoco.MjModel) -> dict[str, slice]:
    """Sensor name -> its slice of ``data.sensordata``."""
    sensors = {}
    for s in range(m.nsensor):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SENSOR, s)
        sensors[name] = slice(int(m.sensor_adr[s]), int(m.sensor_adr[s] + m.sensor_dim[s]))
    return sensors


def base_pivots(m: mujoco.MjModel, d: mujoco.MjData, n_legs: int) -> np.ndarray:
    """(n_legs, 3) world positions [m] of the legs' base joints in the state of ``d`` (after
    ``mj_kinematics``): the anchor of each barrel's first joint (the universal joint's hinges or a ball
    sit at one point: :mod:`hexsim.plant.user_model` checks it)."""
    _, _, barrels = leg_bodies(m, n_legs)
    return d.xanchor[m.body_jntadr[barrels]].copy()


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


def apply_load(spec: mujoco.MjSpec, effects) -> None:
    """Edit the rigid bodies of ``spec`` for the load of ``effects`` (:class:`hexsim.plant.effects.Effects`),
    in place, before it is compiled.

    Single actuator: ``effects.mass_kg`` [kg] replaces the mass of the body that slide ``leg1`` carries;
    ``effects.inclination_deg`` [deg] tilts gravity so the actuator axis is that far from vertical: only
    g cos(angle) acts along the axis (the seed's model is vertical, eq. 3.8; the seed notes gravity is
    not along the hexapod's legs, ch. 4). Hexapod: ``effects.payload_kg`` [kg] at
    ``effects.payload_at_m`` (platform frame [m]) is added to the body ``platform`` as a point mass
    (:func:`hexsim.plant.platform.add_point_masses`). Raises InputError for a load the model cannot take
    (mass or inclination on the hexapod, a payload on the single actuator, or one that leaves the
    platform without mass or with principal moments no rigid body has).
    """
    single = spec.body("platform") is None
    if effects.payload_kg != 0.0:
        if single:
            raise InputError("a payload applies to the hexapod's platform; the single actuator takes mass_kg")
        add_point_masses(spec.body("platform"), effects.payload_kg, np.asarray([effects.payload_at_m], dtype=float),
                         "a payload")
    if effects.mass_kg is None and effects.inclination_deg is None:
        return
    if not single:
        raise InputError("mass_kg and inclination_deg apply to the single-actuator model only")
    if effects.mass_kg is not None:
        spec.joint("leg1").parent.mass = effects.mass_kg
    if effects.inclination_deg is not None:
        g = float(np.linalg.norm(spec.option.gravity))
        angle = np.deg2rad(effects.inclination_deg)
        spec.option.gravity = [g * np.sin(angle), 0.0, -g * np.cos(angle)]


