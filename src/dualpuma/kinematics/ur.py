"""The UR family (UR3, UR5, UR10): geometry read from the loaded model, closed-form IK.

Standard UR Denavit-Hartenberg table, rows ``(theta, d, a, alpha)`` with a2, a3 < 0::

    1: (q1, d1, 0,  +pi/2)   2: (q2, 0, a2, 0)   3: (q3, 0, a3, 0)
    4: (q4, d4, 0,  +pi/2)   5: (q5, d5, 0, -pi/2)   6: (q6, d6, 0, 0)

:func:`geometry_from_model` reads d1 ... d6 from the Pinocchio model at q = 0 (joint axes and
points on them), not from a table: the DH base ``B`` (in the model's root frame; Rz(pi) of
``base_link`` for example-robot-data's URDFs) and the hand frame in the DH flange ``C`` (identity
for ``tool0``), then checks ``B FK_DH(q) C`` against Pinocchio's FK on random joints. A model that
does not fit (another kinematic structure) raises RobotError: use the numeric IK for it.

IK (all eight branches, index ``b = 4 s + 2 e + w``: shoulder s, elbow e, wrist w, as the PUMA's):
with the flange pose ``T = [n o a p]`` in the DH base and ``p5 = p - d6 a`` (axes 5 and 6 meet there):

1. **shoulder** — ``p5 . z1 = d4`` with ``z1 = (s1, -c1, 0)``: ``q1 = phi + asin(d4 / r)`` (s = 0) or
   ``phi + pi - asin(d4 / r)`` (s = 1), ``r = |p5_xy|``; unreachable if r < d4;
2. **wrist** — ``cos q5 = a . z1`` and ``|sin q5| = |(n . z1, o . z1)|`` (``n . z1 = s5 c6``,
   ``o . z1 = -s5 s6``), so ``q5 = +-atan2(|sin q5|, cos q5)`` (w = 0: q5 >= 0) and q6 follow
   without an ill-conditioned acos; at the wrist singularity (|sin q5| < 1e-10) only a combination
   is defined and q6 is taken from the reference joints (the UR's self-motion there also moves
   q2-q4, which are then solved exactly);
3. **elbow** — with frame 4 known, the planar two-link problem: ``q3 = +-acos(c3)`` (e = 0:
   q3 >= 0), then q2, and ``q4 = q234 - q2 - q3``.

Like :mod:`.puma`, the stages are written once and instantiated for Python floats (one pose,
~20 us for all eight branches) and numpy arrays (batches, one branch per pose for paths).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import RobotError
from .limits import wrap, wrap_rows

__all__ = ["WRIST_SINGULAR", "URGeometry", "branch_of", "branches", "geometry_from_model", "ik_all", "ik_branch"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

WRIST_SINGULAR = 1e-10  #: |sin q5| below this: wrist singular, q6 taken from the reference joints
_REACH_TOL = 1e-12  # [m^2] slack of the shoulder's reach (r >= d4)
_CHUNK = 4096  # poses per vectorised chunk
_ELBOW_TOL = 1e-9  # slack of cos q3 at the stretched elbow (FK's rounding reaches ~1e-11 there)
_DH_Z_AT_ZERO = ((0, 0, 1), (0, -1, 0), (0, -1, 0), (0, -1, 0), (0, 0, -1), (0, -1, 0))  # in the DH base


@dataclass(frozen=True, slots=True)
class URGeometry:
    """A UR-like arm's kinematic parameters (read from its model by :func:`geometry_from_model`).

    Attributes:
        d1, a2, a3, d4, d5, d6: the DH parameters [m] (a2, a3 < 0).
        B: (4, 4) the DH base in the model's root frame.
        C: (4, 4) the hand frame in the DH flange frame.
        B_inv, C_inv: their inverses.
    """

    d1: float
    a2: float
    a3: float
    d4: float
    d5: float
    d6: float
    B: FloatArray
    C: FloatArray
    B_inv: FloatArray
    C_inv: FloatArray

    def __eq__(self, other: object) -> bool:
        """The same parameters and frames, the frames compared by value (the generated comparison
        asked numpy for the truth of an array: two UR arms of one cell loaded from different files
        made every plan an internal error)."""
        return isinstance(other, URGeometry) and all(
            np.array_equal(getattr(self, f.name), getattr(other, f.name)) for f in dataclasses.fields(self))

    __hash__ = None  # (arrays: not hashable; URIK hashes the parameters)


def _dh_chain(g: URGeometry, q: FloatArray) -> FloatArray:
    """Flange poses in the DH base for joints q (N, 6): (N, 4, 4)."""
    rows = ((g.d1, 0.0, math.pi / 2), (0.0, g.a2, 0.0), (0.0, g.a3, 0.0), (g.d4, 0.0, math.pi / 2),
            (g.d5, 0.0, -math.pi / 2), (g.d6, 0.0, 0.0))
    T = np.tile(np.eye(4), (q.shape[0], 1, 1))
    for i, (d, a, alpha) in enumerate(rows):
        c, s = np.cos(q[:, i]), np.sin(q[:, i])
        ca, sa = math.cos(alpha), math.sin(alpha)
        A = np.zeros((q.shape[0], 4, 4))
        A[:, 0, 0], A[:, 0, 1], A[:, 0, 2], A[:, 0, 3] = c, -s * ca, s * sa, a * c
        A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = s, c * ca, -c * sa, a * s
        A[:, 2, 1], A[:, 2, 2], A[:, 2, 3], A[:, 3, 3] = sa, ca, d, 1.0
        T = T @ A
    return T


def geometry_from_model(model: pin.Model, hand_frame_id: int, *, n_check: int = 64) -> URGeometry:
    """The UR parameters of a 6-DOF model (hand = frame ``hand_frame_id``), read from its geometry
    at q = 0, and self-checked.

    Raises:
        RobotError: the model is not a UR-like arm (axes, offsets or FK do not fit the table).
    """
    if model.nq != 6 or model.nv != 6:
        raise RobotError(f"not a 6-DOF arm (nq={model.nq})")
    data = model.createData()
    q0 = np.zeros(6)
    pin.computeJointJacobians(model, data, q0)
    pin.updateFramePlacements(model, data)
    J = pin.getJointJacobian(model, data, model.njoints - 1, pin.WORLD)
    u = [J[3:, i] / max(np.linalg.norm(J[3:, i]), 1e-300) for i in range(6)]  # joint axes (world)
    o = [data.oMi[j].translation.copy() for j in range(1, 7)]  # a point on each axis
    fid = int(hand_frame_id)
    p_tool = data.oMf[fid].translation.copy()
    z0 = u[0]
    org = o[0] - z0 * float(np.dot(o[0], z0))
    reach = o[3] - o[1]
    reach = reach - z0 * np.dot(reach, z0) - u[1] * np.dot(reach, u[1])
    if np.linalg.norm(reach) < 1e-6:
        raise RobotError("not UR-like: the elbow does not lie in the arm plane at q = 0")
    x0 = -reach / np.linalg.norm(reach)  # the arm lies along -x0 at q = 0 (a2 < 0)
    B = np.eye(4)
    B[:3, :3] = np.column_stack([x0, np.cross(z0, x0), z0])
    B[:3, 3] = org
    R = B[:3, :3]

    def P(v: FloatArray) -> FloatArray:
        return R.T @ (v - org)

    for i, z in enumerate(_DH_Z_AT_ZERO):
        if abs(float(np.dot(R.T @ u[i], z)) - 1.0) > 1e-9:
            raise RobotError(f"not UR-like: joint {i + 1}'s axis at q = 0 does not fit the UR table")
    d1 = float(P(o[1])[2])
    a2 = float(P(o[2])[0] - P(o[1])[0])
    a3 = float(P(o[3])[0] - P(o[2])[0])
    d4 = float(-P(o[4])[1])
    d5 = float(d1 - P(o[5])[2])
    d6 = float(-P(p_tool)[1] - d4)
    if not (a2 < 0 and a3 < 0 and all(abs(P(o[k])[2] - d1) < 1e-9 for k in (1, 2, 3))):
        raise RobotError("not UR-like: q = 0 is not the UR's stretched-out zero")
    g0 = URGeometry(d1, a2, a3, d4, d5, d6, B, np.eye(4), np.linalg.inv(B), np.eye(4))
    C = np.linalg.inv(B @ _dh_chain(g0, q0[None])[0]) @ data.oMf[fid].homogeneous
    C[np.abs(C) < 1e-12] = 0.0
    g = URGeometry(d1, a2, a3, d4, d5, d6, B, C, g0.B_inv, np.linalg.inv(C))
    Q = np.random.default_rng(1).uniform(-math.pi, math.pi, (n_check, 6))
    T_dh = B @ _dh_chain(g, Q) @ C
    for i in range(n_check):
        pin.framesForwardKinematics(model, data, Q[i])
        if not np.allclose(T_dh[i], data.oMf[fid].homogeneous, rtol=0.0, atol=1e-9):
            raise RobotError("not UR-like: the UR table's FK differs from the model's")
    for M in (g.B, g.C, g.B_inv, g.C_inv):
        M.setflags(write=False)
    return g


# --------------------------------------------------------------------------- the closed form
def _closed_form(atan2, asin, acos, sqrt, sin, cos, clip1, where, any_):
    """The UR IK stages over one kind of number (``math`` for floats, numpy for arrays;
    ``clip1(x)`` clips into [-1, 1])."""

    def shoulder(g, p5x, p5y, s):
        """q1 and (c1, s1) for shoulder bit s (0 or 1, or an array of them)."""
        r = sqrt(p5x * p5x + p5y * p5y)
        asn = asin(clip1(g.d4 / where(r > 0.0, r, 1e-300)))
        q1 = atan2(p5y, p5x) + where(s == 0, asn, math.pi - asn)
        return q1, cos(q1), sin(q1)

    def wrist(g, c1, s1, n, o, a, p5, w, q6_ref):
        """q5, q6 for wrist bit w, then frame 4: (q5, q6, u, v, q234) with (u, v) the wrist point
        in the arm plane and q234 = q2 + q3 + q4."""
        nx, ny, nz = n
        ox, oy, oz = o
        ax, ay, az = a
        c5 = s1 * ax - c1 * ay  # a . z1 = cos q5
        zx, zy = s1 * nx - c1 * ny, s1 * ox - c1 * oy  # n . z1 = s5 c6, o . z1 = -s5 s6
        h = sqrt(zx * zx + zy * zy)  # |sin q5|, well conditioned (acos(c5) is not near q5 = 0)
        sg = where(w == 0, 1.0, -1.0)
        q5 = sg * atan2(h, c5)
        s5 = sg * h
        sing = h < WRIST_SINGULAR
        if any_(sing):
            q6 = where(sing, q6_ref, atan2(-zy * sg, zx * sg))
        else:
            q6 = atan2(-zy * sg, zx * sg)
        c6, s6 = cos(q6), sin(q6)
        p4x = p5[0] + g.d5 * (s6 * nx + c6 * ox)  # p4 = p5 - d5 z4, z4 = -s6 n - c6 o
        p4y = p5[1] + g.d5 * (s6 * ny + c6 * oy)
        p4z = p5[2] + g.d5 * (s6 * nz + c6 * oz)
        x4x = c5 * c6 * nx - c5 * s6 * ox - s5 * ax
        x4y = c5 * c6 * ny - c5 * s6 * oy - s5 * ay
        x4z = c5 * c6 * nz - c5 * s6 * oz - s5 * az
        return q5, q6, c1 * p4x + s1 * p4y, p4z - g.d1, atan2(x4z, c1 * x4x + s1 * x4y)

    def elbow(g, u, v, q234, e):
        """q2, q3, q4 for elbow bit e, and whether the wrist point is within the two links' reach."""
        c3 = (u * u + v * v - g.a2 * g.a2 - g.a3 * g.a3) / (2.0 * g.a2 * g.a3)
        reach = (c3 <= 1.0 + _ELBOW_TOL) & (c3 >= -1.0 - _ELBOW_TOL)
        q3 = where(e == 0, acos(clip1(c3)), -acos(clip1(c3)))
        q2 = atan2(v, u) - atan2(g.a3 * sin(q3), g.a2 + g.a3 * cos(q3))
        return q2, q3, q234 - q2 - q3, reach

    return shoulder, wrist, elbow


