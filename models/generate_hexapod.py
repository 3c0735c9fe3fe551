"""Write ``micro_motion_system.xml``: the MJCF of the Micro Motion System hexapod.

The rigid-body facts of the model live in the MJCF (STYLE.md §2); this script only computes the
joint coordinates of a 6-6 hexapod from the few design numbers below, so the XML is reproducible.
Run ``python models/generate_hexapod.py`` after changing a number; ``tests/test_models.py`` checks
that the committed XML matches its output.

Geometry (a small hexapod of the Micro Motion System's class: 600 kg payload, 0.2 m stroke, seed §2.2):

- base joints on a circle of radius R_b = 0.60 m, in three pairs at 0°, 120°, 240° ± 12°;
- platform joints on a circle of radius R_p = 0.40 m, in three pairs at 60°, 180°, 300° ± 12° (that is 0°, 120°, 240° ± 48°)
  (each leg leans sideways towards the neighbouring pair, the classic 6-6 layout);
- retracted joint-to-joint length L_min = 0.52 m, stroke L_s = 0.2 m (seed app. A), so the neutral
  length is L_min + L_s/2 = 0.62 m and the legs stand at 54.2° elevation;
- base joints 0.15 m above the floor; neutral platform height 0.15 + 0.5027 m.

With this layout heave ±0.06 m needs pistons 0.052…0.150 m and roll/pitch ±6° needs 0.069…0.134 m,
inside the 0…0.2 m stroke (checked in tests/test_kinematics.py).
"""

from __future__ import annotations

import pathlib

import numpy as np

R_BASE = 0.60  # [m] base joint circle radius
R_PLATFORM = 0.40  # [m] platform joint circle radius
HALF_ANGLE_BASE = np.deg2rad(12.0)  # [rad] half separation of a base joint pair
HALF_ANGLE_PLATFORM = np.deg2rad(12.0)  # [rad] half separation of a platform joint pair
L_MIN = 0.52  # [m] joint-to-joint length at y = 0 (piston fully retracted)
STROKE = 0.2  # [m] L_s, seed app. A
Z_BASE = 0.15  # [m] height of the base joints above the floor
PLATFORM_MASS = 600.0  # [kg] seed §2.2.1: payload of approximately 600 kg
PLATFORM_BOX = (1.2, 1.2, 0.4)  # [m] uniform box the platform inertia is computed from
CYLINDER_MASS = 6.0  # [kg] barrel, Ø60 mm steel tube, 0.4 m
ROD_MASS = 2.5  # [kg] Ø30 mm chromed rod (0.4 m, 2.2 kg) + piston


def joint_coordinates() -> tuple[np.ndarray, np.ndarray, float]:
    """Base anchors (6, 3) [m, world], platform anchors (6, 3) [m, platform frame], neutral height h [m]."""
    base, plat = [], []
    for k in range(3):
        c = np.deg2rad(120.0 * k)
        for s in (-1.0, 1.0):
            base.append([R_BASE * np.cos(c + s * HALF_ANGLE_BASE), R_BASE * np.sin(c + s * HALF_ANGLE_BASE), Z_BASE])
            cp = c + s * (np.deg2rad(60.0) - HALF_ANGLE_PLATFORM)
            plat.append([R_PLATFORM * np.cos(cp), R_PLATFORM * np.sin(cp), 0.0])
    base_a, plat_a = np.array(base), np.array(plat)
    horizontal = np.linalg.norm(plat_a[0, :2] - base_a[0, :2])
    h = float(np.sqrt((L_MIN + STROKE / 2) ** 2 - horizontal**2))
    return base_a, plat_a, h


def _f(v) -> str:
    return " ".join(f"{x:.9f}" for x in np.atleast_1d(v))


