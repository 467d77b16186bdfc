"""Closed-form distances of the clearance kernel (:mod:`dualpuma.collision.kernel`), vectorised over entries:
segment–segment (capsule–capsule is that minus the radii), point–box, and the signed segment–box
and box–box distances (negative = penetration depth, from the separating-axis test). Each is
checked against brute-force references and coal in tests/test_kernel.py and tests/test_box_box.py."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = ["box_box", "point_box", "segment_box", "segment_segment"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

_TINY = 1e-300  #: guards 0/0 in the closed forms [m^2]
_NEAR_PARALLEL = 1e-6  #: sin^2 of the angle below which segments also get the end point checks


def segment_segment(
    p0: FloatArray,
    d1: FloatArray,
    q0: FloatArray,
    d2: FloatArray,
    a: npt.ArrayLike,
    e: npt.ArrayLike,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Exact distance between segments ``p0 + s d1`` and ``q0 + t d2`` (s, t in [0, 1]), vectorised.

    Minimises the convex quadratic |p0 + s d1 - q0 - t d2|^2 over the unit square in three clamped
    steps: s from the unconstrained stationary point, t optimal for that s, then s optimal for that
    t. At the joint minimum each coordinate is optimal for the other, so the third step keeps an
    interior solution and repairs a clamped t (the classic closest-point algorithm, branch-free).
    Parallel segments take s = 0 or 1 first, which the next two steps turn into a closest pair.
    Zero-length segments (spheres) keep their parameter at 0.

    Args:
        p0, q0: segment starts [m], shape (3, ...) (component first), broadcastable.
        d1, d2: segment vectors (end - start) [m], shape (3, ...).
        a, e: |d1|^2 and |d2|^2 [m^2], broadcastable to the result (known per pair).

    Returns:
        ``(distance [m], s, t)``, each of the broadcast shape without the leading 3.
    """
    r = p0 - q0
    b = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2]
    c = d1[0] * r[0] + d1[1] * r[1] + d1[2] * r[2]
    f = d2[0] * r[0] + d2[1] * r[1] + d2[2] * r[2]
    a = np.asarray(a, dtype=np.float64)
    e = np.asarray(e, dtype=np.float64)
    inv_a = np.divide(1.0, a, out=np.zeros(a.shape), where=a > 0)
    inv_e = np.divide(1.0, e, out=np.zeros(e.shape), where=e > 0)
    ae = a * e
    den = ae - b * b  # = a e sin^2(angle)
    s = b * f
    s -= c * e
    s /= den + _TINY
    np.clip(s, 0.0, 1.0, out=s)
    t = b * s
    t += f
    t *= inv_e
    np.clip(t, 0.0, 1.0, out=t)
    s = b * t
    s -= c
    s *= inv_a
    np.clip(s, 0.0, 1.0, out=s)
    acc = np.zeros(s.shape)
    for k in range(3):
        x = r[k] + s * d1[k]
        x -= t * d2[k]
        x *= x
        acc += x
    dist = np.sqrt(acc, out=acc)
    near = np.flatnonzero((den <= _NEAR_PARALLEL * ae) & (ae > 0.0))
    if near.size:
        _parallel_fix(near, p0, d1, q0, d2, dist, s, t)
    return dist, s, t


def _parallel_fix(
    near: IntArray,
    p0: FloatArray,
    d1: FloatArray,
    q0: FloatArray,
    d2: FloatArray,
    dist: FloatArray,
    s: FloatArray,
    t: FloatArray,
) -> None:
    """Nearly parallel segments: the stationary point is ill-conditioned, so also try the four
    end point–segment problems (one of which holds the minimum when it is not interior); keeps the
    best of all in ``dist``, ``s``, ``t`` (flat entries ``near``)."""
    shape = (3,) + dist.shape
    P0, D1, Q0, D2 = (np.broadcast_to(x, shape).reshape(3, -1)[:, near] for x in (p0, d1, q0, d2))
    best, bs, bt = dist.reshape(-1)[near], s.reshape(-1)[near], t.reshape(-1)[near]
    for fixed, other, D_f, D_o, swap in ((P0, Q0, D1, D2, False), (Q0, P0, D2, D1, True)):
        for u in (0.0, 1.0):
            x = fixed + u * D_f - other
            v = np.clip((x * D_o).sum(axis=0) / (D_o * D_o).sum(axis=0), 0.0, 1.0)
            d = np.sqrt(((x - v * D_o) ** 2).sum(axis=0))
            better = d < best
            best = np.where(better, d, best)
            bs = np.where(better, v if swap else u, bs)
            bt = np.where(better, u if swap else v, bt)
    dist.reshape(-1)[near], s.reshape(-1)[near], t.reshape(-1)[near] = best, bs, bt


