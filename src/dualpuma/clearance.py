"""Clearance beyond single queries: batches, the seed's node search, configuration mapping, twisting.

* :func:`clearance_batch` — minimum signed distance for many configurations: the exact vectorised
  kernel of :mod:`dualpuma.kernel` for batches, a tight loop of coal C++ calls for a few.
* :func:`node_search` — the seed's graph node search (procedures Coordinate and Node): 16 points per
  arm and a 175 mm threshold, reproduced faithfully as a baseline.
* :func:`grown_obstacles` / :func:`object_point_clear` — the seed's configuration mapping (§5.4):
  obstacles grown by the bar's major dimension so that only the object frame's origin is checked.
* :class:`TwistMonitor` — catches the routine-6 "twisting collision" (arm–arm approach while the
  bar yaws) before contact, from the trend of the arm–arm clearance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .errors import ParameterError
from .kernel import ClearanceKernel, KernelUnsupported
from .puma import A2, SHOULDER_HEIGHT, fk, validate_joints, validate_pose
from .world import World, _se3

__all__ = [
    "BATCH_KERNEL_MIN",
    "NODE_THRESHOLD",
    "TwistMonitor",
    "arm_arm_distance",
    "bar_major_dimension",
    "batch_kernel",
    "clearance_batch",
    "grown_obstacles",
    "node_positions",
    "node_search",
    "object_point_clear",
    "pair_distances_batch",
]

FloatArray = npt.NDArray[np.float64]

NODE_THRESHOLD = 0.175  #: the seed's "safe" node distance: 35 screen units = 175 mm [m]
_NODE_OFFSET = 0.200  #: the seed draws the shoulder offset as 200 mm sideways (node 3)
_NODE_BACK = 0.05091  #: ... and 50.91 mm back at the elbow (node 5): 200 - 50.91 = d2
_NODE_FINGER = 0.125  #: gripper finger length in the node model (25 screen units) [m]


# ------------------------------------------------------------------------ batches
BATCH_KERNEL_MIN = 64  #: ``method="auto"`` uses the kernel from this many configurations up


def _batch_inputs(
    Q_left: npt.ArrayLike, Q_right: npt.ArrayLike, T_world_object: npt.ArrayLike | None, t: npt.ArrayLike | None
) -> tuple[FloatArray, FloatArray | None, FloatArray]:
    """Validate a batch once: (Q (N, 12) [rad], bar frames (N, 4, 4) or None, times (N,) [s])."""
    QL = validate_joints(Q_left, name="Q_left").reshape(-1, 6)
    QR = validate_joints(Q_right, name="Q_right").reshape(-1, 6)
    if QL.shape != QR.shape:
        raise ParameterError(f"Q_left and Q_right differ in shape: {QL.shape} vs {QR.shape}")
    n = QL.shape[0]
    Tw = None if T_world_object is None else validate_pose(T_world_object, name="T_world_object").reshape(-1, 4, 4)
    if Tw is not None and Tw.shape[0] != n:
        raise ParameterError(f"T_world_object: expected {n} poses, got {Tw.shape[0]}")
    try:
        times = np.zeros(n) if t is None else np.broadcast_to(np.asarray(t, dtype=np.float64), (n,))
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"t: expected one time or {n} times [s], got {np.shape(t)}") from exc
    if not np.all(np.isfinite(times)):
        raise ParameterError("t: times must be finite")
    return np.ascontiguousarray(np.hstack([QL, QR])), Tw, np.ascontiguousarray(times)


def batch_kernel(world: World) -> ClearanceKernel | None:
    """The World's :class:`~dualpuma.kernel.ClearanceKernel`, built on first use and kept on the
    World (like its Pinocchio data); None if the World's joints are not modelled by the kernel."""
    kernel = world.__dict__.get("_batch_kernel", False)
    if kernel is False:
        try:
            kernel = ClearanceKernel(world)
        except KernelUnsupported:
            kernel = None
        world.__dict__["_batch_kernel"] = kernel
    return kernel


