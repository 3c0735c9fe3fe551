"""Inverse and forward kinematics of the hexapod (the seed's "axis transformation", §2.2.3).

A platform pose is (surge x, sway y, heave z [m], roll, pitch, yaw [rad]) of the platform frame
relative to its neutral pose, in the world frame (z up). The rotation is R = Rz(yaw) Ry(pitch) Rx(roll)
(intrinsic z-y'-x'', the usual aerospace order). Leg i joins base anchor a_i (world) to platform anchor
b_i (platform frame); its length is L_i = |p + R b_i - a_i| and its piston position y_i = L_i - L_min,i.
All joint coordinates are read from the compiled model (built by models/hexapod.py with MjSpec).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from hexsim.control.scenario import DOF_NAMES
from hexsim.errors import WorkspaceError
from hexsim.plant.model import PlantIndex, base_pivots, reset_neutral


def rotation_matrices(rpy: np.ndarray) -> np.ndarray:
    """(N, 3) roll, pitch, yaw [rad] -> (N, 3, 3) rotation matrices R = Rz(yaw) Ry(pitch) Rx(roll)."""
    rpy = np.atleast_2d(rpy)
    return Rotation.from_euler("ZYX", rpy[:, ::-1]).as_matrix()


@dataclass(frozen=True)
class HexapodGeometry:
    """Joint coordinates of the hexapod, read from the compiled model in its ``neutral`` keyframe.

    base: (6, 3) base anchors, world frame [m]; platform: (6, 3) platform anchors, platform frame [m];
    neutral_position: (3,) platform frame origin at the neutral pose, world [m]; l_min: (6,) leg length at
    y = 0 [m]; stroke: (6, 2) piston range [m].
    """

    base: np.ndarray
    platform: np.ndarray
    neutral_position: np.ndarray
    l_min: np.ndarray
    stroke: np.ndarray

    @classmethod
    def from_model(cls, m: mujoco.MjModel) -> "HexapodGeometry":
        idx = PlantIndex.from_model(m)
        d = mujoco.MjData(m)
        reset_neutral(m, d)
        plat = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "platform")
        if idx.platform_only:  # the platform-only model carries its legs' geometry (hexsim.plant.platform)
            return cls(base=idx.legs.base.copy(), platform=idx.legs.anchor.copy(), neutral_position=d.xpos[plat].copy(),
                       l_min=idx.legs.l_min.copy(), stroke=idx.stroke)
        base = base_pivots(m, d, idx.n_legs)
        sites = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"platform_anchor{i + 1}") for i in range(6)]
        anchors_local = m.site_pos[sites].copy()
        lengths = np.linalg.norm(d.site_xpos[sites] - base, axis=1)
        return cls(
            base=base,
            platform=anchors_local,
            neutral_position=d.xpos[plat].copy(),
            l_min=lengths - idx.neutral_y,
            stroke=idx.stroke,
        )

    def leg_vectors(self, poses: np.ndarray) -> np.ndarray:
        """(N, 6) poses -> (N, 6, 3) vectors from base anchor to platform anchor, world frame [m]."""
        poses = np.atleast_2d(np.asarray(poses, dtype=float))
        rot = rotation_matrices(poses[:, 3:])
        p = self.neutral_position + poses[:, :3]
        return p[:, None, :] + np.einsum("nij,kj->nki", rot, self.platform) - self.base[None]

    def leg_lengths(self, poses: np.ndarray) -> np.ndarray:
        """(N, 6) poses -> (N, 6) joint-to-joint leg lengths [m]."""
        return np.linalg.norm(self.leg_vectors(poses), axis=-1)

    def inverse(self, poses: np.ndarray, times: np.ndarray | None = None, *, check: bool = True) -> np.ndarray:
        """Piston setpoints y [m], shape (N, 6), for platform poses (N, 6) (or (6,) -> (6,)).

        Raises WorkspaceError naming the leg, the length and (if ``times`` [s] is given) the time of the
        first pose that needs a piston outside its stroke.
        """
        single = np.ndim(poses) == 1
        y = self.leg_lengths(poses) - self.l_min
        if check:
            lo, hi = self.stroke[:, 0], self.stroke[:, 1]
            bad = (y < lo) | (y > hi)
            if np.any(bad):
                n, leg = np.argwhere(bad)[0]
                when = f" at t = {times[n]:.3f} s" if times is not None else ""
                pose = ", ".join(f"{k}={v:.4g}" for k, v in zip(DOF_NAMES, np.atleast_2d(poses)[n]))
                raise WorkspaceError(
                    f"setpoint{when} ({pose}) needs leg{leg + 1} length {y[n, leg] + self.l_min[leg]:.4f} m, "
                    f"piston position {y[n, leg]:.4f} m, outside its stroke {lo[leg]:.3g}…{hi[leg]:.3g} m"
                )
        return y[0] if single else y

    def pose_of(self, position: np.ndarray, quat: np.ndarray) -> np.ndarray:
        """Platform poses (N, 6) [m, rad] (module doc: relative to neutral, R = Rz(yaw) Ry(pitch) Rx(roll)) of
        the platform body at world positions (N, 3) [m] with orientations (N, 4) [w, x, y, z] (MuJoCo's
        framepos and framequat sensors)."""
        rpy = Rotation.from_quat(np.asarray(quat)[:, [1, 2, 3, 0]]).as_euler("ZYX")[:, ::-1]
        return np.concatenate([np.asarray(position) - self.neutral_position, rpy], axis=1)

    def forward(self, y: np.ndarray, guess: np.ndarray | None = None, *, tol: float = 1e-12, max_iter: int = 50) -> np.ndarray:
        """Platform pose (6,) from six piston positions y (6,) [m] by Newton's method.

        The seed's "inverse axis transformation" (§2.2.3). Starts from ``guess`` (default: neutral) and
        iterates on the leg lengths with a central-difference Jacobian until the length residual is below
        ``tol`` [m]. Raises WorkspaceError if it does not converge (no pose for these lengths near the guess).
        """
        target = np.asarray(y, dtype=float) + self.l_min
        pose = np.zeros(6) if guess is None else np.array(guess, dtype=float)
        h = 1e-7
        for _ in range(max_iter):
            residual = self.leg_lengths(pose)[0] - target
            if np.max(np.abs(residual)) < tol:
                return pose
            probes = np.concatenate([pose + h * np.eye(6), pose - h * np.eye(6)])
            lengths = self.leg_lengths(probes)
            jac = (lengths[:6] - lengths[6:]).T / (2 * h)
            pose = pose - np.linalg.solve(jac, residual)
        raise WorkspaceError(f"forward kinematics did not converge for piston positions {np.round(y, 5).tolist()} m")
