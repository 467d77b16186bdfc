"""PUMA 560 in the seed's convention: constants, joint limits, closed-form FK and IK.

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

The closed form is written once (``_closed_form``: shoulder, elbow, arm plane and wrist stages) and
instantiated for Python floats and for numpy arrays. :func:`ik_all` runs it on floats for one pose
(no numpy temporaries: ~14 us for all eight branches) and on arrays, broadcast over the branches,
for a batch; :func:`ik_branch` on arrays with one branch per pose (the planners' path IK).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ..checks import validate_joints, validate_pose
from ..errors import JointError, PoseError
from .ik import BRANCH_NAMES, QUIET_FAR_OUT, WRIST_SINGULAR, IKResult, select_branch
from .limits import check_limits, wrap, wrap_rows

__all__ = [
    "A2", "A3", "BRANCH_NAMES", "D2", "D4", "D_FLANGE", "JOINT_LIMITS", "SHOULDER_HEIGHT", "WRIST_SINGULAR",
    "branch_of", "branch_signs", "branches", "config_to_branch", "fk", "ik", "ik_all", "ik_all_unchecked", "ik_branch",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

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
        [[-160.0, 160.0], [-225.0, 45.0], [-225.0, 45.0], [-266.0, 266.0], [-100.0, 100.0], [-266.0, 266.0]]
    )
)
JOINT_LIMITS.setflags(write=False)

_REACH_TOL = 1e-12  # [m^2] slack on square-root arguments at the workspace boundary
_CHUNK = 4096  # poses per vectorised chunk in ik_all (temporaries stay in cache)
_GAMMA = math.atan2(A3, D4)
_RHO3_SQ = A3 * A3 + D4 * D4  # |elbow -> wrist centre|^2
_CG, _SG = D4 / _RHO3_SQ, A3 / _RHO3_SQ
_K_OFFSET = A2 * A2 + A3 * A3 + D2 * D2 + D4 * D4
_LIM_LO: list[float] = JOINT_LIMITS[:, 0].tolist()
_LIM_HI: list[float] = JOINT_LIMITS[:, 1].tolist()
_ZERO_JOINTS = np.zeros(6)
_ZERO_JOINTS.setflags(write=False)


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
    c, s = np.cos(q), np.sin(q)
    c1, c2, c4, c5, c6 = c[..., 0], c[..., 1], c[..., 3], c[..., 4], c[..., 5]
    s1, s2, s4, s5, s6 = s[..., 0], s[..., 1], s[..., 3], s[..., 4], s[..., 5]
    q23 = q[..., 1] + q[..., 2]
    c23, s23 = np.cos(q23), np.sin(q23)
    T = np.zeros(q.shape[:-1] + (4, 4))
    # wrist rotation R36 columns, then R03 applied (written out as in CalcTran);
    # R03 = [[c1 c23, s1, -c1 s23], [s1 c23, -c1, -s1 s23], [-s23, 0, -c23]]
    cols = (
        (c4 * c5 * c6 - s4 * s6, s4 * c5 * c6 + c4 * s6, s5 * c6),
        (-c4 * c5 * s6 - s4 * c6, -s4 * c5 * s6 + c4 * c6, -s5 * s6),
        (-c4 * s5, -s4 * s5, c5),
    )
    for j, (u0, u1, u2) in enumerate(cols):
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


# --------------------------------------------------------------------------- the closed form
def _closed_form(atan2, hypot, cos, sin, sqrt0, where, any_):
    """The closed-form IK stages over one kind of number: ``math`` functions for plain floats or
    numpy ufuncs for arrays (``hypot(a, b)`` = sqrt(a^2 + b^2), ``sqrt0(x)`` = sqrt(max(x, 0)),
    ``where(c, a, b)``, ``any_(mask)``).
    Written once; :data:`_FLOATS` and :data:`_ARRAYS` are its two instances."""

    def shoulder(px, py, rho2, s_sh):
        """Joint 1 for the shoulder sign ``s_sh`` (+1 left, -1 right): ``(q1, c1, s1, r)``, r being
        the signed distance of the wrist centre from the base axis in the arm plane."""
        r = s_sh * sqrt0(rho2 - D2 * D2)
        inv = 1.0 / where(rho2 > 0.0, rho2, 1.0)
        return atan2(py, px) - atan2(D2, r), (r * px + D2 * py) * inv, (r * py - D2 * px) * inv, r

    def elbow(K, s_el):
        """Joint 3 from ``a3 c3 - d4 s3 = K`` for the elbow sign ``s_el`` (+1 up): ``(q3, c3, s3)``."""
        sq = s_el * sqrt0(_RHO3_SQ - K * K)
        return _GAMMA - atan2(K, sq), _CG * sq + _SG * K, _SG * sq - _CG * K

    def arm(r, pz, q3, c3, s3, c1, s1, R, q4_ref):
        """Joint 2 in the arm plane, then joints 4-6 of the no-flip wrist (q5 >= 0) from the wrist
        rotation W = R03^T R: ``(q2, q4, q5, q6, h)`` with h = |sin q5|. Where h is below
        :data:`WRIST_SINGULAR` only q4 + q6 is defined: q4 is ``q4_ref``.

        ``R`` is the target rotation's entries (r00 .. r22) in row order; R03's columns are
        e0 = (c1 c23, s1 c23, -s23), e1 = (s1, -c1, 0), e2 = (-c1 s23, -s1 s23, -c23)."""
        P = A2 * c3 + A3
        Q = A2 * s3 - D4
        ys = Q * r - P * pz
        xs = P * r + Q * pz
        n23 = 1.0 / hypot(ys, xs)
        c23, s23 = xs * n23, ys * n23
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
        a0 = c1 * r00 + s1 * r10
        a1 = c1 * r01 + s1 * r11
        a2 = c1 * r02 + s1 * r12
        w00, w01, w02 = c23 * a0 - s23 * r20, c23 * a1 - s23 * r21, c23 * a2 - s23 * r22
        w10, w11, w12 = s1 * r00 - c1 * r10, s1 * r01 - c1 * r11, s1 * r02 - c1 * r12
        w22 = -s23 * a2 - c23 * r22
        h = hypot(w02, w12)
        sing = h < WRIST_SINGULAR
        if any_(sing):
            hs = where(sing, 1.0, h)
            c4 = where(sing, cos(q4_ref), -w02 / hs)
            s4 = where(sing, sin(q4_ref), -w12 / hs)
            q4 = where(sing, q4_ref, atan2(-w12, -w02))
        else:
            inv_h = 1.0 / h
            c4, s4 = -w02 * inv_h, -w12 * inv_h
            q4 = atan2(-w12, -w02)
        q6 = atan2(c4 * w10 - s4 * w00, c4 * w11 - s4 * w01)
        return atan2(ys, xs) - q3, q4, atan2(h, w22), q6, h

    return shoulder, elbow, arm


_FLOATS = _closed_form(
    math.atan2, math.hypot, math.cos, math.sin, lambda x: math.sqrt(x) if x > 0.0 else 0.0,
    lambda c, a, b: a if c else b, bool,
)
_ARRAYS = _closed_form(
    np.arctan2, lambda a, b: np.sqrt(a * a + b * b), np.cos, np.sin, lambda x: np.sqrt(np.maximum(x, 0.0)),
    np.where, lambda m: bool(m.any()),  # (the method: np.any's dispatch costs more than the test here)
)


def _target(rows):
    """(px, py, pz, R entries, rho2, K) of targets given by the top three rows of their poses,
    ``((r00, r01, r02, px), (r10, ...), (r20, ...))``: plain floats for one pose, or arrays stored
    component-first, (3, 4, N), for many."""
    (r00, r01, r02, px), (r10, r11, r12, py), (r20, r21, r22, pz) = rows
    rho2 = px * px + py * py
    K = (rho2 + pz * pz - _K_OFFSET) * (0.5 / A2)
    return px, py, pz, (r00, r01, r02, r10, r11, r12, r20, r21, r22), rho2, K


def _reachable(rho2, K):
    return (rho2 - D2 * D2 > -_REACH_TOL) & (_RHO3_SQ - K * K > -_REACH_TOL)


# --------------------------------------------------------------------------- all eight branches
def _ik_all_one(T: FloatArray, ref: list[float], lo: list[float], hi: list[float]) -> tuple[FloatArray, BoolArray]:
    """All eight branches of one pose, in plain floats."""
    px, py, pz, R, rho2, K = _target(T[:3].tolist())
    if not _reachable(rho2, K):
        return np.full((8, 6), np.nan), np.zeros(8, dtype=bool)
    q4_ref = min(max(ref[3], lo[3]), hi[3])
    shoulder, elbow, arm = _FLOATS
    elbows = [elbow(K, 1.0), elbow(K, -1.0)]
    rows: list[list[float]] = []
    for s_sh in (1.0, -1.0):
        q1, c1, s1, r = shoulder(px, py, rho2, s_sh)
        for q3, c3, s3 in elbows:
            q2, q4, q5, q6, h = arm(r, pz, q3, c3, s3, c1, s1, R, q4_ref)
            rows.append([q1, q2, q3, q4, q5, q6])
            if h < WRIST_SINGULAR:
                rows.append([q1, q2, q3, q4, q5, q6])
            else:
                rows.append([q1, q2, q3, q4 + math.pi, -q5, q6 + math.pi])
    valid = np.array(wrap_rows(rows, ref, lo, hi))  # (wraps the rows in place first)
    return np.array(rows), valid


def _ik_all_many(T: FloatArray, ref: FloatArray, lim: FloatArray) -> tuple[FloatArray, BoolArray]:
    """All eight branches of poses T (N, 4, 4) with reference joints ref (N, 6); branch axes
    lead internally and the pose axis is last (contiguous)."""
    n = T.shape[0]
    Tt = T.reshape(n, 16).T  # (16, N) view
    px, py, pz, R, rho2, K = _target([[np.ascontiguousarray(Tt[4 * i + j]) for j in range(4)] for i in range(3)])
    qf = np.ascontiguousarray(ref.T)  # (6, N)
    ok = _reachable(rho2, K)
    sgn = np.array([1.0, -1.0])[:, None]
    shoulder, elbow, arm = _ARRAYS
    q1, c1, s1, r = shoulder(px, py, rho2, sgn)  # (2, N): shoulder
    q3, c3, s3 = elbow(K, sgn)  # (2, N): elbow
    q4_ref = np.clip(qf[3], lim[3, 0], lim[3, 1])
    # (2, 2, N): shoulder x elbow
    q2, q4, q5, q6, h = arm(r[:, None], pz, q3[None], c3[None], s3[None], c1[:, None], s1[:, None], R, q4_ref)
    sing = h < WRIST_SINGULAR
    if sing.any():
        flip = np.where(sing, 0.0, math.pi)
        partner = (q4 + flip, np.where(sing, q5, -q5), q6 + flip)
    else:
        partner = (q4 + math.pi, -q5, q6 + math.pi)
    out = np.empty((2, 2, 2, 6, n))
    valid = np.broadcast_to(ok, (2, 2, 2, n)).copy()
    a, inside = wrap(q1, qf[0], lim[0, 0], lim[0, 1])
    out[:, :, :, 0] = a[:, None, None]
    valid &= inside[:, None, None]
    a, inside = wrap(q3, qf[2], lim[2, 0], lim[2, 1])
    out[:, :, :, 2] = a[None, :, None]
    valid &= inside[None, :, None]
    a, inside = wrap(q2, qf[1], lim[1, 0], lim[1, 1])
    out[:, :, :, 1] = a[:, :, None]
    valid &= inside[:, :, None]
    for w, angles in enumerate(((q4, q5, q6), partner)):
        for j, ang in zip((3, 4, 5), angles):
            a, inside = wrap(ang, qf[j], lim[j, 0], lim[j, 1])
            out[:, :, w, j] = a
            valid[:, :, w] &= inside
    res = np.moveaxis(out.reshape(8, 6, n), 2, 0)
    res[~ok] = np.nan
    return res, np.ascontiguousarray(valid.reshape(8, n).T)


def ik_all_unchecked(T: FloatArray, q_near: FloatArray, limits: FloatArray) -> tuple[FloatArray, BoolArray]:
    """:func:`ik_all` for an already validated batch: poses (N, 4, 4), reference joints (6,) or
    (N, 6), limits (6, 2); or one pose (4, 4) with reference joints (6,). No checks (callers
    validated at the public boundary)."""
    if T.shape == (4, 4):
        return _ik_all_one(T, np.asarray(q_near, dtype=np.float64).tolist(), limits[:, 0].tolist(), limits[:, 1].tolist())
    n = T.shape[0]
    ref = np.broadcast_to(q_near, (n, 6))
    with np.errstate(divide="ignore", invalid="ignore"):  # a pose on an axis: its rows come out invalid
        if n <= _CHUNK:
            return _ik_all_many(T, ref, limits)
        sols = np.empty((n, 8, 6))
        valid = np.empty((n, 8), dtype=bool)
        for i in range(0, n, _CHUNK):  # chunks keep the temporaries in cache (about 2x faster)
            sols[i : i + _CHUNK], valid[i : i + _CHUNK] = _ik_all_many(T[i : i + _CHUNK], ref[i : i + _CHUNK], limits)
        return sols, valid


@QUIET_FAR_OUT
def ik_all(
    T: npt.ArrayLike,
    *,
    q_near: npt.ArrayLike | None = None,
    limits: npt.ArrayLike | None = None,
) -> tuple[FloatArray, BoolArray]:
    """All eight closed-form IK branches for wrist-centre poses in the shoulder frame.

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
    lim = JOINT_LIMITS if limits is None else check_limits(limits)
    batch = T.shape[:-2]
    qn = _ZERO_JOINTS if q_near is None else validate_joints(q_near, name="q_near")
    if batch == ():
        if qn.shape != (6,):
            raise JointError(f"q_near: expected shape (6,) for one pose, got {qn.shape}")
        lo, hi = (_LIM_LO, _LIM_HI) if limits is None else (lim[:, 0].tolist(), lim[:, 1].tolist())
        return _ik_all_one(T, qn.tolist(), lo, hi)
    try:
        qn = np.broadcast_to(qn, batch + (6,))
    except ValueError:
        raise JointError(f"q_near: shape {qn.shape} does not broadcast to the poses' {batch + (6,)}") from None
    n = int(np.prod(batch))
    sols, valid = ik_all_unchecked(T.reshape(n, 4, 4), qn.reshape(n, 6), lim)
    return sols.reshape(batch + (8, 6)), valid.reshape(batch + (8,))


