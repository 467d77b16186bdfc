"""How far geometry can move when the joints turn: the bounds behind certified motion
(:mod:`.certify`).

Along any motion between two configurations a and b of both arms (12 joints) in which no joint
reverses, no point of any geometry moves, relative to any other geometry, by more than

    D(a, b) = sum_j |q_j(b) - q_j(a)| R_j + v_max |t_b - t_a|

where ``R_j`` bounds the distance from joint j's axis to every point of every geometry the joint
moves (:func:`joint_reach`, :func:`geometry_reach`: links downstream, the bar for the left arm) and
``v_max`` is the fastest obstacle's speed (:func:`motion_bounds`, :func:`motion_bound`). Per pair
of geometries the bound is tighter (:func:`pair_weights`): only the joints between the two move
their distance, and a round geometry turning about its own axis does not. Along the bar's path
(its SE(3) geodesic, which the arms follow between a plan's rows) the bar moves as a rigid body,
and for the bar against geometry no joint moves (obstacles, the floor) a bound from the object
frame's motion alone holds with no assumption on the joints, and is tighter (:func:`bar_pairs`).
"""

from __future__ import annotations

import math

import coal
import numpy as np
import numpy.typing as npt

__all__ = ["bar_pairs", "geometry_reach", "joint_reach", "motion_bound", "motion_bounds", "pair_weights"]

FloatArray = npt.NDArray[np.float64]

_BOUNDS = "planning.motion_bounds"  # WorldCache keys
_WEIGHTS = "planning.pair_weights"
_REACH = "planning.geometry_reach"
_BAR = "planning.bar_pairs"


def _extent(info) -> float:
    """How far a geometry reaches from its own origin [m] (a box's half diagonal, a capsule's half
    length plus radius, a sphere's radius)."""
    if info.shape == "box":
        return 0.5 * float(np.linalg.norm(info.size))
    if info.shape == "capsule":
        return 0.5 * info.size[1] + info.size[0]
    return info.size[0] if info.size else 0.0


def joint_reach(world, side: str) -> FloatArray:
    """Per joint of one arm (6,): an upper bound of the distance from the joint's axis to any point
    of any geometry it moves [m] (:func:`geometry_reach`)."""
    m = world.model
    cols = [int(m.joints[j].idx_q) for j in range(1, m.njoints) if m.names[j].startswith(side + "/")]
    reach, _ = geometry_reach(world)
    return reach[:, cols].max(axis=0, initial=0.0)