def clearance_batch(
    world: World,
    Q_left: npt.ArrayLike,
    Q_right: npt.ArrayLike,
    T_world_object: npt.ArrayLike | None = None,
    t: npt.ArrayLike | None = None,
    method: str = "auto",
) -> tuple[FloatArray, npt.NDArray[np.int64]]:
    """Minimum signed distance for N configurations.

    ``method="kernel"``: the exact vectorised kernel of :mod:`dualpuma.kernel` (numpy over the
    whole batch; equal to coal's answers to rounding). ``method="coal"``: a tight loop of one
    Pinocchio/coal C++ call per configuration. ``"auto"`` (default): the kernel for batches of at
    least :data:`BATCH_KERNEL_MIN` configurations (it has a fixed cost of a few hundred µs), the
    loop below that and for Worlds the kernel does not model.

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
    if method not in ("auto", "kernel", "coal"):
        raise ParameterError(f"method: expected 'auto', 'kernel' or 'coal', got {method!r}")
    Q, Tw, times = _batch_inputs(Q_left, Q_right, T_world_object, t)
    if method == "kernel" or (method == "auto" and Q.shape[0] >= BATCH_KERNEL_MIN):
        kernel = batch_kernel(world)
        if kernel is not None:
            return kernel.evaluate(Q, Tw, times)
        if method == "kernel":
            raise ParameterError("method='kernel': this World has joints the kernel does not model")
    return _coal_loop(world, Q, Tw, times)


def _coal_loop(
    world: World, Q: FloatArray, Tw: FloatArray | None, times: FloatArray
) -> tuple[FloatArray, npt.NDArray[np.int64]]:
    """The per-configuration loop over Pinocchio/coal (validated inputs)."""
    n = Q.shape[0]
    model, data, gm, gd = world.model, world.data, world.geom_model, world.geom_data
    dist = np.empty(n)
    idx = np.empty(n, dtype=np.int64)
    results = gd.distanceResults
    Tbar = world.T_object_bar
    moving = world.moving
    bar = world.bar_id
    fwd, upd, comp = pin.forwardKinematics, pin.updateGeometryPlacements, pin.computeDistances
    if Tw is None and not moving:  # one C++ call per configuration (FK + placements + distances)
        for i in range(n):
            k = comp(model, data, gm, gd, Q[i])
            idx[i] = k
            dist[i] = results[k].min_distance
        return dist, idx
    for i in range(n):
        fwd(model, data, Q[i])
        upd(model, data, gm, gd)
        if Tw is not None:
            gd.oMg[bar] = _se3(Tw[i] @ Tbar)
        for gid, ob in moving:
            gd.oMg[gid] = _se3(np.asarray(ob.pose_at(times[i]), float))
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
    """Every pair's signed distance for N configurations: (N, P) in ``world.pair_names`` order [m].

    Computed by the vectorised kernel (:meth:`~dualpuma.kernel.ClearanceKernel.pair_distances`,
    closed forms for every pair; box–box pairs by coal).

    Raises:
        JointError, PoseError, ParameterError: malformed input, or a World the kernel does not model.
    """
    Q, Tw, times = _batch_inputs(Q_left, Q_right, T_world_object, t)
    kernel = batch_kernel(world)
    if kernel is None:
        raise ParameterError("pair_distances_batch: this World has joints the kernel does not model")
    return kernel.pair_distances(Q, Tw, times)


def arm_arm_distance(world: World, q_left: npt.ArrayLike, q_right: npt.ArrayLike) -> tuple[float, tuple[str, str]]:
    """Minimum distance over the arm–arm pairs only (used by :class:`TwistMonitor`) [m]."""
    c = world.clearance(q_left, q_right, per_pair=True)
    assert c.pair_distances is not None
    mask = np.array([world.geoms[a].kind == "arm" and world.geoms[b].kind == "arm" for a, b in world.pair_ids])
    d = np.where(mask, c.pair_distances, np.inf)
    k = int(np.argmin(d))
    return float(d[k]), world.pair_names[k]


# ------------------------------------------------------------------------ the seed's node search
def node_positions(T_world_base: npt.ArrayLike, q: npt.ArrayLike) -> FloatArray:
    """The seed's 16 nodes of one arm (procedures Coordinate and Node) in the world frame [m].

    Nodes: 1 base on the floor, 2 shoulder, 3 shoulder offset (200 mm sideways), 4 elbow,
    5 elbow back towards the arm plane (50.91 mm), 6 wrist centre, 7-10 the two gripper fingers
    (125 mm along +-o then along a), 11-12 on the pedestal, 13-14 on the upper arm, 15-16 on the
    forearm (thirds).

    Args:
        T_world_base: shoulder frame (4, 4) [m] (any yaw about the vertical; the seed's are axis-aligned).
        q: joints [rad], shape (..., 6).

    Returns:
        (..., 16, 3) node positions [m].
    """
    Tb = np.asarray(T_world_base, float)
    q = validate_joints(q)
    T = fk(q)
    c1, s1 = np.cos(q[..., 0]), np.sin(q[..., 0])
    c2, s2 = np.cos(q[..., 1]), np.sin(q[..., 1])
    shoulder = Tb[:3, 3]
    Rb = Tb[:3, :3]  # nodes 3-5 are built in the base frame, then rotated into the world
    n = np.zeros(q.shape[:-1] + (16, 3))
    n[..., 0, :] = shoulder - Rb @ [0.0, 0.0, SHOULDER_HEIGHT]
    n[..., 1, :] = shoulder
    n[..., 2, :] = shoulder + np.stack([-s1 * _NODE_OFFSET, c1 * _NODE_OFFSET, 0 * c1], -1) @ Rb.T
    n[..., 3, :] = n[..., 2, :] + np.stack([c1 * c2 * A2, s1 * c2 * A2, -s2 * A2], -1) @ Rb.T
    n[..., 4, :] = n[..., 3, :] + np.stack([s1 * _NODE_BACK, -c1 * _NODE_BACK, 0 * c1], -1) @ Rb.T
    W = Tb @ T
    n[..., 5, :] = W[..., :3, 3]
    o, a = W[..., :3, 1], W[..., :3, 2]
    n[..., 6, :] = n[..., 5, :] + _NODE_FINGER * o
    n[..., 7, :] = n[..., 6, :] + _NODE_FINGER * a
    n[..., 8, :] = n[..., 5, :] - _NODE_FINGER * o
    n[..., 9, :] = n[..., 8, :] + _NODE_FINGER * a
    for k, (i, j) in enumerate(((0, 1), (2, 3), (4, 5))):
        for m in (1, 2):
            n[..., 10 + 2 * k + m - 1, :] = n[..., i, :] + (n[..., j, :] - n[..., i, :]) * (m / 3.0)
    return n


def node_search(
    T_world_base_left: npt.ArrayLike,
    q_left: npt.ArrayLike,
    T_world_base_right: npt.ArrayLike,
    q_right: npt.ArrayLike,
    threshold: float = NODE_THRESHOLD,
) -> tuple[npt.NDArray[np.bool_], FloatArray]:
    """The seed's graph node search: collision if any left node is within ``threshold`` of a right one.

    Returns:
        ``(collision (...,), min node distance (...,) [m])``.
    """
    nl = node_positions(T_world_base_left, q_left)
    nr = node_positions(T_world_base_right, q_right)
    d = np.linalg.norm(nl[..., :, None, :] - nr[..., None, :, :], axis=-1).min(axis=(-2, -1))
    return d <= threshold, d


# ------------------------------------------------------------------------ configuration mapping
def bar_major_dimension(cell) -> float:
    """Distance from the object frame's origin to the bar's farthest point (the seed's §5.4) [m]."""
    T = np.asarray(cell.bar.T_object_bar, float)
    size = np.atleast_1d(np.asarray(cell.bar.size, float))
    if cell.bar.shape == "box":
        h = size / 2.0
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
        pts = corners @ T[:3, :3].T + T[:3, 3]
        return float(np.linalg.norm(pts, axis=1).max())
    if cell.bar.shape == "capsule":
        r, length = size[0], size[1]
        ends = np.array([T[:3, 3] + s * 0.5 * length * T[:3, 2] for s in (-1, 1)])
        return float(np.linalg.norm(ends, axis=1).max() + r)
    r = size[0]
    return float(np.linalg.norm(T[:3, 3]) + r)


@dataclass(frozen=True, slots=True)
class GrownObstacle:
    """An obstacle grown by the bar's major dimension (exactly: its Minkowski sum with a ball).

    Attributes:
        name: the obstacle's name.
        shape: the original shape; the exact grown set is that shape's points within ``grow``.
        size: original size (box full extents, sphere (r,), capsule (r, L)).
        grow: growth radius [m].
        T_world_obstacle: pose at the query time (4, 4).
        box_size: full extents of the drawn (square-cornered, slightly larger) box for boxes.
    """

    name: str
    shape: str
    size: tuple[float, ...]
    grow: float
    T_world_obstacle: FloatArray
    box_size: tuple[float, ...]


def grown_obstacles(cell, t: float = 0.0) -> list[GrownObstacle]:
    """The configuration-mapping obstacles of a cell at time ``t`` (for drawing and checks)."""
    rho = bar_major_dimension(cell)
    out = []
    for ob in cell.obstacles:
        size = tuple(float(v) for v in np.atleast_1d(ob.size))
        box = tuple(v + 2 * rho for v in size) if ob.shape == "box" else ()
        out.append(GrownObstacle(ob.name, ob.shape, size, rho, np.asarray(ob.pose_at(t), float), box))
    return out


def _point_distance(shape: str, size: tuple[float, ...], T: FloatArray, p: FloatArray) -> FloatArray:
    """Signed distance from points p (..., 3) to an obstacle [m] (negative inside)."""
    local = (p - T[:3, 3]) @ T[:3, :3]
    if shape == "box":
        h = np.asarray(size) / 2.0
        q = np.abs(local) - h
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
        inside = np.minimum(q.max(axis=-1), 0.0)
        return outside + inside
    if shape == "sphere":
        return np.linalg.norm(local, axis=-1) - size[0]
    r, length = size[0], size[1]
    z = np.clip(local[..., 2], -length / 2, length / 2)
    return np.linalg.norm(local - np.stack([0 * z, 0 * z, z], -1), axis=-1) - r


def object_point_clear(cell, T_world_object: npt.ArrayLike, t: float = 0.0) -> tuple[bool, str]:
    """Configuration-mapping check: the object origin outside every grown obstacle?

    Returns:
        ``(clear, name of the first grown obstacle containing the origin or "")``.
    """
    p = validate_pose(T_world_object, name="T_world_object")[:3, 3]
    for g in grown_obstacles(cell, t):
        if _point_distance(g.shape, g.size, g.T_world_obstacle, p) < g.grow:
            return False, g.name
    return True, ""


# ------------------------------------------------------------------------ twisting collision
class TwistMonitor:
    """Fires when the arm–arm clearance is below ``margin`` or is predicted to be at the next step.

    Feed the arm–arm distance after each accepted step; :meth:`check` asks about a candidate step
    before it is taken. The prediction extrapolates the last change linearly (the approach speed of
    twisting arms is nearly constant over a few degrees of yaw).

    Args:
        margin: clearance below which motion is refused [m].
    """

    def __init__(self, margin: float) -> None:
        if not np.isfinite(margin) or margin < 0:
            raise ParameterError(f"margin: expected a finite value >= 0 [m], got {margin}")
        self.margin = float(margin)
        self.history: list[float] = []

    def check(self, d_next: float) -> tuple[bool, str]:
        """Would a step to arm–arm distance ``d_next`` be safe? Returns (ok, reason)."""
        if d_next < self.margin:
            return False, f"arm–arm clearance {d_next:.4f} m below the margin {self.margin:.3f} m"
        if self.history:
            rate = d_next - self.history[-1]
            if rate < 0 and d_next + rate < self.margin:
                return False, (
                    f"twisting: arm–arm clearance {d_next:.4f} m closing by {-rate:.4f} m per step "
                    f"would fall below {self.margin:.3f} m at the next step"
                )
        return True, ""

    def accept(self, d: float) -> None:
        """Record the arm–arm distance of a step that was taken."""
        self.history.append(float(d))
