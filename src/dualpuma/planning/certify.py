"""Certified motion between checked configurations (conservative advancement by bisection).

A *chord* is the joint-space straight line between two configurations ``a`` and ``b`` of both arms
(12 joints), traversed between their times. Along it no point of any geometry moves, relative to any
other geometry, by more than

    D(a, b) = sum_j |q_j(b) - q_j(a)| R_j + v_max |t_b - t_a|

where ``R_j`` bounds the distance from joint j's axis to every point of every geometry the joint
moves (links downstream, the bar for the left arm) and ``v_max`` is the fastest obstacle's speed. A
signed distance changes by at most the relative displacement of the two bodies, so with clearances
``d_a``, ``d_b`` at the ends the clearance anywhere on the chord is at least

    max(d_a - s D, d_b - (1 - s) D) >= (d_a + d_b - D) / 2.

:func:`certify_chords` accepts a chord when that bound keeps ``margin``; otherwise it queries the
midpoint (joint-linear, time-linear) and recurses on both halves, like a conservative-advancement
check: a midpoint closer than the margin refuses the chord (with the pair), and so does a chord
still unresolved after ``max_depth`` halvings (it passes too close to the margin to be proved,
which is refused rather than guessed). Every level's midpoints of every chord are queried in one
batched call. The result is independent of how finely the planner sampled the chord.

For two geometries of one arm the bound holds as well: their relative pose depends only on the
joints between them, and each of those moves the downstream one by at most ``|dq_j| R_j``.
"""

from __future__ import annotations

from dataclasses import dataclass

import coal
import numpy as np
import numpy.typing as npt

from ..collision.batch import pair_distances_at

__all__ = ["CERTIFY_DEPTH", "Certificate", "certify_chords", "joint_reach", "motion_bound", "motion_bounds",
           "pair_weights"]

FloatArray = npt.NDArray[np.float64]

CERTIFY_DEPTH = 16  #: halvings of a chord before it is refused as too close to prove
_BOUNDS = "planning.motion_bounds"  # WorldCache keys
_WEIGHTS = "planning.pair_weights"