def geometry_reach(world) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Per geometry and joint (G, nq): an upper bound R_j(g) of the distance from joint j's axis to
    any point of geometry g [m] (0 where j does not move g), and whether j moves g. R_j(g) is the
    distance from a revolute joint's axis to the next link's origin (fixed in the joint's frame;
    a prismatic joint: that origin's distance), plus the further chain offsets to the geometry and
    its extent. Kept in ``world.cache``."""

    def build():
        m, gm = world.model, world.geom_model
        reach = np.zeros((len(gm.geometryObjects), m.nq))
        chain = np.zeros(reach.shape, dtype=bool)
        iq = [int(jm.idx_q) for jm in m.joints]
        parents = [int(j) for j in m.parents]
        links = [M.translation for M in m.jointPlacements]  # joint j's origin in its parent's frame
        offset = [math.hypot(*v.tolist()) for v in links]
        own: dict[int, FloatArray | None] = {}
        off_link: dict[int, float] = {}  # off_axis(parents[c], links[c]), the same for every geometry

        def off_axis(j: int, v: FloatArray) -> float:  # distance from joint j's axis to v (in its frame)
            if j not in own:
                own[j] = _axis(m, j) if m.joints[j].shortname().startswith("JointModelR") else None
            return math.hypot(*v.tolist()) if own[j] is None else _cross_norm(v, own[j])  # revolute only

        for g, (go, info) in enumerate(zip(gm.geometryObjects, world.geoms)):
            j, near = int(go.parentJoint), go.placement.translation  # near: the chain's link in joint j's frame
            acc = _extent(info) + math.hypot(*near.tolist())
            if j > 0:  # joint j turns the chain's first link about its axis: its part off the axis counts
                chain[g, iq[j]] = True
                reach[g, iq[j]] = _extent(info) + off_axis(j, near)
            while j > 0 and parents[j] > 0:  # further up, the link to joint c is the chain's first
                c, j = j, parents[j]
                acc += offset[c]
                if c not in off_link:
                    off_link[c] = off_axis(j, links[c])
                chain[g, iq[j]] = True
                reach[g, iq[j]] = acc - offset[c] + off_link[c]
        reach.setflags(write=False)
        chain.setflags(write=False)
        return reach, chain

    return world.cache.shared(_REACH, build)


def motion_bounds(world) -> tuple[FloatArray, float]:
    """``(R (12,) [m], v_max [m/s])`` of a World: :func:`joint_reach` of both arms (left, right)
    and the fastest obstacle's speed (kept in ``world.cache``)."""

    def build():
        reach = np.concatenate([joint_reach(world, "left"), joint_reach(world, "right")])
        reach.setflags(write=False)
        return reach, max([float(np.linalg.norm(ob.velocity)) for ob in world.cell.obstacles] + [0.0])

    return world.cache.shared(_BOUNDS, build)


def motion_bound(reach: FloatArray, v_max: float, dq: FloatArray, dt: FloatArray) -> FloatArray:
    """``D`` of chords with joint changes dq (K, 12) [rad] and time changes dt (K,) [s] [m]."""
    return np.abs(dq) @ reach + v_max * np.abs(dt)


def _axis(model, j: int) -> FloatArray:
    name = model.joints[j].shortname()
    for k, ax in enumerate("XYZ"):
        if name.endswith(("R" + ax, "P" + ax)):
            return np.eye(3)[k]
    return np.asarray(model.joints[j].extract().axis, dtype=float)


_ROUND = (coal.Sphere, coal.Capsule, coal.Cylinder, coal.Halfspace)  # shapes _round_on_axis can accept


def _cross_norm(x: FloatArray, y: FloatArray) -> float:
    """|x × y| of two 3-vectors (plain floats: np.cross costs more than the arithmetic)."""
    (x0, x1, x2), (y0, y1, y2) = x.tolist(), y.tolist()
    return math.sqrt((x1 * y2 - x2 * y1) ** 2 + (x2 * y0 - x0 * y2) ** 2 + (x0 * y1 - x1 * y0) ** 2)


def _round_on_axis(go, p: FloatArray, u: FloatArray) -> bool:
    """Is geometry ``go`` (placed in the frame of joint j's parent) round and centred on joint j's
    axis (through p along u, in that frame): a sphere on it, a capsule/cylinder along it, or a
    halfspace whose normal is the axis? Turning about that axis then leaves its distance to
    anything beyond the joint unchanged."""
    M = go.placement.homogeneous
    shape = go.geometry
    if isinstance(shape, coal.Halfspace):  # turning about its normal keeps every height
        return _cross_norm(M[:3, :3] @ np.asarray(shape.n, float), u) < 1e-9
    on_line = _cross_norm(M[:3, 3] - p, u) < 1e-9
    if isinstance(shape, coal.Sphere):
        return on_line
    return on_line and _cross_norm(M[:3, 2], u) < 1e-9  # capsule, cylinder


def pair_weights(world) -> tuple[FloatArray, FloatArray]:
    """Per pair (``world.pair_ids`` order) the weights W (P, 12) [m] and speed v (P,) [m/s] of its
    own motion bound ``D_k = W_k . |dq| + v_k |dt|``: a joint that moves both geometries of the pair
    (upstream of both) does not change their distance, one that moves only one of them moves it by
    at most ``|dq_j| R_j(g)`` (:func:`geometry_reach`), and one that turns a round geometry about
    its own axis (an upright pedestal relative to the joint above it) changes nothing; a moving
    obstacle adds its speed. Kept in ``world.cache``."""

    def build():
        reach, chain = geometry_reach(world)
        m, gm = world.model, world.geom_model
        G, nq = len(gm.geometryObjects), m.nq
        turns = np.zeros((G, nq), dtype=bool)  # joints right below it that turn about its round axis
        children: dict[int, list[int]] = {}
        for j in range(1, m.njoints):
            children.setdefault(int(m.parents[j]), []).append(j)
        axes: dict[int, tuple[FloatArray, FloatArray]] = {}  # joint: its axis (point, direction) in the parent frame
        for g, go in enumerate(gm.geometryObjects):
            if not isinstance(go.geometry, _ROUND):  # only these can turn about their own axis
                continue
            for c in children.get(int(go.parentJoint), []):
                if c not in axes:
                    M = m.jointPlacements[c]
                    axes[c] = (M.translation, M.rotation @ _axis(m, c))
                turns[g, int(m.joints[c].idx_q)] = _round_on_axis(go, *axes[c])
        speed = np.zeros(G)
        for gid, ob in world.moving:
            speed[gid] = float(np.linalg.norm(ob.velocity))
        a, b = np.array(world.pair_ids, dtype=np.int64).reshape(-1, 2).T
        only_a, only_b = chain[a] & ~chain[b], chain[b] & ~chain[a]
        W = np.where(only_a & ~turns[b], reach[a], 0.0) + np.where(only_b & ~turns[a], reach[b], 0.0)
        v = speed[a] + speed[b]
        W.setflags(write=False)
        v.setflags(write=False)
        return W, v

    return world.cache.shared(_WEIGHTS, build)


def bar_pairs(world) -> tuple[npt.NDArray[np.bool_], float]:
    """Which pairs (``world.pair_ids`` order, (P,)) are the bar against geometry no joint moves (an
    obstacle, the floor), and the bar's radius rho about the object frame's origin [m] (the
    farthest point of its geometry). Kept in ``world.cache``.

    Along the bar's geodesic from pose A to pose B (translation linear, rotation about a fixed axis
    of the object frame by theta), a point b of the bar (object frame) moves at
    ``|dx/ds| = |dp + R(s) (w x b)| <= |dp| + theta |b|``, so between fractions s1 < s2 no point of
    it moves by more than ``(s2 - s1) (|dp| + theta rho)``: such a pair's distance changes by at most
    that (plus a moving obstacle's speed times the time), whatever the arms' joints do."""

    def build():
        info, M = world.geoms[world.bar_id], np.asarray(world.T_object_bar, float)
        c, R, size = M[:3, 3], M[:3, :3], np.asarray(info.size, float)
        if info.shape == "capsule":  # the segment's ends along the capsule's z axis, plus its radius
            rho = max(float(np.linalg.norm(c + e * 0.5 * size[1] * R[:, 2])) for e in (-1.0, 1.0)) + size[0]
        elif info.shape == "box":  # the farthest corner
            corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * (0.5 * size)
            rho = float(np.linalg.norm(c + corners @ R.T, axis=1).max())
        else:  # a sphere
            rho = float(np.linalg.norm(c)) + float(size[0])
        fixed = {world.floor_id, *world.obstacle_ids}
        mask = np.array([(a == world.bar_id and b in fixed) or (b == world.bar_id and a in fixed)
                         for a, b in world.pair_ids], dtype=bool)
        mask.setflags(write=False)
        return mask, rho

    return world.cache.shared(_BAR, build)