_FLOATS = _closed_form(math.atan2, math.asin, math.acos, math.sqrt, math.sin, math.cos,
                       lambda x: -1.0 if x < -1.0 else min(x, 1.0), lambda c, a, b: a if c else b, bool)
_ARRAYS = _closed_form(np.arctan2, np.arcsin, np.arccos, np.sqrt, np.sin, np.cos, lambda x: np.clip(x, -1.0, 1.0),
                       np.where, np.any)


def _flange(g: URGeometry, T: FloatArray) -> FloatArray:
    """Hand poses in the model's root frame -> flange poses in the DH base."""
    return g.B_inv @ T @ g.C_inv


def ik_all(g: URGeometry, T: FloatArray, q_near: FloatArray, limits: FloatArray) -> tuple[FloatArray, BoolArray]:
    """All eight branches for hand poses T (4, 4) or (N, 4, 4) in the arm's base frame (trusted).

    Args:
        q_near: reference joints (6,) or (N, 6) [rad]: picks the 2 pi equivalents and q6 at the
            wrist singularity.
        limits: (6, 2) [rad].

    Returns:
        ``(solutions (..., 8, 6) [rad], valid (..., 8))`` in branch order; unreachable rows NaN.
    """
    if T.shape == (4, 4):
        return _ik_all_one(g, T, np.asarray(q_near, dtype=np.float64).reshape(6).tolist(), limits)
    n = T.shape[0]
    ref = np.broadcast_to(q_near, (n, 6))
    if n <= _CHUNK:
        return _ik_all_many(g, T, ref, limits)
    sols, valid = np.empty((n, 8, 6)), np.empty((n, 8), dtype=bool)
    for i in range(0, n, _CHUNK):  # chunks keep the temporaries in cache
        sols[i : i + _CHUNK], valid[i : i + _CHUNK] = _ik_all_many(g, T[i : i + _CHUNK], ref[i : i + _CHUNK], limits)
    return sols, valid


