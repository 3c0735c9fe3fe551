"""A user's own hexapod MJCF, adapted with ``mujoco.MjSpec`` so hexsim can drive it (issue 29).

A machine file's ``hexapod.mjcf`` names the file (``docs/your-hexapod.md``). hexsim reads it, finds the
hexapod's parts, checks they form six UPS (or SPS) legs closing on one platform, and adds what it
drives and reads; the user's file is never edited.

What it finds (the names in ``hexapod.mjcf_legs`` / ``hexapod.mjcf_platform``, or by convention):

* **legs**: six slide joints (``leg1`` … ``leg6``, or the model's only six slide joints in file order). Each
  slide moves the leg's **rod** (a body with that one joint) inside its **barrel** (the rod's parent),
  which turns at the base on a universal joint (two hinges; anchors apart are said in a note) or a ball,
  and hangs from the world or a static body. The slide's range is the piston's stroke, 0 …
  ``cylinder.stroke_m`` (y = 0 fully retracted, as the hydraulics count it);
* **platform**: a free-jointed child of the world (body ``platform``, or the model's only free body);
* **closures**: for every leg an active equality ``connect`` between its rod (body or site) and the
  platform (body or site), the platform-side ball joint. The slide's axis must run through the base
  joint and that ball (a leg is a straight line joint to joint: the inverse kinematics rest on it).

What it adds: the slides renamed ``leg{i}`` and the platform ``platform`` (references in actuators,
sensors, equalities and exclusions follow); sites ``platform_anchor{i}`` at the balls and
``platform_centre`` at ``hexapod.mjcf_sensor_site`` (or the platform's origin); the force motors
``leg{i}_force`` (a user's actuators on the slides are removed: the hydraulics drive them) and hexsim's
sensors (:func:`hexsim.models.hexapod.add_instruments`); the keyframe ``neutral`` (the user's, or the
model's reference pose ``qpos0``). It makes the closing connects site to site (``rod{i}_tip`` to
``platform_anchor{i}``) and as stiff as the built hexapod's, 0.5 ms (:data:`CLOSURE_SOLREF`), switches contacts off (a hexapod has no intended contacts) and shortens the physics step to the seed's 1e-4 s where the file's is longer (the oil column is stiff).

Public models' other ways of writing the same legs (a range of any origin, a cross piece, three hinges
or a ball welded or connected at the rod's tip, their own servos) are first rewritten into this form by
:mod:`hexsim.plant.user_legs`, each change said in a :class:`~hexsim.errors.ModelNote`. Each thing it
cannot use is refused with one :class:`~hexsim.errors.InputError` line naming the file, the leg and what
is wrong.
"""

from __future__ import annotations

import pathlib

import mujoco
import numpy as np

from hexsim.errors import InputError
from hexsim.plant.geometry import Geometry
from hexsim.plant.user_legs import (
    BALL_TOLERANCE_M,
    body_joints,
    chain,
    conform,
    equality_bodies,
    hinge_spread,
    name_everything,
    note,
)

#: the physics step hexsim runs a user's hexapod at, at most [s] (the seed's 10 kHz, §3.3)
MAX_TIMESTEP_S = 1e-4
#: a closure open by more than this at the neutral pose is refused [m]
CLOSURE_TOLERANCE_M = 1e-4
#: the closing connects' solver parameters, as the built hexapod's (models/hexapod.py): a 0.5 ms time
#: constant; MuJoCo's default 20 ms would make the closed loop a spring softer than the oil column
CLOSURE_SOLREF, CLOSURE_SOLIMP = [0.0005, 1.0], [0.9999, 0.9999, 0.001, 0.5, 2.0]
#: the custom numeric a user's spec carries with each leg's platform-side hinge spread [m] when it keeps
#: cardans whose hinges sit apart (:func:`cardan_spreads`)
CARDAN_NUMERIC = "hexsim_cardan_spread"
#: a slide axis further than this from the line base joint → ball is said in a note [rad]; further than
#: AXIS_REFUSE_RAD (2°) it is refused
AXIS_TOLERANCE_RAD = 1e-3
AXIS_REFUSE_RAD = float(np.deg2rad(2.0))

_J = mujoco.mjtObj.mjOBJ_JOINT
_B = mujoco.mjtObj.mjOBJ_BODY


