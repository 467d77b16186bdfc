"""Coordinated work envelope of a real cell (the seed's §2.6, procedure Envelope, made exact).

The envelope is the set of object-frame origins ``p`` such that, with the bar held at a fixed
orientation ``R`` (the cell's start orientation by default, or any of a list of orientations), both
arms have an in-limit closed-form IK solution (any of the eight branches) for their grasps (eq. 5.6):
``T_base_hand = inv(T_world_base) [R p; 0 1] T_object_hand``. Optionally some branch pair must also
keep every checked pair of the :class:`~dualpuma.model.world.World` at least the cell's safety margin apart
(and the UR arms' always-close link pairs out of contact: :mod:`dualpuma.collision.contact`).

Membership is exact per point (:func:`contains_real`). :func:`real_envelope` samples it at the centres
of a regular grid (the volume is a Riemann sum; the tests check two resolutions agree within 1 %),
draws the boundary in the vertical x-z plane through the start frame by marching squares with every
crossing refined by bisection on the exact membership, and returns the inside points.

For a fixed ``R`` the hand's wrist centre is an affine function of ``p`` (``w = R_b^T p + c``), so
points whose hand lies outside its arm's reach shell (``r_min <= |w| <= r_max``; the PUMA's wrist centre) are
rejected before the IK; the shell bounds are a strict necessary condition (with slack), never an
approximation. The idealised model (spherical reach, bar of length L) is :mod:`.ideal`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..checks import as_array, flag, instance, real, rotations
from ..checks import points as check_points
from ..collision.batch import clearance_batch
from ..collision.contact import self_contact
from ..errors import ParameterError
from ..kinematics.arm import Arm
from ..model.cell import Cell
from ..values import value_class
from .contour import contour

__all__ = [
    "MAX_GRID_POINTS",
    "RealEnvelope",
    "RealMembership",
    "contains_real",
    "real_envelope",
    "solve_real",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
SIDES = ("left", "right")

#: largest grid :func:`real_envelope` accepts (measured: 51 M points, a 4 mm grid of the default
#: cell, took 2 min 15 s and 1.3 GB: the largest one about 5 min and 2.5 GB)
MAX_GRID_POINTS = 100_000_000
_BLOCK = 1 << 17  # grid points generated per block (bounded temporaries)
_IK_CHUNK = 4096  # poses per IK call (one chunk of the batch IK: no copy of its result)
_BISECT_TOL = 1e-6  # [m] boundary points of the x-z section are bisected to this


@value_class
@dataclass(frozen=True, slots=True)
class RealMembership:
    """Per-point answer of :func:`solve_real`.

    Attributes:
        inside: (...,) bool.
        q_left, q_right: (..., 6) joints [rad] of a valid pair (NaN where outside).
        orientation: (...,) index of the orientation used (-1 where outside).
    """

    inside: BoolArray
    q_left: FloatArray
    q_right: FloatArray
    orientation: npt.NDArray[np.int64]


@value_class
@dataclass(frozen=True, slots=True)
class RealEnvelope:
    """Sampled coordinated work envelope of a cell (all arrays read-only).

    Attributes:
        volume_m3: volume of the set in the box (grid-cell Riemann sum, cells cut at the box) [m^3].
        volume_upper_half_m3: the part with z >= ``z_split_m`` (the seed draws the upper half) [m^3].
        resolution: grid spacing [m].
        points: (M, 3) grid-cell centres inside the set [m] (a cell cut by the box's upper faces: the
            centre of its part inside).
        xz_segments: (K, 2, 3) boundary segments in the plane y = ``y_slice_m`` [m].
        xz_polylines: the same boundary chained into polylines, each (n, 3); closed ones repeat their
            first point at the end [m].
        orientations: number of bar orientations of which any may be used.
        bounds: (3, 2) sampled box [[xmin, xmax], [ymin, ymax], [zmin, zmax]] [m].
        y_slice_m: y of the drawn x-z section (the start frame's) [m].
        z_split_m: height splitting the upper half: the mean of the shoulders' heights
            (:attr:`~dualpuma.kinematics.arm.Arm.shoulder`) [m].
        floor: whether origins below the cell's floor were excluded.
        clearance_checked: whether clearance >= the cell's safety margin was required.
        grid_points: number of grid cells sampled.
    """

    volume_m3: float
    volume_upper_half_m3: float
    resolution: float
    points: FloatArray
    xz_segments: FloatArray
    xz_polylines: tuple[FloatArray, ...]
    orientations: int
    bounds: FloatArray
    y_slice_m: float
    z_split_m: float
    floor: bool
    clearance_checked: bool
    grid_points: int


# ----------------------------------------------------------------------------- membership
def _rotations(cell, R_world_object: npt.ArrayLike | None) -> FloatArray:
    if R_world_object is None:
        return np.asarray(cell.T_world_object_start, float)[None, :3, :3].copy()
    Rs = as_array(R_world_object, "R_world_object")
    if Rs.ndim not in (2, 3) or Rs.shape[-2:] != (3, 3) or Rs.size == 0:
        raise ParameterError(f"R_world_object: expected shape (3, 3) or (K, 3, 3), got {Rs.shape}")
    return rotations(Rs, "R_world_object").reshape(-1, 3, 3)  # PoseError: NaN, not orthonormal, det -1


def _arms(cell) -> list[Arm]:
    """Both arms of the cell; each needs a closed-form IK (the envelope is exact per point)."""
    arms = []
    for side in SIDES:
        arm = Arm.load(getattr(cell, side).robot)
        if not arm.analytic:
            raise ParameterError(f"envelope needs closed-form IK; the {side} arm ({arm.robot}) has a numeric IK")
        arms.append(arm)
    return arms


def _hand_maps(cell, R: FloatArray, arms: list[Arm]) -> list[tuple[FloatArray, FloatArray, FloatArray, Arm]]:
    """Per side: (M (3, 3), c (3,), template (4, 4), arm) with T_base_hand(p) = template,
    position M p + c."""
    out = []
    for side, arm in zip(SIDES, arms):
        mount = getattr(cell, side)
        Tbi = np.linalg.inv(np.asarray(mount.T_world_base, float))
        T_oh = np.asarray(getattr(cell, f"grasp_{side}").T_object_hand, float)
        T0 = np.eye(4)
        T0[:3, :3] = R
        tmpl = Tbi @ T0 @ T_oh  # the hand pose for p = 0
        out.append((Tbi[:3, :3].copy(), tmpl[:3, 3].copy(), tmpl, arm))
    return out


def _ik_side(P: FloatArray, hand) -> tuple[FloatArray, BoolArray]:
    """All eight branches for the hand targets of origins P (N, 3): (N, 8, 6), (N, 8)."""
    M, c, tmpl, arm = hand
    n = len(P)
    S, V = np.empty((n, 8, 6)), np.empty((n, 8), dtype=bool)
    zeros = np.zeros(6)
    for i in range(0, n, _IK_CHUNK):
        p = P[i : i + _IK_CHUNK]
        T = np.empty((len(p), 4, 4))
        T[:] = tmpl
        T[:, :3, 3] = p @ M.T + c
        S[i : i + _IK_CHUNK], V[i : i + _IK_CHUNK] = arm.solver.ik_all(T, zeros, arm.limits)
    return S, V


def _in_shell(P: FloatArray, hand) -> BoolArray:
    """Origins whose hand origin is within the arm's reach shell (a necessary condition)."""
    w = P @ hand[0].T + hand[1]
    r2 = np.einsum("ij,ij->i", w, w)
    r_min, r_max = hand[3].reach_shell
    return (r2 <= r_max * r_max) & (r2 >= r_min * r_min)


def _clear_pairs(world, R, P, SL, VL, SR, VR) -> tuple[BoolArray, npt.NDArray[np.int64]]:
    """Per point: does some valid branch pair keep clearance >= margin? Returns (ok, pair = 8 bL + bR).

    Pairs are tried in rounds (round j: each unresolved point's j-th valid pair), so most points
    cost one clearance query."""
    n = len(P)
    pv = (VL[:, :, None] & VR[:, None, :]).reshape(n, 64)
    order = np.argsort(~pv, axis=1, kind="stable")
    count = pv.sum(axis=1)
    ok = np.zeros(n, dtype=bool)
    chosen = np.full(n, -1, dtype=np.int64)
    margin = float(world.cell.safety_margin)
    for j in range(64):
        act = np.nonzero(~ok & (count > j))[0]
        if len(act) == 0:
            break
        pair = order[act, j]
        T = np.zeros((len(act), 4, 4))
        T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = R, P[act], 1.0
        d = np.empty(len(act))
        for i in range(0, len(act), _IK_CHUNK):
            s = slice(i, i + _IK_CHUNK)
            a, pr = act[s], pair[s]
            d[s] = clearance_batch(world, SL[a, pr // 8], SR[a, pr % 8], T[s])[0]
            # (and the UR arms' always-close pairs out of contact on their meshes: collision.contact)
            touch = self_contact(world, SL[a, pr // 8], SR[a, pr % 8])
            d[s][[x is not None for x in touch]] = -np.inf
        good = d >= margin
        ok[act[good]] = True
        chosen[act[good]] = pair[good]
    return ok, chosen


def solve_real(cell, points: npt.ArrayLike, R_world_object: npt.ArrayLike | None = None, world=None) -> RealMembership:
    """Exact membership with the joints that prove it.

    Args:
        cell: the Cell (both arms with a closed-form IK: the PUMA 560, the UR family).
        points: (..., 3) object origins in the world [m].
        R_world_object: bar orientation (3, 3), or a stack (K, 3, 3) of which any may be used
            (tried in order); default: the cell's start orientation.
        world: optional World built from ``cell``: also require clearance >= the cell's safety
            margin (at t = 0) for some pair of valid branches.

    Returns:
        :class:`RealMembership`: ``inside`` and, where inside, in-limit joints whose hands reach
        ``T_world_object @ T_object_hand`` of both grasps.

    Raises:
        ParameterError: points not finite or not (..., 3); an arm without closed-form IK; a World
            of another cell.
        PoseError: an orientation that is not a rotation.
    """
    instance(cell, Cell, "cell")
    P = check_points(points, "points")
    if world is not None and getattr(world, "cell", None) is not cell:
        raise ParameterError("world: must be the World built from this cell (World(cell))")
    Rs = _rotations(cell, R_world_object)
    arms = _arms(cell)
    maps = [_hand_maps(cell, R, arms) for R in Rs]
    flat = P.reshape(-1, 3)
    n = len(flat)
    inside = np.zeros(n, dtype=bool)
    qs = {s: np.full((n, 6), np.nan) for s in SIDES}
    k_used = np.full(n, -1, dtype=np.int64)
    for k, (R, (hl, hr)) in enumerate(zip(Rs, maps)):
        idx = np.nonzero(~inside)[0]
        idx = idx[_in_shell(flat[idx], hl) & _in_shell(flat[idx], hr)]
        SL, VL = _ik_side(flat[idx], hl)
        okl = VL.any(axis=1)
        idx, SL, VL = idx[okl], SL[okl], VL[okl]
        SR, VR = _ik_side(flat[idx], hr)  # the right arm only where the left one succeeded
        okr = VR.any(axis=1)
        idx, SL, VL, SR, VR = idx[okr], SL[okr], VL[okr], SR[okr], VR[okr]
        if world is None:
            bl, br = np.argmax(VL, axis=1), np.argmax(VR, axis=1)
        else:
            ok, pair = _clear_pairs(world, R, flat[idx], SL, VL, SR, VR)
            idx, SL, SR, pair = idx[ok], SL[ok], SR[ok], pair[ok]
            bl, br = pair // 8, pair % 8
        rows = np.arange(len(idx))
        inside[idx] = True
        qs["left"][idx], qs["right"][idx] = SL[rows, bl], SR[rows, br]
        k_used[idx] = k
    shape = P.shape[:-1]
    out = RealMembership(inside.reshape(shape), qs["left"].reshape(shape + (6,)), qs["right"].reshape(shape + (6,)), k_used.reshape(shape))
    for a in (out.inside, out.q_left, out.q_right, out.orientation):
        a.setflags(write=False)
    return out


def contains_real(cell, points: npt.ArrayLike, R_world_object: npt.ArrayLike | None = None, world=None) -> BoolArray:
    """Exact membership: can both arms hold the bar with its origin at each point?

    Args:
        cell: the Cell (both arms with a closed-form IK: the PUMA 560, the UR family).
        points: (..., 3) object origins [m].
        R_world_object: bar orientation (3, 3) or a stack (K, 3, 3) of which any may be used;
            default the start orientation.
        world: optional World of ``cell``: also require clearance >= the cell's margin.

    Returns:
        (...,) bool.

    Raises:
        ParameterError, PoseError: as :func:`solve_real`.
    """
    return solve_real(cell, points, R_world_object, world).inside


# ----------------------------------------------------------------------------- the sampled set
def _default_bounds(cell, Rs: FloatArray) -> FloatArray:
    """Box containing the set: per orientation, the intersection of both arms' reach spheres
    (in object-origin space: centre ``-M^T c``, radius r_max), unioned over orientations."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    arms = _arms(cell)
    for R in Rs:
        boxes = []
        for M, c, _, arm in _hand_maps(cell, R, arms):
            centre = -M.T @ c
            r = arm.reach_shell[1]
            boxes.append((centre - r, centre + r))
        a = np.maximum(boxes[0][0], boxes[1][0])
        b = np.minimum(boxes[0][1], boxes[1][1])
        if np.all(a < b):
            lo, hi = np.minimum(lo, a), np.maximum(hi, b)
    if not np.all(lo < hi):  # the spheres never meet: an empty set, sample a token box
        lo, hi = np.zeros(3), np.full(3, 1e-3)
    return np.stack([lo, hi], axis=1)


def _check_bounds(bounds) -> FloatArray:
    B = as_array(bounds, "bounds").copy()  # a copy: the floor clip edits it
    if B.shape != (3, 2) or not np.all(np.isfinite(B)) or not np.all(B[:, 0] < B[:, 1]):
        raise ParameterError("bounds: expected finite ((xmin, xmax), (ymin, ymax), (zmin, zmax)) with min < max [m], "
                             f"got shape {B.shape}" + (f": {B.tolist()}" if B.size <= 6 else ""))
    return B


def real_envelope(
    cell,
    resolution: float = 0.025,
    *,
    orientations: npt.ArrayLike | None = None,
    world=None,
    bounds: npt.ArrayLike | None = None,
    floor: bool = True,
) -> RealEnvelope:
    """Sample the coordinated envelope of ``cell`` on a grid of spacing ``resolution``.

    Args:
        cell: the Cell (both arms with a closed-form IK: the PUMA 560, the UR family).
        resolution: grid spacing [m], in (0.002, 0.5].
        orientations: (3, 3) or (K, 3, 3) bar orientations any of which may be used (default: the
            start orientation).
        world: a World of ``cell``: also require clearance >= the safety margin (slower).
        bounds: ((xmin, xmax), (ymin, ymax), (zmin, zmax)) [m] to sample; default: the box of the
            intersection of both arms' reach spheres, which contains the whole set.
        floor: exclude object origins below ``cell.floor_z`` (the grid then starts at the floor, so
            the cut is integrated exactly). ``False`` gives the purely kinematic set.

    Returns:
        :class:`RealEnvelope`.

    Raises:
        ParameterError: resolution out of range, malformed bounds (or, with ``floor``, bounds below
            the floor), a grid of more than
            :data:`MAX_GRID_POINTS` points, or as :func:`solve_real`.
        PoseError: an orientation that is not a rotation.
    """
    h = real(resolution, "resolution", lo=0.002, hi=0.5, lo_open=True, unit="m")
    instance(cell, Cell, "cell")
    floor = flag(floor, "floor")
    Rs = _rotations(cell, orientations)
    B = _default_bounds(cell, Rs) if bounds is None else _check_bounds(bounds)
    floor_z = float(cell.floor_z)
    if floor:
        if bounds is not None and B[2, 1] <= floor_z:
            raise ParameterError(f"bounds: the box (z up to {B[2, 1]:g} m) lies below the floor (z = {floor_z:g} m), where "
                                 "floor=True excludes every origin; floor=False samples it")
        B[2, 0] = max(B[2, 0], floor_z)
        if bounds is None:  # the default box of a set below the floor: one empty layer above it
            B[2, 1] = max(B[2, 1], B[2, 0] + h)
    axes, widths = zip(*(_cells(B[a, 0], B[a, 1], h) for a in range(3)))
    shape = tuple(len(x) for x in axes)
    n_grid = shape[0] * shape[1] * shape[2]
    if n_grid > MAX_GRID_POINTS:
        raise ParameterError(f"resolution: {h:g} m ({h * 1e3:g} mm) gives {n_grid:,} grid points (max {MAX_GRID_POINTS:,}); "
                             "use a coarser grid or smaller bounds")
    inside = []  # the grid's flat indices of the cells inside the set
    for f0 in range(0, n_grid, _BLOCK):
        f = np.arange(f0, min(f0 + _BLOCK, n_grid))
        i, j, k = np.unravel_index(f, shape)
        inside.append(f[contains_real(cell, np.stack([axes[0][i], axes[1][j], axes[2][k]], axis=1), Rs, world)])
    i, j, k = np.unravel_index(np.concatenate(inside), shape)  # (n_grid >= 1: one block at least)
    pts = np.stack([axes[0][i], axes[1][j], axes[2][k]], axis=1)
    area, height = widths[0][i] * widths[1][j], widths[2][k]  # each cell's x-y area [m^2] and height [m]
    top = axes[2][k] + 0.5 * height
    z_split = float(np.mean([_shoulder_height(getattr(cell, s).T_world_base, a) for s, a in zip(SIDES, _arms(cell))]))
    y0 = float(np.asarray(cell.T_world_object_start)[1, 3])

    def member(Q2: FloatArray) -> BoolArray:  # (N, 2) x-z points of the section
        Q = np.stack([Q2[:, 0], np.full(len(Q2), y0), Q2[:, 1]], axis=1)
        m = contains_real(cell, Q, Rs, world)
        return m & (Q[:, 2] >= floor_z) if floor else m

    segs2, lines2 = _section(member, B[0], B[2], h / 2)
    segs = np.insert(segs2, 1, y0, axis=2)
    lines = tuple(np.insert(L, 1, y0, axis=1) for L in lines2)
    for a in (pts, segs, B, *lines):
        a.setflags(write=False)
    vol = float(np.sum(area * height))
    # each cell counts with its part above z_split (the cell straddling the plane in part)
    upper = float(np.sum(area * np.clip(top - z_split, 0.0, height)))
    return RealEnvelope(vol, upper, h, pts, segs, lines, len(Rs), B, y0, z_split, bool(floor), world is not None, n_grid)


def _cells(lo: float, hi: float, h: float) -> tuple[FloatArray, FloatArray]:
    """The grid cells of one axis of the box [lo, hi] [m]: spacing ``h`` from ``lo``, the last one
    cut at ``hi`` (its centre and width are those of the part inside: a box that is not a whole
    number of cells had its last cells counted whole, 2.9x a 70 mm cube's volume at h = 50 mm).
    Returns (centres, widths) [m]."""
    n = max(1, math.ceil((hi - lo) / h - 1e-9))
    edges = lo + h * np.arange(n + 1)
    edges[-1] = hi
    return 0.5 * (edges[:-1] + edges[1:]), np.diff(edges)


def _shoulder_height(T_world_base: FloatArray, arm: Arm) -> float:
    """World height [m] of an arm's shoulder (:attr:`~dualpuma.kinematics.arm.Arm.shoulder`): the
    seed's upper half lies above the shoulders (a UR's is 89-152 mm above its base)."""
    T = np.asarray(T_world_base)
    return float(T[2, :3] @ arm.shoulder + T[2, 3])


def _section(member, xb: FloatArray, zb: FloatArray, step: float) -> tuple[FloatArray, tuple[FloatArray, ...]]:
    """Boundary of {member} in a 2-D box: grid one step beyond the box on each side (outside the set,
    so contours close), marching squares with the exact membership at saddle centres and every
    crossing bisected to :data:`_BISECT_TOL`."""
    xs = np.arange(xb[0] - step, xb[1] + 1.5 * step, step)
    zs = np.arange(zb[0] - step, zb[1] + 1.5 * step, step)
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    up = member(np.stack([X.ravel(), Z.ravel()], axis=1)).reshape(X.shape)

    def centre_up(ci: npt.NDArray[np.int64], cj: npt.NDArray[np.int64]) -> BoolArray:
        return member(np.stack([0.5 * (xs[ci] + xs[ci + 1]), 0.5 * (zs[cj] + zs[cj + 1])], axis=1))

    def edge_points(ia: npt.NDArray[np.int64], ib: npt.NDArray[np.int64], a: FloatArray, b: FloatArray) -> FloatArray:
        a_up = up[ia[:, 0], ia[:, 1]]
        lo = np.where(a_up[:, None], a, b)  # the inside end
        hi = np.where(a_up[:, None], b, a)
        for _ in range(max(1, math.ceil(math.log2(step / _BISECT_TOL)))):
            mid = 0.5 * (lo + hi)
            m = member(mid)
            lo = np.where(m[:, None], mid, lo)
            hi = np.where(m[:, None], hi, mid)
        return 0.5 * (lo + hi)

    return contour(up, xs, zs, centre_up, edge_points)
