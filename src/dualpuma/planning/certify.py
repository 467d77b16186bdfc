"""Certified motion between checked configurations (conservative advancement by bisection).

Two motions between consecutive configurations ``a`` and ``b`` of both arms (12 joints), each
traversed between their times, can be certified:

* a **joint chord** (the straight line in the joints): what a joint controller executes between
  two samples of a timed trajectory (:func:`~dualpuma.planning.timing.time_plan`);
* the **bar's path** (``closed_chain``): the arms holding the bar while it moves along its
  geodesic from the pose it has at ``a`` to the one at ``b`` (translation linear, rotation along
  the shortest arc), each arm continuing its IK branch. This is what the arms do between a plan's
  rows: a timed trajectory follows it, not the joint chord, which leaves the closed chain (by up to
  millimetres at the hands) and can pass an obstacle on the other side of the margin.

Along either, no point of any geometry moves, relative to any other geometry, by more than
``D(a, b) = sum_j |q_j(b) - q_j(a)| R_j + v_max |t_b - t_a|`` (:mod:`.reach`), provided no joint
reverses between a and b (always true on a chord). A signed distance changes by at most the
relative displacement of the two bodies, so with clearances ``d_a``, ``d_b`` at the ends the
clearance anywhere between is at least

    max(d_a - D(a, x), d_b - D(x, b)) >= (d_a + d_b - D(a, b)) / 2.

:func:`certify_chords` accepts a motion when that bound keeps ``margin``; otherwise it queries the
midpoint and recurses on both halves, like a conservative-advancement check: a midpoint closer than
the margin refuses the motion (with the pair), and so does one still unresolved after ``max_depth``
halvings (it passes too close to the margin to be proved, which is refused rather than guessed).
On a chord the midpoint is joint-linear and each half's bound is half of it. On the bar's path the
midpoint is the path's own (the arms solved at the bar's midpoint pose,
:func:`~dualpuma.kinematics.bar_path.hold_bar`) and each half gets the bound of its own two ends
(the two add up to at least the whole's). **Assumption** (the bar's path only): within each interval that the
bound clears, no joint turns back; a joint that did would move further than its end-to-end change.
Halving makes such intervals short, and a joint's turning point inside one changes the bound only
to second order in its length; it is not proved.

All motions are subdivided together, level by level: a level's open (interval, pair) entries get
their midpoint distances in one call (:func:`~dualpuma.collision.batch.entry_distances`: one
placement per configuration, coal for the open pairs only), and a configuration where two motions
meet gets its pair distances once. The first refused one still ends the certified prefix. The
result is independent of how finely the planner sampled the motion.

For two geometries of one arm the bound holds as well: their relative pose depends only on the
joints between them, and each of those moves the downstream one by at most ``|dq_j| R_j``.

On the bar's path the bar and the geometry on both arms' last joints (the PUMA's grippers) move
with the object frame as one rigid body along the geodesic (:func:`~.reach.rigid_pairs`), so a
bound holds for them that needs no assumption on the joints: no point of such geometry moves by
more than ``G = |dp| + theta rho`` over the whole motion (the object frame's translation and
rotation angle, rho the geometry's radius about the frame's origin), and by that times the fraction
over part of it. With ``closed_chain``, at every stage, such geometry against geometry no joint
moves (obstacles, the floor, the pedestals) takes ``G`` (plus a moving obstacle's share) instead of
the joint bound; the two grippers' pair takes nothing (their distance never changes); such geometry
against an arm's link that does not ride with the bar takes the smaller of the joint bound and
``G`` plus that link's own motion (its joints' share). The whole-World bound is ``max(D, G)`` with
the largest such radius, and each half gets half of ``G``. So the bar and the grippers against
obstacles, the floor, the pedestals and each other are certified without the assumption above,
which then concerns only pairs with a link that does not ride with the bar.

``G`` is also mostly the tighter bound. On the benchmark's bar paths near the hard set's obstacles
it is a sixth of the joint bound at the median for the bar (0.26 at p90; never the larger in 1,009
steps) and 0.30 for the grippers (0.50 at p90; the larger in 18 of 2,018 steps, a gripper against
the floor or its own arm's pedestal, which the joint bound sees turn about their own axis). Against
the links the smaller of the two is 0.45 of the joint bound at the median.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..collision.batch import below_margin, entry_distances, min_clearance
from ..collision.contact import first_contact_chord
from ..kinematics.bar_path import hold_bar
from ..kinematics.dual import bar_poses
from ..lie import angles, slerp_pairs
from ..units import below_text
from .reach import BOTH, FIXED, JOINTS, motion_bound, pair_weights, rigid_pairs

__all__ = ["CERTIFY_DEPTH", "Certificate", "between_clearance", "certify_chords"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

CERTIFY_DEPTH = 16  #: halvings of a chord before it is refused as too close to prove
_MAX_DEPTH = 48  # halvings at most (interval positions are integers in units of 2**-depth; a level halves:
#                 fewer queries, measured faster on the hard set than quarters or eighths)
_GRID = 5  # levels of the bar's path solved at once when a chord is first halved (closed_chain; 3 and 4 measured slower)


@dataclass(frozen=True, slots=True)
class Certificate:
    """Result of :func:`certify_chords`.

    Attributes:
        n_ok: the leading chords certified (all of them when ``n_ok`` equals the number of chords).
        reason: why chord ``n_ok`` was refused ("" when all are certified).
        distance: the clearance that refused it [m] (NaN when certified, refused at the depth,
            where the arms cannot hold the bar on its path (``closed_chain``), or for self-contact).
        pair: index of the pair achieving ``distance`` into ``world.pair_names`` (-1 if none).
        queries: configurations whose pair distances were computed (chord ends and midpoints, each once).
    """

    n_ok: int
    reason: str
    distance: float
    pair: int
    queries: int


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


def certify_chords(world, Q: FloatArray, d: FloatArray, times: FloatArray, margin: float, reach: FloatArray,
                   v_max: float, max_depth: int = CERTIFY_DEPTH, closed_chain: bool = False) -> Certificate:
    """Certify the chords between consecutive configurations Q (n, 12) (left then right joints)
    [rad] with clearances d (n,) [m] (the minimum over the pairs, or lower bounds of it) at times
    (n,) [s]: how many leading chords keep ``margin`` [m] along their whole motion (module
    docstring). Configurations below the margin themselves are the caller's to refuse; a chord
    ending at one is refused here.

    First the whole-World bound (``reach``, ``v_max``: :func:`motion_bounds`; with
    ``closed_chain`` at least that of the geometry riding with the bar, :func:`~.reach.rigid_pairs`)
    with the given clearances. A chord it does not clear is taken pair by pair (:func:`pair_weights`): a pair whose
    own bound clears it with the given clearances is done; the others get their own distances at
    the chord's ends (each configuration's once, shared by the two chords that meet there) and are
    subdivided alone, all chords level by level: a level's open (interval, pair) entries get their
    interior points' distances in one batched call (:func:`~dualpuma.collision.batch.entry_distances`),
    and a pair cleared on an interval is not queried again inside it.

    With ``closed_chain`` the motion between two configurations is not their joint chord but the
    arms holding the bar along its geodesic between the poses they hold it at (the path
    :func:`~dualpuma.planning.timing.time_plan` executes): each midpoint is that path's, both arms
    solved there continuing the interval's start (:func:`~dualpuma.kinematics.bar_path.hold_bar`), and
    each half gets its own bound from its own ends (module docstring)."""
    n = Q.shape[0] - 1
    if n <= 0:
        return Certificate(0, "", float("nan"), -1, 0)
    first_bad, reason, dist, pair = n, "", float("nan"), -1
    below = np.flatnonzero(d < margin)
    if below.size:  # a chord cannot be certified from an end already inside the margin
        first_bad = max(int(below[0]) - 1, 0)
        reason, dist = f"it ends {below_text(float(d[below[0]]), margin)} m from an obstacle, below {margin:.3f} m", float(d[below[0]])
    touch, why = first_contact_chord(world, Q[: first_bad + 1], closed_chain)  # close pairs on their meshes (contact maps)
    if touch < first_bad:
        first_bad, reason, dist = touch, why, float("nan")
    m = first_bad
    D = motion_bound(reach, v_max, Q[1 : m + 1] - Q[:m], times[1 : m + 1] - times[:m])
    if closed_chain:  # the bar and the hands ride with the object frame along its geodesic: their own bound
        rig = rigid_pairs(world)
        poses = bar_poses(world, Q[: m + 1])
        dp = np.linalg.norm(poses[1:, :3, 3] - poses[:-1, :3, 3], axis=1)  # (m,) [m]
        th = angles(poses[:-1, :3, :3], poses[1:, :3, :3])  # (m,) [rad]
        D = np.maximum(D, dp + th * rig.rho_fixed + v_max * np.abs(times[1 : m + 1] - times[:m]))
    lb = 0.5 * (d[:m] + d[1 : m + 1] - D)
    chords = np.flatnonzero(lb < margin)
    if chords.size == 0:
        return Certificate(first_bad, reason, dist, pair, 0)
    W, vp = pair_weights(world)
    dt = np.abs(times[chords + 1] - times[chords])[:, None]
    dq = np.abs(Q[chords + 1] - Q[chords])
    held = None
    if not closed_chain:
        bound = dq @ W.T + dt * vp  # (C, P)
    else:  # each half's bounds from its own ends; the pairs riding with the bar from its motion
        rigid = dp[chords, None] + th[chords, None] * rig.rho  # (C, P): the rigid member's motion [m]
        bound = _rigid_bounds(rig.kind, rigid, dq @ W.T, dq @ rig.W_other.T) + dt * vp
        held = (W, vp, rig, dp, th, poses)
    c, k = np.nonzero(0.5 * (d[chords, None] + d[chords + 1, None] - bound) < margin)
    if c.size == 0:
        return Certificate(first_bad, reason, dist, pair, 0)
    depth = min(max(int(max_depth), 0), _MAX_DEPTH)
    slot, why, d_bad, p_bad, queries = _subdivide(world, Q, times, margin, chords, bound, depth, c, k, held)
    if slot >= 0:
        return Certificate(int(chords[slot]), why, d_bad, p_bad, queries)
    return Certificate(first_bad, reason, dist, pair, queries)


def _subdivide(world, Q: FloatArray, times: FloatArray, margin: float, chords: IntArray, bound: FloatArray,
               max_depth: int, c: IntArray, k: IntArray, held=None) -> tuple[int, str, float, int, int]:
    """Halve the open entries (chord slot c into ``chords``, pair k) of all chords at once, level by
    level. ``bound`` (C, P): each chord's per-pair motion bound [m]. ``held``: None (joint chords),
    or, to halve the bar's path instead, (the pair weights W (P, 12) and speeds (P,), the pairs
    riding with the bar (:func:`~.reach.rigid_pairs`), the object frame's translation [m] and
    rotation angle [rad] over each row's step (>= n - 1,) (the rigid members' bound, halved with
    each half), and the bar's poses at the rows (>= n, 4, 4)). Returns the
    slot of the first refused chord (-1 if none), why, the refusing distance [m] (NaN at the depth
    or where the arms cannot hold the bar) and pair (-1), and the configurations queried."""
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
    eb = bound[c, k]  # each entry's motion bound [m] (a joint chord's halves: half of it)
    if held is not None:  # the bar's path, solved where the halving needs it; each entry's ends in its table
        W, vp, rig, dp, th, poses = held
        path = None  # made when the first midpoints are needed, for the chords still open then
        timed = bool(np.any(vp))
        ia, ib = chords[c], chords[c] + 1
        eg = dp[chords[c]] + th[chords[c]] * rig.rho[k]  # the rigid member's motion over the interval [m]
    best, why, d_bad, p_bad, depth = chords.size, "", float("nan"), -1, 0
    while True:
        keep = 0.5 * (da + db - eb) < margin
        keep &= c < best  # chords after the first refused one are not needed
        c, k, lo, da, db, eb = c[keep], k[keep], lo[keep], da[keep], db[keep], eb[keep]
        if held is not None:
            ia, ib, eg = ia[keep], ib[keep], eg[keep]
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
        tm = times[uc] + s * (times[uc + 1] - times[uc])
        lost = None  # (the bar's path) entries whose midpoint the arms cannot hold
        if held is None:
            Qm = Q[uc] + s[:, None] * (Q[uc + 1] - Q[uc])
        else:  # the arms holding the bar on its path there
            uid = np.empty(flat.size, dtype=np.int64)
            uid[order] = np.cumsum(new) - 1
            if path is None:
                # the open slots, sorted (np.unique would import numpy.ma: 12 ms on a process's first plan)
                path = _HeldPath(world, Q, poses, chords, np.flatnonzero(np.bincount(c)), max_depth)
            Qm, held_ok, rows = path.midpoints(ukeys // span, ukeys % span, depth, ia[order[new]])
            im = rows[uid]  # each entry's midpoint in the table
            lost = ~held_ok[uid]
        dm = np.empty(flat.size)
        dm[order] = entry_distances(world, Qm, tm, _cuts(new), k[order].tolist())
        queries += int(ukeys.size)
        if lost is not None:
            dm[lost] = -np.inf  # the path leaves the arms' reach or limits: refused there
        bad = np.flatnonzero(dm < margin)
        if bad.size:
            first = int(c[bad].min())
            if first < best:  # its point below the margin nearest the chord's start
                sel = bad[c[bad] == first]
                i = sel[np.lexsort((dm[sel], pos[sel]))[0]]
                best, p_bad = first, int(k[i])
                where = f"chord {int(chords[best])} at s = {pos[i] / span:.3f}"
                if lost is not None and lost[i]:
                    d_bad, p_bad = float("nan"), -1
                    why = f"on the bar's path the arms cannot hold it within their reach and joint limits ({where})"
                else:
                    d_bad = float(dm[i])
                    a, b = world.pair_names[p_bad]
                    why = f"clearance {below_text(d_bad, margin)} m below {margin:.3f} m on {where} ({a} – {b})"
        if held is None:
            eb = np.repeat(0.5 * eb, 2)
        else:  # each half's own bound from its own ends (the path is not straight in the joints)
            eg = 0.5 * eg  # the rigid member's motion: half of it each half
            kind, Wk, Wo = rig.kind[k], W[k], rig.W_other[k]
            dq_l, dq_r = path.moves(ia, im), path.moves(im, ib)
            left = _rigid_bounds(kind, eg, np.einsum("ij,ij->i", dq_l, Wk), np.einsum("ij,ij->i", dq_l, Wo))
            right = _rigid_bounds(kind, eg, np.einsum("ij,ij->i", dq_r, Wk), np.einsum("ij,ij->i", dq_r, Wo))
            eg = np.repeat(eg, 2)
            if timed:  # a moving obstacle's speed times each half's duration
                t0, t1 = times[chords[c]], times[chords[c] + 1]
                ta, tb = t0 + lo * (1.0 / span) * (t1 - t0), t0 + (lo + 2 * half) * (1.0 / span) * (t1 - t0)
                left += vp[k] * np.abs(tm[uid] - ta)
                right += vp[k] * np.abs(tb - tm[uid])
            eb = _halves(left, right)
            ia, ib = _halves(ia, im), _halves(im, ib)
        da, db = _halves(da, dm), _halves(dm, db)  # the halves' ends
        c, k = np.repeat(c, 2), np.repeat(k, 2)
        lo = _halves(lo, pos)
        depth += 1
    return (best if best < chords.size else -1), why, d_bad, p_bad, queries


def _rigid_bounds(kind, rigid: FloatArray, joints: FloatArray, other: FloatArray) -> FloatArray:
    """Pair motion bounds along the bar's path [m] by :attr:`~.reach.RigidPairs.kind` (broadcast
    with the others): from the joints (``joints``), from the rigid member's motion alone
    (``rigid``), none (both ride with the bar), or the smaller of the joint bound and the rigid
    member's motion plus the link's own (``other``). A moving obstacle's share is the
    caller's."""
    out = np.minimum(joints, rigid + other)  # LINK (np.select's broadcasting costs more than the arithmetic here)
    np.copyto(out, joints, where=kind == JOINTS)
    np.copyto(out, rigid, where=kind == FIXED)
    np.copyto(out, 0.0, where=kind == BOTH)
    return out