def user_spec(g: Geometry) -> mujoco.MjSpec:
    """The ``MjSpec`` of the user's MJCF ``g.mjcf`` adapted for hexsim (module docstring). Raises
    InputError (one line: file, leg, what) for a file MuJoCo cannot read or compile, a model that is not
    six slide-joint legs closing on a free platform, a stroke other than ``g.stroke_m``, or names hexsim
    needs that the model already uses for something else."""
    path = pathlib.Path(g.mjcf)
    where = f"{path} (hexapod.mjcf)"
    if not path.is_file():
        raise InputError(f"{where}: no such MJCF file")
    try:
        spec = mujoco.MjSpec.from_file(str(path))
        _rename_user_sensors(spec, where)
        name_everything(spec)
        m = spec.compile()
    except ValueError as exc:
        raise InputError(f"{where}: MuJoCo cannot load it: {' '.join(str(exc).split())}") from None
    legs = _legs(m, g.mjcf_legs, where)
    platform = _platform(m, g.mjcf_platform, where)
    m, legs = _conformed(spec, m, legs, platform, where)
    d = mujoco.MjData(m)
    key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "neutral")
    if key >= 0:
        mujoco.mj_resetDataKeyframe(m, d, key)
    mujoco.mj_forward(m, d)
    closed = []  # per leg: (its closing equality, its rod, the rod's end, the platform joint's hinge spread)
    anchors = []
    for i, joint in enumerate(legs, 1):
        rod = _check_leg(m, d, i, joint, g.stroke_m, where)
        eq, anchor, tip, spread = _closure(m, d, i, rod, platform, where)
        anchors.append(anchor)
        closed.append((eq, rod, tip, spread))
    sensor_at = _sensor_site(m, g.mjcf_sensor_site, platform, where)
    _check_names(m, legs, platform, where)
    names = [mujoco.mj_id2name(m, _J, j) for j in legs]
    replaced = [a for a in spec.actuators if a.target in names]
    if replaced:
        note(f"{where}: the model's actuators on the slides ({', '.join(a.name or '(unnamed)' for a in replaced)}) are "
             f"replaced by hexsim's force motors (the hydraulics drive the legs)")
    for a in replaced:
        spec.delete(a)
    for i, name in enumerate(names, 1):
        _rename(spec, "joint", name, f"leg{i}")
    _rename(spec, "body", mujoco.mj_id2name(m, _B, platform), "platform")
    body = spec.body("platform")  # its inertia as compiled, explicit: a payload and the rods are added to it
    body.mass, body.ipos, body.iquat = float(m.body_mass[platform]), m.body_ipos[platform], m.body_iquat[platform]
    body.inertia, body.explicitinertial = m.body_inertia[platform], True
    _add(spec, anchors, sensor_at, None if key >= 0 else m.qpos0)
    _close_legs(spec, m, d, platform, closed)
    return spec


def _close_legs(spec: mujoco.MjSpec, m: mujoco.MjModel, d: mujoco.MjData, platform: int, closed: list[tuple]) -> None:
    """Each leg's closure (``closed``: per leg its equality, rod, rod-side end and hinge spread, as
    :func:`_closure` gives them) made between sites, as the built hexapod's (the native kernels read the
    sites' gap), and as stiff (:data:`CLOSURE_SOLREF`: MuJoCo's default 20 ms would make the closed loop a
    spring softer than the oil column): a connect from ``rod{i}_tip``, a kept cardan's weld from
    ``cardan{i}_end`` at its last hinge, to ``platform_anchor{i}``; the spreads as :data:`CARDAN_NUMERIC`."""
    for i, (eq, rod, tip, spread) in enumerate(closed, 1):
        site = _body(spec, m, rod).add_site(name=f"rod{i}_tip", pos=list(tip), size=[0.02, 0.005, 0.005])
        rod_side = site.name if spread == 0.0 else _cardan_site(spec, m, d, eq, platform, i)
        e = spec.equalities[eq]
        e.objtype, e.name1, e.name2 = mujoco.mjtObj.mjOBJ_SITE, rod_side, f"platform_anchor{i}"
        e.solref, e.solimp = CLOSURE_SOLREF, CLOSURE_SOLIMP
    spreads = [spread for *_, spread in closed]
    if any(spreads):
        spec.add_numeric(name=CARDAN_NUMERIC, data=list(map(float, spreads)), size=len(spreads))


def cardan_spreads(spec: mujoco.MjSpec) -> np.ndarray:
    """(n,) the spread [m] of each leg's platform-side hinges that ``spec`` keeps as a chain (a cardan as CAD
    draws it, :func:`hexsim.plant.user_legs.conform`); zeros for balls (and any spec without such legs)."""
    numeric = next((n for n in spec.numerics if n.name == CARDAN_NUMERIC), None)
    return np.zeros(0) if numeric is None else np.array(numeric.data, dtype=float)