# --------------------------------------------------------------------------- one branch per pose
def branch_signs(q: FloatArray) -> tuple[float, float, bool]:
    """(shoulder sign, elbow sign, wrist flipped) of one trusted joint vector (6,) [rad]: the
    branch :func:`ik_branch` continues (as :func:`branch_of`, in plain floats)."""
    q2, q3, q5 = float(q[1]), float(q[2]), float(q[4])
    r = A2 * math.cos(q2) + A3 * math.cos(q2 + q3) - D4 * math.sin(q2 + q3)
    return (-1.0 if r < 0 else 1.0), (-1.0 if math.cos(_GAMMA - q3) < 0 else 1.0), math.sin(q5) < 0


def ik_branch(
    T: FloatArray, s_sh: FloatArray, s_el: FloatArray, flip: BoolArray, q4_ref: FloatArray
) -> tuple[FloatArray, BoolArray, FloatArray]:
    """Closed-form IK on one branch per pose (trusted input).

    Args:
        T: target ``T_base_wrist`` poses (M, 4, 4) [m].
        s_sh, s_el: (M,) +1 / -1 shoulder and elbow signs (see :func:`branch_signs`).
        flip: (M,) bool, wrist flipped.
        q4_ref: (M,) q4 to use where the wrist is singular [rad] (already inside the limits).

    Returns:
        ``(q, reach, h)``: raw angles (M, 6) [rad] (not wrapped into any range), reachability (M,)
        and |sin q5| (M,). Unreachable rows hold finite garbage; singular rows (h below
        :data:`WRIST_SINGULAR`) have q4 = ``q4_ref`` and are the same for both wrist labels.
    """
    px, py, pz, R, rho2, K = _target(T.reshape(-1, 16).T[:12].reshape(3, 4, -1))  # strided views, no copy
    shoulder, elbow, arm = _ARRAYS
    q = np.empty((6, px.shape[0]))
    q[0], c1, s1, r = shoulder(px, py, rho2, s_sh)
    q[2], c3, s3 = elbow(K, s_el)
    q[1], q4, q5, q6, h = arm(r, pz, q[2], c3, s3, c1, s1, R, q4_ref)
    f = np.where(flip & (h >= WRIST_SINGULAR), math.pi, 0.0)
    q[3], q[5] = q4 + f, q6 + f
    q[4] = np.where(f != 0.0, -q5, q5)
    return q.T, _reachable(rho2, K), h


