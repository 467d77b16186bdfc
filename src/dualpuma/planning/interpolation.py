"""Object-pose and joint-space interpolation (the seed's CalcRot, imaginary PUMA and RobMov).

Orientation between two object poses, four ways (:func:`interpolate_object`):

* ``"slerp"`` — rotation along the shortest arc, translation linear (:func:`dualpuma.lie.slerp`);
* ``"se3"`` — the SE(3) geodesic (screw motion, :func:`dualpuma.lie.screw`);
* ``"rpy"`` — roll-pitch-yaw increments (eq. 5.7, procedure CalcRot);
* ``"puma"`` — the seed's "imaginary PUMA" (routine 3): the orientation is the rotation of a
  PUMA's hand at joint angles theta; the joint angles are interpolated.

:func:`robmov` is the seed's RobMov: equal joint-space steps of both arms (routine 1).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ..checks import choice, integer, real, rotations, validate_joints, validate_pose, vector
from ..errors import ParameterError, PoseError
from ..kinematics import puma
from ..lie import rot_to_rpy, rpy_to_rot, screw, slerp

__all__ = ["MAX_POSES", "interpolate_object", "orientation_joints", "robmov"]

FloatArray = npt.NDArray[np.float64]
MAX_POSES = 1_000_000  #: most poses (or joint rows) one interpolation returns (128 MB of poses)
_WIDE_LIMITS = np.tile([-10.0, 10.0], (6, 1))  # the imaginary PUMA has no joint limits


def orientation_joints(R: FloatArray, branch: int) -> FloatArray:
    """Joint angles (6,) [rad] of an imaginary PUMA, on IK branch ``branch``, whose hand has the
    orientation R (3, 3) (the seed's joint-angle representation of orientation).

    Raises:
        PoseError: ``R`` not one rotation matrix. ParameterError: ``branch`` not in 0..7.
    """
    R = rotations(R, "R")
    if R.shape != (3, 3):
        raise PoseError(f"R: expected one rotation (3, 3), got {R.shape}")
    branch = integer(branch, "branch", lo=0, hi=7)
    Tq = np.eye(4)
    Tq[:3, :3] = R
    Tq[:3, 3] = puma.fk(np.zeros(6))[:3, 3]  # any reachable wrist position works
    sols, _ = puma.ik_all(Tq, limits=_WIDE_LIMITS)
    return sols[branch]


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
        rpy_start, rpy_goal: for ``"rpy"``: explicit angle sets [rad] (so a yaw of -180 deg can be
            commanded as such, as the seed's routine 6 does); default: extracted from the poses.
        puma_branch: for ``"puma"``: the imaginary PUMA's IK branch (0..7).

    Raises:
        ParameterError: n < 1, unknown method or branch; PoseError: malformed poses.
    """
    A = validate_pose(T_start, name="T_start")
    B = validate_pose(T_goal, name="T_goal")
    if A.shape != (4, 4) or B.shape != (4, 4):
        raise ParameterError("T_start, T_goal: expected single poses (4, 4)")
    n = integer(n, "n", lo=1, hi=MAX_POSES)
    choice(method, ("slerp", "se3", "rpy", "puma"), "method")
    s = np.arange(1, n + 1) / n
    if method == "slerp":
        return slerp(A, B, s)
    if method == "se3":
        return screw(A, B, s)
    out = slerp(A, B, s)  # translation linear; the rotation is replaced below
    if method == "rpy":
        r0 = rot_to_rpy(A[:3, :3]) if rpy_start is None else vector(rpy_start, "rpy_start", 3, unit="rad")
        if rpy_goal is None:  # extracted angles: take the shortest change per angle
            r1 = rot_to_rpy(B[:3, :3])
            r1 = r0 + (r1 - r0 + np.pi) % (2 * np.pi) - np.pi
        else:
            r1 = vector(rpy_goal, "rpy_goal", 3, unit="rad")
        out[:, :3, :3] = rpy_to_rot(r0 + s[:, None] * (r1 - r0))
    elif method == "puma":
        b = integer(puma_branch, "puma_branch", lo=0, hi=7)
        qa, qb = orientation_joints(A[:3, :3], b), orientation_joints(B[:3, :3], b)
        qb = qa + (qb - qa + np.pi) % (2 * np.pi) - np.pi  # shortest change per joint
        out[:, :3, :3] = puma.fk(qa + s[:, None] * (qb - qa))[:, :3, :3]
    else:
        raise ParameterError(f"method: expected 'slerp', 'se3', 'rpy' or 'puma', got {method!r}")
    out[-1] = B  # exact end point
    return out


def robmov(q_start: npt.ArrayLike, q_goal: npt.ArrayLike, max_step: float = math.radians(20.0)) -> FloatArray:
    """The seed's RobMov: equal joint-space steps, none larger than ``max_step`` [rad]; (n, ...) rows.

    Works on one arm (6,) or both stacked (2, 6). The last row equals ``q_goal`` exactly.

    Raises:
        JointError: malformed joints. ParameterError: shapes differ; max_step not in (0, 2 pi].
    """
    step = real(max_step, "max_step", lo=0.0, hi=2 * math.pi, lo_open=True, unit="rad")
    a = validate_joints(q_start, name="q_start")
    b = validate_joints(q_goal, name="q_goal")
    if a.shape != b.shape:
        raise ParameterError(f"q_start and q_goal differ in shape: {a.shape} vs {b.shape}")
    if a.size == 0:
        raise ParameterError("q_start, q_goal: no joints (empty arrays)")
    with np.errstate(over="ignore"):
        span = float(np.max(np.abs(b - a))) / step
    if not span <= MAX_POSES:  # (inf and NaN too)
        raise ParameterError(f"max_step: {step:g} rad gives more than {MAX_POSES} steps; use a larger step")
    n = max(1, math.ceil(span - 1e-12))
    if n > MAX_POSES:
        raise ParameterError(f"max_step: {step:g} rad gives {n} steps (max {MAX_POSES}); use a larger step")
    s = (np.arange(1, n + 1) / n).reshape((n,) + (1,) * a.ndim)
    out = a + s * (b - a)
    out[-1] = b
    return out