def _conformed(spec: mujoco.MjSpec, m: mujoco.MjModel, legs: list[int], platform: int,
               where: str) -> tuple[mujoco.MjModel, list[int]]:
    """The model and its legs' slide ids after a public model's conventions are made hexsim's leg
    (:func:`hexsim.plant.user_legs.conform`, ``spec`` edited in place); ``m`` and ``legs`` as they are if
    nothing changed. Raises InputError if MuJoCo cannot compile the edited spec."""
    if not conform(spec, m, legs, platform, where):
        return m, legs
    names = [mujoco.mj_id2name(m, _J, j) for j in legs]
    try:
        m = spec.compile()
    except ValueError as exc:
        raise InputError(f"{where}: MuJoCo cannot compile it after hexsim's edits: {' '.join(str(exc).split())}") from None
    return m, [mujoco.mj_name2id(m, _J, n) for n in names]


def _body(spec: mujoco.MjSpec, m: mujoco.MjModel, body: int) -> mujoco.MjsBody:
    """The spec's body of compiled body ``body`` (named, or found by its place among the spec's bodies)."""
    name = mujoco.mj_id2name(m, _B, body)
    return spec.body(name) if name else spec.bodies[body]


def _legs(m: mujoco.MjModel, names, where: str) -> list[int]:
    """The six leg slide joints' ids, legs 1…6."""
    slides = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE]
    if names is not None:
        ids = [mujoco.mj_name2id(m, _J, n) for n in names]
        for n, j in zip(names, ids):
            if j < 0:
                raise InputError(f"{where}: hexapod.mjcf_legs names joint {n!r}, which the model does not have")
            if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_SLIDE:
                raise InputError(f"{where}: leg joint {n!r} is not a slide joint (a leg's piston is one)")
        return ids
    named = [mujoco.mj_name2id(m, _J, f"leg{i}") for i in range(1, 7)]
    if all(j >= 0 for j in named):
        for i, j in enumerate(named, 1):
            if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_SLIDE:
                raise InputError(f"{where}: joint 'leg{i}' is not a slide joint (a leg's piston is one)")
        return named
    if len(slides) != 6:
        raise InputError(f"{where}: a hexapod has six legs; the model has {len(slides)} slide joints (name them "
                         f"leg1…leg6 or list them in hexapod.mjcf_legs)")
    return slides


def _platform(m: mujoco.MjModel, name, where: str) -> int:
    """The platform body's id: named, or ``platform``, or the only body with a free joint."""
    free = [b for b in range(1, m.nbody) if m.body_jntnum[b] == 1
            and m.jnt_type[m.body_jntadr[b]] == mujoco.mjtJoint.mjJNT_FREE]
    if name is not None or mujoco.mj_name2id(m, _B, "platform") >= 0:
        body = mujoco.mj_name2id(m, _B, name or "platform")
        if body < 0:
            raise InputError(f"{where}: hexapod.mjcf_platform names body {name!r}, which the model does not have")
        if body not in free:
            raise InputError(f"{where}: the platform body {name or 'platform'!r} must move freely (one free joint)")
    elif len(free) != 1:
        raise InputError(f"{where}: the model has {len(free)} free bodies; name the platform in "
                         f"hexapod.mjcf_platform (or call it 'platform')")
    else:
        body = free[0]
    if m.body_parentid[body] != 0:
        raise InputError(f"{where}: the platform body must be a child of the world body")
    return int(body)