def point_box(x: FloatArray, h: FloatArray) -> FloatArray:
    """Signed distance from points to a box centred at the origin (negative inside) [m].

    Args:
        x: points in the box frame [m], shape (3, ...).
        h: half extents [m], shape (3, ...) broadcastable.
    """
    q = np.abs(x) - h
    out = np.maximum(q, 0.0)
    return np.sqrt((out * out).sum(axis=0)) + np.minimum(q.max(axis=0), 0.0)


def _box_slope(A: FloatArray, B: FloatArray, h: FloatArray, s: FloatArray) -> FloatArray:
    """Half the s-derivative of the squared distance from ``A + s B`` to the box, at parameters s
    (summed coordinate by coordinate: the temporaries have the shape of s, not three times it)."""
    out = None
    for k in range(3):
        x = A[k] + s * B[k]
        psi = x - np.clip(x, -h[k], h[k])
        psi *= B[k]
        if out is None:
            out = psi
        else:
            out += psi
    return out


def segment_box(A: FloatArray, B: FloatArray, h: FloatArray) -> FloatArray:
    """Exact signed distance between the segment ``A + s B`` (s in [0, 1]) and a box, vectorised.

    Apart: the squared distance from ``A + s B`` to the box is convex and piecewise quadratic in s,
    with breakpoints where a coordinate crosses a face plane (at most six). Its derivative is
    monotone and piecewise linear, so its values at 0, 1 and the breakpoints bracket its root inside
    one linear piece, where interpolation finds it exactly. Meeting: the penetration depth is the
    smallest overlap over the separating axes of a segment and a box — the three face normals and
    the three cross products of the segment with the box edges (complete for this pair of
    polytopes) — returned as a negative distance. The separated case is worked out only for the
    entries that do not overlap.

    Args:
        A: segment start in the box frame [m], shape (3, M).
        B: segment vector (end - start) in the box frame [m], shape (3, M).
        h: box half extents [m], shape (3, M) or (3, 1).

    Returns:
        Signed distance (M,) [m] (negative = penetration depth).
    """
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    h = np.broadcast_to(np.asarray(h, dtype=np.float64), A.shape)
    m = A.shape[1]
    E = A + B
    depth = (h + np.minimum(-np.minimum(A, E), np.maximum(A, E))).min(axis=0)
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        # axis n = B x e_i = (.., B_k, -B_j) on (j, k); the box projects to +-(h_j|n_j| + h_k|n_k|)
        norm = np.sqrt(B[j] * B[j] + B[k] * B[k])
        num = h[j] * np.abs(B[k]) + h[k] * np.abs(B[j]) - np.abs(B[k] * A[j] - B[j] * A[k])
        depth = np.minimum(depth, np.divide(num, norm, out=np.full(m, np.inf), where=norm > 0.0))
    apart = np.flatnonzero(~(depth > 0.0))  # not overlapping: only these need the distance (entry by entry)
    if apart.size == m:
        return _segment_box_apart(A, B, h)
    out = -depth
    if apart.size:
        out[apart] = _segment_box_apart(A[:, apart], B[:, apart], h[:, apart])
    return out


def _segment_box_apart(A: FloatArray, B: FloatArray, h: FloatArray) -> FloatArray:
    """:func:`segment_box` for a segment and box that do not overlap: their distance (>= 0) [m]."""
    m = A.shape[1]
    inv_b = B / (
        B * B + _TINY
    )  # 0 where B = 0 (no crossing: the extra candidate s = 0 is harmless)
    S = np.empty((8, m))
    S[0] = 0.0
    S[1] = 1.0
    S[2:5] = (h - A) * inv_b
    S[5:8] = (-h - A) * inv_b
    np.clip(S[2:], 0.0, 1.0, out=S[2:])
    gp = _box_slope(A[:, None], B[:, None], h[:, None], S)  # (8, M), nondecreasing in s
    s_lo = np.maximum((S - 2.0 * (gp > 0.0)).max(axis=0), 0.0)  # last candidate with slope <= 0
    s_hi = np.minimum((S + 2.0 * (gp < 0.0)).min(axis=0), 1.0)  # first candidate with slope >= 0
    g_lo = _box_slope(A, B, h, s_lo)
    g_hi = _box_slope(A, B, h, s_hi)
    span = g_hi - g_lo
    frac = np.divide(-g_lo, span, out=np.zeros(m), where=span > 0.0)
    s = np.clip(s_lo + np.clip(frac, 0.0, 1.0) * (s_hi - s_lo), 0.0, 1.0)
    return np.maximum(point_box(A + s * B, h), 0.0)