class _HeldPath:
    """The arms holding the bar along its geodesic between the ends of chords being halved
    (:func:`_subdivide` with ``held``): a table of configurations, the chords' ends first. The first
    :data:`_GRID` levels of every open chord are solved at once when it is made, with the first
    midpoints (2**_GRID - 1 poses a chord, each continuing the joint chord's point at its fraction,
    which is within the closed chain's drift of it); deeper midpoints level by level, each
    continuing its interval's start. ``poses``: the bar's poses at the rows (at least at the open
    chords' ends)."""

    def __init__(self, world, Q: FloatArray, poses: FloatArray, chords: IntArray, slots: IntArray,
                 max_depth: int) -> None:
        self.world, self.poses, self.chords, self.max_depth = world, poses, chords, max_depth
        self.levels = min(_GRID, max_depth)
        g = (1 << self.levels) - 1  # interior points a chord
        self.base = Q.shape[0]
        self.slot_row = np.full(chords.size, -1, dtype=np.int64)
        self.slot_row[slots] = np.arange(slots.size) * g
        cs = np.repeat(chords[slots], g)
        f = np.tile(np.arange(1, g + 1) / (g + 1), slots.size)
        near = Q[cs] + f[:, None] * (Q[cs + 1] - Q[cs])
        grid, self.grid_ok = hold_bar(world, slerp_pairs(poses[cs], poses[cs + 1], f), near)
        self.table = np.concatenate([Q, grid])

    def midpoints(self, slot: IntArray, pos: IntArray, depth: int, start: IntArray):
        """The configurations at positions ``pos`` (units of 2**-max_depth) of chord slots ``slot``
        at halving ``depth``, the intervals starting at table rows ``start``: ``(Q (U, 12), held (U,),
        their table rows (U,))``."""
        if depth < self.levels:
            j = pos >> (self.max_depth - self.levels)
            rows = self.base + self.slot_row[slot] + j - 1
            return self.table[rows], self.grid_ok[rows - self.base], rows
        c, s = self.chords[slot], pos * 2.0**-self.max_depth
        Qm, ok = hold_bar(self.world, slerp_pairs(self.poses[c], self.poses[c + 1], s), self.table[start])
        rows = self.table.shape[0] + np.arange(Qm.shape[0])
        self.table = np.concatenate([self.table, Qm])
        return Qm, ok, rows

    def moves(self, a: IntArray, b: IntArray) -> FloatArray:
        """Each joint's change |q(b) - q(a)| between table rows a and b (E, 12) [rad] (weighted by a
        pair's joint weights, :func:`~.reach.pair_weights`, it bounds the pair's motion)."""
        return np.abs(self.table[b] - self.table[a])


def _halves(first: npt.NDArray, second: npt.NDArray) -> npt.NDArray:
    """Each entry's two halves, interleaved: ``first[0], second[0], first[1], ...`` (2 E,)."""
    out = np.empty(2 * first.size, dtype=first.dtype)
    out[0::2] = first
    out[1::2] = second
    return out


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