def _check_leg(m: mujoco.MjModel, d: mujoco.MjData, i: int, joint: int, stroke: float, where: str) -> int:
    """Check leg ``i``'s slide, rod, barrel and base joint; return the rod's body id."""
    leg = f"{where}: leg{i} ({mujoco.mj_id2name(m, _J, joint) or 'unnamed joint'})"
    lo, hi = m.jnt_range[joint]
    if not m.jnt_limited[joint] or abs(lo) > 1e-9 or abs(hi - stroke) > 1e-9 * max(1.0, stroke):
        shown = f"{lo:g}…{hi:g} m" if m.jnt_limited[joint] else "unlimited"
        raise InputError(f"{leg}: its range {shown} must be the piston's stroke 0…{stroke:g} m (cylinder.stroke_m; "
                         f"y = 0 fully retracted)")
    rod = int(m.jnt_bodyid[joint])
    if m.body_jntnum[rod] != 1:
        raise InputError(f"{leg}: its rod body carries {m.body_jntnum[rod]} joints; the slide must be its only one")
    barrel = int(m.body_parentid[rod])
    kinds = [int(m.jnt_type[j]) for j in range(m.body_jntadr[barrel], m.body_jntadr[barrel] + m.body_jntnum[barrel])]
    hinge, ball = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_BALL)
    if barrel == 0 or kinds not in ([hinge, hinge], [ball]):
        raise InputError(f"{leg}: its barrel (the rod's parent body) must turn at the base on a universal joint "
                         f"(two hinges) or a ball; it has {len(kinds)} joint(s) of kinds {kinds}")
    parent = int(m.body_parentid[barrel])
    if m.body_weldid[parent] != 0:
        raise InputError(f"{leg}: its barrel must hang from the world or a static base body")
    first = m.body_jntadr[barrel]
    gap = float(np.linalg.norm(d.xanchor[first] - d.xanchor[first + 1])) if len(kinds) == 2 else 0.0
    if gap > 1e-9:
        note(f"{leg}: its two base hinges' anchors are {gap * 1e3:.1f} mm apart; hexsim's kinematics pivot the leg "
             f"at the first (the leg's length off by up to {gap * (1 - np.cos(np.deg2rad(10.0))) * 1e3:.2f} mm at "
             f"10° about the second)")
    return rod


def _point(m: mujoco.MjModel, d: mujoco.MjData, eq: int, side: int) -> tuple[int, np.ndarray]:
    """Body and world position of side ``side`` (0, 1) of connect ``eq`` in the state of ``d``."""
    obj = m.eq_obj1id[eq] if side == 0 else m.eq_obj2id[eq]
    if m.eq_objtype[eq] == mujoco.mjtObj.mjOBJ_SITE:
        return int(m.site_bodyid[obj]), d.site_xpos[obj].copy()
    local = m.eq_data[eq, 3 * side:3 * side + 3]
    return int(obj), d.xpos[obj] + d.xmat[obj].reshape(3, 3) @ local


def _closure(m: mujoco.MjModel, d: mujoco.MjData, i: int, rod: int, platform: int,
             where: str) -> tuple[int, np.ndarray, np.ndarray, float]:
    """The equality that closes leg ``i``'s loop, the leg's ball (3,) [m] in the platform's frame, its
    rod-side end (3,) [m] in the rod's frame, and the spread of its platform joint's hinges [m]: a connect
    between the rod and the platform (a ball: spread 0), or a weld to the platform from the bodies of a
    cardan at the rod's tip whose hinges sit apart (:func:`hexsim.plant.user_legs.conform` keeps those; the
    leg's ends are then its last hinge, on the platform's side, and its first, on the rod)."""
    leg = f"{where}: leg{i}"
    for eq in range(m.neq):
        if not m.eq_active0[eq]:
            continue
        if m.eq_type[eq] == mujoco.mjtEq.mjEQ_WELD:
            cardan = _cardan(m, d, eq, rod, platform)
            if cardan is not None:
                return _checked(m, d, leg, eq, rod, platform, *cardan)
            continue
        if m.eq_type[eq] != mujoco.mjtEq.mjEQ_CONNECT:
            continue
        sides = [_point(m, d, eq, 0), _point(m, d, eq, 1)]
        bodies = [b for b, _ in sides]
        if sorted(bodies) != sorted([rod, platform]):
            continue
        gap = np.linalg.norm(sides[0][1] - sides[1][1])
        if gap > CLOSURE_TOLERANCE_M:
            raise InputError(f"{leg}: its connect is open by {gap * 1e3:.2f} mm at the neutral pose (keyframe 'neutral' "
                             f"or qpos0): the legs must meet the platform there")
        return _checked(m, d, leg, eq, rod, platform, sides[bodies.index(platform)][1], sides[bodies.index(rod)][1],
                        0.0)
    raise InputError(f"{leg}: no active <connect> ties its rod to the platform; hexsim needs each leg's loop closed "
                     f"(the platform-side ball joint)")