@dataclass(frozen=True, slots=True)
class Certificate:
    """Result of :func:`certify_chords`.

    Attributes:
        n_ok: the leading chords certified (all of them when ``n_ok`` equals the number of chords).
        reason: why chord ``n_ok`` was refused ("" when all are certified).
        distance: the clearance that refused it [m] (NaN when certified, or refused at the depth).
        pair: index of the pair achieving ``distance`` into ``world.pair_names`` (-1 if none).
        queries: configurations queried (midpoints).
    """

    n_ok: int
    reason: str
    distance: float
    pair: int
    queries: int


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
    of any geometry it moves [m] (the distance from the joint's origin: chain of joint offsets, the
    geometry's placement and its extent)."""
    m, gm = world.model, world.geom_model
    joints = [j for j in range(1, m.njoints) if m.names[j].startswith(side + "/")]
    R = np.zeros(len(joints))
    for g, info in zip(gm.geometryObjects, world.geoms):
        if g.parentJoint not in joints:
            continue
        ext = _extent(info) + float(np.linalg.norm(g.placement.translation))
        i = joints.index(g.parentJoint)
        for k in range(i, -1, -1):  # the geometry's joint and every joint above it
            chain = sum(float(np.linalg.norm(m.jointPlacements[joints[x]].translation)) for x in range(k + 1, i + 1))
            R[k] = max(R[k], chain + ext)
    return R


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


def _round_on_axis(go, j_placement, axis: FloatArray) -> bool:
    """Is geometry ``go`` (placed in the frame of joint j's parent) round and centred on joint j's
    axis (a sphere on it, a capsule/cylinder along it), or a halfspace whose normal is the axis?
    Turning about that axis then leaves its distance to anything beyond the joint unchanged."""
    M = go.placement.homogeneous
    p, u = j_placement.translation, j_placement.rotation @ axis
    on_line = np.linalg.norm(np.cross(M[:3, 3] - p, u)) < 1e-9
    if isinstance(go.geometry, coal.Sphere):
        return bool(on_line)
    if isinstance(go.geometry, (coal.Capsule, coal.Cylinder)):
        return bool(on_line and np.linalg.norm(np.cross(M[:3, 2], u)) < 1e-9)
    if isinstance(go.geometry, coal.Halfspace):  # turning about its normal keeps every height
        return bool(np.linalg.norm(np.cross(M[:3, :3] @ np.asarray(go.geometry.n, float), u)) < 1e-9)
    return False


def pair_weights(world) -> tuple[FloatArray, FloatArray]:
    """Per pair (``world.pair_ids`` order) the weights W (P, 12) [m] and speed v (P,) [m/s] of its
    own motion bound ``D_k = W_k . |dq| + v_k |dt|``: a joint that moves both geometries of the pair
    (upstream of both) does not change their distance, one that moves only one of them moves it by
    at most ``|dq_j| R_j(g)`` (R_j(g): chain offsets from the joint to the geometry plus its extent),
    and one that turns a round geometry about its own axis (an upright pedestal relative to the
    joint above it) changes nothing; a moving obstacle adds its speed. Kept in ``world.cache``."""

    def build():
        m, gm = world.model, world.geom_model
        G, nq = len(gm.geometryObjects), m.nq
        reach = np.zeros((G, nq))
        chain = np.zeros((G, nq), dtype=bool)  # joints that move the geometry
        turns = np.zeros((G, nq), dtype=bool)  # joints right below it that turn about its round axis
        children: dict[int, list[int]] = {}
        for j in range(1, m.njoints):
            children.setdefault(int(m.parents[j]), []).append(j)
        for g, (go, info) in enumerate(zip(gm.geometryObjects, world.geoms)):
            j, acc = go.parentJoint, _extent(info) + float(np.linalg.norm(go.placement.translation))
            for c in children.get(int(j), []):
                turns[g, m.joints[c].idx_q] = _round_on_axis(go, m.jointPlacements[c], _axis(m, c))
            while j > 0:
                chain[g, m.joints[j].idx_q] = True
                reach[g, m.joints[j].idx_q] = acc
                acc += float(np.linalg.norm(m.jointPlacements[j].translation))
                j = m.parents[j]
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


def certify_chords(world, Q: FloatArray, d: FloatArray, times: FloatArray, margin: float, reach: FloatArray,
                   v_max: float, max_depth: int = CERTIFY_DEPTH) -> Certificate:
    """Certify the chords between consecutive configurations Q (n, 12) (left then right joints)
    [rad] with clearances d (n,) [m] (the minimum over the pairs, or lower bounds of it) at times
    (n,) [s]: how many leading chords keep ``margin`` [m] along their whole motion (module
    docstring). Configurations below the margin themselves are the caller's to refuse; a chord
    ending at one is refused here.

    First the whole-World bound (``reach``, ``v_max``: :func:`motion_bounds`) with the given
    clearances. A chord it does not clear is taken pair by pair (:func:`pair_weights`): a pair whose
    own bound clears it with the given clearances is done; the others get their own distances at
    the chord's ends and are bisected alone — a pair cleared on an interval is not queried again
    inside it, so a level costs one placement and a few pair distances."""
    n = Q.shape[0] - 1
    if n <= 0:
        return Certificate(0, "", float("nan"), -1, 0)
    first_bad, reason, dist, pair = n, "", float("nan"), -1
    below = np.flatnonzero(d < margin)
    if below.size:  # a chord cannot be certified from an end already inside the margin
        first_bad = max(int(below[0]) - 1, 0)
        reason, dist = f"it ends {float(d[below[0]]):.4f} m from an obstacle, below {margin:.3f} m", float(d[below[0]])
    m = first_bad
    lb = 0.5 * (d[:m] + d[1 : m + 1] - motion_bound(reach, v_max, Q[1 : m + 1] - Q[:m], times[1 : m + 1] - times[:m]))
    W, vp = pair_weights(world)
    queries = 0
    for c in np.flatnonzero(lb < margin).tolist():  # in order: the first refused chord ends the prefix
        dq, dt = np.abs(Q[c + 1] - Q[c]), abs(float(times[c + 1] - times[c]))
        pairs = np.flatnonzero(0.5 * (d[c] + d[c + 1] - (W @ dq + vp * dt)) < margin)
        if pairs.size == 0:
            continue
        da = pair_distances_at(world, Q[c], float(times[c]), pairs)
        db = pair_distances_at(world, Q[c + 1], float(times[c + 1]), pairs)
        queries += 2
        stack = [(0.0, 1.0, Q[c], Q[c + 1], float(times[c]), float(times[c + 1]), pairs, da, db, 0)]
        why = ""
        while stack:
            sa, sb, qa, qb, ta, tb, pairs, da, db, depth = stack.pop()
            keep = 0.5 * (da + db - (np.abs(qb - qa) @ W[pairs].T + vp[pairs] * abs(tb - ta))) < margin
            if not keep.any():
                continue
            pairs, da, db = pairs[keep], da[keep], db[keep]
            if depth >= max_depth:
                why = f"it passes too close to the margin to be certified (chord {c}, {max_depth} halvings)"
                dist, pair = float("nan"), -1
                break
            qm, tm, sm = 0.5 * (qa + qb), 0.5 * (ta + tb), 0.5 * (sa + sb)
            dm = pair_distances_at(world, qm, tm, pairs)
            queries += 1
            j = int(np.argmin(dm))
            if dm[j] < margin:
                dist, pair = float(dm[j]), int(pairs[j])
                a, b = world.pair_names[pair]
                why = f"clearance {dist:.4f} m below {margin:.3f} m on chord {c} at s = {sm:.3f} ({a} – {b})"
                break
            stack.append((sm, sb, qm, qb, tm, tb, pairs, dm, db, depth + 1))
            stack.append((sa, sm, qa, qm, ta, tm, pairs, da, dm, depth + 1))
        if why:
            return Certificate(c, why, dist, pair, queries)
    return Certificate(first_bad, reason, dist, pair, queries)
