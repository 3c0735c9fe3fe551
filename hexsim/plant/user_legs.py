"""Public hexapod MJCFs' conventions brought to hexsim's leg (issue 41), before
:func:`hexsim.plant.user_model.user_spec` checks and adapts the model.

hexsim drives a leg built one way: a **barrel** that turns at the base on its own joints (two hinges, a
universal joint, or a ball) and hangs from a static body, a **rod** moved by the slide alone, and an
active ``connect`` from the rod to the platform (the platform-side ball) — the piston at y = 0 fully
retracted. Public Stewart-platform models write the same mechanism in other ways; each is rewritten
here, in the ``MjSpec``, into that form, and said as a :class:`~hexsim.errors.ModelNote`:

* **a slide range with any origin** (−0.1 … 0.35 m): the lower limit is fully retracted; the slide's
  reference, spring reference and range are shifted by it (its qpos then counts from the lower limit,
  as the hydraulics do). The bodies do not move;
* **a universal joint on two bodies** (a cross piece with one hinge, the barrel with the other): both
  hinges are put on the barrel, the cross piece's first (their order kept; MuJoCo turns a body's joints
  in order, so the motion is the same); the cross piece stays with the base (its mass no longer moves);
* **the platform end as two or three hinges through one point, or a ball, on bodies of their own at the
  rod's tip, closed by a ``weld`` or ``connect`` to the platform**: those joints are taken out (their bodies
  then move with the rod) and the closure is replaced by a ``connect`` at their common point, the ball;
* **the file's own actuators on the slides** are replaced by hexsim's force motors; **its sensors and
  joint equalities on joints taken out** are removed; a sensor named like one of hexsim's is renamed
  ``user_<name>``;
* **keyframes**: ``neutral`` (or the model's reference pose) is carried over joint by joint; the others
  are dropped when the joints changed.

Hinges at the platform end further apart than :data:`BALL_TOLERANCE_M` and closed by a ``weld`` (a cardan
whose two axes sit some centimetres apart, as real cardans and CAD exports have them) are not a ball: they
are kept with their bodies, and hexsim runs that hexapod on the full model with its joint chain (the
platform-only model's legs are straight lines between two points; :func:`hexsim.plant.model.model_spec`
says which model runs and what the offset costs). A closure whose bodies cannot be read as one of these (a
chain hanging from the platform, joints other than hinges and balls, hinges apart closed by a ``connect``)
is refused with one line.
"""

from __future__ import annotations

import warnings

import mujoco
import numpy as np

from hexsim.errors import InputError, ModelNote

#: the hinges of a leg's platform joint within this of each other [m] are made a ball (a point leg's
#: length then off by at most 1 mm x (1 - cos 10 deg) = 0.015 mm at 10 deg of swing); further apart, and closed
#: by a weld, they are kept and the full model runs them
BALL_TOLERANCE_M = 1e-3

_J = mujoco.mjtObj.mjOBJ_JOINT
_B = mujoco.mjtObj.mjOBJ_BODY
_HINGE, _BALL = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_BALL)
#: a joint's attributes carried over when it is re-made on another body
_JOINT_FIELDS = ("type", "range", "limited", "ref", "springref", "stiffness", "damping", "armature", "frictionloss",
                 "solref_limit", "solimp_limit", "margin", "group")


def note(message: str) -> None:
    """Say what hexsim changed in a user's model (:class:`~hexsim.errors.ModelNote`)."""
    warnings.warn(message, ModelNote, stacklevel=3)


def _kinds(m: mujoco.MjModel, body: int) -> list[int]:
    adr, n = m.body_jntadr[body], m.body_jntnum[body]
    return [int(m.jnt_type[j]) for j in range(adr, adr + n)]


def body_joints(m: mujoco.MjModel, body: int) -> list[int]:
    """The ids of the joints of ``body``, in their order."""
    return list(range(m.body_jntadr[body], m.body_jntadr[body] + m.body_jntnum[body]))


