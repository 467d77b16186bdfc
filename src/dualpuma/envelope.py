"""Coordinated work envelope of a real cell (the seed's §2.6, procedure Envelope, made exact).

The set of object-frame origins ``p`` such that, with the bar held at orientation ``R`` (the cell's
start orientation by default, or any of a list of orientations), both arms have an in-limit IK
solution for their grasps — optionally also with clearance above the safety margin. Membership is
exact per point (closed-form IK of both arms, eq. 5.6); the set is sampled on a regular grid, so the
volume is a Riemann sum whose convergence the tests check (two resolutions within 1 %).

The idealised model (spherical reach, bar of length L) lives in :mod:`dualpuma.envelope_ideal`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from . import puma
from .errors import ParameterError

__all__ = ["RealEnvelope", "contains_real", "marching_squares", "real_envelope"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class RealEnvelope:
    """Sampled coordinated work envelope of a cell.

    Attributes:
        volume_m3: volume of the set [m^3].
        volume_upper_half_m3: the part above the shoulders' height [m^3] (the seed draws the
            upper half).
        resolution: grid spacing [m].
        points: (M, 3) world positions of the grid points inside the set [m].
        xz_segments: (K, 2, 3) boundary segments of the set in the vertical plane through the
            start object frame (y = y_start), for drawing [m].
        orientations: number of bar orientations tried per point.
    """

    volume_m3: float
    volume_upper_half_m3: float
    resolution: float
    points: FloatArray
    xz_segments: FloatArray
    orientations: int


def contains_real(cell, points: npt.ArrayLike, R_world_object: npt.ArrayLike | None = None, world=None) -> npt.NDArray[np.bool_]:
    """Exact membership: can both arms hold the bar with its origin at each point?

    Args:
        cell: the Cell (PUMA arms: closed-form IK).
        points: (..., 3) object origins [m].
        R_world_object: bar orientation (3, 3) or a stack (K, 3, 3) of which any may be used;
            default the start orientation.
        world: optional World: also require clearance >= the cell's margin (slow path).

    Returns:
        (...,) bool.
    """
    P = np.asarray(points, dtype=np.float64)
    if P.shape[-1:] != (3,) or not np.all(np.isfinite(P)):
        raise ParameterError(f"points: expected finite shape (..., 3), got {P.shape}")
    Rs = np.asarray(cell.T_world_object_start, float)[None, :3, :3] if R_world_object is None else np.asarray(R_world_object, float)
    Rs = Rs.reshape(-1, 3, 3)
    flat = P.reshape(-1, 3)
    inside = np.zeros(len(flat), dtype=bool)
    for side in ("left", "right"):
        if getattr(cell, side).robot != "puma560":
            raise ParameterError(f"envelope needs closed-form IK; the {side} arm is {getattr(cell, side).robot!r}")
    hands = {}
    for side in ("left", "right"):
        Tbi = np.linalg.inv(np.asarray(getattr(cell, side).T_world_base, float))
        hands[side] = (Tbi, np.asarray(getattr(cell, f"grasp_{side}").T_object_hand, float))
    zeros = np.zeros(6)
    for R in Rs:
        todo = np.nonzero(~inside)[0]
        for c0 in range(0, len(todo), _CHUNK):
            idx = todo[c0 : c0 + _CHUNK]
            qs = {}
            for side in ("left", "right"):  # the right arm only where the left one succeeded
                if len(idx) == 0:
                    break
                # T_base_hand = inv(T_world_base) [R p; 0 1] T_object_hand: fixed rotation, affine position
                Tbi, Toh = hands[side]
                T = np.empty((len(idx), 4, 4))
                T[:] = Tbi @ _pose(R, np.zeros(3)) @ Toh
                T[:, :3, 3] = flat[idx] @ Tbi[:3, :3].T + T[0, :3, 3]
                S, V = puma._ik_all_trusted(T, zeros, puma.JOINT_LIMITS)
                ok = V.any(axis=1)
                if world is not None:
                    qs = {k: v[ok] for k, v in qs.items()}
                    qs[side] = S[ok, np.argmax(V[ok], axis=1)]
                idx = idx[ok]
            if world is not None and len(idx):
                keep = np.array([world.clearance(qs["left"][k], qs["right"][k], _pose(R, flat[i])).distance
                                 >= cell.safety_margin for k, i in enumerate(idx)], dtype=bool)
                idx = idx[keep]
            inside[idx] = True
    return inside.reshape(P.shape[:-1])


_CHUNK = 32768  # points per IK call (bounded temporaries)


def _pose(R: FloatArray, p: FloatArray) -> FloatArray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def real_envelope(
    cell,
    resolution: float = 0.025,
    *,
    orientations: npt.ArrayLike | None = None,
    world=None,
    bounds: tuple[tuple[float, float], tuple[float, float], tuple[float, float]] | None = None,
) -> RealEnvelope:
    """Sample the coordinated envelope of ``cell`` on a grid of spacing ``resolution`` [m].

    Args:
        cell: the Cell.
        resolution: grid spacing [m], in (0.002, 0.5].
        orientations: (K, 3, 3) bar orientations any of which may be used (default: start's).
        world: pass a World to also require clearance (much slower).
        bounds: ((xmin, xmax), (ymin, ymax), (zmin, zmax)) [m]; default: both arms' reach boxes.

    Raises:
        ParameterError: resolution out of range.
    """
    if not (np.isfinite(resolution) and 0.002 < resolution <= 0.5):
        raise ParameterError(f"resolution: expected 0.002 < resolution <= 0.5 [m], got {resolution}")
    if bounds is None:
        reach = puma.A2 + np.hypot(puma.A3, puma.D4) + puma.D2 + float(np.abs(np.asarray(cell.grasp_left.T_object_hand)[:3, 3]).max())
        c = np.array([np.asarray(getattr(cell, s).T_world_base)[:3, 3] for s in ("left", "right")])
        lo, hi = c.min(axis=0) - reach, c.max(axis=0) + reach
        lo[2] = max(lo[2], float(cell.floor_z))
        bounds = tuple(zip(lo.tolist(), hi.tolist()))  # type: ignore[assignment]
    axes = [np.arange(b[0] + resolution / 2, b[1], resolution) for b in bounds]  # cell centres
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    P = np.stack([X, Y, Z], axis=-1)
    inside = contains_real(cell, P, orientations, world)
    vol = float(inside.sum()) * resolution**3
    z_sh = float(np.asarray(cell.left.T_world_base)[2, 3])
    upper = float((inside & (Z >= z_sh)).sum()) * resolution**3
    y0 = float(np.asarray(cell.T_world_object_start)[1, 3])
    # the x-z slice through the start frame, sampled at twice the resolution
    sx = np.arange(bounds[0][0], bounds[0][1] + 1e-12, resolution / 2)
    sz = np.arange(bounds[2][0], bounds[2][1] + 1e-12, resolution / 2)
    SX, SZ = np.meshgrid(sx, sz, indexing="ij")
    mask = contains_real(cell, np.stack([SX, np.full_like(SX, y0), SZ], -1), orientations, world)
    segs2 = marching_squares(mask.astype(float), sx, sz)
    segs = np.zeros(segs2.shape[:2] + (3,))
    segs[..., 0], segs[..., 1], segs[..., 2] = segs2[..., 0], y0, segs2[..., 1]
    pts = P[inside]
    for a in (pts, segs):
        a.setflags(write=False)
    n_or = 1 if orientations is None else int(np.asarray(orientations).reshape(-1, 3, 3).shape[0])
    return RealEnvelope(vol, upper, float(resolution), pts, segs, n_or)


def marching_squares(field: npt.ArrayLike, xs: npt.ArrayLike, ys: npt.ArrayLike, level: float = 0.5) -> FloatArray:
    """Iso-line segments of a 2-D field sampled at (xs[i], ys[j]): (K, 2, 2) end points."""
    F = np.asarray(field, float)
    xs = np.asarray(xs, float)
    ys = np.asarray(ys, float)
    segs = []

    def interp(p, q, fp, fq):
        t = 0.5 if fq == fp else (level - fp) / (fq - fp)
        return (p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1]))

    up = F > level
    mixed = (up[:-1, :-1] != up[1:, :-1]) | (up[:-1, :-1] != up[1:, 1:]) | (up[:-1, :-1] != up[:-1, 1:])
    for i, j in zip(*np.nonzero(mixed)):
        c = [(xs[i], ys[j]), (xs[i + 1], ys[j]), (xs[i + 1], ys[j + 1]), (xs[i], ys[j + 1])]
        f = [F[i, j], F[i + 1, j], F[i + 1, j + 1], F[i, j + 1]]
        above = [v > level for v in f]
        pts = [interp(c[k], c[(k + 1) % 4], f[k], f[(k + 1) % 4]) for k in range(4) if above[k] != above[(k + 1) % 4]]
        for k in range(0, len(pts) - 1, 2):
            segs.append((pts[k], pts[k + 1]))
    return np.array(segs, dtype=float).reshape(-1, 2, 2)
