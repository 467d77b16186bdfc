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
(its SE(3) geodesic, which the arms follow between a plan's rows) the bar and the hands' last links
move with the object frame as one rigid body, and for them against geometry no joint moves
(obstacles, the floor, the pedestals) a bound from the object frame's motion alone holds with no
assumption on the joints, and is mostly the tighter one (:func:`rigid_pairs`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import coal
import numpy as np
import numpy.typing as npt

from ..errors import ParameterError
from ..kinematics.urdf import joint_axis

__all__ = [
    "BOTH",
    "FIXED",
    "JOINTS",
    "LINK",
    "RigidPairs",
    "geometry_reach",
    "joint_reach",
    "motion_bound",
    "motion_bounds",
    "pair_weights",
    "rigid_pairs",
]

FloatArray = npt.NDArray[np.float64]

_BOUNDS = "planning.motion_bounds"  # WorldCache keys
_WEIGHTS = "planning.pair_weights"
_REACH = "planning.geometry_reach"
_RIGID = "planning.rigid_pairs"
_TURNING = "planning.turning"


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
                own[j] = joint_axis(m, j) if m.joints[j].shortname().startswith("JointModelR") else None
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


def _turning(world) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Per geometry and joint (G, nq): ``turns`` where the joint is right below the geometry's own
    and turns about its round axis (an upright pedestal and the first joint), ``spins`` where the
    joint is the geometry's own, revolute, and turns it about its round axis (a column on the first
    joint): either way the turn leaves the geometry's set of points where it was. Kept in
    ``world.cache``."""

    def build():
        m, gm = world.model, world.geom_model
        G, nq = len(gm.geometryObjects), m.nq
        turns, spins = np.zeros((G, nq), dtype=bool), np.zeros((G, nq), dtype=bool)
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
                    axes[c] = (M.translation, M.rotation @ joint_axis(m, c))
                turns[g, int(m.joints[c].idx_q)] = _round_on_axis(go, *axes[c])
            j = int(go.parentJoint)
            if j > 0 and m.joints[j].shortname().startswith("JointModelR"):  # its own axis, in its own frame
                spins[g, int(m.joints[j].idx_q)] = _round_on_axis(go, np.zeros(3), joint_axis(m, j))
        turns.setflags(write=False)
        spins.setflags(write=False)
        return turns, spins

    return world.cache.shared(_TURNING, build)


def pair_weights(world) -> tuple[FloatArray, FloatArray]:
    """Per pair (``world.pair_ids`` order) the weights W (P, 12) [m] and speed v (P,) [m/s] of its
    own motion bound ``D_k = W_k . |dq| + v_k |dt|``: a joint that moves both geometries of the pair
    (upstream of both) does not change their distance, one that moves only one of them moves it by
    at most ``|dq_j| R_j(g)`` (:func:`geometry_reach`), and one that turns a round geometry about
    its own axis (an upright pedestal relative to the joint above it, a column on its own joint)
    changes nothing; a moving obstacle adds its speed. Kept in ``world.cache``."""

    def build():
        reach, chain = geometry_reach(world)
        turns, spins = _turning(world)
        G = len(world.geom_model.geometryObjects)
        speed = np.zeros(G)
        for gid, ob in world.moving:
            speed[gid] = float(np.linalg.norm(ob.velocity))
        a, b = np.array(world.pair_ids, dtype=np.int64).reshape(-1, 2).T
        only_a, only_b = chain[a] & ~chain[b], chain[b] & ~chain[a]
        W = (np.where(only_a & ~turns[b] & ~spins[a], reach[a], 0.0)
             + np.where(only_b & ~turns[a] & ~spins[b], reach[b], 0.0))
        v = speed[a] + speed[b]
        W.setflags(write=False)
        v.setflags(write=False)
        return W, v

    return world.cache.shared(_WEIGHTS, build)


@dataclass(frozen=True, slots=True)
class RigidPairs:
    """The pairs whose motion along the bar's path is bounded by the object frame's own motion
    (:func:`rigid_pairs`), in ``world.pair_ids`` order.

    Attributes:
        kind: (P,) per pair: :data:`JOINTS` (neither member rides with the bar: the joint bound
            only), :data:`FIXED` (one rides with the bar, the other is geometry no joint moves: the
            rigid bound only), :data:`BOTH` (both ride with the bar: their distance never changes)
            or :data:`LINK` (one rides with the bar, the other is an arm's link that does not).
        rho: (P,) the radius about the object frame's origin of the member that rides with the bar
            [m] (0 for :data:`JOINTS` and :data:`BOTH`).
        W_other: (P, 12) for :data:`LINK` the link's own joint weights [m]: how far its points move
            in the world per radian of each joint upstream of it (:func:`geometry_reach`; none for a
            joint that turns it about its own round axis); zero elsewhere.
        rho_fixed: the largest ``rho`` of a :data:`FIXED` pair [m] (0 if none).
    """

    kind: npt.NDArray[np.int8]
    rho: FloatArray
    W_other: FloatArray
    rho_fixed: float


JOINTS, FIXED, BOTH, LINK = 0, 1, 2, 3  #: :attr:`RigidPairs.kind` values


def rigid_pairs(world) -> RigidPairs:
    """Which pairs have a member that rides with the bar, and how far that member reaches from the
    object frame's origin (:class:`RigidPairs`). Kept in ``world.cache``.

    Along the bar's path (its geodesic from pose A to pose B: translation linear, rotation about a
    fixed axis of the object frame by theta) the bar, and each hand's links with it (the geometry
    on an arm's last joint: the hand holds its grasp along the path, exactly on the closed form and
    to its tolerance, 1e-9 m, with a numeric IK), move as one rigid body with the object frame. A
    point b of such geometry (object frame) moves at ``|dx/ds| = |dp + R(s) (w x b)| <= |dp| +
    theta |b|``, so between fractions s1 < s2 no point of it moves by more than ``(s2 - s1) (|dp| +
    theta rho)``, ``rho`` its radius about the origin, whatever the joints do. Against geometry no
    joint moves (obstacles, the floor, the pedestals) that bounds the pair's change of distance
    (plus a moving obstacle's speed times the time); two such geometries never move relative to
    each other; against an arm's link that does not ride with the bar, that motion plus the link's
    own in the world (``W_other``, its joints' share) is another bound of the pair's."""

    def build():
        m, gm = world.model, world.geom_model
        reach, chain = geometry_reach(world)
        _, spins = _turning(world)
        last = {int(m.frames[world.hand_frame_ids[s]].parentJoint): s for s in world.hand_frame_ids}
        radius = np.full(len(gm.geometryObjects), np.nan)  # rides with the bar: its radius [m]
        for g, (go, info) in enumerate(zip(gm.geometryObjects, world.geoms)):
            side = last.get(int(go.parentJoint))
            if g == world.bar_id:
                radius[g] = _radius_about_origin(info, np.asarray(world.T_object_bar, float))
            elif side is not None:
                hand = m.frames[world.hand_frame_ids[side]].placement
                M = world.T_object_hand[side] @ (hand.inverse() * go.placement).homogeneous
                radius[g] = _radius_about_origin(info, M)
        fixed = np.array([int(go.parentJoint) == 0 for go in gm.geometryObjects])
        rigid = ~np.isnan(radius)
        P = len(world.pair_ids)
        kind = np.full(P, JOINTS, dtype=np.int8)
        rho, W_other = np.zeros(P), np.zeros((P, m.nq))
        for k, (a, b) in enumerate(world.pair_ids):
            if rigid[a] and rigid[b]:
                kind[k] = BOTH
            elif rigid[a] or rigid[b]:
                g, h = (a, b) if rigid[a] else (b, a)
                kind[k], rho[k] = (FIXED if fixed[h] else LINK), radius[g]
                if not fixed[h]:  # the link's own motion in the world
                    W_other[k] = np.where(chain[h] & ~spins[h], reach[h], 0.0)
        for x in (kind, rho, W_other):
            x.setflags(write=False)
        return RigidPairs(kind, rho, W_other, float(rho[kind == FIXED].max(initial=0.0)))

    return world.cache.shared(_RIGID, build)


def _radius_about_origin(info, M: FloatArray) -> float:
    """The farthest point of a geometry placed at M (4, 4) from the origin of M's frame [m]: a
    capsule's segment ends plus its radius, a box's farthest corner, a sphere's centre plus its
    radius."""
    c, R, size = M[:3, 3], M[:3, :3], np.asarray(info.size, float)
    if info.shape == "capsule":  # the segment's ends along the capsule's z axis
        return max(float(np.linalg.norm(c + e * 0.5 * size[1] * R[:, 2])) for e in (-1.0, 1.0)) + float(size[0])
    if info.shape == "box":
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * (0.5 * size)
        return float(np.linalg.norm(c + corners @ R.T, axis=1).max())
    if info.shape == "sphere":
        return float(np.linalg.norm(c)) + float(size[0])
    raise ParameterError(f"{info.name}: no radius for a {info.shape} riding with the bar")