# --------------------------------------------------------------------------- one pose, one branch
def config_to_branch(shoulder: int | str = 1, elbow: int | str = 1, wrist: int | str = 1) -> int:
    """Branch index from the seed's indicators (``chars``: +1 / -1) or names (shoulder "left" /
    "right", elbow "up" / "down", wrist "noflip" / "flip").

    Raises:
        JointError: any other value.
    """
    index = 0
    for v, weight, pos, neg, label in ((shoulder, 4, "left", "right", "shoulder"), (elbow, 2, "up", "down", "elbow"),
                                       (wrist, 1, "noflip", "flip", "wrist")):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer, str)) or v not in (1, -1, pos, neg):
            raise JointError(f"{label}: expected +1/-1 or '{pos}'/'{neg}', got {v!r}")
        index += weight * (v in (-1, neg))
    return index


def branch_of(q: npt.ArrayLike) -> npt.NDArray[np.int64]:
    """Branch index (0..7) that joint vector(s) belong to, shape (...,).

    Raises:
        JointError: malformed ``q``.
    """
    return branches(validate_joints(q))


def branches(q: FloatArray) -> npt.NDArray[np.int64]:
    """:func:`branch_of` for trusted joint vectors (..., 6) [rad]."""
    q2, q3, q5 = q[..., 1], q[..., 2], q[..., 4]
    r = A2 * np.cos(q2) + A3 * np.cos(q2 + q3) - D4 * np.sin(q2 + q3)
    return 4 * (r < 0).astype(np.int64) + 2 * (np.cos(_GAMMA - q3) < 0).astype(np.int64) + (np.sin(q5) < 0)