_TIE = 1e-9  #: |cos| of box axes below which an edge choice is ambiguous (then every edge is tried)
_NEXT, _LAST = [1, 2, 0], [2, 0, 1]  #: the axes after and before each axis (mod 3)
_SIGNS = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)]).T[:, :, None]  #: box vertices
_EYE = np.eye(3)[:, :, None, None]


def _rotate(R: FloatArray, x: FloatArray) -> FloatArray:
    """``R x`` for rotations R (3, 3, ...) and vectors x (3, ...) (broadcast), summed in a fixed order
    entry by entry (numpy's einsum sums in an order that follows the arrays' size and layout, so an
    entry's last bit would depend on the other entries of a call)."""
    return R[:, 0] * x[0] + R[:, 1] * x[1] + R[:, 2] * x[2]


def _rotate_back(R: FloatArray, x: FloatArray) -> FloatArray:
    """``R^T x`` as :func:`_rotate`."""
    return R[0] * x[0] + R[1] * x[1] + R[2] * x[2]


def box_box(R: FloatArray, t: FloatArray, ha: FloatArray, hb: FloatArray) -> FloatArray:
    """Exact signed distance between two boxes, vectorised (negative = penetration depth).

    Meeting: the penetration depth is the smallest overlap over the 15 separating axes (the six
    face normals and the nine edge cross products, complete for two boxes). Apart: a closest pair
    has a vertex of one box (point–box distances of the 16 vertices) or lies on two crossing
    edges, whose separating direction n is their cross product: each box's edge in that direction
    is then its support edge along n (signs of n on its other axes), one segment–segment problem
    per pair of edge directions. Where such a sign is ambiguous (an axis of one box perpendicular,
    to 1e-9, to an axis of the other: parallel faces, an edge along a face), every edge of each box
    is measured against the other box (:func:`segment_box`). The separated case is worked out
    only for the entries that do not overlap, and every sum is taken in a fixed order entry by
    entry (:func:`_rotate`): an entry's result does not depend on the other entries of the call.

    Args:
        R: rotation of box A in box B's frame, shape (3, 3, M) (columns: A's axes).
        t: centre of A in B's frame [m], shape (3, M).
        ha, hb: half extents of A and B [m], shape (3, M) or (3, 1).

    Returns:
        Signed distance (M,) [m].
    """
    m = t.shape[1]
    ha = np.broadcast_to(ha, (3, m))
    hb = np.broadcast_to(hb, (3, m))
    aR = np.abs(R)
    Rt = _rotate_back(R, t)  # B's centre is -Rt in A's frame
    depth = np.minimum((ha * aR).sum(axis=1) + hb - np.abs(t),  # B's face normals
                       (hb[:, None] * aR).sum(axis=0) + ha - np.abs(Rt)).min(axis=0)  # A's
    # cross axes n = e_l x a_k (entry [l, k]); with p, q = l+1, l+2 and i, j = k+1, k+2 (mod 3):
    # n = -R[q, k] e_p + R[p, k] e_q, |n.a_i| = |R[l, j]|, |n.a_j| = |R[l, i]|
    Rp, Rq, aRi, aRj = R[_NEXT], R[_LAST], aR[:, _NEXT], aR[:, _LAST]
    norm = np.sqrt(Rp * Rp + Rq * Rq)
    nt = Rp * t[_LAST, None] - Rq * t[_NEXT, None]  # n.t
    num = ha[_NEXT] * aRj + ha[_LAST] * aRi + hb[_NEXT, None] * np.abs(Rq) + hb[_LAST, None] * np.abs(Rp) - np.abs(nt)
    np.divide(num, norm, out=num, where=norm > 1e-9)
    num[norm <= 1e-9] = np.inf
    depth = np.minimum(depth, num.min(axis=(0, 1)))
    apart = np.flatnonzero(~(depth > 0.0))  # not overlapping: only these need the distance (entry by entry)
    if apart.size == m:
        return _box_box_apart(R, t, Rt, ha, hb, nt)
    out = -depth
    if apart.size:
        out[apart] = _box_box_apart(*(x[..., apart] for x in (R, t, Rt, ha, hb, nt)))
    return out


