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
which is refused rather than guessed). All chords are subdivided together, level by level: a
level's open (interval, pair) entries of every chord get their midpoint distances in one call
(:func:`~dualpuma.collision.batch.entry_distances`: one placement per configuration, coal for the
open pairs only), and a configuration where two chords meet gets its pair distances once. The
first refused chord still ends the certified prefix. The result is independent of how finely the
planner sampled the chord.

For two geometries of one arm the bound holds as well: their relative pose depends only on the
joints between them, and each of those moves the downstream one by at most ``|dq_j| R_j``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import coal
import numpy as np
import numpy.typing as npt

from ..collision.batch import below_margin, entry_distances, min_clearance

__all__ = ["CERTIFY_DEPTH", "Certificate", "between_clearance", "certify_chords", "geometry_reach", "joint_reach",
           "motion_bound", "motion_bounds", "pair_weights"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

CERTIFY_DEPTH = 16  #: halvings of a chord before it is refused as too close to prove
_MAX_DEPTH = 48  # halvings at most (interval positions are integers in units of 2**-depth; a level halves:
#                 fewer queries, measured faster on the hard set than quarters or eighths)
_BOUNDS = "planning.motion_bounds"  # WorldCache keys
_WEIGHTS = "planning.pair_weights"
_REACH = "planning.geometry_reach"


@dataclass(frozen=True, slots=True)
class Certificate:
    """Result of :func:`certify_chords`.

    Attributes:
        n_ok: the leading chords certified (all of them when ``n_ok`` equals the number of chords).
        reason: why chord ``n_ok`` was refused ("" when all are certified).
        distance: the clearance that refused it [m] (NaN when certified, or refused at the depth).
        pair: index of the pair achieving ``distance`` into ``world.pair_names`` (-1 if none).
        queries: configurations whose pair distances were computed (chord ends and midpoints, each once).
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


def between_clearance(world, Qe: FloatArray, de: FloatArray, te: FloatArray, Q: FloatArray, times: FloatArray,
                      k: IntArray, margin: float, reach: FloatArray, v_max: float) -> tuple[FloatArray, IntArray]:
    """Clearance of poses Q (F, 12) [rad] at times (F,) [s] that lie between the step configurations
    ``Qe[k]`` and ``Qe[k + 1]`` (Qe (m + 1, 12) with clearances de [m] at times te [s]; ``de[0]``
    may be -inf when unknown), queried only where it can matter: a pose whose rigorous lower bound
    ``max(de[k] - D(Qe[k], q), de[k + 1] - D(q, Qe[k + 1]))`` (:func:`motion_bound`, the World's
    ``reach`` and ``v_max``) keeps ``margin`` is not queried; the others are asked only whether they
    keep it (:func:`~dualpuma.collision.batch.below_margin`), and only those that do not get their
    distance (:func:`~dualpuma.collision.batch.min_clearance`).

    Returns ``(d (F,) [m], pair (F,))``: the exact distance and its pair where it is below the
    margin; elsewhere a lower bound that keeps the margin (the bound, or ``margin`` itself) and pair -1.
    """
    lb = np.maximum(de[k] - np.abs(Q - Qe[k]) @ reach - v_max * np.abs(times - te[k]),
                    de[k + 1] - np.abs(Qe[k + 1] - Q) @ reach - v_max * np.abs(te[k + 1] - times))
    d, pair = lb, np.full(lb.shape, -1, dtype=np.int64)
    need = np.flatnonzero(lb < margin)
    if need.size:
        d[need] = margin
        hit = need[below_margin(world, Q[need], times[need], margin)]
        if hit.size:
            d[hit], pair[hit] = min_clearance(world, Q[hit], times[hit])
    return d, pair


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
    the chord's ends (each configuration's once, shared by the two chords that meet there) and are
    subdivided alone, all chords level by level: a level's open (interval, pair) entries get their
    interior points' distances in one batched call (:func:`~dualpuma.collision.batch.entry_distances`),
    and a pair cleared on an interval is not queried again inside it."""
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
    chords = np.flatnonzero(lb < margin)
    if chords.size == 0:
        return Certificate(first_bad, reason, dist, pair, 0)
    W, vp = pair_weights(world)
    bound = np.abs(Q[chords + 1] - Q[chords]) @ W.T + np.abs(times[chords + 1] - times[chords])[:, None] * vp  # (C, P)
    c, k = np.nonzero(0.5 * (d[chords, None] + d[chords + 1, None] - bound) < margin)
    if c.size == 0:
        return Certificate(first_bad, reason, dist, pair, 0)
    depth = min(max(int(max_depth), 0), _MAX_DEPTH)
    slot, why, d_bad, p_bad, queries = _subdivide(world, Q, times, margin, chords, bound, depth, c, k)
    if slot >= 0:
        return Certificate(int(chords[slot]), why, d_bad, p_bad, queries)
    return Certificate(first_bad, reason, dist, pair, queries)


def _subdivide(world, Q: FloatArray, times: FloatArray, margin: float, chords: IntArray, bound: FloatArray,
               max_depth: int, c: IntArray, k: IntArray) -> tuple[int, str, float, int, int]:
    """Halve the open entries (chord slot c into ``chords``, pair k) of all chords at once, level by
    level. ``bound`` (C, P): each chord's per-pair motion bound [m]. Returns the slot of the first
    refused chord (-1 if none), why, the refusing distance [m] (NaN at the depth) and pair (-1), and
    the configurations queried."""
    P = bound.shape[1]
    ends = np.concatenate([chords[c], chords[c] + 1]) * P + np.concatenate([k, k])  # (configuration, pair) keys
    mark = np.zeros((int(chords[-1]) + 2) * P, dtype=bool)  # endpoint distances: each key once, in key order
    mark[ends] = True
    keys = np.flatnonzero(mark)
    cfgs = keys // P
    new = _starts(cfgs)
    cfg = cfgs[new]
    de = np.array(entry_distances(world, Q[cfg], times[cfg], _cuts(new), (keys % P).tolist()))
    de = de[(np.cumsum(mark) - 1)[ends]]
    da, db = de[: c.size], de[c.size :]
    queries, span = int(cfg.size), 1 << max_depth
    lo = np.zeros(c.size, dtype=np.int64)  # interval starts in units of 2**-max_depth
    best, why, d_bad, p_bad, depth = chords.size, "", float("nan"), -1, 0
    while True:
        keep = 0.5 * (da + db - bound[c, k] * 2.0**-depth) < margin
        keep &= c < best  # chords after the first refused one are not needed
        c, k, lo, da, db = c[keep], k[keep], lo[keep], da[keep], db[keep]
        if c.size == 0:
            break
        if depth >= max_depth:
            best = int(c.min())
            why = f"it passes too close to the margin to be certified (chord {int(chords[best])}, {max_depth} halvings)"
            d_bad, p_bad = float("nan"), -1
            break
        half = 1 << (max_depth - depth - 1)
        pos = lo + half  # the open intervals' midpoints
        flat = c * span + pos  # the midpoints' keys, queried in key order (each once)
        order = np.argsort(flat, kind="stable")
        sk = flat[order]
        new = _starts(sk)
        ukeys = sk[new]
        uc, s = chords[ukeys // span], (ukeys % span) * (1.0 / span)
        Qm = Q[uc] + s[:, None] * (Q[uc + 1] - Q[uc])
        tm = times[uc] + s * (times[uc + 1] - times[uc])
        dm = np.empty(flat.size)
        dm[order] = entry_distances(world, Qm, tm, _cuts(new), k[order].tolist())
        queries += int(ukeys.size)
        bad = np.flatnonzero(dm < margin)
        if bad.size:
            first = int(c[bad].min())
            if first < best:  # its point below the margin nearest the chord's start
                sel = bad[c[bad] == first]
                i = sel[np.lexsort((dm[sel], pos[sel]))[0]]
                best, d_bad, p_bad = first, float(dm[i]), int(k[i])
                a, b = world.pair_names[p_bad]
                why = (f"clearance {d_bad:.4f} m below {margin:.3f} m on chord {int(chords[best])} at "
                       f"s = {pos[i] / span:.3f} ({a} – {b})")
        da, db = np.stack([da, dm], axis=1).reshape(-1), np.stack([dm, db], axis=1).reshape(-1)  # the halves' ends
        c, k = np.repeat(c, 2), np.repeat(k, 2)
        lo = np.stack([lo, pos], axis=1).reshape(-1)
        depth += 1
    return (best if best < chords.size else -1), why, d_bad, p_bad, queries


def _starts(sorted_ids: IntArray) -> npt.NDArray[np.bool_]:
    """Where a new value starts in ``sorted_ids`` (True at 0 and wherever it differs from the previous)."""
    new = np.empty(sorted_ids.size, dtype=bool)
    new[:1] = True
    np.not_equal(sorted_ids[1:], sorted_ids[:-1], out=new[1:])
    return new


def _cuts(new: npt.NDArray[np.bool_]) -> list[int]:
    """Offsets of the groups that start where ``new`` is True, and the end (for grouped queries)."""
    cuts = np.flatnonzero(new).tolist()
    cuts.append(new.size)
    return cuts