def name_everything(spec: mujoco.MjSpec) -> None:
    """Give every unnamed joint, body and equality of ``spec`` a name (``hexsim_joint{k}``, … by its place
    in the spec) so that values and references can follow them through edits."""
    for j, joint in enumerate(spec.joints):
        if not joint.name:
            joint.name = f"hexsim_joint{j}"
    for b, body in enumerate(spec.bodies):
        if b and not body.name:
            body.name = f"hexsim_body{b}"
    for e, eq in enumerate(spec.equalities):
        if not eq.name:
            eq.name = f"hexsim_equality{e}"


def neutral_pose(m: mujoco.MjModel) -> dict[str, np.ndarray]:
    """Joint name -> its qpos values at the neutral pose (keyframe ``neutral``, else ``qpos0``)."""
    key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "neutral")
    qpos = m.key_qpos[key] if key >= 0 else m.qpos0
    size = {int(mujoco.mjtJoint.mjJNT_FREE): 7, _BALL: 4}
    return {mujoco.mj_id2name(m, _J, j): qpos[m.jnt_qposadr[j]:m.jnt_qposadr[j] + size.get(int(m.jnt_type[j]), 1)].copy()
            for j in range(m.njnt)}


def conform(spec: mujoco.MjSpec, m: mujoco.MjModel, legs: list[int], platform: int, where: str) -> bool:
    """Rewrite the legs of ``spec`` (compiled as ``m``, every joint and body named: :func:`name_everything`)
    into hexsim's form (module docstring), in place. ``legs``: the six slides' ids in ``m``; ``platform``:
    its body id. Returns whether anything changed (the caller compiles again). Raises InputError (one
    line naming the file, the leg and what) for a leg it cannot read."""
    d = mujoco.MjData(m)
    key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "neutral")
    if key >= 0:
        mujoco.mj_resetDataKeyframe(m, d, key)
    mujoco.mj_forward(m, d)
    pose = neutral_pose(m)
    removed: list[str] = []
    said: dict[str, list[int]] = {}  # what was changed -> the legs it was changed on (one note each)
    for i, slide in enumerate(legs, 1):
        leg = f"{where}: leg{i} ({mujoco.mj_id2name(m, _J, slide)})"
        for text in (_merge_cross_piece(spec, m, int(m.jnt_bodyid[slide])),
                     _platform_end(spec, m, d, int(m.jnt_bodyid[slide]), platform, leg, removed),
                     _range_from_zero(spec, m, slide, pose)):
            if text:
                said.setdefault(text, []).append(i)
    for text, which in said.items():
        note(f"{where}: leg{'s' if len(which) > 1 else ''} {', '.join(map(str, which))}: {text}")
    changed = bool(said)
    if removed:
        _drop_references(spec, set(removed))
    if changed:
        _carry_keyframe(spec, pose)
    return changed


def _merge_cross_piece(spec: mujoco.MjSpec, m: mujoco.MjModel, rod: int) -> str | None:
    """A universal joint on two bodies (barrel: one hinge, its parent: one hinge, hanging from a static
    body) made the barrel's two hinges, the cross piece's first. Returns what it changed (None: nothing)."""
    barrel = int(m.body_parentid[rod])
    cross = int(m.body_parentid[barrel])
    if not (_kinds(m, barrel) == [_HINGE] and cross and _kinds(m, cross) == [_HINGE]
            and m.body_weldid[m.body_parentid[cross]] == 0):
        return None
    outer, inner = body_joints(m, cross)[0], body_joints(m, barrel)[0]
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, m.body_quat[barrel])
    rot = rot.reshape(3, 3)
    at = rot.T @ (m.jnt_pos[outer] - m.body_pos[barrel])  # the cross piece's hinge in the barrel's frame
    axis = rot.T @ m.jnt_axis[outer]
    body = spec.body(mujoco.mj_id2name(m, _B, barrel))
    old_outer, old_inner = spec.joint(mujoco.mj_id2name(m, _J, outer)), spec.joint(mujoco.mj_id2name(m, _J, inner))
    saved = [(j.name, {f: getattr(j, f) for f in _JOINT_FIELDS}, list(j.pos), list(j.axis))
             for j in (old_outer, old_inner)]
    spec.delete(old_outer)
    spec.delete(old_inner)
    for (name, fields, pos, ax), (new_pos, new_axis) in zip(saved, ((at, axis), (None, None))):
        j = body.add_joint(name=name)
        for f, value in fields.items():
            setattr(j, f, value)
        j.pos = list(new_pos) if new_pos is not None else pos
        j.axis = list(new_axis) if new_axis is not None else ax
    return (f"the universal joint's hinges sit on two bodies (a cross piece and the barrel); both are put on the "
            f"barrel, in their order (the cross piece, {m.body_mass[cross]:.3g} kg, stays with the base)")