def _box_box_apart(R: FloatArray, t: FloatArray, Rt: FloatArray, ha: FloatArray, hb: FloatArray,
                   nt: FloatArray) -> FloatArray:
    """:func:`box_box` for boxes that do not overlap: their distance (>= 0) [m]. ``Rt``: B's
    centre in A's frame, negated; ``nt`` (3, 3, M): t along the cross axes (see :func:`box_box`)."""
    m = t.shape[1]
    aR = np.abs(R)
    Rp, Rq = R[_NEXT], R[_LAST]
    va = _rotate(R[:, :, None], _SIGNS * ha[:, None]) + t[:, None]  # A's vertices in B's frame
    vb = _rotate_back(R[:, :, None], _SIGNS * hb[:, None]) - Rt[:, None]  # B's vertices in A's frame
    apart = np.minimum(point_box(va, hb[:, None]).min(axis=0), point_box(vb, ha[:, None]).min(axis=0))
    # edge pairs: with n turned from A to B (sign g), each box's support edge along n (resp. -n):
    # n.a_i = g R[l, j], n.a_j = -g R[l, i], -n.e_p = g R[q, k], -n.e_q = -g R[p, k]
    g = np.where(nt > 0.0, -1.0, 1.0)
    pos = lambda x: np.where(x >= 0.0, 1.0, -1.0)
    sa = np.empty((3, 3, 3, m))  # [A axis, l, k]: the edge's start in A's frame
    sb = np.empty((3, 3, 3, m))  # [B axis, l, k]
    gi, gj, gp, gq = pos(g * R[:, _LAST]), pos(-g * R[:, _NEXT]), pos(g * Rq), pos(-g * Rp)
    for c in range(3):
        i, j = _NEXT[c], _LAST[c]
        sa[c, :, c] = -ha[c]
        sa[i, :, c] = gi[:, c] * ha[i]
        sa[j, :, c] = gj[:, c] * ha[j]
        sb[c, c] = -hb[c]
        sb[i, c] = gp[c] * hb[i]
        sb[j, c] = gq[c] * hb[j]
    pa = _rotate(R[:, :, None, None], sa) + t[:, None, None]
    da = (2.0 * ha) * R[:, None]  # (3, 1, k, M): 2 h_k a_k
    db = (2.0 * hb)[None, :, None] * _EYE  # (3, l, 1, M): 2 h_l e_l
    d, _, _ = segment_segment(pa, da, sb, db, 4.0 * (ha * ha), 4.0 * (hb * hb)[:, None])
    np.minimum(apart, d.min(axis=(0, 1)), out=apart)
    tie = np.flatnonzero((aR < _TIE).any(axis=(0, 1)))
    if tie.size:
        apart[tie] = _box_box_edges(R[:, :, tie], t[:, tie], Rt[:, tie], ha[:, tie], hb[:, tie])
    return np.maximum(apart, 0.0)


def _box_box_edges(R: FloatArray, t: FloatArray, Rt: FloatArray, ha: FloatArray, hb: FloatArray) -> FloatArray:
    """Distance between separated boxes as the least over the 12 edges of each of the edge's
    distance to the other box (a closest pair always has a point on an edge of one of them): the
    24 edges of each entry in one :func:`segment_box` call."""
    m = t.shape[1]
    A, B, H = np.empty((3, 24, m)), np.empty((3, 24, m)), np.empty((3, 24, m))
    H[:, :12], H[:, 12:] = hb[:, None], ha[:, None]  # the box each edge is measured against
    Rinv = np.swapaxes(R, 0, 1)
    e = 0
    for rot, c, h in ((R, t, ha), (Rinv, -Rt, hb)):  # A's edges in B's frame, then B's in A's
        for k in range(3):
            i, j = (k + 1) % 3, (k + 2) % 3
            for si in (-1.0, 1.0):
                for sj in (-1.0, 1.0):
                    local = np.zeros((3, m))
                    local[i], local[j], local[k] = si * h[i], sj * h[j], -h[k]
                    A[:, e] = _rotate(rot, local) + c
                    B[:, e] = 2.0 * h[k] * rot[:, k]
                    e += 1
    return segment_box(A.reshape(3, -1), B.reshape(3, -1), H.reshape(3, -1)).reshape(24, m).min(axis=0)
