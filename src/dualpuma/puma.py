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
    "D2",
    "D4",
    "D_FLANGE",
    "SHOULDER_HEIGHT",
    "JOINT_LIMITS",
    "BRANCH_NAMES",
    "IKStatus",
    "IKResult",
    "fk",
    "ik_all",
    "ik",
    "branch_of",
    "config_to_branch",
    "validate_pose",
    "validate_joints",
]

FloatArray = npt.NDArray[np.float64]

A2 = 0.4318  #: upper-arm length [m]
A3 = -0.02032  #: elbow offset [m] (the seed's param[4][2])
D2 = 0.14909  #: shoulder offset [m]
D4 = 0.43307  #: forearm length, elbow to wrist centre [m]
D_FLANGE = 0.05625  #: wrist centre to tool flange along the approach axis [m]
SHOULDER_HEIGHT = 0.6604  #: shoulder above the floor [m]

#: Joint limits [rad], shape (6, 2), in the seed's convention. Sources: Lee (1982, IEEE Computer,
#: "Robot arm kinematics, dynamics and control", Table 1) for joints 1-3 and 5 (joint 3's range
#: shifted by -180 deg because the seed's zero has the forearm hanging down instead of up), and
#: Unimation's PUMA 560 specification (532 deg of travel) for joints 4 and 6, as in the Robotics
#: Toolbox's Puma560 model. See docs/kinematics.md.
JOINT_LIMITS: FloatArray = np.deg2rad(
    np.array(
        [
            [-160.0, 160.0],
            [-225.0, 45.0],
            [-225.0, 45.0],
            [-266.0, 266.0],
            [-100.0, 100.0],
            [-266.0, 266.0],
        ]
    )
)
JOINT_LIMITS.setflags(write=False)
_LIM_LO: list[float] = JOINT_LIMITS[:, 0].tolist()
_LIM_HI: list[float] = JOINT_LIMITS[:, 1].tolist()
_ZEROS6: list[float] = [0.0] * 6

BRANCH_NAMES: tuple[str, ...] = tuple(
    f"{s}/{e}/{w}"
    for s in ("left", "right")
    for e in ("up", "down")
    for w in ("noflip", "flip")
)

_ORTHO_TOL = 1e-9  # max |R^T R - I| accepted for a rotation
_REACH_TOL = 1e-12  # [m^2] slack on square-root arguments at the workspace boundary
_WRIST_SING = 1e-10  # |sin q5| below this: wrist singular, q4 taken from q_near
_CHUNK = 4096  # poses per vectorised chunk in ik_all
_LIMIT_TOL = 1e-12  # [rad] a joint this far outside a limit still counts as inside
_GAMMA = math.atan2(A3, D4)
_RHO3_SQ = A3 * A3 + D4 * D4
_K_OFFSET = A2 * A2 + A3 * A3 + D2 * D2 + D4 * D4


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


def _wrap_joint(theta: FloatArray, ref: FloatArray, lo: float, hi: float) -> tuple[FloatArray, FloatArray]:
    """Equivalent angle theta + 2 pi k inside [lo, hi], nearest to ``ref``; and an inside mask.

    For ranges narrower than a turn there is at most one such angle; wider ranges (q4, q6 of the
    PUMA) take the one nearest to ``ref``.
    """
    two_pi = 2.0 * np.pi
    if hi - lo < two_pi:
        # in [lo - tol, lo + 2 pi - tol): angles within tol below lo stay put
        base = theta - two_pi * np.floor((theta - lo + _LIMIT_TOL) * (1.0 / two_pi))
        return base, base <= hi + _LIMIT_TOL
    best = theta - two_pi * np.round((theta - ref) * (1.0 / two_pi))
    best = np.where(best > hi + _LIMIT_TOL, best - two_pi, best)
    best = np.where(best < lo - _LIMIT_TOL, best + two_pi, best)
    return best, np.ones(best.shape, dtype=bool)


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


