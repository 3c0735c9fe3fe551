"""The platform-only formulation of the hexapod: the platform as the only moving body, the legs as
geometry (issue 15).

The full model (``models/hexapod.py``, its XML ``models/micro_motion_system.xml``) has 13 bodies, 18
leg joints and six 3-D connect constraints closing the loops; most of a step is MuJoCo solving those constraints. Here the same
hexapod, built with ``mujoco.MjSpec`` from the full model's own spec (one source of geometry), is one
free body, and each leg is computed from the platform's pose:

* **kinematics**: leg i runs from its base anchor b_i (world) to its platform anchor a_i (platform
  frame); with the pose (p, R): L_i = |p + R a_i - b_i|, u_i the unit vector along it, the piston
  position y_i = L_i - L_min,i and ẏ_i = u_i · (v + R (ω × a_i)) (MuJoCo's free joint: v in the
  world frame, ω in the body frame);
* **force**: the leg force F_i (seed eq. 3.8) along u_i at the anchor, applied as the platform's
  ``xfrc_applied`` (force at the centre of mass and its moment);
* **the legs' inertia**: each leg's mass along its axis (the rod, m_r) lumped as a point mass at its
  anchor, folded into the platform's inertia (mass, centre of mass, inertia by the parallel-axis
  theorem). Across the leg the true effective mass is I_pivot / L² (2.25…2.77 kg over the stroke for
  this model, 2.43 kg at mid-stroke) where the point mass has m_r = 2.5 kg: 0.04 % of the platform's mass;
* **the legs' weight**: a leg pivoting at its base hangs part of its weight on the platform. With S(y)
  the leg's first moment of mass about the base pivot along the leg (barrel m_c r_c + rod m_r r_r(y)),
  the platform carries (S/L) g⊥ across the leg (g⊥ = g - (g·u) u) and the rod's weight along it. The
  point mass already puts m_r g there, so the correction (S/L - m_r) g⊥ is applied at the anchor. The
  static leg forces then equal the full model's (tests/plant/test_platform.py);
* **end stops**: the full model's piston limit (a soft constraint, time constant τ and damping ratio ζ
  from its ``solreflimit``) as a one-sided spring-damper on the leg's effective mass m_e (from the
  mobility at the neutral pose): F = m_e (δ/τ² + 2ζ δ̇/τ) while the piston is beyond its range by δ,
  never pulling.

Left out (and why it is small): the legs' rotational inertia beyond the point mass and the Coriolis and
centripetal forces of the swinging legs (a leg swings at most ~0.1 rad/s here).

The compiled functions (:func:`read_legs`, :func:`leg_wrench`) are used by the kernel and, called from
Python, by the reference engine; they are written once.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import mujoco
import numba
import numpy as np

from hexsim.errors import InputError

#: the custom numerics the platform model carries: name -> meaning
NUMERICS = {
    "hexsim_leg_base": "(3 n,) base anchors, world frame [m]",
    "hexsim_leg_anchor": "(3 n,) platform anchors, platform frame [m]",
    "hexsim_leg_lmin": "(n,) leg length at y = 0 [m]",
    "hexsim_leg_stroke": "(2,) piston range lo, hi [m]",
    "hexsim_leg_mass": "(3,) lumped mass m_r [kg], first moment S(0) [kg m], dS/dy = m_r [kg]",
    "hexsim_end_stop": "(2,) time constant τ [s] and damping ratio ζ of the piston limit",
}


class LegGeometry(NamedTuple):
    """The legs of a platform-only model (``kind`` 1) or of a model with slide joints (``kind`` 0, the
    other fields unused). Arrays: base (n, 3) world [m], anchor (n, 3) platform frame [m], l_min (n,)
    [m], stroke (2,) [m]; body: the platform's body id; qadr/dadr: its free joint's qpos/qvel address;
    com (3,) its centre of mass, platform frame [m]; gravity (3,) [m/s^2]; lumped m_r [kg], s0 [kg m]
    (S(y) = s0 + m_r y); stop_k (n,) [N/m] and stop_c (n,) [N s/m], the end stops' gains; ``work``
    (n, 6): each anchor's world position and leg unit vector, written by :func:`read_legs` and read by
    :func:`leg_wrench` at the same pose (computed once per step)."""

    kind: int
    base: np.ndarray
    anchor: np.ndarray
    l_min: np.ndarray
    stroke: np.ndarray
    body: int
    qadr: int
    dadr: int
    com: np.ndarray
    gravity: np.ndarray
    lumped: float
    s0: float
    stop_k: np.ndarray
    stop_c: np.ndarray
    work: np.ndarray


def joint_legs(n: int) -> LegGeometry:
    """The :class:`LegGeometry` of a model whose legs are slide joints (kind 0)."""
    z3, z = np.zeros((n, 3)), np.zeros(n)
    return LegGeometry(0, z3, z3, z, np.zeros(2), 0, 0, 0, np.zeros(3), np.zeros(3), 0.0, 0.0, z, z, np.zeros((n, 6)))


def _numeric(m: mujoco.MjModel, name: str) -> np.ndarray:
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_NUMERIC, name)
    if i < 0:
        raise InputError(f"platform model has no numeric {name!r}")
    adr, size = m.numeric_adr[i], m.numeric_size[i]
    return m.numeric_data[adr:adr + size].copy()


def is_platform_model(m: mujoco.MjModel) -> bool:
    """Whether ``m`` is a platform-only model (it carries the numerics :data:`NUMERICS`)."""
    return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_NUMERIC, "hexsim_leg_lmin") >= 0


def leg_geometry(m: mujoco.MjModel) -> LegGeometry:
    """The legs of a platform-only model, read from its numerics (:data:`NUMERICS`) and its platform body;
    end-stop gains zero until :func:`with_end_stops`. Raises InputError for a model without them."""
    l_min = _numeric(m, "hexsim_leg_lmin")
    n = len(l_min)
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "platform")
    if body < 0 or m.body_jntnum[body] != 1 or m.jnt_type[m.body_jntadr[body]] != mujoco.mjtJoint.mjJNT_FREE:
        raise InputError("platform model needs a body 'platform' with a free joint")
    joint = m.body_jntadr[body]
    lumped, s0, _ = _numeric(m, "hexsim_leg_mass")
    z = np.zeros(n)
    return LegGeometry(1, _numeric(m, "hexsim_leg_base").reshape(n, 3), _numeric(m, "hexsim_leg_anchor").reshape(n, 3),
                       l_min, _numeric(m, "hexsim_leg_stroke"), int(body), int(m.jnt_qposadr[joint]),
                       int(m.jnt_dofadr[joint]), m.body_ipos[body].copy(), m.opt.gravity.copy(), float(lumped),
                       float(s0), z, z, np.zeros((n, 6)))


def with_end_stops(m: mujoco.MjModel, legs: LegGeometry, effective_mass: np.ndarray) -> LegGeometry:
    """``legs`` with end-stop gains for the legs' effective masses (n,) [kg]: k = m_e / τ²,
    c = 2 ζ m_e / τ (τ, ζ: the full model's piston ``solreflimit``)."""
    tau, zeta = _numeric(m, "hexsim_end_stop")
    m_e = np.asarray(effective_mass, dtype=float)
    return legs._replace(stop_k=m_e / tau**2, stop_c=2.0 * zeta * m_e / tau)


# ---------------------------------------------------------------------------------------- the model
def platform_spec(full: mujoco.MjSpec) -> mujoco.MjSpec:
    """The platform-only hexapod built from the full model's spec ``full`` (edited in place and
    returned): the leg bodies, their connects, motors and joint sensors removed; each rod's mass lumped
    at its platform anchor (platform mass, centre of mass and inertia updated); the legs' geometry, mass
    and end stops as the numerics :data:`NUMERICS`; the ``neutral`` keyframe keeps the platform's pose.
    Only what the simulation needs stays: no geoms (contacts are off; hexsim draws the full model from
    the recorded poses), lights or sites but the sensors' ``platform_centre``; each costs time every
    step; MuJoCo's constraint pipeline is switched off, no constraint being left. Raises InputError if
    ``full`` lacks a leg element or its legs differ in mass, stroke or end stops."""
    compiled = full.compile()
    d = mujoco.MjData(compiled)
    mujoco.mj_resetDataKeyframe(compiled, d, mujoco.mj_name2id(compiled, mujoco.mjtObj.mjOBJ_KEY, "neutral"))
    mujoco.mj_forward(compiled, d)
    n = 0
    while mujoco.mj_name2id(compiled, mujoco.mjtObj.mjOBJ_JOINT, f"leg{n + 1}") >= 0:
        n += 1
    if n == 0:
        raise InputError("the full model has no slide joint leg1")
    slide, rod, barrel = leg_bodies(compiled, n)
    anchor_ids = [mujoco.mj_name2id(compiled, mujoco.mjtObj.mjOBJ_SITE, f"platform_anchor{i + 1}") for i in range(n)]
    base = d.xanchor[compiled.body_jntadr[barrel]].copy()
    y0 = d.qpos[compiled.jnt_qposadr[slide]]
    l_min = np.linalg.norm(d.site_xpos[anchor_ids] - base, axis=1) - y0
    r_c, r_r = _along_legs(compiled, slide, rod, barrel)
    legs_alike = [(compiled.body_mass[b], rc, compiled.body_mass[r], rr, *compiled.jnt_range[j], *compiled.jnt_solref[j])
                  for b, r, j, rc, rr in zip(barrel, rod, slide, r_c, r_r)]
    if any(not np.allclose(leg, legs_alike[0], rtol=1e-12) for leg in legs_alike):
        raise InputError("the platform-only model takes legs alike (masses, centres of mass, stroke, end stops)")
    m_r = float(compiled.body_mass[rod[0]])
    # first moment about the base pivot along the leg: barrel m_c r_c + rod m_r (r_r,ref + y - ref)
    s0 = float(compiled.body_mass[barrel[0]] * r_c[0] + m_r * (r_r[0] - compiled.qpos0[compiled.jnt_qposadr[slide[0]]]))
    stroke = compiled.jnt_range[slide[0]].copy()
    tau, zeta = compiled.jnt_solref[slide[0]]
    anchors = compiled.site_pos[anchor_ids].copy()
    body = functools.partial(mujoco.mj_name2id, compiled, mujoco.mjtObj.mjOBJ_BODY)

    _strip_legs(full, n)
    add_point_masses(full.body("platform"), m_r, anchors, "a rod")
    for name, data in (("hexsim_leg_base", base.ravel()), ("hexsim_leg_anchor", anchors.ravel()),
                       ("hexsim_leg_lmin", l_min), ("hexsim_leg_stroke", stroke), ("hexsim_leg_mass", [m_r, s0, m_r]),
                       ("hexsim_end_stop", [tau, zeta])):
        full.add_numeric(name=name, data=list(map(float, data)), size=len(data))
    key = full.key("neutral")
    plat = compiled.jnt_qposadr[compiled.body_jntadr[body("platform")]]
    key.qpos = list(d.qpos[plat:plat + 7])
    full.modelname = full.modelname.removesuffix(" scene") + "_platform"
    full.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)  # ~10 % of a step, to the bit
    return full