def _ik_all_many(g: URGeometry, T: FloatArray, ref: FloatArray, limits: FloatArray) -> tuple[FloatArray, BoolArray]:
    """All eight branches of poses T (N, 4, 4) with reference joints (N, 6)."""
    n = T.shape[0]
    F = _flange(g, T)
    n_, o_, a_, p = (np.ascontiguousarray(F[:, :3, k].T) for k in range(4))
    p5 = p - g.d6 * a_
    reach1 = p5[0] * p5[0] + p5[1] * p5[1] >= g.d4 * g.d4 - _REACH_TOL
    shoulder, wrist, elbow = _ARRAYS
    b3 = np.array([0, 1])
    q1, c1, s1 = shoulder(g, p5[0], p5[1], b3[:, None])  # (2, N)
    c1w, s1w = c1[:, None], s1[:, None]
    q5, q6, u, v, q234 = wrist(g, c1w, s1w, n_, o_, a_, (p5[0], p5[1], p5[2]), b3[None, :, None], ref[:, 5])  # (2, 2, N)
    q2, q3, q4, reach = elbow(g, u[:, :, None], v[:, :, None], q234[:, :, None], b3[None, None, :, None])  # (2,2,2,N)
    out = np.empty((2, 2, 2, 6, n))  # (s, w, e, joint, N)
    out[:, :, :, 0] = q1[:, None, None]
    out[:, :, :, 1], out[:, :, :, 2], out[:, :, :, 3] = q2, q3, q4
    out[:, :, :, 4] = q5[:, :, None]
    out[:, :, :, 5] = q6[:, :, None]
    ok = np.broadcast_to(reach & reach1, (2, 2, 2, n))
    sols = np.moveaxis(out, (0, 1, 2), (0, 2, 1)).reshape(8, 6, n)  # branch 4 s + 2 e + w
    ok = np.moveaxis(ok, (0, 1, 2), (0, 2, 1)).reshape(8, n)
    valid = ok.copy()
    for j in range(6):
        sols[:, j], inside = wrap(sols[:, j], ref[:, j], limits[j, 0], limits[j, 1])
        valid &= inside
    res = np.moveaxis(sols, 2, 0).copy()
    res[~ok.T] = np.nan
    return res, np.ascontiguousarray(valid.T)