def _cardan(m: mujoco.MjModel, d: mujoco.MjData, eq: int, rod: int,
            platform: int) -> tuple[np.ndarray, np.ndarray, float] | None:
    """For weld ``eq`` from a body below ``rod`` whose bodies up to the rod carry hinges apart by more than
    :data:`hexsim.plant.user_legs.BALL_TOLERANCE_M` (a kept cardan): its last hinge's anchor, its first
    hinge's anchor (world, (3,) [m] each) and the hinges' spread [m]; else None."""
    sides = equality_bodies(m, eq)
    if platform not in sides:
        return None
    bodies = chain(m, rod, sides[1 - sides.index(platform)])
    joints = sorted(j for b in bodies or [] for j in body_joints(m, b))
    if not joints or any(m.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE for j in joints):
        return None
    spread = hinge_spread(d.xanchor[joints])
    if spread <= BALL_TOLERANCE_M:
        return None
    return d.xanchor[joints[-1]].copy(), d.xanchor[joints[0]].copy(), spread


def _cardan_site(spec: mujoco.MjSpec, m: mujoco.MjModel, d: mujoco.MjData, eq: int, platform: int, i: int) -> str:
    """Add site ``cardan{i}_end`` on the body weld ``eq`` ties to the platform, at leg ``i``'s ball
    (``platform_anchor{i}``, the cardan's last hinge) and turned as the platform's frame, and return its name:
    the weld made between it and ``platform_anchor{i}`` matches position and orientation at the hinge. Left
    at the body's origin some decimetres away, the weld matched the cardan's position through the rotation of
    its small bodies, which MuJoCo's soft constraint barely holds (the slide moved under a unit force as if
    free: 0.36 against 0.0015-0.0064 1/kg)."""
    sides = equality_bodies(m, eq)
    body = sides[1 - sides.index(platform)]
    anchor = spec.site(f"platform_anchor{i}")
    rot_p, rot_b = d.xmat[platform].reshape(3, 3), d.xmat[body].reshape(3, 3)
    world = d.xpos[platform] + rot_p @ np.asarray(anchor.pos)
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, (rot_b.T @ rot_p).ravel())
    name = f"cardan{i}_end"
    _body(spec, m, body).add_site(name=name, pos=list(rot_b.T @ (world - d.xpos[body])), quat=list(quat),
                                  size=[0.015, 0.005, 0.005])
    return name


def _checked(m: mujoco.MjModel, d: mujoco.MjData, leg: str, eq: int, rod: int, platform: int, ball: np.ndarray,
             tip: np.ndarray, spread: float) -> tuple[int, np.ndarray, np.ndarray, float]:
    """Leg ``leg``'s closure ``eq`` with its ball and its rod-side end (world, (3,) [m]) checked (the slide
    along the line from the base joint to the ball, the piston inside its stroke at the neutral pose) and
    returned as :func:`_closure` does."""
    j = m.body_jntadr[m.body_parentid[rod]]
    base = d.xanchor[j]
    slide = m.body_jntadr[rod]
    line = (ball - base) / np.linalg.norm(ball - base)
    off = np.arccos(np.clip(abs(line @ d.xaxis[slide]), -1.0, 1.0))
    if off > AXIS_REFUSE_RAD:
        raise InputError(f"{leg}: its slide axis is {np.rad2deg(off):.2f}° off the line from its base joint to "
                         f"its platform ball (more than {np.rad2deg(AXIS_REFUSE_RAD):g}°); a leg's piston runs along "
                         f"that line")
    if off > AXIS_TOLERANCE_RAD:
        note(f"{leg}: its slide axis is {np.rad2deg(off):.2f}° off the line from its base joint to its platform "
             f"ball; hexsim's kinematics take the leg along that line (the piston's travel is off by "
             f"{(1 - np.cos(off)) * 100:.2g} % of the length change)")
    y = d.qpos[m.jnt_qposadr[slide]]
    if not 0.0 < y < m.jnt_range[slide, 1]:
        raise InputError(f"{leg}: its piston sits at {y:g} m at the neutral pose, not inside its stroke")
    on_platform = d.xmat[platform].reshape(3, 3).T @ (ball - d.xpos[platform])
    on_rod = d.xmat[rod].reshape(3, 3).T @ (tip - d.xpos[rod])
    return eq, on_platform, on_rod, spread


def _sensor_site(m: mujoco.MjModel, name, platform: int, where: str) -> tuple[np.ndarray, np.ndarray]:
    """Position (3,) and orientation quaternion (4,) of the sensor site in the platform's frame."""
    if name is None:
        return np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])
    site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, name)
    if site < 0:
        raise InputError(f"{where}: hexapod.mjcf_sensor_site names site {name!r}, which the model does not have")
    if m.site_bodyid[site] != platform:
        raise InputError(f"{where}: the sensor site {name!r} must sit on the platform body")
    return m.site_pos[site].copy(), m.site_quat[site].copy()