def leg_bodies(m: mujoco.MjModel, n_legs: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Slide joints ``leg1`` … ``leg{n_legs}``, their rods (the bodies the slides move) and barrels (the
    rods' parents), as (n_legs,) id arrays of a model with slide-joint legs. Raises InputError for a
    missing slide."""
    slides = np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"leg{i + 1}") for i in range(n_legs)])
    if np.any(slides < 0):
        raise InputError(f"model has no slide joint leg{int(np.argmin(slides)) + 1}")
    rods = m.jnt_bodyid[slides]
    return slides, rods, m.body_parentid[rods]


def _along_legs(m: mujoco.MjModel, slide: np.ndarray, rod: np.ndarray, barrel: np.ndarray):
    """(n,) each: the barrels' and the rods' centres of mass along their legs from the base pivot [m], the
    rods at the slide's reference position (``qpos0``), computed in the barrels' frames (where hexsim's
    builder makes them its numbers exactly)."""
    r_c, r_r = np.empty(len(slide)), np.empty(len(slide))
    axis, ipos = np.empty(3), np.empty(3)
    for i, (j, r, b) in enumerate(zip(slide, rod, barrel)):
        mujoco.mju_rotVecQuat(axis, m.jnt_axis[j], m.body_quat[r])  # the slide's axis in the barrel frame
        mujoco.mju_rotVecQuat(ipos, m.body_ipos[r], m.body_quat[r])
        pivot = m.jnt_pos[m.body_jntadr[b]]
        r_c[i] = (m.body_ipos[b] - pivot) @ axis
        r_r[i] = (m.body_pos[r] + ipos - pivot) @ axis
    return r_c, r_r


def _strip_legs(full: mujoco.MjSpec, n: int) -> None:
    """Delete from ``full`` the ``n`` legs' bodies, connects, motors and every sensor but the platform's,
    tendons, contact pairs and exclusions, and every geom, light, site (but ``platform_centre``) and
    static body left empty (each costs time every step)."""
    from hexsim.models.hexapod import PLATFORM_SENSORS

    keep = {name for name, _ in PLATFORM_SENSORS}
    for element in [*full.equalities, *full.actuators, *full.tendons, *full.pairs, *full.excludes]:
        full.delete(element)
    for s in list(full.sensors):
        if s.name not in keep:
            full.delete(s)
    for i in range(n):
        full.delete(full.joint(f"leg{i + 1}").parent.parent)
    for element in [*full.geoms, *full.lights, *(s for s in full.sites if s.name != "platform_centre")]:
        full.delete(element)
    for static in [b for b in full.worldbody.bodies if b.name != "platform" and not b.bodies and not b.sites]:
        full.delete(static)  # the base, a visual geom only: an empty body still costs a step


def add_point_masses(body: mujoco.MjsBody, mass: float, points: np.ndarray, what: str = "a point mass") -> None:
    """Add a point mass ``mass`` [kg] (negative: take mass away) at each of ``points`` (k, 3) [m, body
    frame] to the inertial of ``body`` (a spec's body, edited in place): new mass, centre of mass and
    inertia about it (parallel-axis theorem on the full tensor, then principal axes through ``iquat``).
    Raises InputError, naming ``what``, if the body would be left with no mass, an inertia that is not
    positive definite, or principal moments that break the triangle inequality A + B >= C."""
    m0, c0 = body.mass, np.array(body.ipos)
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.array(body.iquat))
    rot = rot.reshape(3, 3)
    inertia0 = rot @ np.diag(body.inertia) @ rot.T
    total = m0 + mass * len(points)
    where = f" at {tuple(float(x) for x in points[0])} m" if len(points) == 1 else ""
    if total <= 0.0:
        raise InputError(f"{what} of {mass:g} kg leaves the {body.name} with {total:g} kg")
    com = (m0 * c0 + mass * points.sum(axis=0)) / total

    def shifted(m, r):
        return m * (r @ r * np.eye(3) - np.outer(r, r))

    inertia = inertia0 + shifted(m0, c0 - com) + sum(shifted(mass, a - com) for a in points)
    w, v = np.linalg.eigh(inertia)
    if w.min() <= 0.0:
        raise InputError(f"{what} of {mass:g} kg{where} leaves an inertia that is not positive definite")
    if w[0] + w[1] < w[2]:  # eigh sorts ascending; MuJoCo refuses such a body when it compiles
        raise InputError(f"{what} of {mass:g} kg{where} leaves principal moments {w[0]:.4g}, {w[1]:.4g}, "
                         f"{w[2]:.4g} kg m^2 that no rigid body has (A + B < C)")
    if np.linalg.det(v) < 0:
        v[:, 0] = -v[:, 0]
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, v.flatten())
    body.mass, body.ipos, body.inertia, body.iquat = total, com, w, quat
    body.explicitinertial = True


# ------------------------------------------------------------------------------ compiled kinematics
@numba.njit(cache=True, inline="always")
def _pose(qpos, a):
    """The platform's position (x, y, z) and rotation matrix entries (row-major, 9) from its free joint's
    qpos at address ``a`` (quaternion normalised), as 12 scalars: the per-step kernels allocate nothing."""
    w, x, y, z = qpos[a + 3], qpos[a + 4], qpos[a + 5], qpos[a + 6]
    s = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w * s, x * s, y * s, z * s
    return (qpos[a], qpos[a + 1], qpos[a + 2],
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))


@numba.njit(cache=True, inline="always")
def read_legs(g, qpos, qvel, y, yd):
    """Piston positions y (n,) [m] and velocities ẏ (n,) [m/s] of a platform-only model (``g`` its
    :class:`LegGeometry`) from the platform's qpos/qvel, written in place (module docstring); each
    anchor's world position and leg unit vector into ``g.work``."""
    anchor, base, l_min, work, da = g.anchor, g.base, g.l_min, g.work, g.dadr
    px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22 = _pose(qpos, g.qadr)
    vx, vy, vz, wx, wy, wz = qvel[da], qvel[da + 1], qvel[da + 2], qvel[da + 3], qvel[da + 4], qvel[da + 5]
    for i in range(l_min.shape[0]):
        a0, a1, a2 = anchor[i, 0], anchor[i, 1], anchor[i, 2]
        ax = px + r00 * a0 + r01 * a1 + r02 * a2
        ay = py + r10 * a0 + r11 * a1 + r12 * a2
        az = pz + r20 * a0 + r21 * a1 + r22 * a2
        dx, dy, dz = ax - base[i, 0], ay - base[i, 1], az - base[i, 2]
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        ux, uy, uz = dx / length, dy / length, dz / length
        work[i, 0], work[i, 1], work[i, 2], work[i, 3], work[i, 4], work[i, 5] = ax, ay, az, ux, uy, uz
        c0, c1, c2 = wy * a2 - wz * a1, wz * a0 - wx * a2, wx * a1 - wy * a0  # ω × a (body frame)
        y[i] = length - l_min[i]
        yd[i] = (ux * (vx + r00 * c0 + r01 * c1 + r02 * c2) + uy * (vy + r10 * c0 + r11 * c1 + r12 * c2)
                 + uz * (vz + r20 * c0 + r21 * c1 + r22 * c2))


@numba.njit(cache=True, inline="always")
def leg_wrench(g, qpos, y, yd, force, xfrc):
    """Write the platform's ``xfrc_applied`` row (``xfrc`` (nbody, 6): force and moment about its centre
    of mass, world frame) for the leg forces ``force`` (n,) [N] along the legs at their anchors, the
    end stops and the legs' weight correction (module docstring); y, ẏ (n,) and the anchors (``g.work``)
    from :func:`read_legs` at the same ``qpos``."""
    com, grav, stroke, work, l_min = g.com, g.gravity, g.stroke, g.work, g.l_min
    stop_k, stop_c, s0, lumped = g.stop_k, g.stop_c, g.s0, g.lumped
    px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22 = _pose(qpos, g.qadr)
    cx = px + r00 * com[0] + r01 * com[1] + r02 * com[2]
    cy = py + r10 * com[0] + r11 * com[1] + r12 * com[2]
    cz = pz + r20 * com[0] + r21 * com[1] + r22 * com[2]
    gx, gy, gz = grav[0], grav[1], grav[2]
    lo, hi = stroke[0], stroke[1]
    fx = fy = fz = tx = ty = tz = 0.0
    for i in range(l_min.shape[0]):
        ax, ay, az, ux, uy, uz = work[i, 0], work[i, 1], work[i, 2], work[i, 3], work[i, 4], work[i, 5]
        axial = force[i]
        if y[i] < lo:
            axial += max(0.0, stop_k[i] * (lo - y[i]) - stop_c[i] * yd[i])
        elif y[i] > hi:
            axial -= max(0.0, stop_k[i] * (y[i] - hi) + stop_c[i] * yd[i])
        gu = gx * ux + gy * uy + gz * uz
        across = (s0 + lumped * y[i]) / (l_min[i] + y[i]) - lumped
        f0 = axial * ux + across * (gx - gu * ux)
        f1 = axial * uy + across * (gy - gu * uy)
        f2 = axial * uz + across * (gz - gu * uz)
        r0, r1, r2 = ax - cx, ay - cy, az - cz
        fx += f0
        fy += f1
        fz += f2
        tx += r1 * f2 - r2 * f1
        ty += r2 * f0 - r0 * f2
        tz += r0 * f1 - r1 * f0
    xfrc[g.body, 0], xfrc[g.body, 1], xfrc[g.body, 2] = fx, fy, fz
    xfrc[g.body, 3], xfrc[g.body, 4], xfrc[g.body, 5] = tx, ty, tz


def leg_jacobian(m: mujoco.MjModel, d: mujoco.MjData, g: LegGeometry) -> np.ndarray:
    """(n, nv) Jacobian of the piston positions y with respect to qvel: row i is u_iᵀ times MuJoCo's
    translational Jacobian (``mj_jac``) of the platform at leg i's anchor; its transpose maps leg forces
    to generalised forces. Needs ``d``'s kinematics and the anchors of :func:`read_legs` (``g.work``) at
    the same pose."""
    jacp = np.empty((3, m.nv))
    jac = np.empty((len(g.l_min), m.nv))
    for i, row in enumerate(g.work):
        mujoco.mj_jac(m, d, jacp, None, row[:3].copy(), g.body)
        jac[i] = row[3:] @ jacp
    return jac
