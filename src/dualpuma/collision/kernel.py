"""Vectorised exact clearance for batches of configurations (the batch path of clearance).

:class:`ClearanceKernel` returns the same minimum signed distance and arg-min pair as
``pin.computeDistances`` over a :class:`~dualpuma.model.world.World`'s collision pairs, for N
configurations at once, with numpy arrays instead of one C++ call per configuration:

1. **Placements** of every geometry for the whole block (:class:`~.placements.Placements`).
2. **Closed forms** (:mod:`.forms`), exact up to rounding: capsule–capsule (a sphere is a capsule
   of length 0) as segment–segment distance minus the radii; capsule–halfspace and box–halfspace
   as the lowest point along the normal; capsule–box as the signed segment–box distance;
   box–box by :func:`~.forms.box_box` (separating axes when meeting, vertices and support edges
   when apart).
3. **Bounds first, exact work only where it can matter** (:mod:`.bounds`). Each solid pair gets a
   lower and an upper bound: capsule/sphere pairs from their bounding and inscribed balls; pairs
   with a box (capsule–box, box–box) in the box's frame, from the face-normal separating-axis
   distance to the partner's axis (lower) and the distance from the partner's centre to the box
   (upper); a group of fixed boxes with one partner is first bounded as a whole (its common
   bounding box), and its per-box bounds are computed only where that bound does not exceed the
   best upper bound so far. An entry (configuration, pair) is evaluated exactly only if its lower
   bound does not exceed the configuration's best upper bound so far; capsule–box entries pass one more filter
   (segment to the box's bounding capsule, and one point of the segment to the box). Pairs with a
   fixed geometry (on the universe joint, e.g. static obstacles) get their bounds from one small
   matrix product per group of pairs sharing the other geometry, with an allowance for its
   rounding that keeps them bounds. Box–box entries pass one more filter (the thinner box's
   bounding capsule against the other box); shape pairs without a closed form here are answered
   by coal itself (``coal.distance``, a fresh request each time), again only where their bound
   could be the minimum. Skipped entries are provably above the minimum, so the result is exact;
   the returned pair is the first (in ``world.pair_ids`` order) holding the computed minimum.

Checked against coal and against independent references in tests/test_kernel.py. Work is done in
blocks of configurations with preallocated buffers (numpy's fresh allocations above 128 KiB cost
more than the arithmetic on them), single-threaded: element-wise numpy, ``einsum`` and small matrix
products only.
"""

from __future__ import annotations

import coal
import numpy as np
import numpy.typing as npt

from ..checks import has_attributes, integer, validate_joints, validate_pose
from ..checks import times as check_times
from ..errors import JointError, PoseError
from .bounds import box_bounds, centre_distances
from .classes import PairClasses
from .forms import box_box, point_box, segment_box, segment_segment
from .kinematics import KernelUnsupported
from .placements import Placements

