"""Independent distance references for the clearance tests (no coal, no dualpuma geometry code)."""

from __future__ import annotations

import numpy as np


def point_segment(p, a, b):
    ab = b - a
    t = np.clip(np.dot(p - a, ab) / max(np.dot(ab, ab), 1e-300), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + t * ab)))


def segment_segment(p0, p1, q0, q1):
    """Exact distance between two segments: the convex problem's interior stationary point if it
    lies in [0,1]^2, else the best of the four edge (point-segment) problems."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, b = d1 @ d1, d2 @ d2, d1 @ d2
    c, f = d1 @ r, d2 @ r
    cands = [point_segment(p0, q0, q1), point_segment(p1, q0, q1), point_segment(q0, p0, p1), point_segment(q1, p0, p1)]
    den = a * e - b * b
    if den > 1e-14 * a * e:
        s = (b * f - c * e) / den
        t = (a * f - b * c) / den
        if 0 <= s <= 1 and 0 <= t <= 1:
            cands.append(float(np.linalg.norm(p0 + s * d1 - q0 - t * d2)))
    return min(cands)


def capsule_capsule(c1, c2):
    (a0, a1, ra), (b0, b1, rb) = c1, c2
    return segment_segment(a0, a1, b0, b1) - ra - rb


def capsule_halfspace(c, z0):
    a0, a1, r = c
    return float(min(a0[2], a1[2]) - z0 - r)


def _point_box(p, T, half):
    local = T[:3, :3].T @ (p - T[:3, 3])
    return float(np.linalg.norm(np.maximum(np.abs(local) - half, 0.0)))


def capsule_box(c, T, size):
    """Signed distance capsule-box. Separated: golden-section search of the convex function
    t -> dist(segment(t), box). Intersecting: separating-axis penetration depth (box face normals
    and segment x box-axis crosses), plus the radius."""
    a0, a1, r = c
    half = np.asarray(size) / 2.0
    f = lambda t: _point_box(a0 + t * (a1 - a0), T, half)
    lo, hi = 0.0, 1.0
    g = (np.sqrt(5) - 1) / 2
    for _ in range(200):
        m1, m2 = hi - g * (hi - lo), lo + g * (hi - lo)
        if f(m1) < f(m2):
            hi = m2
        else:
            lo = m1
    d = min(f(0.0), f(1.0), f(0.5 * (lo + hi)))
    if d > 1e-12:
        return d - r
    # penetration depth of the segment in the box by SAT
    R, c0 = T[:3, :3], T[:3, 3]
    u = a1 - a0
    axes = [R[:, i] for i in range(3)]
    for i in range(3):
        x = np.cross(u, R[:, i])
        if np.linalg.norm(x) > 1e-9:
            axes.append(x / np.linalg.norm(x))
    depth = np.inf
    for n in axes:
        box_r = sum(half[i] * abs(n @ R[:, i]) for i in range(3))
        box_c = n @ c0
        s0, s1 = sorted((n @ a0, n @ a1))
        overlap = min(s1 - (box_c - box_r), (box_c + box_r) - s0)
        depth = min(depth, overlap)
    return -depth - r


def box_surface_samples(T, size, n=40):
    """Dense points on a box's surface (for sanity checks of the box reference)."""
    half = np.asarray(size) / 2.0
    g = np.linspace(-1, 1, n)
    pts = []
    for ax in range(3):
        for sgn in (-1, 1):
            u, v = np.meshgrid(g, g)
            p = np.zeros((n * n, 3))
            others = [k for k in range(3) if k != ax]
            p[:, ax] = sgn
            p[:, others[0]] = u.ravel()
            p[:, others[1]] = v.ravel()
            pts.append(p * half)
    P = np.vstack(pts)
    return P @ T[:3, :3].T + T[:3, 3]


def _project_box(p, T, half):
    local = T[:3, :3].T @ (p - T[:3, 3])
    return T[:3, :3] @ np.clip(local, -half, half) + T[:3, 3]


def box_box(TA, sizeA, TB, sizeB):
    """Signed distance between two boxes: alternating projections (convex sets) while separated,
    separating-axis penetration depth over the 15 candidate axes when they overlap."""
    ha, hb = np.asarray(sizeA) / 2, np.asarray(sizeB) / 2
    p = TA[:3, 3].copy()
    for _ in range(5000):
        q = _project_box(p, TB, hb)
        p_new = _project_box(q, TA, ha)
        if np.linalg.norm(p_new - p) < 1e-15:
            p = p_new
            break
        p = p_new
    d = float(np.linalg.norm(p - _project_box(p, TB, hb)))
    if d > 1e-9:
        return d
    axes = [TA[:3, i] for i in range(3)] + [TB[:3, i] for i in range(3)]
    for i in range(3):
        for j in range(3):
            x = np.cross(TA[:3, i], TB[:3, j])
            if np.linalg.norm(x) > 1e-9:
                axes.append(x / np.linalg.norm(x))
    depth = np.inf
    for n in axes:
        ra = sum(ha[i] * abs(n @ TA[:3, i]) for i in range(3))
        rb = sum(hb[i] * abs(n @ TB[:3, i]) for i in range(3))
        depth = min(depth, ra + rb - abs(n @ (TB[:3, 3] - TA[:3, 3])))
    return -depth


def pose(R=None, p=(0.0, 0.0, 0.0)):
    """A 4x4 pose from an optional rotation and a position (test helper)."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    T[:3, 3] = p
    return T
