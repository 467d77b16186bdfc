"""Vectorised exact clearance for batches of configurations (the batch path of clearance).

:class:`ClearanceKernel` returns the same minimum signed distance and arg-min pair as
``pin.computeDistances`` over a :class:`~dualpuma.world.World`'s collision pairs, for N
configurations at once, with numpy arrays instead of one C++ call per configuration:

1. **Kinematics.** Every joint of the World's Pinocchio model (revolute or prismatic about x, y, z
   or an unaligned axis), then every collision geometry's world placement (joint placement x
   geometry placement, as ``updateGeometryPlacements``). The bar is placed by
   ``T_world_object @ T_object_bar`` when that is given; moving obstacles by their pose at t.
2. **Closed forms**, exact up to rounding:

   * capsule–capsule (a sphere is a capsule of length 0): segment–segment distance minus the
     radii (:func:`segment_segment`);
   * capsule–halfspace and box–halfspace: the lowest point along the normal;
   * capsule–box: the signed segment–box distance (:func:`segment_box`).

3. **Bounds first, exact work only where it can matter.** Each solid pair gets a lower bound from
   the distance between the geometries' bounding spheres (for capsule–box pairs, from the
   capsule's centre to the axis of the box's bounding capsule) and an upper bound from balls inside
   them. An entry (configuration, pair) is evaluated exactly only if its lower bound does not
   exceed the configuration's best upper bound so far; capsule–box entries pass one more filter
   (segment to the box's bounding capsule, and one point of the segment to the box). Box–box pairs
   (the bar against a box obstacle) and shape pairs without a closed form here are answered by coal
   itself (``coal.distance``, a fresh request each time), again only where their bound could be
   the minimum. Skipped entries are provably above the minimum, so the result is exact; the
   returned pair is the first (in ``world.pair_ids`` order) holding the computed minimum.

The kernel is checked against coal and against independent references in tests/test_kernel.py.
Work is done in blocks of configurations with preallocated buffers (numpy's fresh allocations above
128 KiB cost more than the arithmetic on them), single-threaded: element-wise numpy and
``einsum`` only, no BLAS.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .errors import JointError, ParameterError, PoseError
from .kernel_exact import _ExactStage
from .kernel_forms import point_box, segment_box, segment_segment
from .kernel_model import KernelUnsupported, _Buffers, _geom_of, _joint_of, _PairTables

__all__ = ["ClearanceKernel", "KernelUnsupported", "point_box", "segment_box", "segment_segment"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


# ----------------------------------------------------------------------------- the kernel
class ClearanceKernel(_PairTables, _ExactStage):
    """Exact minimum signed distance over a World's collision pairs for many configurations.

    Build once per World (about a millisecond) and call it with batches; see the module docstring
    for the method. Like the World, not thread-safe (it owns reusable work buffers): one kernel
    per thread. Results do not depend on earlier calls, on the block size or on the order of the
    configurations.

    Args:
        world: the :class:`~dualpuma.world.World`; its model, geometry model and pairs are read
            (never modified).
        block: configurations per internal block.

    Raises:
        KernelUnsupported: the model has a joint other than revolute/prismatic (x, y, z or an
            unaligned axis); use the per-configuration loop for such a World.
        ParameterError: block < 1.
    """

    def __init__(self, world, block: int = 1024) -> None:
        if int(block) < 1:
            raise ParameterError(
                f"block: expected a positive number of configurations, got {block}"
            )
        self.world = world
        self.block = int(block)
        model = world.model
        self.nq = int(model.nq)
        self._joints = [
            _joint_of(model.joints[j], int(model.parents[j]), model.jointPlacements[j])
            for j in range(1, model.njoints)
        ]
        self._geoms = [_geom_of(go) for go in world.geom_model.geometryObjects]
        self._bar = int(world.bar_id)
        self._T_object_bar = np.array(world.T_object_bar, dtype=np.float64)
        self._moving = [
            (int(gid), np.array(ob.T_world_obstacle, dtype=np.float64), np.array(ob.velocity, dtype=np.float64),
             float(ob.t_start), float(ob.t_end))
            for gid, ob in world.moving
        ]  # fmt: skip
        # joint local transforms: placement M, M K and M K^2 (K = [axis]x; zero for prismatic)
        self._jq = np.array([J.iq for J in self._joints], dtype=np.int64)
        self._M = np.array([J.R for J in self._joints]).reshape(-1, 3, 3)
        Ks = [np.cross(np.eye(3), J.axis) * J.revolute for J in self._joints]  # = [axis]x
        self._MK = np.array([J.R @ K for J, K in zip(self._joints, Ks)]).reshape(-1, 3, 3)
        self._MK2 = np.array([J.R @ K @ K for J, K in zip(self._joints, Ks)]).reshape(-1, 3, 3)
        self._gj = np.array([g.joint for g in self._geoms], dtype=np.int64)
        self._gR = np.array([g.R for g in self._geoms]).reshape(-1, 3, 3)
        self._gp = np.array([g.p for g in self._geoms]).reshape(-1, 3)
        self._hl = np.array([g.half_length for g in self._geoms])[None, :, None]
        self._halfspaces = [i for i, g in enumerate(self._geoms) if g.kind == "halfspace"]
        self._pairs = [(int(a), int(b)) for a, b in world.pair_ids]
        self.n_pairs = len(self._pairs)
        self._setup_pairs()
        self._buf = _Buffers()
        self._shapes = [go.geometry for go in world.geom_model.geometryObjects]
        self._exhaustive = False

    # ------------------------------------------------------------------ placements
    def _placements(
        self, Q: FloatArray, Tw: FloatArray | None, t: FloatArray, full: bool = False
    ) -> tuple[FloatArray, FloatArray]:
        """World rotations (3, 3, G, n) and translations (3, G, n) of every geometry (for capsules
        and spheres outside coal's pairs only the third column, their axis, unless ``full``)."""
        n = Q.shape[0]
        buf = self._buf
        nj = len(self._joints) + 1
        JR = buf("JR", (nj, 3, 3, n))
        Jt = buf("Jt", (nj, 3, n))
        JR[0] = np.eye(3)[:, :, None]
        Jt[0] = 0.0
        # local transforms placement * motion(q) of every joint at once: for a revolute joint
        # M Rot(axis, q) = M + sin(q) M K + (1 - cos(q)) M K^2 (Rodrigues, K = [axis]x)
        L = buf("L", (nj - 1, 3, 3, n))
        tmp = buf("Ltmp", (nj - 1, 3, 3, n))
        q = Q[:, self._jq].T  # (J, n)
        np.multiply(self._MK[..., None], np.sin(q)[:, None, None, :], out=L)
        np.multiply(self._MK2[..., None], (1.0 - np.cos(q))[:, None, None, :], out=tmp)
        L += tmp
        L += self._M[..., None]
        for j, J in enumerate(self._joints, start=1):
            Lj = L[j - 1]
            tl = (
                J.p[:, None]
                if J.revolute
                else J.p[:, None] + np.multiply.outer(J.R @ J.axis, Q[:, J.iq])
            )
            if J.parent == 0:
                JR[j] = Lj
                Jt[j] = tl
            else:
                np.einsum("ikn,kjn->ijn", JR[J.parent], Lj, out=JR[j])
                np.einsum("ikn,kn->in", JR[J.parent], np.broadcast_to(tl, (3, n)), out=Jt[j])
                Jt[j] += Jt[J.parent]
        G = len(self._geoms)
        JRg = buf("JRg", (G, 3, 3, n))
        np.take(JR, self._gj, axis=0, out=JRg)
        GR = buf("GR", (3, 3, G, n))
        Gt = buf("Gt", (3, G, n))
        if full:
            np.einsum("gikn,gkj->ijgn", JRg, self._gR, out=GR)
        else:  # segments need only their axis; full rotations for boxes, halfspaces and coal's pairs
            np.einsum("gikn,gk->ign", JRg, self._gR[:, :, 2], out=GR[:, 2])
            f = self._full_ids
            if f.size:
                GR[:, :, f] = np.einsum("gikn,gkj->ijgn", JRg[f], self._gR[f])
        np.einsum("gikn,gk->ign", JRg, self._gp, out=Gt)
        Gt += np.moveaxis(np.take(Jt, self._gj, axis=0), 0, 1)
        if Tw is not None:
            T = self._T_object_bar
            np.einsum("nik,kj->ijn", Tw[:, :3, :3], T[:3, :3], out=GR[:, :, self._bar])
            np.einsum("nik,k->in", Tw[:, :3, :3], T[:3, 3], out=Gt[:, self._bar])
            Gt[:, self._bar] += Tw[:, :3, 3].T
        for gid, T0, v, t0, t1 in self._moving:
            dt = np.minimum(np.maximum(t, t0), t1) - t0  # as Obstacle.pose_at
            GR[:, :, gid] = T0[:3, :3, None]
            Gt[:, gid] = T0[:3, 3, None] + v[:, None] * dt
        return GR, Gt

    # ------------------------------------------------------------------ distances
    def _block(
        self, Q: FloatArray, Tw: FloatArray | None, t: FloatArray, exhaustive: bool = False
    ) -> FloatArray:
        """Signed distances (P, n) of one block: exact where they can be the minimum, else a lower
        bound above it (every entry exact if ``exhaustive``)."""
        self._exhaustive = exhaustive
        n = Q.shape[0]
        buf = self._buf
        GR, Gt = self._placements(Q, Tw, t)
        G = len(self._geoms)
        # round geometries as segments P0 + s D (s in [0, 1]); other geometries: P0 = origin, D = 0
        D = buf("D", (3, G, n))
        np.multiply(GR[:, 2], self._hl, out=D)
        P0 = buf("P0", (3, G, n))
        np.subtract(Gt, D, out=P0)
        D *= 2.0
        dist = buf("dist", (self.n_pairs, n))
        upper = np.full(n, np.inf)  # per configuration: a bound on the minimum, at last the minimum
        # exact halfspace pairs
        if self._halfspaces:
            N, off = self._halfspace_frames(GR, Gt)
        if self._ch_rows.size:
            g, h = self._ch_g, self._ch_h
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
            lo -= self._ch_r
            dist[self._ch_rows] = lo
            np.minimum(upper, lo.min(axis=0), out=upper)
        for k, gx, ih in self._bh:
            nrm = N[:, ih]
            reach = sum(
                self._geoms[gx].half[i] * np.abs((GR[:, i, gx] * nrm).sum(axis=0)) for i in range(3)
            )
            d = (nrm * Gt[:, gx]).sum(axis=0) - reach - off[ih]
            dist[k] = d
            np.minimum(upper, d, out=upper)
        # stage A: bounding / inscribed balls of every solid pair
        PA = self._A_rows.size
        if PA:
            ca = buf("ca", (3, PA, n))
            cb = buf("cb", (3, PA, n))
            np.take(Gt, self._A_a, axis=1, out=ca)
            np.take(Gt, self._A_b, axis=1, out=cb)
            ca -= cb
            ca *= ca
            lower = buf("lower", (PA, n))
            np.sum(ca, axis=0, out=lower)
            np.sqrt(lower, out=lower)
            ub = cb[0]
            np.subtract(lower, self._A_inner, out=ub)
            np.minimum(upper, ub.min(axis=0), out=upper)
            lower -= self._A_outer
            self._tighten_cb(Gt, GR, lower)
            self._exact_cc(P0, D, lower, upper)
            self._exact_cb(P0, D, GR, Gt, lower, upper)
            self._refine_bb(GR, Gt, lower, upper)
            dist[self._A_rows] = lower
        if self._coal_always.size:
            for k in self._coal_always:
                for i in range(n):
                    dist[k, i] = self._coal(GR, Gt, int(k), i)
        return dist

    # ------------------------------------------------------------------ public
    def _validate(
        self, Q: npt.ArrayLike, T_world_object: npt.ArrayLike | None, t: npt.ArrayLike | None
    ) -> tuple[FloatArray, FloatArray | None, FloatArray]:
        from .puma import validate_pose

        try:
            arr = np.asarray(Q, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise JointError(f"Q: expected numbers, shape (N, {self.nq}): {exc}") from exc
        if arr.ndim != 2 or arr.shape[1] != self.nq:
            raise JointError(f"Q: expected shape (N, {self.nq}), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise JointError("Q: contains NaN or inf")
        n = arr.shape[0]
        Tw = None
        if T_world_object is not None:
            Tw = validate_pose(T_world_object, name="T_world_object")
            if Tw.shape != (n, 4, 4):
                raise PoseError(f"T_world_object: expected shape ({n}, 4, 4), got {Tw.shape}")
        if t is None:
            times = np.zeros(n)
        else:
            try:
                times = np.broadcast_to(np.asarray(t, dtype=np.float64), (n,))
            except ValueError as exc:
                raise ParameterError(
                    f"t: expected one time or {n} times [s], got shape {np.shape(t)}"
                ) from exc
            if not np.all(np.isfinite(times)):
                raise ParameterError("t: times must be finite")
        return np.ascontiguousarray(arr), Tw, np.ascontiguousarray(times)

    def __call__(
        self,
        Q: npt.ArrayLike,
        T_world_object: npt.ArrayLike | None = None,
        t: npt.ArrayLike | None = None,
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
        Q, Tw, times = self._validate(Q, T_world_object, t)
        return self.evaluate(Q, Tw, times)

    def evaluate(
        self, Q: FloatArray, Tw: FloatArray | None, times: FloatArray
    ) -> tuple[FloatArray, IntArray]:
        """:meth:`__call__` for inputs already validated (no checks).

        Args:
            Q: finite joint vectors (N, nq) [rad], C-contiguous.
            Tw: None or valid bar frames (N, 4, 4) [m].
            times: finite times (N,) [s].
        """
        n = Q.shape[0]
        dist = np.empty(n)
        idx = np.empty(n, dtype=np.int64)
        for s in range(0, n, self.block):
            e = min(n, s + self.block)
            D = self._block(Q[s:e], None if Tw is None else Tw[s:e], times[s:e])
            best = D.min(axis=0)
            dist[s:e] = best
            idx[s:e] = (D == best).argmax(axis=0)  # the first pair holding the minimum
        return dist, idx

    def pair_distances(
        self,
        Q: npt.ArrayLike,
        T_world_object: npt.ArrayLike | None = None,
        t: npt.ArrayLike | None = None,
    ) -> FloatArray:
        """Every pair's signed distance (no pruning; box–box pairs by coal for every configuration).

        Args:
            Q: joint vectors [rad], shape (N, nq).
            T_world_object: optional bar frames (N, 4, 4) [m].
            t: optional time(s) [s] for moving obstacles.

        Returns:
            (N, P) signed distances [m] in ``world.pair_ids`` order.

        Raises:
            JointError, PoseError, ParameterError: as :meth:`__call__`.
        """
        Q, Tw, times = self._validate(Q, T_world_object, t)
        n = Q.shape[0]
        out = np.empty((n, self.n_pairs))
        for s in range(0, n, self.block):
            e = min(n, s + self.block)
            out[s:e] = self._block(
                Q[s:e], None if Tw is None else Tw[s:e], times[s:e], exhaustive=True
            ).T
        return out

    def geometry_placements(
        self,
        Q: npt.ArrayLike,
        T_world_object: npt.ArrayLike | None = None,
        t: npt.ArrayLike | None = None,
    ) -> FloatArray:
        """World placement of every collision geometry (what ``GeometryData.oMg`` holds).

        Args:
            Q: joint vectors [rad], shape (N, nq).
            T_world_object: optional bar frames (N, 4, 4) [m].
            t: optional time(s) [s] for moving obstacles.

        Returns:
            (N, G, 4, 4) homogeneous transforms [m] (G geometries, ``world.geom_model`` order).

        Raises:
            JointError, PoseError, ParameterError: as :meth:`__call__`.
        """
        Q, Tw, times = self._validate(Q, T_world_object, t)
        n, G = Q.shape[0], len(self._geoms)
        out = np.zeros((n, G, 4, 4))
        out[..., 3, 3] = 1.0
        for s in range(0, n, self.block):
            e = min(n, s + self.block)
            GR, Gt = self._placements(
                Q[s:e], None if Tw is None else Tw[s:e], times[s:e], full=True
            )
            out[s:e, :, :3, :3] = np.moveaxis(GR, (2, 3), (1, 0))
            out[s:e, :, :3, 3] = np.moveaxis(Gt, (1, 2), (1, 0))
        return out
