"""A hexapod's geometry and masses as data: the machine file's ``hexapod`` section (issue 29).

:class:`Geometry` describes a Stewart platform the way simulation tools do (joint circles with radii,
heights and angles, or joint coordinates; the legs' retracted length and stroke; the masses and
inertias of platform, barrels and rods; where the accelerometer and gyro sit). ``models/hexapod.py``
builds the MuJoCo model from it with ``mujoco.MjSpec``; the defaults are the built-in Micro Motion System
(seed §2.2, app. A), built bit-identical to the model hexsim has always run. A user's own MJCF is named
here too (``mjcf``) and adapted by :mod:`hexsim.plant.user_model`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np

from hexsim.errors import InputError


def _circle(radius: float, angles_deg, z: float) -> np.ndarray:
    angles = np.deg2rad(np.asarray(angles_deg, dtype=float))
    return np.stack([radius * np.cos(angles), radius * np.sin(angles), np.full(len(angles), z)], axis=1)


def joint_coordinates(g: Geometry) -> tuple[np.ndarray, np.ndarray, float]:
    """Base joints (6, 3) [m, world], platform joints (6, 3) [m, platform frame] and the height of the
    platform frame at the neutral pose h [m] above the base joints' plane (above leg 1's base joint).

    Raises InputError if a leg cannot reach the neutral length (its joints farther apart horizontally) or
    the legs have different lengths at the neutral pose (more than 1 µm apart)."""
    base = np.asarray(g.base_joints_m, dtype=float) if g.base_joints_m is not None else \
        _circle(g.base_radius_m, g.base_angles_deg, g.base_height_m)
    plat = np.asarray(g.platform_joints_m, dtype=float) if g.platform_joints_m is not None else \
        _circle(g.platform_radius_m, g.platform_angles_deg, 0.0)
    horizontal = np.linalg.norm(plat[:, :2] - base[:, :2], axis=1)
    if horizontal[0] >= g.neutral_length:
        raise InputError(f"Geometry: leg 1's joints are {horizontal[0]:.4g} m apart horizontally, more than its neutral "
                         f"length {g.neutral_length:.4g} m")
    h = float(np.sqrt(g.neutral_length**2 - horizontal[0] ** 2))
    top = np.array([0.0, 0.0, base[0, 2] + h]) + plat
    lengths = np.linalg.norm(top - base, axis=1)
    if np.max(np.abs(lengths - g.neutral_length)) > 1e-6:
        raise InputError("Geometry: the legs have different lengths at the neutral pose (" + ", ".join(
            f"{x:.4f}" for x in lengths) + " m): hexsim's builder takes a layout whose six legs are alike there")
    return base, plat, h


#: default seated occupant (:attr:`Geometry.seat_point`, :attr:`Geometry.head_point`) [m]
SEAT_ABOVE_DECK_M = 0.30
HEAD_ABOVE_SEAT_M = 0.77


@dataclass(frozen=True)
class Geometry:
    """A Stewart platform as simulation tools describe it: two joint circles, the legs' length and stroke,
    the masses. The defaults are the Micro Motion System (module docstring; seed §2.2, app. A).

    Joints: base joint i at angle ``base_angles_deg[i]`` [deg] on a circle of ``base_radius_m`` [m] at
    height ``base_height_m`` [m] (world frame, z up, origin on the floor below the centre); platform joint i
    at ``platform_angles_deg[i]`` on a circle of ``platform_radius_m`` in the platform frame (origin: the
    centre of the upper joint plane, z up). ``base_joints_m`` / ``platform_joints_m`` ((6, 3) [m], same
    frames) give the joints as coordinates instead (then the circle's numbers are not used). Leg i runs
    from base joint i to platform joint i.

    Legs: ``retracted_length_m`` L_min [m] joint to joint at y = 0; ``stroke_m`` L_s [m] (the machine
    file's ``cylinder.stroke_m``); ``neutral_piston_m`` [m] the piston position at the neutral pose (None:
    mid-stroke); the neutral pose is the platform level above the base's centre with every leg at that
    length (its height is solved from leg 1; every leg must then have it, as on a symmetric layout).
    Barrel: mass [kg], principal inertia (3,) [kg m^2] about its centre of mass, which lies ``barrel_com_m``
    [m] from the base joint along the leg; rod (with piston): mass, inertia, centre of mass
    ``rod_com_m`` [m] from the platform joint back along the rod. Platform (frame and payload): mass,
    principal inertia (3,) about its centre of mass ``platform_com_m`` (3,) [m, platform frame];
    ``sensor_at_m`` (3,) [m, platform frame]: the accelerometer and gyro (site ``platform_centre``).
    The occupant (:mod:`hexsim.studies.perception`): ``head_at_m`` (3,) [m, platform frame], the head's
    vestibular organs, and ``seat_at_m``, the seat's cushion where whole-body vibration enters; None: a
    seated occupant above the platform's centre (:attr:`seat_point`, :attr:`head_point`).
    Drawing only: ``platform_size_m`` (the platform's box), ``barrel_length_m``, ``rod_length_m``
    (the cylinders drawn), ``base_plate_m`` (radius of the base plate; None: 0.1 m beyond the base joints).

    ``mjcf`` (a path) with ``mjcf_legs`` (six slide-joint names), ``mjcf_platform`` (body) and
    ``mjcf_sensor_site``: a user's own MJCF is the hexapod instead (:mod:`hexsim.plant.user_model`); then
    the numbers above are not used.
    """

    name: str = field(default="Micro Motion System (Rexroth-Hydraudyne)", compare=False)
    base_radius_m: float = 0.60
    base_height_m: float = 0.15
    base_angles_deg: tuple[float, ...] = (-12.0, 12.0, 108.0, 132.0, 228.0, 252.0)
    platform_radius_m: float = 0.40
    platform_angles_deg: tuple[float, ...] = (-48.0, 48.0, 72.0, 168.0, 192.0, 288.0)
    base_joints_m: tuple[tuple[float, float, float], ...] | None = None
    platform_joints_m: tuple[tuple[float, float, float], ...] | None = None
    retracted_length_m: float = 0.52
    stroke_m: float = 0.2
    neutral_piston_m: float | None = None
    platform_mass_kg: float = 600.0
    platform_inertia_kgm2: tuple[float, float, float] = (80.0, 80.0, 144.0)  # a uniform 1.2 x 1.2 x 0.4 m box
    platform_com_m: tuple[float, float, float] = (0.0, 0.0, 0.2)
    platform_size_m: tuple[float, float, float] = (1.2, 1.2, 0.4)
    barrel_mass_kg: float = 6.0  # Ø60 mm steel tube, 0.4 m
    barrel_inertia_kgm2: tuple[float, float, float] = (0.083, 0.083, 0.0048)
    barrel_com_m: float = 0.25
    barrel_length_m: float = 0.4
    rod_mass_kg: float = 2.5  # Ø30 mm chromed rod (0.4 m, 2.2 kg) + piston
    rod_inertia_kgm2: tuple[float, float, float] = (0.034, 0.034, 0.0003)
    rod_com_m: float = 0.2
    rod_length_m: float = 0.4
    base_plate_m: float | None = None
    sensor_at_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    head_at_m: tuple[float, float, float] | None = None
    seat_at_m: tuple[float, float, float] | None = None
    mjcf: str | None = None
    mjcf_legs: tuple[str, ...] | None = None
    mjcf_platform: str | None = None
    mjcf_sensor_site: str | None = None

    def __post_init__(self) -> None:
        positive = ("base_radius_m", "platform_radius_m", "retracted_length_m", "stroke_m", "platform_mass_kg",
                    "barrel_mass_kg", "rod_mass_kg", "barrel_length_m", "rod_length_m")
        for name in positive:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InputError(f"Geometry.{name} must be a positive number, got {value!r}")
        for name in ("base_height_m", "barrel_com_m", "rod_com_m"):
            if not math.isfinite(getattr(self, name)):
                raise InputError(f"Geometry.{name} must be a finite number, got {getattr(self, name)!r}")
        for name in ("base_angles_deg", "platform_angles_deg"):
            if len(getattr(self, name)) != 6 or not np.all(np.isfinite(getattr(self, name))):
                raise InputError(f"Geometry.{name} must be six angles in degrees, got {getattr(self, name)!r}")
        for name in ("head_at_m", "seat_at_m"):
            value = getattr(self, name)
            if value is not None and (np.shape(value) != (3,) or not np.all(np.isfinite(value))):
                raise InputError(f"Geometry.{name} must be one [x, y, z] point in metres, got {value!r}")
        for name in ("base_joints_m", "platform_joints_m"):
            value = getattr(self, name)
            if value is not None and np.shape(value) != (6, 3):
                raise InputError(f"Geometry.{name} must be six [x, y, z] points in metres, got {value!r}")
        for name in ("platform_inertia_kgm2", "barrel_inertia_kgm2", "rod_inertia_kgm2"):
            a, b, c = sorted(getattr(self, name))
            if a <= 0 or a + b < c:
                raise InputError(f"Geometry.{name} {list(getattr(self, name))} kg m^2: principal moments must be "
                                 f"positive and no one larger than the other two together (a rigid body's)")
        if not 0.0 < self.neutral_piston < self.stroke_m:
            raise InputError(f"Geometry.neutral_piston_m {self.neutral_piston!r} m must lie inside the stroke "
                             f"0…{self.stroke_m:g} m")
        if self.mjcf_legs is not None and (len(self.mjcf_legs) != 6 or len(set(self.mjcf_legs)) != 6):
            raise InputError(f"Geometry.mjcf_legs must name six different slide joints, got {list(self.mjcf_legs)!r}")
        if self.mjcf is None:
            joint_coordinates(self)

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))

    @property
    def is_mjcf(self) -> bool:
        """Whether the hexapod is a user's own MJCF (``mjcf``), not built from these numbers."""
        return self.mjcf is not None

    @property
    def neutral_piston(self) -> float:
        """Piston position y at the neutral pose [m]."""
        return self.stroke_m / 2 if self.neutral_piston_m is None else self.neutral_piston_m

    @property
    def neutral_length(self) -> float:
        """Joint-to-joint leg length at the neutral pose [m]."""
        return self.retracted_length_m + self.neutral_piston

    @property
    def deck_height(self) -> float:
        """Height of the platform's deck above its frame's origin [m]: the top of the drawn box
        (``platform_size_m``), 0 for a user's MJCF (its deck is not known)."""
        return 0.0 if self.is_mjcf else float(self.platform_size_m[2])

    @property
    def seat_point(self) -> np.ndarray:
        """The seat cushion (3,) [m, platform frame]: ``seat_at_m``, or 0.30 m above the deck's centre (a car
        seat's H-point height above its floor, SAE J1100 H30: 0.25-0.30 m)."""
        if self.seat_at_m is not None:
            return np.asarray(self.seat_at_m, dtype=float)
        return np.array([0.0, 0.0, self.deck_height + SEAT_ABOVE_DECK_M])

    @property
    def head_point(self) -> np.ndarray:
        """The head's vestibular organs (3,) [m, platform frame]: ``head_at_m``, or 0.77 m above the seat
        point (sitting eye height of adults, about 0.79 m at the 50th percentile (DINED, Tilley 2002), the
        labyrinths about 2 cm lower)."""
        if self.head_at_m is not None:
            return np.asarray(self.head_at_m, dtype=float)
        return self.seat_point + np.array([0.0, 0.0, HEAD_ABOVE_SEAT_M])

    @property
    def scale(self) -> float:
        """Size relative to the Micro Motion System (its base radius 0.6 m): the scene's extent and camera."""
        return self.base_radius_m / 0.60 if self.base_joints_m is None else \
            float(np.max(np.linalg.norm(np.asarray(self.base_joints_m)[:, :2], axis=1))) / 0.60


#: the built-in hexapod, the seed's Micro Motion System (module docstring)
MICRO_MOTION_SYSTEM = Geometry()