def _ik_all_one(g: URGeometry, T: FloatArray, ref: list[float], limits: FloatArray) -> tuple[FloatArray, BoolArray]:
    """All eight branches of one pose, in plain floats."""
    F = _flange(g, T)
    (nx, ox, ax, px), (ny, oy, ay, py), (nz, oz, az, pz) = F[:3].tolist()
    p5 = (px - g.d6 * ax, py - g.d6 * ay, pz - g.d6 * az)
    if p5[0] * p5[0] + p5[1] * p5[1] < g.d4 * g.d4 - _REACH_TOL:
        return np.full((8, 6), np.nan), np.zeros(8, dtype=bool)
    shoulder, wrist, elbow = _FLOATS
    rows: list[list[float]] = [[]] * 8
    reach = [False] * 8
    for s in (0, 1):
        q1, c1, s1 = shoulder(g, p5[0], p5[1], s)
        for w in (0, 1):
            q5, q6, u, v, q234 = wrist(g, c1, s1, (nx, ny, nz), (ox, oy, oz), (ax, ay, az), p5, w, ref[5])
            for e in (0, 1):
                q2, q3, q4, ok = elbow(g, u, v, q234, e)
                b = 4 * s + 2 * e + w
                rows[b], reach[b] = [q1, q2, q3, q4, q5, q6], bool(ok)
    lo, hi = limits[:, 0].tolist(), limits[:, 1].tolist()
    valid = np.array(wrap_rows(rows, ref, lo, hi)) & np.array(reach)
    sols = np.array(rows)
    sols[~np.array(reach)] = np.nan
    return sols, valid