def _check_names(m: mujoco.MjModel, legs: list[int], platform: int, where: str) -> None:
    """InputError if a name hexsim gives or adds is taken by another element of the model."""
    taken = {
        _J: {f"leg{i}": legs[i - 1] for i in range(1, 7)},
        _B: {"platform": platform},
        mujoco.mjtObj.mjOBJ_SITE: {n: None for n in ["platform_centre", *(f"platform_anchor{i}" for i in range(1, 7)),
                                                     *(f"rod{i}_tip" for i in range(1, 7)),
                                                     *(f"cardan{i}_end" for i in range(1, 7))]},
        mujoco.mjtObj.mjOBJ_SENSOR: {n: None for n in _hexsim_sensor_names()},
    }
    for kind, names in taken.items():
        for name, allowed in names.items():
            found = mujoco.mj_name2id(m, kind, name)
            if found >= 0 and found != allowed:
                raise InputError(f"{where}: hexsim names its own {kind.name.removeprefix('mjOBJ_').lower()} {name!r}; "
                                 f"the model uses that name for another element: rename it")
    for i in range(1, 7):
        actuator = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"leg{i}_force")
        if actuator >= 0 and not (m.actuator_trntype[actuator] == mujoco.mjtTrn.mjTRN_JOINT
                                  and m.actuator_trnid[actuator, 0] in legs):
            raise InputError(f"{where}: hexsim names its own actuator 'leg{i}_force'; the model uses that name for "
                             f"another element: rename it")


def _hexsim_sensor_names() -> list[str]:
    """The sensors hexsim adds to a user's hexapod (:func:`hexsim.models.hexapod.add_instruments`)."""
    from hexsim.models.hexapod import PLATFORM_SENSORS

    return [*(s for s, _ in PLATFORM_SENSORS), *(f"leg{i}_{q}" for i in range(1, 7) for q in ("pos", "vel"))]


def _rename_user_sensors(spec: mujoco.MjSpec, where: str) -> None:
    """The model's own sensors named like one of hexsim's renamed ``user_<name>`` (said in a note)."""
    ours = set(_hexsim_sensor_names())
    for sensor in spec.sensors:
        if sensor.name in ours:
            note(f"{where}: the model's sensor {sensor.name!r} is renamed 'user_{sensor.name}' (hexsim names its own "
                 f"so)")
            sensor.name = f"user_{sensor.name}"


def _rename(spec: mujoco.MjSpec, kind: str, old: str, new: str) -> None:
    """Rename joint or body ``old`` to ``new`` in ``spec`` and every reference to it (actuators, sensors,
    equalities, exclusions): MjSpec keeps references as names."""
    if old == new:
        return
    getattr(spec, kind)(old).name = new
    for a in spec.actuators:
        if a.target == old:
            a.target = new
    for s in spec.sensors:
        if s.objname == old:
            s.objname = new
        if s.refname == old:
            s.refname = new
    for e in spec.equalities:
        if e.name1 == old:
            e.name1 = new
        if e.name2 == old:
            e.name2 = new
    if kind == "body":
        for x in spec.excludes:
            if x.bodyname1 == old:
                x.bodyname1 = new
            if x.bodyname2 == old:
                x.bodyname2 = new


def _add(spec: mujoco.MjSpec, anchors: list[np.ndarray], sensor_at, qpos0) -> None:
    """hexsim's sites, motors, sensors and (``qpos0`` not None) the ``neutral`` keyframe; contacts off and
    the step at most :data:`MAX_TIMESTEP_S`."""
    from hexsim.models.hexapod import add_instruments

    platform = spec.body("platform")
    pos, quat = sensor_at
    platform.add_site(name="platform_centre", pos=list(pos), quat=list(quat), size=[0.03, 0.005, 0.005],
                      rgba=[1, 0, 0, 1])
    for i, anchor in enumerate(anchors, 1):
        platform.add_site(name=f"platform_anchor{i}", pos=list(anchor), size=[0.025, 0.005, 0.005],
                          rgba=[0.9, 0.5, 0.1, 1])
    add_instruments(spec, 6)
    if qpos0 is not None:
        spec.add_key(name="neutral", qpos=list(qpos0))
    spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    spec.option.timestep = min(spec.option.timestep, MAX_TIMESTEP_S)
