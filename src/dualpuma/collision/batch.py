"""Clearance of many configurations: distances, per-pair distances and margin tests.

* :func:`clearance_batch` — minimum signed distance and its pair for N configurations: the exact
  vectorised kernel (:class:`~.kernel.ClearanceKernel`) for batches, a tight loop of Pinocchio/coal
  C++ calls for a few.
* :func:`pair_distances_batch` — every pair's distance (N, P).
* :func:`min_clearance` / :func:`below_margin` — the same questions for trusted joint arrays (the
  planners' own), where pairs of two geometries that never move (pedestals, columns turning about
  their own axis, static obstacles) are computed once per World and left out of the
  per-configuration queries; :func:`below_margin` asks only *whether* each configuration is closer
  than a margin (coal's collision test with a security margin stops as soon as a separating plane
  proves the margin: ~9 against 15 us per configuration of the default cell).

The kernel and the coal data prepared for these queries are kept in the World's
:class:`~dualpuma.model.cache.WorldCache` (one per thread).
"""

from __future__ import annotations

import coal
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..checks import choice, instance, validate_joints, validate_pose
from ..checks import times as check_times
from ..errors import ParameterError
from ..lie import to_se3
from ..model.world import World
from .kernel import ClearanceKernel, KernelUnsupported

__all__ = [
    "BATCH_KERNEL_MIN",
    "KERNEL_MARGIN_MIN",
    "ConstantPairs",
    "batch_kernel",
    "below_margin",
    "clearance_batch",
    "coal_loop",
    "constant_pairs",
    "entry_distances",
    "min_clearance",
    "pair_distances_batch",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

BATCH_KERNEL_MIN = 64  #: ``method="auto"`` uses the kernel from this many configurations up
KERNEL_MARGIN_MIN = 2 * BATCH_KERNEL_MIN  #: from this many up :func:`below_margin` uses the kernel
_KERNEL = "collision.kernel"  # WorldCache keys
_SPLIT = "collision.split"


def batch_kernel(world: World) -> ClearanceKernel | None:
    """This thread's :class:`~.kernel.ClearanceKernel` of the World (built on first use, kept in
    ``world.cache``); None if the World has joints the kernel does not model.

    Raises:
        ParameterError: ``world`` is not a World.
    """
    instance(world, World, "world")

    def build() -> ClearanceKernel | None:
        try:
            return ClearanceKernel(world)
        except KernelUnsupported:
            return None

    return world.cache.per_thread(_KERNEL, build)


def _batch_inputs(Q_left, Q_right, T_world_object, t) -> tuple[FloatArray, FloatArray | None, FloatArray]:
    """Validate a batch once: (Q (N, 12) [rad], bar frames (N, 4, 4) or None, times (N,) [s])."""
    QL = validate_joints(Q_left, name="Q_left").reshape(-1, 6)
    QR = validate_joints(Q_right, name="Q_right").reshape(-1, 6)
    if QL.shape != QR.shape:
        raise ParameterError(f"Q_left and Q_right differ in shape: {QL.shape} vs {QR.shape}")
    n = QL.shape[0]
    Tw = None if T_world_object is None else validate_pose(T_world_object, name="T_world_object").reshape(-1, 4, 4)
    if Tw is not None and Tw.shape[0] != n:
        raise ParameterError(f"T_world_object: expected {n} poses, got {Tw.shape[0]}")
    return np.ascontiguousarray(np.hstack([QL, QR])), Tw, np.ascontiguousarray(check_times(t, n))


def clearance_batch(
    world: World,
    Q_left: npt.ArrayLike,
    Q_right: npt.ArrayLike,
    T_world_object: npt.ArrayLike | None = None,
    t: npt.ArrayLike | None = None,
    method: str = "auto",
) -> tuple[FloatArray, IntArray]:
    """Minimum signed distance for N configurations.

    ``method="kernel"``: the exact vectorised kernel (numpy over the whole batch; equal to coal's
    answers to rounding). ``method="coal"``: a tight loop of one Pinocchio/coal C++ call per
    configuration. ``"auto"`` (default): the kernel for batches of at least
    :data:`BATCH_KERNEL_MIN` configurations (it has a fixed cost of about 0.7–2.3 ms a call, more
    with more obstacle boxes: some thousand numpy calls), the loop below that and for Worlds the
    kernel does not model.

    Args:
        world: the World.
        Q_left, Q_right: joints [rad], shape (N, 6) (or (6,) for one configuration).
        T_world_object: optional bar frames (N, 4, 4) [m] (default: implied by the left grasp).
        t: optional time or times (N,) [s] for moving obstacles (default 0).
        method: ``"auto"``, ``"kernel"`` or ``"coal"``.

    Returns:
        ``(distance (N,) [m], pair index (N,))`` — negative distance = penetration depth; the index
        (into ``world.pair_names``) is a pair achieving the minimum.

    Raises:
        JointError, PoseError, ParameterError: malformed input (checked once for the whole batch),
            an unknown method, or ``"kernel"`` for a World the kernel does not model.
    """
    choice(method, ("auto", "kernel", "coal"), "method")
    instance(world, World, "world")
    Q, Tw, times = _batch_inputs(Q_left, Q_right, T_world_object, t)
    if method == "kernel" or (method == "auto" and Q.shape[0] >= BATCH_KERNEL_MIN):
        kernel = batch_kernel(world)
        if kernel is not None:
            return kernel.evaluate(Q, Tw, times)
        if method == "kernel":
            raise ParameterError("method='kernel': this World has joints the kernel does not model")
    return coal_loop(world, Q, Tw, times)


def coal_loop(world: World, Q: FloatArray, Tw: FloatArray | None, times: FloatArray) -> tuple[FloatArray, IntArray]:
    """The per-configuration loop over Pinocchio/coal for trusted input: joints (N, 12) [rad],
    bar frames (N, 4, 4) or None [m], times (N,) [s]."""
    n = Q.shape[0]
    model, data, gm, gd = world.model, world.data, world.geom_model, world.geom_data
    dist = np.empty(n)
    idx = np.empty(n, dtype=np.int64)
    results = gd.distanceResults
    comp = pin.computeDistances
    if Tw is None and not world.moving:  # one C++ call per configuration (FK + placements + distances)
        for i in range(n):
            k = comp(model, data, gm, gd, Q[i])
            idx[i] = k
            dist[i] = results[k].min_distance
        return dist, idx
    upd, Tbar, bar = pin.updateGeometryPlacements, world.T_object_bar, world.bar_id
    for i in range(n):
        upd(model, data, gm, gd, Q[i])
        if Tw is not None:
            gd.oMg[bar] = to_se3(Tw[i] @ Tbar)
        for gid, ob in world.moving:
            gd.oMg[gid] = to_se3(ob.pose_at(times[i]))
        k = comp(gm, gd)
        idx[i] = k
        dist[i] = results[k].min_distance
    return dist, idx


def pair_distances_batch(
    world: World,
    Q_left: npt.ArrayLike,
    Q_right: npt.ArrayLike,
    T_world_object: npt.ArrayLike | None = None,
    t: npt.ArrayLike | None = None,
) -> FloatArray:
    """Every pair's signed distance for N configurations: (N, P) in ``world.pair_names`` order [m]
    (the kernel's closed forms for every pair; box–box pairs by coal).

    Raises:
        JointError, PoseError, ParameterError: malformed input, or a World the kernel does not model.
    """
    if not isinstance(world, World):
        raise ParameterError(f"world: expected a dualpuma World, got {type(world).__name__}")
    Q, Tw, times = _batch_inputs(Q_left, Q_right, T_world_object, t)
    kernel = batch_kernel(world)
    if kernel is None:
        raise ParameterError("pair_distances_batch: this World has joints the kernel does not model")
    return kernel.pair_distances(Q, Tw, times)


# ----------------------------------------------------------------------------- trusted queries
class ConstantPairs:
    """A World's pairs split into constant ones (computed once) and the rest (per query), with
    this thread's coal data for distance and margin queries over the rest."""

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
            return (isinstance(go.geometry, (coal.Capsule, coal.Sphere, coal.Cylinder)) and abs(R[2, 2]) > 1 - 1e-12
                    and abs(p[0]) < 1e-12 and abs(p[1]) < 1e-12)

        still = [fixed(g) for g in range(len(world.geoms))]
        self.const = np.array([still[a] and still[b] for a, b in world.pair_ids], dtype=bool)
        self.d_const, self.k_const = np.inf, -1
        # the distance queries' data; copied for the margin queries (the constant pairs, computed here once, are off)
        self.dist_data = gd = world.new_geom_data()
        self.data = model.createData()
        if self.const.any():
            pin.updateGeometryPlacements(model, self.data, gm, gd, pin.neutral(model))
            for k in np.flatnonzero(self.const).tolist():
                d = pin.computeDistance(gm, gd, k).min_distance
                if d < self.d_const:
                    self.d_const, self.k_const = float(d), k
                gd.deactivateCollisionPair(k)
        self.margin_data: dict[float, pin.GeometryData] = {}

    def margin(self, gm: pin.GeometryModel, margin: float) -> pin.GeometryData:
        """GeometryData whose collision requests use ``margin`` as security margin (kept per margin;
        a copy of the distance queries' data: the same active pairs, every placement set by a query)."""
        gd = self.margin_data.get(margin)
        if gd is None:
            gd = self.margin_data[margin] = self.dist_data.copy()
            for req in gd.collisionRequests:
                req.security_margin = margin
        return gd


def constant_pairs(world: World) -> ConstantPairs:
    """This thread's :class:`ConstantPairs` of the World (kept in ``world.cache``)."""
    return world.cache.per_thread(_SPLIT, lambda: ConstantPairs(world))


def min_clearance(world: World, Q: FloatArray, times: FloatArray) -> tuple[FloatArray, IntArray]:
    """``clearance_batch(world, Q[:, :6], Q[:, 6:], t=times)`` (bar frames implied) for trusted
    joints Q (N, 12) (left then right) [rad] at times (N,) [s]."""
    n = Q.shape[0]
    if n >= BATCH_KERNEL_MIN:
        kernel = batch_kernel(world)
        if kernel is not None:
            return kernel.evaluate(Q, None, times)
    sp = constant_pairs(world)
    if world.moving or not sp.const.any():
        return coal_loop(world, Q, None, times)
    model, data, gm, gd = world.model, sp.data, world.geom_model, sp.dist_data
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
    """Per configuration Q (N, 12) (left then right joints) [rad] at times (N,) [s]: True where
    some checked pair is closer than ``margin`` [m] (bar frames implied by the left grasp)."""
    n = Q.shape[0]
    if n >= KERNEL_MARGIN_MIN and batch_kernel(world) is not None:
        return min_clearance(world, Q, times)[0] < margin
    sp = constant_pairs(world)
    if sp.d_const < margin:  # a pair that never moves is already too close
        return np.ones(n, dtype=bool)
    model, data, gm = world.model, sp.data, world.geom_model
    gd = sp.margin(gm, float(margin))
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
            gd.oMg[gid] = to_se3(ob.pose_at(times[i]))
        out[i] = coll(gm, gd, True)
    return out


def entry_distances(world: World, Q: FloatArray, times: FloatArray, cuts: list[int], pairs: list[int]) -> list[float]:
    """Signed distances [m] of chosen (configuration, pair) entries, grouped by configuration: pairs
    ``pairs[cuts[i] : cuts[i + 1]]`` (indices into ``world.pair_names``) at the trusted configuration
    ``Q[i]`` (12 joints, left then right [rad], the bar implied by the left grasp) at time
    ``times[i]`` [s] (``cuts``: len(Q) + 1 ascending offsets into ``pairs``). One placement update per
    configuration and coal's distance for its entries only, in ``pairs``' order (the calling
    thread's data, no warm start; measured faster than placing every geometry with the kernel and
    evaluating the entries with its closed forms, for the few pairs per configuration a motion
    certificate asks about)."""
    model, data, gm, gd, moving = world.model, world.data, world.geom_model, world.geom_data, world.moving
    upd, dist, res = pin.updateGeometryPlacements, pin.computeDistance, []
    for i in range(len(cuts) - 1):
        if cuts[i] < cuts[i + 1]:
            upd(model, data, gm, gd, Q[i])
            for gid, ob in moving:
                gd.oMg[gid] = to_se3(ob.pose_at(float(times[i])))
            res += [dist(gm, gd, k).min_distance for k in pairs[cuts[i] : cuts[i + 1]]]
    return res