def ik_branch(g: URGeometry, T: FloatArray, branch: npt.NDArray[np.int64], q_ref: FloatArray) -> tuple[FloatArray, BoolArray, FloatArray]:
    """One branch per pose (trusted): poses (M, 4, 4), branch indices (M,), reference joints
    (M, 6) (q6 at the wrist singularity). Returns raw angles (M, 6) [rad] (not wrapped),
    reachability (M,) and |sin q5| (M,)."""
    F = _flange(g, T)
    n_, o_, a_, p = (np.ascontiguousarray(F[:, :3, k].T) for k in range(4))
    p5 = p - g.d6 * a_
    reach1 = p5[0] * p5[0] + p5[1] * p5[1] >= g.d4 * g.d4 - _REACH_TOL
    s, e, w = branch >> 2, (branch >> 1) & 1, branch & 1
    shoulder, wrist, elbow = _ARRAYS
    q = np.empty((6, T.shape[0]))
    q[0], c1, s1 = shoulder(g, p5[0], p5[1], s)
    q[4], q[5], u, v, q234 = wrist(g, c1, s1, n_, o_, a_, (p5[0], p5[1], p5[2]), w, q_ref[:, 5])
    q[1], q[2], q[3], reach = elbow(g, u, v, q234, e)
    return q.T, reach & reach1, np.abs(np.sin(q[4]))


def branch_of(g: URGeometry, q: FloatArray) -> int:
    """Branch index of one joint vector (6,) [rad]: shoulder from the sign of the wrist point's
    reach in the arm plane (a2 c2 + a3 c23 + d5 s234), elbow from sin q3, wrist from sin q5."""
    q2, q3, q4, q5 = float(q[1]), float(q[2]), float(q[3]), float(q[4])
    x = g.a2 * math.cos(q2) + g.a3 * math.cos(q2 + q3) + g.d5 * math.sin(q2 + q3 + q4)
    return 4 * (x < 0) + 2 * (math.sin(q3) < 0) + (math.sin(q5) < 0)


def branches(g: URGeometry, Q: FloatArray) -> npt.NDArray[np.int64]:
    """:func:`branch_of` of many joint vectors (K, 6) [rad] at once."""
    q2, q3, q4, q5 = Q[:, 1], Q[:, 2], Q[:, 3], Q[:, 4]
    x = g.a2 * np.cos(q2) + g.a3 * np.cos(q2 + q3) + g.d5 * np.sin(q2 + q3 + q4)
    return 4 * (x < 0).astype(np.int64) + 2 * (np.sin(q3) < 0).astype(np.int64) + (np.sin(q5) < 0)
