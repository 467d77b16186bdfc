"""PUMA 560 in the seed's convention: constants, joint limits, closed-form FK and all-branch IK.

Convention (reconstructed from the seed's procedures CalcTran and InvKin, in SI):
standard Denavit-Hartenberg, one row per joint ``(theta_i, d_i, a_i, alpha_i)``::

    1: (q1, 0,  0,  -pi/2)
    2: (q2, d2, a2,  0   )      a2 = 0.4318 m, d2 = 0.14909 m
    3: (q3, 0,  a3, -pi/2)      a3 = -0.02032 m
    4: (q4, d4, 0,  +pi/2)      d4 = 0.43307 m
    5: (q5, 0,  0,  -pi/2)
    6: (q6, 0,  0,   0   )

The base frame sits at the shoulder (0.6604 m above the floor), the hand frame ("wrist") at the
wrist centre with its z axis (the approach vector ``a``) along the last joint axis. At ``q = 0``
the upper arm points along +x and the forearm hangs straight down (-z), approach pointing down.

IK branches: index ``b = 4*s + 2*e + w`` with ``s`` shoulder (0 = left, the seed's chars[1] = +1),
``e`` elbow (0 = up, chars[2] = +1), ``w`` wrist (0 = no-flip, chars[3] = +1, i.e. q5 >= 0).
:data:`BRANCH_NAMES` lists them in that order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .errors import JointError, PoseError

__all__ = [
    "A2",
    "A3",
    "BRANCH_NAMES",
    "D2",
    "D4",
    "D_FLANGE",
    "JOINT_LIMITS",
    "SHOULDER_HEIGHT",
    "IKResult",
    "IKStatus",
    "branch_of",
    "config_to_branch",
    "fk",
    "ik",
    "ik_all",
    "validate_joints",
    "validate_pose",
]

from .puma_kernels import (  # noqa: F401 - constants and kernels re-exported
    _CHUNK,
    _GAMMA,
    _K_OFFSET,
    _LIM_HI,
    _LIM_LO,
    _LIMIT_TOL,
    _ORTHO_TOL,
    _REACH_TOL,
    _RHO3_SQ,
    _WRIST_SING,
    _ZEROS6,
    A2,
    A3,
    BRANCH_NAMES,
    D2,
    D4,
    D_FLANGE,
    JOINT_LIMITS,
    SHOULDER_HEIGHT,
    FloatArray,
    _ik_all_batch,
    _ik_all_scalar,
    _wrap_joint,
)


# --------------------------------------------------------------------------- validation
def validate_pose(T: npt.ArrayLike, *, name: str = "T") -> FloatArray:
    """Check a homogeneous transform (or a batch) and return it as float64.

    Args:
        T: pose(s), shape (4, 4) or (..., 4, 4) [m].
        name: argument name used in error messages.

    Raises:
        PoseError: wrong shape, NaN/inf, bottom row not (0, 0, 0, 1), or a rotation that is not
            orthonormal with determinant +1 (tolerance 1e-9).
    """
    arr = np.asarray(T, dtype=np.float64)
    if arr.shape == (4, 4):
        _check_pose_scalar(arr.tolist(), name)
        return arr
    if arr.ndim < 2 or arr.shape[-2:] != (4, 4):
        raise PoseError(f"{name}: expected shape (4, 4) or (..., 4, 4), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise PoseError(f"{name}: contains NaN or inf")
    if np.any(np.abs(arr[..., 3, :] - (0.0, 0.0, 0.0, 1.0)) > 1e-12):
        raise PoseError(f"{name}: bottom row must be (0, 0, 0, 1)")
    c0 = arr[..., :3, 0]
    c1 = arr[..., :3, 1]
    c2 = arr[..., :3, 2]
    err = np.maximum.reduce(
        [
            np.abs(np.einsum("...i,...i->...", c0, c0) - 1.0),
            np.abs(np.einsum("...i,...i->...", c1, c1) - 1.0),
            np.abs(np.einsum("...i,...i->...", c2, c2) - 1.0),
            np.abs(np.einsum("...i,...i->...", c0, c1)),
            np.abs(np.einsum("...i,...i->...", c0, c2)),
            np.abs(np.einsum("...i,...i->...", c1, c2)),
        ]
    )
    det = np.einsum("...i,...i->...", np.cross(c0, c1), c2)
    bad = (err > _ORTHO_TOL) | (det < 0.0)
    if np.any(bad):
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        raise PoseError(
            f"{name}: rotation at index {idx} is not orthonormal with det +1 "
            f"(|R^T R - I| = {float(err[idx]):.2e}, det = {float(det[idx]):.6f})"
        )
    return arr


def _check_pose_scalar(m: list[list[float]], name: str) -> None:
    (a, b, c, x), (d, e, f, y), (g, h, i, z), bottom = m
    if not all(map(math.isfinite, (a, b, c, x, d, e, f, y, g, h, i, z, *bottom))):
        raise PoseError(f"{name}: contains NaN or inf")
    if bottom != [0.0, 0.0, 0.0, 1.0]:
        raise PoseError(f"{name}: bottom row must be (0, 0, 0, 1), got {bottom}")
    err = max(
        abs(a * a + d * d + g * g - 1.0),
        abs(b * b + e * e + h * h - 1.0),
        abs(c * c + f * f + i * i - 1.0),
        abs(a * b + d * e + g * h),
        abs(a * c + d * f + g * i),
        abs(b * c + e * f + h * i),
    )
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    if err > _ORTHO_TOL or det < 0.0:
        raise PoseError(
            f"{name}: rotation is not orthonormal with det +1 (|R^T R - I| = {err:.2e}, det = {det:.6f})"
        )


def validate_joints(q: npt.ArrayLike, *, name: str = "q") -> FloatArray:
    """Check a joint vector (or batch) of shape (..., 6) [rad].

    Raises:
        JointError: wrong shape or NaN/inf.
    """
    arr = np.asarray(q, dtype=np.float64)
    if arr.shape == (6,):  # fast path: plain floats
        if not all(map(math.isfinite, arr.tolist())):
            raise JointError(f"{name}: contains NaN or inf")
        return arr
    if arr.ndim < 1 or arr.shape[-1] != 6:
        raise JointError(f"{name}: expected shape (6,) or (..., 6), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise JointError(f"{name}: contains NaN or inf")
    return arr


# --------------------------------------------------------------------------- forward kinematics
def fk(q: npt.ArrayLike) -> FloatArray:
    """Closed-form forward kinematics of the seed's CalcTran (wrist centre in the shoulder frame).

    Args:
        q: joint angles [rad], shape (6,) or (..., 6).

    Returns:
        Homogeneous transforms ``T_base_wrist``, shape (4, 4) or (..., 4, 4) [m].

    Raises:
        JointError: malformed ``q``.
    """
    q = validate_joints(q)
    c = np.cos(q)
    s = np.sin(q)
    c1, c2, c4, c5, c6 = c[..., 0], c[..., 1], c[..., 3], c[..., 4], c[..., 5]
    s1, s2, s4, s5, s6 = s[..., 0], s[..., 1], s[..., 3], s[..., 4], s[..., 5]
    q23 = q[..., 1] + q[..., 2]
    c23 = np.cos(q23)
    s23 = np.sin(q23)
    T = np.zeros(q.shape[:-1] + (4, 4))
    # wrist rotation R36 columns, then R03 applied (written out as in CalcTran)
    w00 = c4 * c5 * c6 - s4 * s6
    w01 = -c4 * c5 * s6 - s4 * c6
    w02 = -c4 * s5
    w10 = s4 * c5 * c6 + c4 * s6
    w11 = -s4 * c5 * s6 + c4 * c6
    w12 = -s4 * s5
    w20 = s5 * c6
    w21 = -s5 * s6
    w22 = c5
    # R03 = [[c1 c23, s1, -c1 s23], [s1 c23, -c1, -s1 s23], [-s23, 0, -c23]]
    for j, (u0, u1, u2) in enumerate(((w00, w10, w20), (w01, w11, w21), (w02, w12, w22))):
        v = c23 * u0 - s23 * u2
        T[..., 0, j] = c1 * v + s1 * u1
        T[..., 1, j] = s1 * v - c1 * u1
        T[..., 2, j] = -s23 * u0 - c23 * u2
    r = A2 * c2 + A3 * c23 - D4 * s23
    T[..., 0, 3] = c1 * r - D2 * s1
    T[..., 1, 3] = s1 * r + D2 * c1
    T[..., 2, 3] = -A2 * s2 - A3 * s23 - D4 * c23
    T[..., 3, 3] = 1.0
    return T


# --------------------------------------------------------------------------- inverse kinematics
class IKStatus:
    """Status codes of :func:`ik` (plain strings, stable)."""

    OK = "ok"
    UNREACHABLE = "unreachable"
    JOINT_LIMITS = "joint_limits"


@dataclass(frozen=True, slots=True)
class IKResult:
    """Result of :func:`ik` for one pose.

    Attributes:
        q: joint angles [rad], shape (6,); ``None`` unless ``status == "ok"``.
        branch: branch index 0..7 (see :data:`BRANCH_NAMES`), or -1.
        status: ``"ok"``, ``"unreachable"`` or ``"joint_limits"``.
        reason: human-readable explanation when not ok.
        wrist_singular: True when |sin q5| < 1e-10 (q4 was taken from ``q_near``).
    """

    q: FloatArray | None
    branch: int
    status: str
    reason: str = ""
    wrist_singular: bool = False

    @property
    def ok(self) -> bool:
        return self.status == IKStatus.OK


def _check_limits(limits: npt.ArrayLike | None) -> FloatArray:
    lim = JOINT_LIMITS if limits is None else np.asarray(limits, dtype=np.float64)
    if lim.shape != (6, 2) or not np.all(np.isfinite(lim)) or not np.all(lim[:, 0] <= lim[:, 1]):
        raise JointError(f"limits: expected finite shape (6, 2) with lower <= upper, got {lim.shape}")
    return lim


def ik_all(
    T: npt.ArrayLike,
    *,
    q_near: npt.ArrayLike | None = None,
    limits: npt.ArrayLike | None = None,
) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """All eight closed-form IK branches for wrist-centre poses in the shoulder frame.

    A single (4, 4) pose takes a scalar fast path (plain floats); batches are vectorised.

    Args:
        T: target ``T_base_wrist``, shape (4, 4) or (..., 4, 4) [m].
        q_near: reference joints [rad], shape (6,) or broadcastable to (..., 6). Selects among
            equivalent angles (q +- 2 pi) and supplies q4 at the wrist singularity. Default zeros.
        limits: joint limits [rad], shape (6, 2); default :data:`JOINT_LIMITS`.

    Returns:
        ``(solutions, valid)``: solutions of shape (..., 8, 6) [rad] in branch order
        (:data:`BRANCH_NAMES`) and ``valid`` of shape (..., 8): reachable and inside the limits.
        Unreachable branches hold NaN; branches outside the limits hold the nearest equivalent
        angles. Never use a row without checking ``valid``.

    Raises:
        PoseError: malformed ``T``.
        JointError: malformed ``q_near`` or ``limits``.
    """
    T = validate_pose(T)
    lim = JOINT_LIMITS if limits is None else _check_limits(limits)
    batch = T.shape[:-2]
    if batch == ():
        if q_near is None:
            qn_l: list[float] = _ZEROS6
        else:
            qn_l = validate_joints(q_near, name="q_near").reshape(6).tolist()
        lo, hi = (_LIM_LO, _LIM_HI) if limits is None else (lim[:, 0].tolist(), lim[:, 1].tolist())
        return _ik_all_scalar(T, qn_l, lo, hi)
    if q_near is None:
        qn = np.zeros(batch + (6,))
    else:
        qn = np.broadcast_to(validate_joints(q_near, name="q_near"), batch + (6,))
    n = int(np.prod(batch))
    Tf = T.reshape(n, 4, 4)
    qf = np.broadcast_to(qn, batch + (6,)).reshape(n, 6)
    if n <= _CHUNK:
        sols, valid = _ik_all_batch(Tf, qf, lim)
    else:  # chunks keep the temporaries in cache (about 2x faster than one big pass)
        sols = np.empty((n, 8, 6))
        valid = np.empty((n, 8), dtype=bool)
        for i in range(0, n, _CHUNK):
            sols[i : i + _CHUNK], valid[i : i + _CHUNK] = _ik_all_batch(Tf[i : i + _CHUNK], qf[i : i + _CHUNK], lim)
    return sols.reshape(batch + (8, 6)), valid.reshape(batch + (8,))


def _ik_all_trusted(T: FloatArray, q_near: FloatArray, lim: FloatArray) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """:func:`ik_all` for an already validated batch (N, 4, 4), one q_near (6,), limits (6, 2)."""
    n = T.shape[0]
    qf = np.broadcast_to(q_near, (n, 6))
    if n <= _CHUNK:
        return _ik_all_batch(T, qf, lim)
    sols = np.empty((n, 8, 6))
    valid = np.empty((n, 8), dtype=bool)
    for i in range(0, n, _CHUNK):
        sols[i : i + _CHUNK], valid[i : i + _CHUNK] = _ik_all_batch(T[i : i + _CHUNK], qf[i : i + _CHUNK], lim)
    return sols, valid


def config_to_branch(shoulder: int | str = 1, elbow: int | str = 1, wrist: int | str = 1) -> int:
    """Branch index from the seed's indicators (``chars``) or names.

    Args:
        shoulder: +1 / "left" or -1 / "right".
        elbow: +1 / "up" or -1 / "down".
        wrist: +1 / "noflip" or -1 / "flip".
    """
    def bit(v: int | str, pos: str, neg: str, label: str) -> int:
        if v in (1, pos):
            return 0
        if v in (-1, neg):
            return 1
        raise JointError(f"{label}: expected +1/-1 or '{pos}'/'{neg}', got {v!r}")

    return 4 * bit(shoulder, "left", "right", "shoulder") + 2 * bit(elbow, "up", "down", "elbow") + bit(
        wrist, "noflip", "flip", "wrist"
    )


def branch_of(q: npt.ArrayLike) -> npt.NDArray[np.int64]:
    """Branch index (0..7) that a joint vector belongs to, shape (...,)."""
    q = validate_joints(q)
    q1, q2, q3, q5 = q[..., 0], q[..., 1], q[..., 2], q[..., 4]
    r = A2 * np.cos(q2) + A3 * np.cos(q2 + q3) - D4 * np.sin(q2 + q3)
    s = (r < 0).astype(np.int64)
    e = (np.cos(_GAMMA - q3) < 0).astype(np.int64)
    w = (np.sin(q5) < 0).astype(np.int64)
    del q1
    return 4 * s + 2 * e + w


def ik(
    T: npt.ArrayLike,
    *,
    config: int | tuple[int | str, int | str, int | str] | None = None,
    q_near: npt.ArrayLike | None = None,
    limits: npt.ArrayLike | None = None,
) -> IKResult:
    """Closed-form IK for one pose, choosing one branch.

    Args:
        T: target ``T_base_wrist``, shape (4, 4) [m].
        config: a branch index 0..7 or the seed's ``chars`` triple, e.g. ``(1, 1, 1)``
            (shoulder left, elbow up, no flip). ``None``: the valid solution nearest to ``q_near``
            (max-abs joint distance), or branch 0 if ``q_near`` is also None.
        q_near: previous joints [rad], shape (6,): picks equivalent angles and q4 at q5 ~ 0.
        limits: joint limits [rad], shape (6, 2); default :data:`JOINT_LIMITS`.

    Returns:
        :class:`IKResult`; ``status`` tells unreachable / joint-limit failures (never NaN).

    Raises:
        PoseError: malformed ``T`` (or a batch: use :func:`ik_all`).
        JointError: malformed ``q_near`` or ``config``.
    """
    T = validate_pose(T)
    if T.shape != (4, 4):
        raise PoseError(f"T: ik() takes one pose of shape (4, 4), got {T.shape}; use ik_all for batches")
    sols, valid = ik_all(T, q_near=q_near, limits=limits)
    if config is None:
        if q_near is None:
            cand = [0]
        else:
            qn = np.asarray(q_near, dtype=np.float64)
            with np.errstate(invalid="ignore"):
                dist = np.max(np.abs(sols - qn), axis=-1)
            dist = np.where(valid, dist, np.inf)
            cand = [int(np.argmin(dist))] if np.isfinite(dist).any() else list(range(8))
    elif isinstance(config, (int, np.integer)):
        if not 0 <= int(config) <= 7:
            raise JointError(f"config: branch index must be 0..7, got {config}")
        cand = [int(config)]
    else:
        if len(config) != 3:
            raise JointError(f"config: expected (shoulder, elbow, wrist), got {config!r}")
        cand = [config_to_branch(*config)]
    b = cand[0]
    singular = bool(_wrist_singular(sols[b]))
    if valid[b]:
        q = sols[b].copy()
        q.setflags(write=False)
        return IKResult(q=q, branch=b, status=IKStatus.OK, wrist_singular=singular)
    if np.isnan(sols[b]).any():
        p = T[:3, 3]
        return IKResult(
            q=None,
            branch=-1,
            status=IKStatus.UNREACHABLE,
            reason=f"wrist centre {np.round(p, 4).tolist()} m is outside the arm's reach",
        )
    lim = _check_limits(limits)
    bad = [i + 1 for i in range(6) if not lim[i, 0] - 1e-12 <= sols[b, i] <= lim[i, 1] + 1e-12]
    return IKResult(
        q=None,
        branch=-1,
        status=IKStatus.JOINT_LIMITS,
        reason=f"branch {BRANCH_NAMES[b]} needs joint(s) {bad} outside their limits",
    )


def _wrist_singular(q: FloatArray) -> bool:
    return bool(np.isfinite(q[4]) and abs(math.sin(q[4])) < _WRIST_SING)
