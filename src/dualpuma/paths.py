"""Object-pose and joint-space interpolation (the seed's Step, CalcRot, ThetaIncr, RobMov).

Orientation between two object poses, three ways:

* ``"rpy"`` — roll-pitch-yaw increments (eq. 5.7, procedure CalcRot): R = Rz(yaw) Ry(pitch) Rx(roll).
* ``"puma"`` — the seed's "imaginary PUMA" (routine 3): the orientation is the rotation of a PUMA's
  hand at joint angles theta; the joint angles are interpolated.
* ``"slerp"`` — spherical linear interpolation of the rotation (shortest arc), translation linear;
  ``"se3"`` — the SE(3) geodesic (screw motion).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from . import puma
from .errors import ParameterError
from .puma import validate_joints, validate_pose

__all__ = [
    "DEFAULT_STEP",
    "ROTATION_ONLY_STEPS",
    "calc_rot",
    "interpolate_object",
    "n_steps",
    "robmov",
    "rpy_from_rot",
    "theta_incr",
]

FloatArray = npt.NDArray[np.float64]
DEFAULT_STEP = 0.05  #: the seed's 10 screen units = 50 mm per step [m]
ROTATION_ONLY_STEPS = 5  #: the seed's step count for a pure rotation (procedure Step)


def calc_rot(rpy: npt.ArrayLike) -> FloatArray:
    """The seed's CalcRot (eq. 5.7): rotation from (roll, pitch, yaw) [rad], shape (..., 3) -> (..., 3, 3)."""
    a = np.asarray(rpy, dtype=np.float64)
    if a.shape[-1:] != (3,) or not np.all(np.isfinite(a)):
        raise ParameterError(f"rpy: expected finite shape (..., 3), got {a.shape}")
    cr, sr = np.cos(a[..., 0]), np.sin(a[..., 0])
    cp, sp = np.cos(a[..., 1]), np.sin(a[..., 1])
    cy, sy = np.cos(a[..., 2]), np.sin(a[..., 2])
    R = np.empty(a.shape[:-1] + (3, 3))
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp * sr - sy * cr
    R[..., 0, 2] = cy * sp * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp * sr + cy * cr
    R[..., 1, 2] = sy * sp * cr - cy * sr
    R[..., 2, 0] = -sp
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr
    return R


def rpy_from_rot(R: npt.ArrayLike) -> FloatArray:
    """(roll, pitch, yaw) [rad] with R = calc_rot(rpy), pitch in [-pi/2, pi/2]."""
    R = np.asarray(R, dtype=np.float64)
    pitch = np.arctan2(-R[..., 2, 0], np.hypot(R[..., 0, 0], R[..., 1, 0]))
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def n_steps(T_start: npt.ArrayLike, T_goal: npt.ArrayLike, step: float = DEFAULT_STEP) -> int:
    """The seed's procedure Step: round(distance / step) steps, or 5 for a pure rotation.

    Raises:
        ParameterError: step <= 0 or not finite.
    """
    if not (np.isfinite(step) and step > 0):
        raise ParameterError(f"step: expected a finite length > 0 [m], got {step}")
    d = float(np.linalg.norm(validate_pose(T_goal)[:3, 3] - validate_pose(T_start)[:3, 3]))
    n = round(d / step)
    return ROTATION_ONLY_STEPS if n == 0 else int(n)