def equality_bodies(m: mujoco.MjModel, eq: int) -> list[int]:
    """The two bodies equality ``eq`` ties (a site's body for a site)."""
    site = int(m.eq_objtype[eq]) == int(mujoco.mjtObj.mjOBJ_SITE)
    return [int(m.site_bodyid[o]) if site else int(o) for o in (m.eq_obj1id[eq], m.eq_obj2id[eq])]


def hinge_spread(anchors: np.ndarray) -> float:
    """The largest distance [m] between two of the joints' anchors (k, 3) [m]: 0 for a ball or hinges
    through one point."""
    anchors = np.asarray(anchors, dtype=float)
    return float(np.max(np.linalg.norm(anchors[:, None, :] - anchors[None, :, :], axis=-1)))


def chain(m: mujoco.MjModel, top: int, body: int) -> list[int] | None:
    """The bodies from ``body`` up to ``top`` (exclusive), if ``body`` hangs from ``top``; else None."""
    out = []
    while body not in (top, 0):
        out.append(body)
        body = int(m.body_parentid[body])
    return out if body == top else None


def _platform_end(spec: mujoco.MjSpec, m: mujoco.MjModel, d: mujoco.MjData, rod: int, platform: int, leg: str,
                  removed: list[str]) -> str | None:
    """The rod's closure to the platform: an active connect or weld from a body at the rod's tip whose
    bodies up to the rod carry two or three hinges or a ball, made a connect from the rod at their common
    point (the joints taken out are added to ``removed``) when the hinges meet within
    :data:`BALL_TOLERANCE_M`; hinges further apart and closed by a weld (a cardan as CAD exports it) are kept
    as they are, the full model running their chain (:func:`hexsim.plant.user_model.user_spec`). Returns
    what it changed or kept (None: nothing)."""
    for eq in range(m.neq):
        if not m.eq_active0[eq] or int(m.eq_type[eq]) not in (int(mujoco.mjtEq.mjEQ_CONNECT), int(mujoco.mjtEq.mjEQ_WELD)):
            continue
        sides = equality_bodies(m, eq)
        if platform not in sides:
            continue
        other = sides[1 - sides.index(platform)]
        bodies = chain(m, rod, other)
        if bodies is None:
            if chain(m, platform, other) is not None and other != platform:
                raise InputError(f"{leg}: its platform joint hangs from the platform ({mujoco.mj_id2name(m, _B, other)}); "
                                 f"hexsim reads it at the rod's tip (bodies below the rod)")
            continue
        joints = [j for b in bodies for j in body_joints(m, b)]
        kinds = sorted(int(m.jnt_type[j]) for j in joints)
        if not bodies:  # closed at the rod itself
            if int(m.eq_type[eq]) == int(mujoco.mjtEq.mjEQ_WELD):
                raise InputError(f"{leg}: a weld ties its rod to the platform rigidly; the platform end needs a ball "
                                 f"(a connect, a ball joint or three hinges at the rod's tip)")
            return None
        if kinds not in ([_HINGE] * 2, [_HINGE] * 3, [_BALL]):
            raise InputError(f"{leg}: the bodies between its rod and its closure carry joints of kinds {kinds}; a "
                             f"platform joint is two or three hinges or a ball")
        anchors = d.xanchor[joints]
        spread = hinge_spread(anchors)
        if spread > BALL_TOLERANCE_M:
            if int(m.eq_type[eq]) != int(mujoco.mjtEq.mjEQ_WELD):
                raise InputError(f"{leg}: the hinges of its platform joint are {spread * 1e3:.1f} mm apart and a "
                                 f"connect closes them to the platform (a ball on top of the hinges); close a cardan "
                                 f"with a weld, or bring its hinges within {BALL_TOLERANCE_M * 1e3:g} mm of one point")
            return (f"the platform joint's {'three' if len(joints) == 3 else 'two'} hinges sit {spread * 1e3:.1f} mm apart (a cardan as CAD "
                    f"draws it, closed by a weld): kept with their bodies, as the file has them")
        ball = anchors.mean(axis=0)
        on_rod = d.xmat[rod].reshape(3, 3).T @ (ball - d.xpos[rod])
        names = [mujoco.mj_id2name(m, _J, j) for j in joints]
        for name in names:
            spec.delete(spec.joint(name))
        removed.extend(names)
        kind = "weld" if int(m.eq_type[eq]) == int(mujoco.mjtEq.mjEQ_WELD) else "connect"
        spec.delete(spec.equality(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_EQUALITY, eq)))
        spec.add_equality(type=mujoco.mjtEq.mjEQ_CONNECT, objtype=_B, name1=mujoco.mj_id2name(m, _B, rod),
                          name2=mujoco.mj_id2name(m, _B, platform), data=[*on_rod, 0.0, 0.0, 0.0, 0, 0, 0, 0, 0, 0])
        what = "a ball" if kinds == [_BALL] else f"{'three' if len(joints) == 3 else 'two'} hinges through one point"
        return (f"the platform joint ({what} on bodies at the rod's tip, "
                f"closed by a {kind}) is made a ball at their common point, closed by a connect (those bodies move "
                f"with the rod)")
    return None