def _ik_all_batch(T: FloatArray, qn: FloatArray, lim: FloatArray) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Vectorised IK. Internally branch axes lead and the pose axis is last (contiguous)."""
    batch = T.shape[:-2]
    Tf = T.reshape(-1, 16).T  # (16, N): row 4*i + j holds T[i, j]
    qf = np.ascontiguousarray(np.broadcast_to(qn, batch + (6,)).reshape(-1, 6).T)  # (6, N)
    r00, r01, r02, px, r10, r11, r12, py, r20, r21, r22, pz = (np.ascontiguousarray(Tf[i]) for i in range(12))
    sgn2 = np.array([1.0, -1.0])[:, None]
    # shoulder: r = +-sqrt(px^2 + py^2 - d2^2), shape (2, N)
    rho2 = px * px + py * py
    disc1 = rho2 - D2 * D2
    ok = disc1 > -_REACH_TOL
    r = sgn2 * np.sqrt(np.maximum(disc1, 0.0))
    q1 = np.arctan2(py, px) - np.arctan2(D2, r)
    inv = 1.0 / np.where(rho2 > 0.0, rho2, 1.0)
    c1 = (r * px + D2 * py) * inv
    s1 = (r * py - D2 * px) * inv
    # elbow: a3 c3 - d4 s3 = K, shape (2, N)
    K = (rho2 + pz * pz - _K_OFFSET) * (0.5 / A2)
    disc3 = _RHO3_SQ - K * K
    ok &= disc3 > -_REACH_TOL
    sq = sgn2 * np.sqrt(np.maximum(disc3, 0.0))
    q3 = _GAMMA - np.arctan2(K, sq)
    rho3 = math.sqrt(_RHO3_SQ)
    cg, sg = D4 / rho3 / rho3, A3 / rho3 / rho3
    c3 = cg * sq + sg * K
    s3 = sg * sq - cg * K
    # arm plane: q23 for every (shoulder, elbow), shape (2, 2, N)
    P = (A2 * c3 + A3)[None]
    Q = (A2 * s3 - D4)[None]
    rb = r[:, None]
    ys = Q * rb - P * pz
    xs = P * rb + Q * pz
    q23 = np.arctan2(ys, xs)
    n23 = 1.0 / np.sqrt(ys * ys + xs * xs)
    c23 = xs * n23
    s23 = ys * n23
    q2 = q23 - q3[None]
    # wrist W = R03^T R; R03 columns e0 = (c1 c23, s1 c23, -s23), e1 = (s1, -c1, 0),
    # e2 = (-c1 s23, -s1 s23, -c23). a_k = c1 R0k + s1 R1k (shape (2, 1, N))
    c1b = c1[:, None]
    s1b = s1[:, None]
    a0 = c1b * r00 + s1b * r10
    a1 = c1b * r01 + s1b * r11
    a2 = c1b * r02 + s1b * r12
    w10 = s1b * r00 - c1b * r10
    w11 = s1b * r01 - c1b * r11
    w12 = s1b * r02 - c1b * r12
    w00 = c23 * a0 - s23 * r20
    w01 = c23 * a1 - s23 * r21
    w02 = c23 * a2 - s23 * r22
    w22 = -s23 * a2 - c23 * r22
    w12 = np.broadcast_to(w12, w02.shape)
    h = np.sqrt(w02 * w02 + w12 * w12)
    sing = h < _WRIST_SING
    if np.any(sing):
        q4n = np.broadcast_to(np.clip(qf[3], lim[3, 0], lim[3, 1]), h.shape)
        safe = np.where(sing, 1.0, h)
        c4 = np.where(sing, np.cos(q4n), -w02 / safe)
        s4 = np.where(sing, np.sin(q4n), -w12 / safe)
        q4 = np.where(sing, q4n, np.arctan2(-w12, -w02))
        flip = np.where(sing, 0.0, np.pi)
        q5 = np.arctan2(-(c4 * w02 + s4 * w12), w22)
        q5f = np.where(sing, q5, -q5)
    else:
        inv_h = 1.0 / h
        c4 = -w02 * inv_h
        s4 = -w12 * inv_h
        q4 = np.arctan2(-w12, -w02)
        flip = np.pi
        q5 = np.arctan2(h, w22)
        q5f = -q5
    q6 = np.arctan2(-s4 * w00 + c4 * w10, -s4 * w01 + c4 * w11)
    n = px.shape[0]
    out = np.empty((2, 2, 2, 6, n))
    valid = np.broadcast_to(ok, (2, 2, 2, n)).copy()

    def put(j: int, ang: FloatArray, view: tuple) -> None:
        w, inside = _wrap_joint(ang, qf[j], lim[j, 0], lim[j, 1])
        out[view + (j,)] = w
        valid[view] &= inside

    a1_, i1 = _wrap_joint(q1, qf[0], lim[0, 0], lim[0, 1])
    out[:, :, :, 0] = a1_[:, None, None]
    valid &= i1[:, None, None]
    a3_, i3 = _wrap_joint(q3, qf[2], lim[2, 0], lim[2, 1])
    out[:, :, :, 2] = a3_[None, :, None]
    valid &= i3[None, :, None]
    a2_, i2 = _wrap_joint(q2, qf[1], lim[1, 0], lim[1, 1])
    out[:, :, :, 1] = a2_[:, :, None]
    valid &= i2[:, :, None]
    for wi, (a4, a5, a6) in enumerate(((q4, q5, q6), (q4 + flip, q5f, q6 + flip))):
        put(3, a4, (slice(None), slice(None), wi))
        put(4, a5, (slice(None), slice(None), wi))
        put(5, a6, (slice(None), slice(None), wi))
    res = np.moveaxis(out.reshape(8, 6, n), 2, 0)
    res[~ok] = np.nan
    return res.reshape(batch + (8, 6)), np.moveaxis(valid.reshape(8, n), 1, 0).reshape(batch + (8,))


def _ik_all_scalar(
    T: FloatArray, qn_l: list[float], lo: list[float], hi: list[float]
) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Pure-float version of :func:`_ik_all_batch` for one pose (no numpy temporaries)."""
    (r00, r01, r02, px), (r10, r11, r12, py), (r20, r21, r22, pz) = T[:3].tolist()
    atan2 = math.atan2
    rho2 = px * px + py * py
    disc1 = rho2 - D2 * D2
    K = (rho2 + pz * pz - _K_OFFSET) / (2.0 * A2)
    disc3 = _RHO3_SQ - K * K
    valid = np.zeros(8, dtype=bool)
    if disc1 <= -_REACH_TOL or disc3 <= -_REACH_TOL:
        return np.full((8, 6), np.nan), valid
    rr = math.sqrt(max(disc1, 0.0))
    sq3 = math.sqrt(max(disc3, 0.0))
    phi = atan2(py, px)
    inv = 1.0 / rho2 if rho2 > 0.0 else 1.0
    rho3 = math.sqrt(_RHO3_SQ)
    cg, sg = D4 / rho3, A3 / rho3
    two_pi = 2.0 * math.pi
    rows: list[list[float]] = []
    for r in (rr, -rr):
        q1 = phi - atan2(D2, r)
        c1 = (r * px + D2 * py) * inv
        s1 = (r * py - D2 * px) * inv
        a0 = c1 * r00 + s1 * r10
        a1 = c1 * r01 + s1 * r11
        a2 = c1 * r02 + s1 * r12
        w10 = s1 * r00 - c1 * r10
        w11 = s1 * r01 - c1 * r11
        w12 = s1 * r02 - c1 * r12
        for sq in (sq3, -sq3):
            q3 = _GAMMA - atan2(K, sq)
            c3 = (cg * sq + sg * K) / rho3
            s3 = (sg * sq - cg * K) / rho3
            P = A2 * c3 + A3
            Q = A2 * s3 - D4
            ys = Q * r - P * pz
            xs = P * r + Q * pz
            q23 = atan2(ys, xs)
            n23 = 1.0 / math.hypot(ys, xs)
            c23 = xs * n23
            s23 = ys * n23
            w02 = c23 * a2 - s23 * r22
            w22 = -s23 * a2 - c23 * r22
            w00 = c23 * a0 - s23 * r20
            w01 = c23 * a1 - s23 * r21
            h = math.hypot(w02, w12)
            if h < _WRIST_SING:  # any q4 works: keep q_near's, clipped into the limits
                q4 = min(max(qn_l[3], lo[3]), hi[3])
                c4, s4 = math.cos(q4), math.sin(q4)
                flip = 0.0
            else:
                c4, s4 = -w02 / h, -w12 / h
                q4 = atan2(-w12, -w02)
                flip = math.pi
            q5 = atan2(-(c4 * w02 + s4 * w12), w22)
            q6 = atan2(-s4 * w00 + c4 * w10, -s4 * w01 + c4 * w11)
            q2 = q23 - q3
            rows.append([q1, q2, q3, q4, q5, q6])
            rows.append([q1, q2, q3, q4 + flip, -q5 if flip else q5, q6 + flip])
    wide = [u - l >= two_pi for l, u in zip(lo, hi)]
    for b, row in enumerate(rows):
        ok = True
        for j in range(6):
            th = row[j]
            l, u = lo[j], hi[j]
            if wide[j]:  # nearest equivalent to q_near, then shifted into the range
                th -= two_pi * round((th - qn_l[j]) / two_pi)
                if th > u + _LIMIT_TOL:
                    th -= two_pi
                elif th < l - _LIMIT_TOL:
                    th += two_pi
                row[j] = th
            elif not l - _LIMIT_TOL <= th <= u + _LIMIT_TOL:
                th -= two_pi * math.floor((th - l + _LIMIT_TOL) / two_pi)
                if th > u + _LIMIT_TOL:
                    ok = False
                row[j] = th
        valid[b] = ok
    return np.array(rows), valid


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
