"""First-stage bounds of the clearance kernel (:mod:`dualpuma.collision.kernel`): for every solid pair
and configuration of a block, a lower bound of the signed distance (entries whose bound exceeds the
minimum need no exact work) and an upper bound (the best of them bounds the minimum).

* **Centre rows** (capsule/sphere pairs, coal's solids): the bounding and inscribed balls,
  :func:`centre_distances`.
* **Box rows** (box a against partner b, a capsule, sphere or box), :func:`box_bounds`: with b's
  centre c in a's frame and q = |c| - h_a per axis, the upper bound is |max(q, 0)| (the distance
  from c to the box, or 0 inside it) less b's inscribed radius; the lower bound is the face-normal
  separating-axis distance max_k (|c_k| - |e_k| - h_k) less b's radius, where e is a capsule's half
  axis in a's frame (0 for spheres and boxes, whose radius is then their bounding ball's).
* **Groups of fixed boxes** with one partner: the same lower bound against their common
  world-axis-aligned box (it holds each of them, so its signed distance to the partner is at most
  each box's), which spares the per-box bounds where it already exceeds the minimum's bound.

Why the lower bound is one: b lies in K + B(r) (K its axis segment, or its centre; r its radius),
so sd(a, b) >= sd(a, K) - r; K lies in its axis-aligned box in a's frame (centre c, half extents
|e|), so sd(a, K) >= sd(a, that box); and two boxes with parallel axes are at signed distance at
least their largest gap |c_k| - |e_k| - h_k along an axis (apart: the gap along any axis;
meeting: the penetration depth is the least overlap over the separating axes, and the overlap
along axis k is minus that gap). The upper bound: a ball B(c, rho) inside b has
sd(a, B) = sd(c, a) - rho <= |max(q, 0)| - rho.

Rounding: the box frames are linear in the placements (no cancellation), so the bounds are off by
a few machine epsilons of the coordinates (under 1e-14 m in a cell a few metres across), inside
the kernel's evaluation slack of 1e-12 m. Checked against coal and the
independent reference in tests/test_kernel_bounds.py.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .classes import PairClasses
from .placements import Buffers

__all__ = ["box_bounds", "centre_distances"]

FloatArray = npt.NDArray[np.float64]


def centre_distances(tb: PairClasses, Gt: FloatArray, out: FloatArray, buf: Buffers) -> float:
    """Distances between the centre rows' geometry centres, less a rounding allowance tol, into
    ``out`` (n_centre, n) [m]; returns tol [m]. Pairs with a fixed geometry use
    |c - f|^2 = |c|^2 - 2 c.f + |f|^2 (one matrix product per group): its rounding (a few
    machine epsilons of |c|^2 + |f|^2) is covered by tol, so out stays a lower bound and
    out + 2 tol an upper bound of each centre distance.

    Args:
        tb: the World's pair tables.
        Gt: world translations of every geometry (3, G, n) [m].
        out: the centre rows of the bounds array (n_centre, n), overwritten.
        buf: the kernel's work buffers.
    """
    n = Gt.shape[2]
    dense = tb.fixed_dense
    if dense.size:
        P = dense.size
        ca = buf("ca", (3, P, n))
        cb = buf("cb", (3, P, n))
        np.take(Gt, tb.a[dense], axis=1, out=ca)
        np.take(Gt, tb.b[dense], axis=1, out=cb)
        ca -= cb
        ca *= ca
        whole = P == out.shape[0]  # no groups: straight into out
        d = out if whole else cb[0]
        np.sum(ca, axis=0, out=d)
        np.sqrt(d, out=d)
        if not whole:
            out[dense] = d
    if not tb.fixed_groups:
        return 0.0
    C = Gt[:, tb.fixed_free]  # (3, F, n)
    cc = np.einsum("ign,ign->gn", C, C)
    tol = float(np.sqrt(1e-14 * (float(cc.max()) + tb.fixed_f_max + 1.0)))
    for j, (g, rows, F, F2) in enumerate(tb.fixed_groups):
        X = F @ Gt[:, g]  # (m, n)
        X *= -2.0
        X += cc[j]
        X += F2
        np.maximum(X, 0.0, out=X)
        np.sqrt(X, out=X)
        X -= tol
        out[rows] = X
    return tol


def box_bounds(tb: PairClasses, GR: FloatArray, Gt: FloatArray, D: FloatArray, lower: FloatArray, upper: FloatArray,
               buf: Buffers, cap: FloatArray | None = None) -> None:
    """Lower and upper bounds of the box rows' signed distances (see the module docstring), into
    ``lower`` and ``upper`` (B, n) [m]: fixed boxes by one matrix product per partner (their frames
    are constants), a moving box with all its partners at once.

    With ``cap`` (n,) [m], a group of fixed boxes (one partner) is first bounded as a whole: the
    same lower bound against the group's common world-axis-aligned box, which holds every box of
    it (so it bounds each box's distance from below). At configurations where that bound exceeds
    cap, the group's rows get it as their lower bound and an upper bound of inf; the per-box bounds
    are computed only at the others (all of them when they are at least half).

    Args:
        tb: the World's pair tables.
        GR, Gt: world rotations (3, 3, G, n) and translations (3, G, n) of every geometry [m].
        D: every round geometry's axis vector, end - start (3, G, n) [m] (zero for other shapes).
        lower, upper: the box rows of the bounds arrays (B, n), overwritten.
        buf: the kernel's work buffers.
        cap: optional per-configuration level above which a group's per-box bounds are not needed [m].
    """
    n = Gt.shape[2]
    if tb.box_fixed:
        c1 = buf("bx_c1", (4, n))  # a partner's centre, homogeneous
        c1[3] = 1.0
    for b, (s, e), lift, half_rt, group in tb.box_fixed:
        m = e - s
        c1[:3] = Gt[:, b]
        rad, inner = float(tb.box_rad[s, 0]), float(tb.box_inner[s, 0])
        if cap is not None and group is not None:
            X = buf("bx_g", (6, n))
            np.matmul(group, c1, out=X)
            np.maximum(X[:3], X[3:], out=X[:3])
            Y = None
            if half_rt is not None:
                Y = buf("bx_ge", (3, n))
                np.multiply(D[:, b], 0.5, out=Y)
            glb = buf("bx_glb", (1, n))
            _box_frame(X[:3, None], None if Y is None else Y[:, None], rad, inner, glb, buf("bx_gub", (1, n)))
            near = np.flatnonzero(glb[0] <= cap)
            if near.size < n // 2:
                lower[s:e] = glb
                upper[s:e] = np.inf
                if near.size:
                    lo, up = np.empty((m, near.size)), np.empty((m, near.size))
                    _fixed_group(lift, half_rt, c1[:, near], None if half_rt is None else D[:, b, near], rad, inner,
                                 lo, up, buf)
                    lower[s:e, near] = lo
                    upper[s:e, near] = up
                continue
        _fixed_group(lift, half_rt, c1, D[:, b], rad, inner, lower[s:e], upper[s:e], buf)
    for a, (s, e), partners in tb.box_moving:
        m = e - s
        rel = buf("bx_rel", (3, m, n))
        np.take(Gt, partners, axis=1, out=rel)
        rel -= Gt[:, a, None]
        X = buf("bx_c", (3, m, n))
        np.einsum("lkn,lmn->kmn", GR[:, :, a], rel, out=X)
        np.take(D, partners, axis=1, out=rel)
        Y = buf("bx_e", (3, m, n))
        np.einsum("lkn,lmn->kmn", GR[:, :, a], rel, out=Y)
        Y *= 0.5
        np.abs(X, out=X)
        X -= tb.box_half[:, s:e]
        _box_frame(X, Y, tb.box_rad[s:e], tb.box_inner[s:e], lower[s:e], upper[s:e])


def _fixed_group(lift: FloatArray, half_rt: FloatArray | None, c1: FloatArray, Db: FloatArray | None, rad: float,
                 inner: float, lower: FloatArray, upper: FloatArray, buf: Buffers) -> None:
    """Bounds of one partner (centres [c; 1] (4, k), axis vectors Db (3, k)) against a group of m
    fixed boxes (``lift`` (6m, 4), ``half_rt`` (3m, 3) or None) into ``lower`` and ``upper`` (m, k)."""
    m, k = lift.shape[0] // 6, c1.shape[1]
    X = buf("bx_c", (6 * m, k))
    np.matmul(lift, c1, out=X)
    q = X[: 3 * m]
    np.maximum(q, X[3 * m :], out=q)  # |x| - h
    Y = None
    if half_rt is not None:
        Y = buf("bx_e", (3 * m, k))
        np.matmul(half_rt, Db, out=Y)
        Y = Y.reshape(3, m, k)
    _box_frame(q.reshape(3, m, k), Y, rad, inner, lower, upper)


def _box_frame(q: FloatArray, Y: FloatArray | None, rad: FloatArray | float, inner: FloatArray | float,
               lower: FloatArray, upper: FloatArray) -> None:
    """Bounds from q = |x| - h per axis, x the partners' centres in the box frame, and their half axes
    Y (None: zero) in that frame, (3, m, n) [m] (both overwritten), partner radii ``rad`` and
    inscribed radii ``inner`` (m, 1), or one partner's [m], into ``lower`` and ``upper`` (m, n)."""
    if Y is not None:
        np.abs(Y, out=Y)
        np.subtract(q, Y, out=Y)
    g = q if Y is None else Y  # per axis, the gap between the box and the partner's axis-aligned box
    np.maximum(g[0], g[1], out=lower)
    np.maximum(lower, g[2], out=lower)
    lower -= rad
    np.maximum(q, 0.0, out=q)
    q *= q
    np.add(q[0], q[1], out=upper)
    upper += q[2]
    np.sqrt(upper, out=upper)
    upper -= inner
