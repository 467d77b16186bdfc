"""Numeric kernels of the PUMA 560 closed-form IK (scalar fast path and vectorised batch), and
the constants they share with :mod:`dualpuma.puma` (which documents the convention and is the
public entry point: ``puma.ik_all`` / ``puma.ik``)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

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


def _wrist_terms(c1, s1, c23, s23, R):
    """Entries (00, 01, 02, 10, 11, 12, 22) of the wrist rotation W = R03^T R (arrays broadcast).

    R03's columns are e0 = (c1 c23, s1 c23, -s23), e1 = (s1, -c1, 0), e2 = (-c1 s23, -s1 s23, -c23);
    ``R`` is the target rotation's entries r00 .. r22 in row order.
    """
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
    a0 = c1 * r00 + s1 * r10  # a_k = c1 R0k + s1 R1k
    a1 = c1 * r01 + s1 * r11
    a2 = c1 * r02 + s1 * r12
    w10 = s1 * r00 - c1 * r10
    w11 = s1 * r01 - c1 * r11
    w12 = s1 * r02 - c1 * r12
    return (c23 * a0 - s23 * r20, c23 * a1 - s23 * r21, c23 * a2 - s23 * r22, w10, w11, w12,
            -s23 * a2 - c23 * r22)


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
    w00, w01, w02, w10, w11, w12, w22 = _wrist_terms(c1[:, None], s1[:, None], c23, s23,
                                                     (r00, r01, r02, r10, r11, r12, r20, r21, r22))
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