__all__ = ["ClearanceKernel", "KernelUnsupported"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

_SLACK = 1e-12  #: a bound within this of the best upper bound is still evaluated [m]
_COAL_SLACK = 1e-9  #: same, against coal's answers (its GJK/EPA tolerances are relative) [m]
_SEG_CHUNK = 4096  #: entries per segment–segment call (temporaries stay small)
_BOX_CHUNK = 1024  #: entries per segment–box call (its per-call cost is amortised; larger chunks pay for fresh allocations)


class ClearanceKernel:
    """Exact minimum signed distance over a World's collision pairs for many configurations.

    Build once per World and thread (about a millisecond; ``clearance_batch`` keeps one in the
    World's cache) and call it with batches. Not thread-safe (it owns work buffers). Results do
    not depend on earlier calls, on the block size or on the order of the configurations.

    Args:
        world: the :class:`~dualpuma.model.world.World` (read, never modified).
        block: configurations per internal block.

    Raises:
        KernelUnsupported: the model has a joint other than revolute/prismatic (x, y, z or an
            unaligned axis); use the per-configuration loop for such a World.
        ParameterError: block < 1.
    """

    def __init__(self, world, block: int = 2048) -> None:
        self.block = integer(block, "block", lo=1, hi=1 << 20)
        has_attributes(world, ("model", "geom_model", "pair_ids"), "World", "world")
        self.world = world
        self.place = Placements(world)
        self.nq = self.place.nq
        self.pairs = [(int(a), int(b)) for a, b in world.pair_ids]
        self.n_pairs = len(self.pairs)
        varying = {self.place.bar} | {gid for gid, *_ in self.place.moving}
        self.t = PairClasses(self.place.geoms, self.pairs, varying)
        self._exhaustive = False
        self._request = coal.DistanceRequest()  # read only by coal.distance: no warm start is kept
        self._fixed_tf = {g: coal.Transform3s(geo.R, geo.p) for g, geo in enumerate(self.place.geoms)
                          if geo.joint == 0 and g not in varying}  # their placement is their world pose

    # ------------------------------------------------------------------ public
    def _validate(self, Q, T_world_object, t) -> tuple[FloatArray, FloatArray | None, FloatArray]:
        arr = validate_joints(Q, name="Q", n=self.nq)
        if arr.ndim != 2:
            raise JointError(f"Q: expected shape (N, {self.nq}), got {arr.shape}")
        n = arr.shape[0]
        Tw = None
        if T_world_object is not None:
            Tw = validate_pose(T_world_object, name="T_world_object")
            if Tw.shape != (n, 4, 4):
                raise PoseError(f"T_world_object: expected shape ({n}, 4, 4), got {Tw.shape}")
        return np.ascontiguousarray(arr), Tw, np.ascontiguousarray(check_times(t, n))

    def __call__(
        self, Q: npt.ArrayLike, T_world_object: npt.ArrayLike | None = None, t: npt.ArrayLike | None = None
    ) -> tuple[FloatArray, IntArray]:
        """Minimum signed distance and the pair achieving it, for N configurations.

        Args:
            Q: joint vectors of the World's model (left arm, then right arm) [rad], shape (N, nq).
            T_world_object: optional bar frames (N, 4, 4) [m] (default: carried by the left hand).
            t: optional time, or times (N,), for moving obstacles [s] (default 0).

        Returns:
            ``(distance (N,) [m], pair index (N,))``: negative distance = penetration depth; the
            index is into ``world.pair_ids`` / ``world.pair_names`` (a pair achieving the minimum).

        Raises:
            JointError: Q of the wrong shape, or not finite.
            PoseError: malformed T_world_object.
            ParameterError: t not finite or of the wrong shape.
        """
        return self.evaluate(*self._validate(Q, T_world_object, t))

    def evaluate(self, Q: FloatArray, Tw: FloatArray | None, times: FloatArray) -> tuple[FloatArray, IntArray]:
        """:meth:`__call__` for trusted input: finite joints (N, nq) C-contiguous [rad], None or
        valid bar frames (N, 4, 4) [m], finite times (N,) [s]."""
        n = Q.shape[0]
        dist = np.empty(n)
        idx = np.empty(n, dtype=np.int64)
        for s in range(0, n, self.block):
            e = min(n, s + self.block)
            D = self._block(Q[s:e], None if Tw is None else Tw[s:e], times[s:e])
            best = D.min(axis=0)
            dist[s:e] = best
            # the first pair holding the minimum: the entries equal to it (about one per
            # configuration) by one flat scan, the least pair index per configuration
            hit = np.flatnonzero(D == best)
            k = hit // (e - s)
            first = idx[s:e]
            first[...] = self.n_pairs
            np.minimum.at(first, hit - k * (e - s), k)
        return dist, idx

    def pair_distances(
        self, Q: npt.ArrayLike, T_world_object: npt.ArrayLike | None = None, t: npt.ArrayLike | None = None
    ) -> FloatArray:
        """Every pair's signed distance (no pruning; pairs without a closed form by coal):
        (N, P) in ``world.pair_ids`` order [m]. Arguments and errors as :meth:`__call__`."""
        Q, Tw, times = self._validate(Q, T_world_object, t)
        n = Q.shape[0]
        out = np.empty((n, self.n_pairs))
        for s in range(0, n, self.block):
            e = min(n, s + self.block)
            out[s:e] = self._block(Q[s:e], None if Tw is None else Tw[s:e], times[s:e], exhaustive=True).T
        return out

    def geometry_placements(
        self, Q: npt.ArrayLike, T_world_object: npt.ArrayLike | None = None, t: npt.ArrayLike | None = None
    ) -> FloatArray:
        """World placement of every collision geometry (what ``GeometryData.oMg`` holds):
        (N, G, 4, 4) [m] in ``world.geom_model`` order. Arguments and errors as :meth:`__call__`."""
        Q, Tw, times = self._validate(Q, T_world_object, t)
        n, G = Q.shape[0], len(self.place.geoms)
        out = np.zeros((n, G, 4, 4))
        out[..., 3, 3] = 1.0
        for s in range(0, n, self.block):
            e = min(n, s + self.block)
            GR, Gt = self.place.compute(Q[s:e], None if Tw is None else Tw[s:e], times[s:e])
            out[s:e, :, :3, :3] = np.moveaxis(GR, (2, 3), (1, 0))
            out[s:e, :, :3, 3] = np.moveaxis(Gt, (1, 2), (1, 0))
        return out

    # ------------------------------------------------------------------ one block
    def _block(self, Q: FloatArray, Tw: FloatArray | None, t: FloatArray, exhaustive: bool = False) -> FloatArray:
        """Signed distances (P, n) of one block: exact where they can be the minimum, else a lower
        bound above it (every entry exact if ``exhaustive``)."""
        self._exhaustive = exhaustive
        tb, buf, G = self.t, self.place.buf, len(self.place.geoms)
        n = Q.shape[0]
        GR, Gt = self.place.compute(Q, Tw, t, tb.full_ids)
        # round geometries as segments P0 + s D (s in [0, 1]); other geometries: P0 = origin, D = 0
        D = buf("D", (3, G, n))
        np.multiply(GR[:, 2], self.place.half_lengths, out=D)
        P0 = buf("P0", (3, G, n))
        np.subtract(Gt, D, out=P0)
        D *= 2.0
        dist = buf("dist", (self.n_pairs, n))
        upper = np.full(n, np.inf)  # per configuration: a bound on the minimum, at last the minimum
        if tb.halfspaces:  # exact halfspace pairs
            N, off = self._halfspace_frames(GR, Gt)
            if tb.ch_rows.size:
                g, h = tb.ch_g, tb.ch_h
                lo = buf("ch", (g.size, n))
                tmp = buf("ch2", (g.size, n))
                lo[...] = 0.0
                tmp[...] = 0.0
                for k in range(3):
                    lo += N[k, h] * P0[k, g]
                    tmp += N[k, h] * D[k, g]
                np.minimum(tmp, 0.0, out=tmp)
                lo += tmp
                lo -= off[h]
                lo -= tb.ch_r
                dist[tb.ch_rows] = lo
                np.minimum(upper, lo.min(axis=0), out=upper)
            for k, gx, ih in tb.bh:
                nrm = N[:, ih]
                reach = sum(self.place.geoms[gx].half[i] * np.abs((GR[:, i, gx] * nrm).sum(axis=0)) for i in range(3))
                d = (nrm * Gt[:, gx]).sum(axis=0) - reach - off[ih]
                dist[k] = d
                np.minimum(upper, d, out=upper)
        PA, nc = tb.rows.size, tb.n_centre  # lower and upper bounds of every solid pair
        if PA:
            lower = buf("lower", (PA, n))
            ub = buf("ub", (PA, n))
            if nc:
                tol = centre_distances(tb, Gt, lower[:nc], buf)
                np.subtract(lower[:nc], tb.inner - 2.0 * tol, out=ub[:nc])  # lower holds centre distance - tol
                lower[:nc] -= tb.outer
                np.minimum(upper, ub[:nc].min(axis=0), out=upper)
            if PA > nc:
                box_bounds(tb, GR, Gt, D, lower[nc:], ub[nc:], buf, None if exhaustive else upper + _SLACK)
                np.minimum(upper, ub[nc:].min(axis=0), out=upper)
            self._exact_cc(P0, D, lower, upper)
            self._exact_cb(P0, D, GR, Gt, lower, upper)
            self._refine_bb(GR, Gt, lower, upper)
            dist[tb.rows] = lower
        for k in tb.coal_always:
            for i in range(n):
                dist[k, i] = self._coal(GR, Gt, int(k), i)
        return dist

    def _halfspace_frames(self, GR: FloatArray, Gt: FloatArray) -> tuple[FloatArray, FloatArray]:
        """World normals (3, H, n) and offsets (H, n) of the halfspaces."""
        hs, geoms = self.t.halfspaces, self.place.geoms
        N = np.stack([np.einsum("ikn,k->in", GR[:, :, g], geoms[g].normal) for g in hs], axis=1)
        off = np.stack([geoms[g].offset + (N[:, i] * Gt[:, g]).sum(axis=0) for i, g in enumerate(hs)])
        return N, off

    # ------------------------------------------------------------------ exact stage
    def _candidates(self, lower: FloatArray, cls: str, upper: FloatArray, slack: float = _SLACK):
        """Flat (pair, configuration) entries of a class whose lower bound can reach the minimum."""
        s, e = self.t.ranges[cls]
        n = upper.shape[0]
        rows = lower[s:e]
        cand = np.arange(rows.size) if self._exhaustive else np.flatnonzero(rows <= upper + slack)
        k = cand // n
        return rows, cand, k, cand - k * n

    def _exact_cc(self, P0: FloatArray, D: FloatArray, lower: FloatArray, upper: FloatArray) -> None:
        rows, cand, k, i = self._candidates(lower, "cc", upper)
        if cand.size == 0:
            return
        tb, n = self.t, upper.shape[0]
        s = tb.ranges["cc"][0]
        fa = tb.a[s + k] * n + i
        fb = tb.b[s + k] * n + i
        P0f, Df = P0.reshape(3, -1), D.reshape(3, -1)
        flat = rows.reshape(-1)
        for c0 in range(0, cand.size, _SEG_CHUNK):
            sl = slice(c0, c0 + _SEG_CHUNK)
            a, b, kk = fa[sl], fb[sl], k[sl]
            d, _, _ = segment_segment(P0f[:, a], Df[:, a], P0f[:, b], Df[:, b], tb.cc_aa[kk], tb.cc_ee[kk])
            d -= tb.cc_r[kk]
            flat[cand[sl]] = d
        np.minimum(upper, rows.min(axis=0), out=upper)

    @staticmethod
    def _to_box_frame(P0, D, GR, Gt, fa, fb):
        """Segments (flat round indices fa) in the frames of boxes (flat indices fb): (A, B) (3, M)."""
        R = GR.reshape(3, 3, -1)[:, :, fb]
        rel = P0.reshape(3, -1)[:, fa] - Gt.reshape(3, -1)[:, fb]
        return np.einsum("kim,km->im", R, rel), np.einsum("kim,km->im", R, D.reshape(3, -1)[:, fa])

    def _exact_cb(self, P0, D, GR, Gt, lower: FloatArray, upper: FloatArray) -> None:
        rows, cand, k, i = self._candidates(lower, "cb", upper)
        if cand.size == 0:
            return
        tb, n = self.t, upper.shape[0]
        s = tb.ranges["cb"][0]
        flat = rows.reshape(-1)
        A, B = self._to_box_frame(P0, D, GR, Gt, tb.b[s + k] * n + i, tb.a[s + k] * n + i)
        # second filter: the box's bounding capsule (lower) and one point of the segment (upper)
        core, u, _ = segment_segment(A, B, tb.cb_core0[:, k], tb.cb_cored[:, k], tb.cb_aa[k], tb.cb_ee[k])
        r = tb.cb_r[k]
        lb = core - r - tb.cb_rho[k]
        ubs = point_box(A + u * B, tb.cb_half[:, k]) - r
        best = np.full(upper.shape, np.inf)
        np.minimum.at(best, i, ubs)
        np.minimum(upper, best, out=upper)
        flat[cand] = lb
        keep = np.arange(cand.size) if self._exhaustive else np.flatnonzero(lb <= upper[i] + _SLACK)
        for c0 in range(0, keep.size, _BOX_CHUNK):
            sel = keep[c0 : c0 + _BOX_CHUNK]
            kk = k[sel]
            flat[cand[sel]] = segment_box(A[:, sel], B[:, sel], tb.cb_half[:, kk]) - tb.cb_r[kk]
        np.minimum(upper, rows.min(axis=0), out=upper)

    def _refine_bb(self, GR, Gt, lower: FloatArray, upper: FloatArray) -> None:
        """Box–box pairs by their closed form, other solid pairs by coal, where they can matter."""
        tb, n = self.t, upper.shape[0]
        rows, cand, k, i = self._candidates(lower, "bb", upper)
        if cand.size:
            s = tb.ranges["bb"][0]
            flat = rows.reshape(-1)
            fa, fb = tb.a[s + k] * n + i, tb.b[s + k] * n + i
            Ra, Rb = GR.reshape(3, 3, -1)[:, :, fa], GR.reshape(3, 3, -1)[:, :, fb]
            rel = Gt.reshape(3, -1)[:, fa] - Gt.reshape(3, -1)[:, fb]
            # first the thinner box's bounding capsule against the other box (a lower bound)
            A = np.einsum("kim,km->im", Rb, rel + np.einsum("ikm,km->im", Ra, tb.bb_core0[:, k]))
            B = np.einsum("kim,km->im", Rb, np.einsum("ikm,km->im", Ra, tb.bb_cored[:, k]))
            lb = np.empty(cand.size)
            for c0 in range(0, cand.size, _BOX_CHUNK):
                sl = slice(c0, c0 + _BOX_CHUNK)
                lb[sl] = segment_box(A[:, sl], B[:, sl], tb.bb_half[:, k[sl]]) - tb.bb_rho[k[sl]]
            flat[cand] = lb
            keep = np.arange(cand.size) if self._exhaustive else np.flatnonzero(lb <= upper[i] + _SLACK)
            for c0 in range(0, keep.size, _BOX_CHUNK):
                sel = keep[c0 : c0 + _BOX_CHUNK]
                R = np.einsum("lim,lkm->ikm", Rb[:, :, sel], Ra[:, :, sel])  # A in B's frame
                t = np.einsum("lim,lm->im", Rb[:, :, sel], rel[:, sel])
                flat[cand[sel]] = box_box(R, t, tb.bb_half_a[:, k[sel]], tb.bb_half[:, k[sel]])
            np.minimum(upper, rows.min(axis=0), out=upper)
        rows, cand, k, i = self._candidates(lower, "sx", upper, _COAL_SLACK)
        s = tb.ranges["sx"][0]
        flat = rows.reshape(-1)
        for c, kk, ii in zip(cand.tolist(), k.tolist(), i.tolist()):
            if self._exhaustive or flat[c] <= upper[ii] + _COAL_SLACK:
                d = self._coal(GR, Gt, int(tb.rows[s + kk]), ii)
                flat[c] = d
                upper[ii] = min(upper[ii], d)

    def _coal(self, GR: FloatArray, Gt: FloatArray, k: int, i: int) -> float:
        """coal's signed distance of world pair k at configuration i of the block (a default request
        and a fresh result each time: no warm start, so the answer does not depend on earlier
        queries)."""
        a, b = self.pairs[k]
        fixed = self._fixed_tf
        tf = [fixed[g] if g in fixed else coal.Transform3s(np.ascontiguousarray(GR[:, :, g, i]), np.ascontiguousarray(Gt[:, g, i]))
              for g in (a, b)]
        shapes = self.place.shapes
        return float(coal.distance(shapes[a], tf[0], shapes[b], tf[1], self._request, coal.DistanceResult()))