def _range_from_zero(spec: mujoco.MjSpec, m: mujoco.MjModel, slide: int, pose: dict) -> str | None:
    """A slide range lo…hi with lo ≠ 0 counted from lo (fully retracted): range 0…hi-lo, reference and
    spring reference less lo; the bodies stay where they are. Returns what it changed (None: nothing)."""
    lo, hi = (float(v) for v in m.jnt_range[slide])
    if not m.jnt_limited[slide] or lo == 0.0:
        return None
    name = mujoco.mj_id2name(m, _J, slide)
    j = spec.joint(name)
    j.range = [0.0, hi - lo]
    j.ref = float(m.qpos0[m.jnt_qposadr[slide]]) - lo
    j.springref = float(m.qpos_spring[m.jnt_qposadr[slide]]) - lo
    pose[name] = pose[name] - lo
    return f"the slide's range {lo:g}…{hi:g} m is counted from its lower limit (fully retracted): 0…{hi - lo:g} m"


def _drop_references(spec: mujoco.MjSpec, joints: set[str]) -> None:
    """Remove the sensors, actuators and joint equalities that name a joint taken out."""
    gone = [s for s in spec.sensors if s.objname in joints or s.refname in joints]
    gone += [a for a in spec.actuators if a.target in joints]
    gone += [e for e in spec.equalities if e.type == mujoco.mjtEq.mjEQ_JOINT and (e.name1 in joints or e.name2 in joints)]
    if gone:
        note("the model's " + ", ".join(f"{type(e).__name__.removeprefix('Mjs').lower()} {e.name or '(unnamed)'}"
                                        for e in gone) + (" name" if len(gone) > 1 else " names")
             + " joints hexsim took out of the platform joints: removed")
    for element in gone:
        spec.delete(element)


def _carry_keyframe(spec: mujoco.MjSpec, pose: dict[str, np.ndarray]) -> None:
    """The ``neutral`` keyframe of the edited spec from ``pose`` (joint name -> qpos values), every other
    keyframe dropped (their joints changed)."""
    others = [k.name for k in spec.keys if k.name != "neutral"]
    for k in list(spec.keys):
        spec.delete(k)
    m = spec.compile()
    qpos = m.qpos0.copy()
    for j in range(m.njnt):
        values = pose.get(mujoco.mj_id2name(m, _J, j))
        if values is not None:
            qpos[m.jnt_qposadr[j]:m.jnt_qposadr[j] + len(values)] = values
    spec.add_key(name="neutral", qpos=list(qpos))
    if others:
        note(f"keyframes {', '.join(others)} dropped: the legs' joints changed (neutral carried over)")