def interpolate_object(
    T_start: npt.ArrayLike,
    T_goal: npt.ArrayLike,
    n: int,
    method: str = "slerp",
    *,
    rpy_start: npt.ArrayLike | None = None,
    rpy_goal: npt.ArrayLike | None = None,
    puma_branch: int = 0,
) -> FloatArray:
    """``n`` poses after ``T_start``, the last one equal to ``T_goal`` exactly: shape (n, 4, 4).

    Args:
        T_start, T_goal: object poses (4, 4) [m].
        n: number of steps (>= 1).
        method: ``"slerp"``, ``"se3"``, ``"rpy"`` or ``"puma"``.
        rpy_start, rpy_goal: for ``"rpy"``: explicit angle sets (so a yaw of -180 deg can be
            commanded as such, as the seed's routine 6 does); default: extracted from the poses.
        puma_branch: for ``"puma"``: the imaginary PUMA's IK branch.

    Raises:
        ParameterError: n < 1 or unknown method; PoseError: malformed poses.
    """
    A = validate_pose(T_start, name="T_start")
    B = validate_pose(T_goal, name="T_goal")
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise ParameterError(f"n: expected an integer >= 1, got {n!r}")
    s = np.arange(1, n + 1) / n
    out = np.tile(np.eye(4), (n, 1, 1))
    out[:, :3, 3] = A[:3, 3] + s[:, None] * (B[:3, 3] - A[:3, 3])
    if method == "slerp":
        out[:, :3, :3] = A[:3, :3] @ _exp3_batch(s[:, None] * pin.log3(A[:3, :3].T @ B[:3, :3]))
    elif method == "se3":
        MA, MB = pin.SE3(A), pin.SE3(B)
        v = pin.log6(MA.actInv(MB))
        for i, si in enumerate(s):
            out[i] = (MA * pin.exp6(si * v)).homogeneous
    elif method == "rpy":
        r0 = rpy_from_rot(A[:3, :3]) if rpy_start is None else np.asarray(rpy_start, float)
        if rpy_goal is None:  # extracted angles: take the shortest change per angle
            r1 = rpy_from_rot(B[:3, :3])
            r1 = r0 + (r1 - r0 + np.pi) % (2 * np.pi) - np.pi
        else:
            r1 = np.asarray(rpy_goal, float)
        out[:, :3, :3] = calc_rot(r0 + s[:, None] * (r1 - r0))
    elif method == "puma":
        qa, qb = _imaginary_puma(A, puma_branch), _imaginary_puma(B, puma_branch, near=None)
        qb = qa + (qb - qa + np.pi) % (2 * np.pi) - np.pi  # shortest change per joint
        out[:, :3, :3] = puma.fk(qa + s[:, None] * (qb - qa))[:, :3, :3]
    else:
        raise ParameterError(f"method: expected 'slerp', 'se3', 'rpy' or 'puma', got {method!r}")
    out[-1] = B  # exact end point
    return out


def _exp3_batch(w: FloatArray) -> FloatArray:
    """Rodrigues' formula for many rotation vectors (N, 3) -> (N, 3, 3)."""
    th = np.linalg.norm(w, axis=1)
    small = th < 1e-8
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th**2 / 6.0, np.sin(ths) / ths)
    b = np.where(small, 0.5 - th**2 / 24.0, (1.0 - np.cos(ths)) / ths**2)
    K = np.zeros((w.shape[0], 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = w[:, 2], -w[:, 1], w[:, 0]
    return np.eye(3) + a[:, None, None] * K + b[:, None, None] * (K @ K)


def _imaginary_puma(T: FloatArray, branch: int, near: FloatArray | None = None) -> FloatArray:
    """Joint angles of a PUMA at the origin whose hand has T's orientation (position ignored)."""
    Tq = np.eye(4)
    Tq[:3, :3] = T[:3, :3]
    Tq[:3, 3] = puma.fk(np.zeros(6))[:3, 3]  # any reachable wrist position works
    sols, _ = puma.ik_all(Tq, limits=np.tile([-10.0, 10.0], (6, 1)))
    return sols[branch]


def robmov(q_start: npt.ArrayLike, q_goal: npt.ArrayLike, max_step: float = math.radians(20.0)) -> FloatArray:
    """The seed's RobMov: equal joint-space steps, none larger than ``max_step`` [rad]; (n, ...) rows.

    Works on one arm (6,) or both stacked (2, 6). The last row equals ``q_goal`` exactly.
    """
    return _joint_steps(q_start, q_goal, max_step, "max_step")


def theta_incr(q_start: npt.ArrayLike, q_goal: npt.ArrayLike, step: float = math.radians(10.0)) -> FloatArray:
    """The seed's ThetaIncr: the largest joint change split into ~``step`` (10 deg) increments."""
    return _joint_steps(q_start, q_goal, step, "step")


def _joint_steps(q_start, q_goal, step: float, name: str) -> FloatArray:
    if not (np.isfinite(step) and step > 0):
        raise ParameterError(f"{name}: expected a finite angle > 0 [rad], got {step}")
    a = validate_joints(q_start, name="q_start")
    b = validate_joints(q_goal, name="q_goal")
    if a.shape != b.shape:
        raise ParameterError(f"q_start and q_goal differ in shape: {a.shape} vs {b.shape}")
    n = max(1, math.ceil(float(np.max(np.abs(b - a))) / step - 1e-12))
    s = (np.arange(1, n + 1) / n).reshape((n,) + (1,) * a.ndim)
    out = a + s * (b - a)
    out[-1] = b
    return out