def render() -> str:
    base, plat, h = joint_coordinates()
    z_plat = Z_BASE + h
    l_neutral = L_MIN + STROKE / 2
    bx, by, bz = PLATFORM_BOX
    ixx = PLATFORM_MASS / 12 * (by**2 + bz**2)
    iyy = PLATFORM_MASS / 12 * (bx**2 + bz**2)
    izz = PLATFORM_MASS / 12 * (bx**2 + by**2)
    legs = []
    for i in range(6):
        n = i + 1
        direction = (np.array([0, 0, z_plat]) + plat[i]) - base[i]
        direction /= np.linalg.norm(direction)
        legs.append(f"""
    <!-- leg {n}: universal joint at the base, barrel, slide `leg{n}` (piston position y), rod -->
    <body name="cylinder{n}" pos="{_f(base[i])}" zaxis="{_f(direction)}">
      <joint name="leg{n}_u1" class="ujoint" axis="1 0 0"/>
      <joint name="leg{n}_u2" class="ujoint" axis="0 1 0"/>
      <inertial pos="0 0 0.25" mass="{CYLINDER_MASS}" diaginertia="0.083 0.083 0.0048"/>
      <geom class="visual" type="cylinder" fromto="0 0 0.05 0 0 0.45" size="0.03" material="barrel"/>
      <body name="rod{n}">
        <joint name="leg{n}" class="piston"/>
        <inertial pos="0 0 {l_neutral - 0.2:.6f}" mass="{ROD_MASS}" diaginertia="0.034 0.034 0.0003"/>
        <geom class="visual" type="cylinder" fromto="0 0 {l_neutral - 0.4:.6f} 0 0 {l_neutral:.9f}" size="0.015" material="rod"/>
        <site name="rod{n}_tip" pos="0 0 {l_neutral:.9f}" size="0.02"/>
      </body>
    </body>""")
    anchors = "\n".join(
        f'      <site name="platform_anchor{i + 1}" pos="{_f(plat[i])}" size="0.025" rgba="0.9 0.5 0.1 1"/>'
        for i in range(6)
    )
    connects = "\n".join(
        f'    <connect name="leg{i + 1}_top" site1="rod{i + 1}_tip" site2="platform_anchor{i + 1}"/>' for i in range(6)
    )
    sensors_legs = "\n".join(
        f'    <jointpos name="leg{i + 1}_pos" joint="leg{i + 1}"/>\n    <jointvel name="leg{i + 1}_vel" joint="leg{i + 1}"/>'
        for i in range(6)
    )
    motors = "\n".join(f'    <motor name="leg{i + 1}_force" joint="leg{i + 1}"/>' for i in range(6))
    # qpos: platform free joint (x y z, quaternion w x y z), then per leg u1, u2, piston y.
    key_qpos = f"0 0 {z_plat:.9f} 1 0 0 0 " + " ".join("0 0 0.1" for _ in range(6))
    return f"""<!-- Micro Motion System (Rexroth-Hydraudyne), six-DOF hydraulic hexapod.
     GENERATED by models/generate_hexapod.py: edit the numbers there, then rerun it.
     Seed: "Compensation of the reversal bump", Rexroth-Hydraudyne / TU Eindhoven 2005, ch. 2 and app. A.
     Geometry: base joint radius {R_BASE} m (pairs at 0/120/240 deg +-{np.rad2deg(HALF_ANGLE_BASE):.0f} deg), platform joint
     radius {R_PLATFORM} m (pairs at 60/180/300 deg +-{np.rad2deg(HALF_ANGLE_PLATFORM):.0f} deg,
     i.e. 0/120/240 deg +-{60 - np.rad2deg(HALF_ANGLE_PLATFORM):.0f} deg), retracted joint-to-joint length
     {L_MIN} m, stroke {STROKE} m, neutral leg length {l_neutral} m at {np.rad2deg(np.arcsin(h / l_neutral)):.1f} deg elevation.
     Each leg is a UPS chain: universal joint (two hinges) at the base, slide joint = piston position y
     (0 = fully retracted, `ref` 0.1 = mid-stroke at the neutral pose), ball at the platform realised as an
     equality `connect` between the rod tip and the platform anchor. Contacts are disabled: the hexapod has
     no intended contacts and the legs cross near the joints. -->
<mujoco model="micro_motion_system">
  <compiler angle="radian" autolimits="true"/>

  <!-- 10 kHz physics as in the seed's Simulink model (seed section 3.3). -->
  <option timestep="1e-4" integrator="Euler">
    <flag contact="disable"/>
  </option>

  <default>
    <default class="visual">
      <geom contype="0" conaffinity="0" group="2" density="0"/>
    </default>
    <default class="collision">
      <geom group="3" density="0"/>
    </default>
    <default class="ujoint">
      <joint type="hinge" damping="0"/>
    </default>
    <default class="piston">
      <!-- Piston position y over the stroke L_s = 0.2 m (seed app. A). Soft end stops: a limit constraint
           with a 4 ms time constant, critically damped (cushioned cylinder ends). -->
      <joint type="slide" axis="0 0 1" ref="0.1" range="0 {STROKE}" solreflimit="0.004 1" solimplimit="0.95 0.99 0.001"/>
    </default>
    <!-- Connects stiff enough that the static violation under 600 kg stays well below 0.1 mm
         (time constant 0.5 ms = 5 physics steps, the smallest MuJoCo keeps stable at dt = 1e-4 s). -->
    <equality solref="0.0005 1" solimp="0.9999 0.9999 0.001"/>
  </default>

  <asset>
    <material name="base" rgba="0.35 0.35 0.38 1"/>
    <material name="platform" rgba="0.15 0.35 0.65 0.85"/>
    <material name="barrel" rgba="0.75 0.75 0.78 1"/>
    <material name="rod" rgba="0.92 0.92 0.95 1"/>
  </asset>

  <worldbody>
    <body name="base">
      <geom class="visual" type="cylinder" size="{R_BASE + 0.1} 0.02" pos="0 0 {Z_BASE - 0.04}" material="base"/>
    </body>

    <!-- Platform (frame + payload): {PLATFORM_MASS:.0f} kg, inertia of a uniform {bx} x {by} x {bz} m box (a simulator
         cabin on a 1.2 m square frame) with its centre of mass {bz / 2} m above the upper joint plane:
         Ixx = Iyy = m (b^2 + c^2) / 12 = {ixx:.1f} kg m^2, Izz = {izz:.1f} kg m^2. The site `platform_centre` is
         the centre of the upper joint plane, where the accelerometer and gyro sit. -->
    <body name="platform" pos="0 0 {z_plat:.9f}">
      <freejoint name="platform"/>
      <inertial pos="0 0 {bz / 2}" mass="{PLATFORM_MASS}" diaginertia="{ixx:.4f} {iyy:.4f} {izz:.4f}"/>
      <geom class="visual" type="box" size="{bx / 2} {by / 2} 0.03" pos="0 0 0.03" material="platform"/>
      <geom class="visual" type="box" size="0.45 0.45 {bz / 2 - 0.03:.3f}" pos="0 0 {bz / 2 + 0.03:.3f}" rgba="0.6 0.6 0.65 0.3"/>
      <site name="platform_centre" pos="0 0 0" size="0.03" rgba="1 0 0 1"/>
{anchors}
    </body>
{"".join(legs)}
  </worldbody>

  <equality>
{connects}
  </equality>

  <actuator>
    <!-- Hydraulic leg force P1 A1 - P_s A2 - F_f (seed eq. 3.8) in N, written by hexsim's control callback. -->
{motors}
  </actuator>

  <sensor>
    <accelerometer name="platform_acc" site="platform_centre"/>
    <gyro name="platform_gyro" site="platform_centre"/>
    <frameangacc name="platform_angacc" objtype="site" objname="platform_centre"/>
    <framepos name="platform_pos" objtype="site" objname="platform_centre"/>
    <framequat name="platform_quat" objtype="site" objname="platform_centre"/>
{sensors_legs}
  </sensor>

  <keyframe>
    <!-- All legs at mid-stroke (y = 0.1 m), platform at rest in its neutral pose. -->
    <key name="neutral" qpos="{key_qpos}"/>
  </keyframe>
</mujoco>
"""


def main() -> None:
    out = pathlib.Path(__file__).with_name("micro_motion_system.xml")
    out.write_text(render())
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
