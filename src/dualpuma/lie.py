"""The only SO(3)/SE(3) helpers of dualpuma: conversions, angles, interpolation and step counts.

Poses are 4x4 homogeneous float64 arrays [m]; rotations 3x3. Roll-pitch-yaw follows the seed's
CalcRot (eq. 5.7) and Pinocchio's ``pin.rpy``: ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.

* :func:`to_se3`, :func:`quaternion_wxyz` — conversions for Pinocchio/coal and viser.
* :func:`rpy_to_rot`, :func:`rot_to_rpy` — vectorised roll-pitch-yaw.
* :func:`angle` — rotation angle between two orientations [rad].
* :func:`slerp` — poses along the SE(3) path "translation linear, rotation along the shortest arc"
  (the planners' straight runs and edges).
* :func:`screw` — poses along the SE(3) geodesic (screw motion, ``exp6``/``log6``).
* :func:`n_steps` — how many steps a straight run needs under a translation and a rotation bound.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .checks import as_array, rotations
from .errors import ParameterError, PoseError

__all__ = [
    "angle",
    "angles",
    "n_steps",
    "pose_from_wxyz",
    "quaternion_wxyz",
    "rot_to_rpy",
    "rpy_to_rot",
    "screw",
    "slerp",
    "slerp_pairs",
    "to_se3",
]

FloatArray = npt.NDArray[np.float64]


def to_se3(T: FloatArray) -> pin.SE3:
    """``pin.SE3`` of a 4x4 homogeneous transform (trusted: no validation)."""
    return pin.SE3(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))


def quaternion_wxyz(R: npt.ArrayLike) -> tuple[float, float, float, float]:
    """Unit quaternion (w, x, y, z) of a rotation matrix (viser's convention).

    Raises:
        PoseError: not a rotation matrix (3, 3).
    """
    R = rotations(R, "R")
    if R.shape != (3, 3):
        raise PoseError(f"R: expected one rotation (3, 3), got {R.shape}")
    q = pin.Quaternion(R)
    q.normalize()
    return (q.w, q.x, q.y, q.z)


def pose_from_wxyz(wxyz: npt.ArrayLike, position: npt.ArrayLike) -> FloatArray:
    """4x4 pose from a quaternion (w, x, y, z) (normalised here) and a position [m].

    Raises:
        PoseError: not 4 finite numbers of non-zero norm, or a position that is not 3 finite numbers.
    """
    qa, pa = as_array(wxyz, "wxyz", PoseError), as_array(position, "position", PoseError)
    if qa.shape != (4,) or not np.all(np.isfinite(qa)) or not 1e-9 < float(np.linalg.norm(qa)) < 1e150:
        raise PoseError(f"wxyz: expected 4 finite numbers of non-zero norm, got shape {qa.shape}")
    if pa.shape != (3,) or not np.all(np.isfinite(pa)):
        raise PoseError(f"position: expected 3 finite numbers [m], got shape {pa.shape}")
    w, x, y, z = (float(v) for v in qa)
    T = np.eye(4)
    T[:3, :3] = pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()
    T[:3, 3] = pa
    return T


def rpy_to_rot(rpy: npt.ArrayLike) -> FloatArray:
    """Rotation ``Rz(yaw) Ry(pitch) Rx(roll)`` from (roll, pitch, yaw) [rad]: (..., 3) -> (..., 3, 3).

    Raises:
        ParameterError: not finite numbers of shape (..., 3).
    """
    a = as_array(rpy, "rpy")
    if a.shape[-1:] != (3,) or not np.all(np.isfinite(a)):
        raise ParameterError(f"rpy: expected finite angles of shape (..., 3) [rad], got shape {a.shape}")
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


def rot_to_rpy(R: npt.ArrayLike) -> FloatArray:
    """(roll, pitch, yaw) [rad] with ``R = rpy_to_rot(rpy)``, pitch in [-pi/2, pi/2]: (..., 3, 3) -> (..., 3).

    Raises:
        PoseError: not rotation matrices.
    """
    R = rotations(R, "R")
    pitch = np.arctan2(-R[..., 2, 0], np.hypot(R[..., 0, 0], R[..., 1, 0]))
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    # yaw from the roll just computed, not from R[1, 0] and R[0, 0] on their own: at pitch +-90 deg
    # (gimbal lock) both roll's entries are rounding noise, and only roll - yaw (pitch +90) or
    # roll + yaw (-90) is defined; yaw taken this way keeps that combination whatever roll came out
    # (``fk --q 10 20 30 0 40 0`` printed angles 6.8 deg off its own rotation), and elsewhere it is
    # the same angle (sin and cos of yaw, by the rows of Rz(yaw)^T R = Ry(pitch) Rx(roll))
    sr, cr = np.sin(roll), np.cos(roll)
    yaw = np.arctan2(sr * R[..., 0, 2] - cr * R[..., 0, 1], cr * R[..., 1, 1] - sr * R[..., 1, 2])
    return np.stack([roll, pitch, yaw], axis=-1)


def angle(Ra: FloatArray, Rb: FloatArray) -> float:
    """Angle of the rotation taking orientation ``Ra`` to ``Rb`` (3x3 each) [rad], in [0, pi].

    Trusted: two rotation matrices (it is the fallback planner's inner distance; callers validate).
    """
    return float(np.linalg.norm(pin.log3(Ra.T @ Rb)))


def angles(Ra: FloatArray, Rb: FloatArray) -> FloatArray:
    """:func:`angle` of many pairs of rotations (K, 3, 3) each: (K,) [rad] in [0, pi], as
    ``atan2(2 sin, 2 cos)`` of ``Ra^T Rb`` (accurate at every angle). Trusted input."""
    return _relative_rotations(Ra, Rb)[3]


def _relative_rotations(Ra: FloatArray, Rb: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """``R = Ra^T Rb`` (K, 3, 3), its skew part's vector (K, 3) (2 sin(theta) times the axis), its
    norm 2 sin(theta) (K,) and theta = atan2(2 sin, 2 cos) in [0, pi] (K,)."""
    R = Ra.transpose(0, 2, 1) @ Rb
    vee = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
    sin2 = np.sqrt(np.einsum("ij,ij->i", vee, vee))
    return R, vee, sin2, np.arctan2(sin2, R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2] - 1.0)


def slerp(A: FloatArray, B: FloatArray, s: FloatArray) -> FloatArray:
    """Poses at fractions ``s`` (K,) of the way from pose A to B: translation linear, rotation along
    the shortest arc (``R_A exp(s log(R_A^T R_B))``). Returns (K, 4, 4); ``s == 1`` gives B exactly.

    Trusted: A and B are valid poses (callers validate at the boundary).
    """
    s = np.asarray(s, dtype=np.float64)
    out = np.empty((s.size, 4, 4))
    out[:] = A
    out[:, :3, 3] = A[:3, 3] + s[:, None] * (B[:3, 3] - A[:3, 3])
    if not (A[:3, :3] == B[:3, :3]).all():  # (np.array_equal's checks cost more than the test)
        w = pin.log3(A[:3, :3].T @ B[:3, :3])
        th = float(np.linalg.norm(w))
        if th > 0.0:
            k = w / th
            K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
            a = s * th
            Rs = np.sin(a)[:, None, None] * K + (1.0 - np.cos(a))[:, None, None] * (K @ K)
            Rs += np.eye(3)
            out[:, :3, :3] = A[:3, :3] @ Rs
    out[s == 1.0] = B
    return out


def slerp_pairs(A: FloatArray, B: FloatArray, s: FloatArray) -> FloatArray:
    """:func:`slerp` of many pairs at once: the pose at fraction ``s[k]`` of the way from ``A[k]``
    to ``B[k]`` (A, B (K, 4, 4), s (K,)), translation linear, rotation along the shortest arc
    (``R_A exp(s log(R_A^T R_B))``). Returns (K, 4, 4); ``s == 1`` gives B exactly. Trusted input."""
    s = np.asarray(s, dtype=np.float64)
    Ra = A[:, :3, :3]
    R, vee, sin2, th = _relative_rotations(Ra, B[:, :3, :3])
    u = vee / np.where(sin2 > 0.0, sin2, 1.0)[:, None]  # the unit axis (0 where there is no rotation)
    for k in np.flatnonzero(th > 3.0).tolist():  # near pi the skew part loses the axis: Pinocchio's log
        w = pin.log3(R[k])
        th[k] = float(np.linalg.norm(w))
        u[k] = w / th[k]
    a = s * th
    c, sn = np.cos(a), np.sin(a)
    ux = np.zeros((s.size, 3, 3))
    ux[:, 2, 1], ux[:, 0, 2], ux[:, 1, 0] = u[:, 0], u[:, 1], u[:, 2]
    ux -= ux.transpose(0, 2, 1)
    Rs = (1.0 - c)[:, None, None] * (u[:, :, None] * u[:, None, :]) + sn[:, None, None] * ux
    Rs[:, [0, 1, 2], [0, 1, 2]] += c[:, None]
    out = A.copy()
    out[:, :3, 3] += s[:, None] * (B[:, :3, 3] - A[:, :3, 3])
    out[:, :3, :3] = Ra @ Rs
    one = s == 1.0
    out[one] = B[one]
    return out


def screw(A: FloatArray, B: FloatArray, s: FloatArray) -> FloatArray:
    """Poses at fractions ``s`` (K,) along the SE(3) geodesic (screw motion) from A to B: (K, 4, 4);
    ``s == 1`` gives B exactly. Trusted input."""
    MA = pin.SE3(A)
    v = pin.log6(MA.actInv(pin.SE3(B)))
    out = np.array([(MA * pin.exp6(float(si) * v)).homogeneous for si in np.asarray(s, dtype=np.float64)])
    out = out.reshape(-1, 4, 4)
    out[np.asarray(s) == 1.0] = B
    return out


def n_steps(distance: float, rotation: float, step: float, rot_step: float) -> int:
    """Steps for a straight run of ``distance`` [m] turning by ``rotation`` [rad] so that no step is
    longer than ``step`` [m] nor turns more than ``rot_step`` [rad] (at least 1; a run exactly a
    whole number of steps long is not given one more for rounding)."""
    return max(1, math.ceil(distance / step - 1e-9), math.ceil(rotation / rot_step - 1e-9))
