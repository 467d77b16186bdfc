"""The seed's clearance methods, kept beside the exact capsule clearance they are compared with.

* :func:`node_search` — the seed's graph node search (procedures Coordinate and Node): 16 points per
  arm and a 175 mm threshold, reproduced faithfully as a baseline (docs/clearance.md shows where it
  misses a collision and where it raises a false alarm).
* :func:`grown_obstacles` / :func:`object_point_clear` — the seed's configuration mapping (§5.4):
  obstacles grown by the bar's major dimension so that only the object frame's origin is checked.
* :func:`arm_arm_distance` / :func:`twisting` — the routine-6 "twisting collision": arms spiralling
  into each other while the bar yaws are stopped while the arm–arm clearance is inside a buffer and
  closing, before they touch (the seed's node search did it with its 175 mm threshold).
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..checks import instance, real, validate_joints, validate_pose
from ..errors import JointError, ParameterError, PoseError
from ..kinematics.puma import A2, SHOULDER_HEIGHT, fk
from ..model.cell import Cell
from ..model.world import World

__all__ = [
    "NODE_THRESHOLD",
    "GrownObstacle",
    "arm_arm_distance",
    "bar_major_dimension",
    "grown_obstacles",
    "node_positions",
    "node_search",
    "object_point_clear",
    "point_distance",
    "twisting",
]

FloatArray = npt.NDArray[np.float64]

NODE_THRESHOLD = 0.175  #: the seed's "safe" node distance: 35 screen units = 175 mm [m]
_NODE_OFFSET = 0.200  #: the seed draws the shoulder offset as 200 mm sideways (node 3)
_NODE_BACK = 0.05091  #: ... and 50.91 mm back at the elbow (node 5): 200 - 50.91 = d2
_NODE_FINGER = 0.125  #: gripper finger length in the node model (25 screen units) [m]
_ARM_ARM = "collision.arm_arm_mask"  # WorldCache key


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

    Raises:
        PoseError: ``T_world_base`` not one pose. JointError: malformed ``q``.
    """
    Tb = _one_pose(T_world_base, "T_world_base")
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

    Raises:
        PoseError, JointError: malformed poses or joints. ParameterError: ``threshold`` not a
            finite length >= 0.
    """
    threshold = real(threshold, "threshold", lo=0.0, hi=100.0, unit="m")
    nl = node_positions(T_world_base_left, q_left)
    nr = node_positions(T_world_base_right, q_right)
    try:
        np.broadcast_shapes(nl.shape[:-2], nr.shape[:-2])
    except ValueError:
        raise JointError(f"q_left, q_right: batches of shapes {nl.shape[:-2]} and {nr.shape[:-2]} do not "
                         "broadcast together") from None
    d = np.linalg.norm(nl[..., :, None, :] - nr[..., None, :, :], axis=-1).min(axis=(-2, -1))
    return d <= threshold, d


# ------------------------------------------------------------------------ configuration mapping
def bar_major_dimension(cell) -> float:
    """Distance from the object frame's origin to the bar's farthest point (the seed's §5.4) [m].

    Raises:
        ParameterError: ``cell`` is not a Cell.
    """
    instance(cell, Cell, "cell")
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
    """The configuration-mapping obstacles of a cell at time ``t`` [s] (for drawing and checks).

    Raises:
        ParameterError: ``cell`` is not a Cell; ``t`` not finite.
    """
    t = real(t, "t", unit="s")
    rho = bar_major_dimension(cell)
    out = []
    for ob in cell.obstacles:
        size = tuple(float(v) for v in np.atleast_1d(ob.size))
        box = tuple(v + 2 * rho for v in size) if ob.shape == "box" else ()
        out.append(GrownObstacle(ob.name, ob.shape, size, rho, np.asarray(ob.pose_at(t), float), box))
    return out


def point_distance(shape: str, size: tuple[float, ...], T: FloatArray, p: FloatArray) -> FloatArray:
    """Signed distance from points p (..., 3) [m] to a box (full extents), sphere (r,) or capsule
    (r, L) posed at T (4, 4) [m] (negative inside). Trusted input."""
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

    Raises:
        ParameterError: ``cell`` is not a Cell; ``t`` not finite. PoseError: not one pose.
    """
    instance(cell, Cell, "cell")
    p = _one_pose(T_world_object, "T_world_object")[:3, 3]
    for g in grown_obstacles(cell, t):
        if point_distance(g.shape, g.size, g.T_world_obstacle, p) < g.grow:
            return False, g.name
    return True, ""


# ------------------------------------------------------------------------ twisting collision
def arm_arm_distance(world, q_left: npt.ArrayLike, q_right: npt.ArrayLike,
                     T_world_object: npt.ArrayLike | None = None) -> tuple[float, tuple[str, str]]:
    """Minimum distance over the arm–arm pairs only, and that pair [m].

    Raises:
        JointError, PoseError: malformed input. ParameterError: ``world`` is not a World.
    """
    instance(world, World, "world")
    c = world.clearance(q_left, q_right, T_world_object, per_pair=True)
    mask = world.cache.shared(_ARM_ARM, lambda: np.array(
        [world.geoms[a].kind == "arm" and world.geoms[b].kind == "arm" for a, b in world.pair_ids]))
    d = np.where(mask, c.pair_distances, np.inf)
    k = int(np.argmin(d))
    return float(d[k]), world.pair_names[k]


def twisting(d_prev: float, d: float, buffer: float) -> bool:
    """The twisting-collision rule: the arm–arm clearance ``d`` [m] of the next step is inside the
    ``buffer`` [m] and closing (smaller than the last step's ``d_prev``; NaN = no last step).

    Raises:
        ParameterError: not real numbers (the distances may be NaN or inf: no step, no pair).
    """
    for name, v in (("d_prev", d_prev), ("d", d)):
        if isinstance(v, bool) or not isinstance(v, numbers.Real):
            raise ParameterError(f"{name}: expected a distance [m], got {type(v).__name__}")
    buffer = real(buffer, "buffer", lo=0.0, unit="m")
    return bool(d < buffer and d < d_prev)


def _one_pose(T: npt.ArrayLike, name: str) -> FloatArray:
    arr = validate_pose(T, name=name)
    if arr.shape != (4, 4):
        raise PoseError(f"{name}: expected one pose (4, 4), got {arr.shape}")
    return arr
