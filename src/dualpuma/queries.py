"""The planner's batched clearance queries on its own finite joints (no input validation).

* :func:`min_clearance` — minimum signed distance and its pair per configuration:
  :func:`dualpuma.clearance.clearance_batch`'s choice (the numpy kernel for large batches, a loop
  of coal calls for small ones) without re-validating.
* Pairs of two geometries that never move (pedestals, columns turning about their own axis,
  static obstacles) have one distance for every configuration: it is computed once per World and
  those pairs are left out of the per-configuration queries (10 % of the pairs with two obstacles).
* :func:`below_margin` — only *whether* each configuration is closer than a margin, which is all
  the between-step poses need: coal's collision test with a security margin (a pair counts as
  colliding when its distance is below the margin) answers that faster than the distance query
  (about 9 against 15 µs per configuration of the default cell, measured while building this),
  because GJK stops as soon as a separating plane proves the margin. The planner
  asks for distances only where it says yes (to report the pair). ``tests/test_queries.py``
  compares it with the distance query, configurations at the margin included.
"""

from __future__ import annotations

import warnings

import coal
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .clearance import BATCH_KERNEL_MIN, _coal_loop, batch_kernel
from .world import World, _se3

FloatArray = npt.NDArray[np.float64]

#: from this many configurations up :func:`below_margin` uses the kernel's distances instead
KERNEL_MARGIN_MIN = 2 * BATCH_KERNEL_MIN


class _Split:
    """A World's pairs split into constant ones (computed once) and the rest (per query)."""

    def __init__(self, world: World) -> None:
        model, gm = world.model, world.geom_model
        moving = {gid for gid, _ in world.moving}

        def fixed(g: int) -> bool:  # placement independent of q and t
            go = gm.geometryObjects[g]
            if go.parentJoint == 0:
                return g not in moving
            j = go.parentJoint
            if model.parents[j] != 0 or model.joints[j].shortname() != "JointModelRZ":
                return False
            R, p = go.placement.rotation, go.placement.translation  # a round shape on the axis
            return isinstance(go.geometry, (coal.Capsule, coal.Sphere, coal.Cylinder)) and abs(R[2, 2]) > 1 - 1e-12 \
                and abs(p[0]) < 1e-12 and abs(p[1]) < 1e-12

        self.const = np.array([fixed(a) and fixed(b) for a, b in world.pair_ids], dtype=bool)
        self.d_const, self.k_const = np.inf, -1
        if self.const.any():
            gd = _fresh_data(world)
            pin.updateGeometryPlacements(model, world.model.createData(), gm, gd, pin.neutral(model))
            for k in np.flatnonzero(self.const):
                d = pin.computeDistance(gm, gd, int(k)).min_distance
                if d < self.d_const:
                    self.d_const, self.k_const = float(d), int(k)
        self.dist_data = _fresh_data(world)
        for k in np.flatnonzero(self.const):
            self.dist_data.deactivateCollisionPair(int(k))
        self.margin_data: dict[float, pin.GeometryData] = {}

    def margin(self, world: World, margin: float) -> pin.GeometryData:
        """GeometryData whose collision requests use ``margin`` as security margin (kept per margin)."""
        gd = self.margin_data.get(margin)
        if gd is None:
            gd = self.margin_data[margin] = _fresh_data(world, margin)
            for k in np.flatnonzero(self.const):
                gd.deactivateCollisionPair(int(k))
        return gd


def _fresh_data(world: World, margin: float | None = None) -> pin.GeometryData:
    """A GeometryData of the World with coal's warm start off (answers never depend on history)."""
    gd = pin.GeometryData(world.geom_model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        for reqs in (gd.distanceRequests, gd.collisionRequests):
            for req in reqs:
                if hasattr(req, "enable_cached_gjk_guess"):
                    req.enable_cached_gjk_guess = False
    if margin is not None:
        for req in gd.collisionRequests:
            req.security_margin = margin
    return gd


def _split(world: World) -> _Split:
    """The World's split, built once and rebuilt whenever :meth:`World.reset` renews its data."""
    cached = world.__dict__.get("_query_split")
    if cached is None or cached[0] is not world.geom_data:
        cached = world.__dict__["_query_split"] = (world.geom_data, _Split(world))
    return cached[1]


def min_clearance(world: World, Q: FloatArray, times: FloatArray):
    """``clearance_batch(world, Q[:, :6], Q[:, 6:], t=times)`` (bar frames implied) for trusted
    joints Q (N, 12) (left then right) at times (N,)."""
    n = Q.shape[0]
    if n >= BATCH_KERNEL_MIN:
        kernel = batch_kernel(world)
        if kernel is not None:
            return kernel.evaluate(Q, None, times)
    sp = _split(world)
    if world.moving or not sp.const.any():
        return _coal_loop(world, Q, None, times)
    model, data, gm, gd = world.model, world.data, world.geom_model, sp.dist_data
    dist = np.empty(n)
    idx = np.empty(n, dtype=np.int64)
    results, comp = gd.distanceResults, pin.computeDistances
    dc, kc = sp.d_const, sp.k_const
    for i in range(n):
        k = comp(model, data, gm, gd, Q[i])
        d = results[k].min_distance
        if dc < d or (dc == d and kc < k):
            d, k = dc, kc
        dist[i], idx[i] = d, k
    return dist, idx


def below_margin(world: World, Q: FloatArray, times: FloatArray, margin: float) -> npt.NDArray[np.bool_]:
    """Per configuration Q (N, 12) (left then right joints) at times (N,): True where some
    checked pair is closer than ``margin`` [m] (bar frames implied by the left grasp)."""
    n = Q.shape[0]
    if n >= KERNEL_MARGIN_MIN and batch_kernel(world) is not None:
        return min_clearance(world, Q, times)[0] < margin
    sp = _split(world)
    if sp.d_const < margin:  # a pair that never moves is already too close
        return np.ones(n, dtype=bool)
    model, data, gm = world.model, world.data, world.geom_model
    gd = sp.margin(world, float(margin))
    out = np.empty(n, dtype=bool)
    coll = pin.computeCollisions
    if not world.moving:
        for i in range(n):
            out[i] = coll(model, data, gm, gd, Q[i], True)
        return out
    upd = pin.updateGeometryPlacements
    for i in range(n):
        upd(model, data, gm, gd, Q[i])
        for gid, ob in world.moving:
            gd.oMg[gid] = _se3(np.asarray(ob.pose_at(times[i]), float))
        out[i] = coll(gm, gd, True)
    return out