@QUIET_FAR_OUT
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
            (max-abs joint distance), or the first valid branch if ``q_near`` is also None.
        q_near: previous joints [rad], shape (6,): picks equivalent angles and q4 at q5 ~ 0.
        limits: joint limits [rad], shape (6, 2); default :data:`JOINT_LIMITS`.

    Returns:
        :class:`IKResult`; ``status`` tells unreachable / joint-limit failures (never NaN).

    Raises:
        PoseError: malformed ``T`` (or a batch: use :func:`ik_all`).
        JointError: malformed ``q_near``, ``limits`` or ``config``.
    """
    T = validate_pose(T)
    if T.shape != (4, 4):
        raise PoseError(f"T: ik() takes one pose of shape (4, 4), got {T.shape}; use ik_all for batches")
    lim = JOINT_LIMITS if limits is None else check_limits(limits)
    if config is None:
        b = -1
    elif isinstance(config, (int, np.integer)) and not isinstance(config, bool):
        if not 0 <= int(config) <= 7:
            raise JointError(f"config: branch index must be 0..7, got {config}")
        b = int(config)
    elif isinstance(config, (tuple, list)) and len(config) == 3:
        b = config_to_branch(*config)
    else:
        raise JointError(f"config: expected a branch index 0..7 or (shoulder, elbow, wrist), got {config!r}")
    sols, valid = ik_all(T, q_near=q_near, limits=lim)
    return select_branch(sols, valid, None if b < 0 else b, q_near, lim, f"wrist centre {[round(x, 4) for x in T[:3, 3].tolist()]} m")
