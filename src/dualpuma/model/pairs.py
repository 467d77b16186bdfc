"""Which geometry pairs a World checks: self-collision inside one arm (a derived allowed list),
arm–arm, arm–obstacle, bar and floor pairs.

Self-collision. Every pair of capsules of one arm is put in one of four classes by
:func:`classify_self_pairs`, from the arm's own geometry and joint limits — not by hand:

* ``rigid`` — both on the same link: their distance never changes (shoulder–upper arm, elbow–forearm).
* ``adjacent`` — closer than ``threshold`` in *every* one of ``samples`` configurations drawn
  uniformly inside the joint limits: they meet at a joint (column–upper arm at the shoulder, upper
  arm–forearm at the elbow, forearm–gripper at the spherical wrist's centre). Checking them would
  refuse every configuration, as an SRDF's adjacent / "always in collision" exclusions say.
* ``never`` — *proven* never closer than ``threshold`` anywhere inside the joint limits, by branch and
  bound over the joints between the two links: a box of joint values is cleared when the distance at
  its centre minus ``sum_k R_k * half_width_k`` (``R_k`` bounds the distance of every point of the
  downstream capsule from joint k's axis, so no point moves more than that) is at least
  ``threshold``; otherwise it is split, and a box centre closer than ``threshold`` is a witness
  that the pair is reachable. A capsule lying on the axis of the joint next to it (pedestal on J1,
  gripper on J6) makes that joint irrelevant, which is used.
* ``checked`` — reachable: a configuration inside the limits brings them closer than
  ``threshold`` and they are not always that close. These pairs are checked by the World.

For the PUMA 560 seven pairs per arm are checked: the forearm, wrist and gripper against the pedestal
and the column, and the gripper against the shoulder (the wrist bent back over the shoulder). The verdicts for the known robots are stored in :data:`SELF_PAIR_TABLE`
(``model/data/self_pairs.json``, derived by :func:`classify_self_pairs` and re-derived by
tests/test_pairs.py, which fails if the table and the derivation ever disagree), each with the
geometry it was derived for (:func:`geometry_signature`; it serves an arm within
:data:`GEOMETRY_TOL` of it: :func:`stored_for`); any other arm (a URDF, or a known name
whose geometry differs) is classified when its first World is built, once per geometry. Pairs
proven ``never`` closer than :data:`SELF_PAIR_THRESHOLD` (50 mm) are left out, so a
margin larger than that would need them: :func:`self_pairs` adds back every excluded ``never`` pair
whose proven bound is below the margin it is given.

Floor pairs: every arm geometry whose distance to the floor can change. A geometry fixed to the
base, or a round one turning about its own axis when that axis is perpendicular to the floor (the
upright column), keeps a constant distance: it stands on the floor and is left out. A tilted base
keeps its column (and everything above it) against the floor.
"""

from __future__ import annotations

import hashlib
import heapq
import itertools
import json
import math
import threading
from dataclasses import dataclass
from importlib import resources

import coal
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..kinematics.urdf import joint_axis

__all__ = [
    "GEOMETRY_TOL",
    "SELF_PAIR_KINDS",
    "SELF_PAIR_TABLE",
    "SELF_PAIR_THRESHOLD",
    "TABLE_FILE",
    "SelfPair",
    "classify_self_pairs",
    "constant_to_floor",
    "derive_table",
    "excluded_bound",
    "fingerprint",
    "geometry_signature",
    "reach_radius",
    "same_geometry",
    "self_pairs",
    "stored_for",
    "stored_robot",
    "verdicts",
]

FloatArray = npt.NDArray[np.float64]

SELF_PAIR_THRESHOLD = 0.05  #: the distance that separates ``adjacent``/``never`` from ``checked`` [m]
SELF_PAIR_KINDS = ("rigid", "adjacent", "never", "checked")
_SAMPLES = 20_000
_MAX_BOXES = 400_000


@dataclass(frozen=True, slots=True)
class SelfPair:
    """The verdict on one capsule pair of an arm.

    Attributes:
        a, b: capsule names (``a`` on the link nearer the base).
        kind: one of :data:`SELF_PAIR_KINDS`.
        bound: ``never``: the proven lower bound of their distance [m]; ``checked``: the smallest
            distance found (a witness below the threshold); ``rigid``: their constant distance;
            ``adjacent``: the largest distance sampled (below the threshold).
    """

    a: str
    b: str
    kind: str
    bound: float



def _on_axis(M: FloatArray, p: FloatArray, u: FloatArray, tol: float = 1e-9) -> bool:
    """Does the capsule placed at M (its segment along M's z) lie on the line p + s u?"""
    z, c = M[:3, 2], M[:3, 3]
    return _cross_norm(z, u) < tol and _cross_norm(c - p, u) < tol


def _cross_norm(a: FloatArray, b: FloatArray) -> float:
    """|a x b| of two 3-vectors (scalar arithmetic: these are single vectors)."""
    (a0, a1, a2), (b0, b1, b2) = a.tolist(), b.tolist()
    return math.sqrt((a1 * b2 - a2 * b1) ** 2 + (a2 * b0 - a0 * b2) ** 2 + (a0 * b1 - a1 * b0) ** 2)


class _PairGeometry:
    """Distance of capsule b relative to capsule a as a function of the joints between them."""

    def __init__(self, arm, ia: int, ib: int) -> None:
        caps, model = arm.capsules, arm.model
        self.model, self.data = model, model.createData()
        self.a, self.b = caps[ia], caps[ib]
        self.sa, self.sb = coal.Capsule(self.a.radius, self.a.length), coal.Capsule(self.b.radius, self.b.length)
        ja, jb = self.a.joint, self.b.joint
        chain = []
        j = jb
        while j > ja:
            chain.append(j)
            j = model.parents[j]
        joints = sorted(chain)
        # a capsule on the axis of the joint beside it does not move with that joint
        if joints:
            first, last = joints[0], joints[-1]
            Mf = model.jointPlacements[first].homogeneous
            if _on_axis(self.a.placement, Mf[:3, 3], Mf[:3, :3] @ joint_axis(model, first)):
                joints = joints[1:]
            if joints and joints[-1] == last and _on_axis(self.b.placement, np.zeros(3), joint_axis(model, last)):
                joints = joints[:-1]
        self.joints = joints
        self.iq = [model.joints[j].idx_q for j in joints]
        # R_k: no point of capsule b is farther than this from joint k's axis
        ext = float(np.linalg.norm(self.b.placement[:3, 3])) + 0.5 * self.b.length + self.b.radius
        self.reach = np.array([
            ext + sum(float(np.linalg.norm(model.jointPlacements[x].translation)) for x in chain if x > k)
            for k in joints
        ])

    def distance(self, q_sub: FloatArray) -> float:
        q = np.zeros(self.model.nq)
        q[self.iq] = q_sub
        pin.forwardKinematics(self.model, self.data, q)
        out = []
        for c in (self.a, self.b):
            T = (np.eye(4) if c.joint == 0 else self.data.oMi[c.joint].homogeneous) @ c.placement
            out.append(coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3])))
        return float(coal.distance(self.sa, out[0], self.sb, out[1], coal.DistanceRequest(), coal.DistanceResult()))


def _branch_and_bound(g: _PairGeometry, lo: FloatArray, hi: FloatArray, threshold: float) -> tuple[str, float]:
    """("never", proven lower bound) or ("checked", a distance below ``threshold`` found)."""
    if not g.joints:
        d = g.distance(np.zeros(0))
        return ("never", d) if d >= threshold else ("checked", d)
    heap = [(0.0, 0, lo, hi)]
    proven = np.inf
    n = 0
    while heap:
        _, _, a, b = heapq.heappop(heap)
        c, hw = 0.5 * (a + b), 0.5 * (b - a)
        d = g.distance(c)
        if d < threshold:
            return "checked", d
        lb = d - float(g.reach @ hw)
        if lb >= threshold:
            proven = min(proven, lb)
            continue
        n += 1
        if n > _MAX_BOXES:  # not provable at this resolution: keep the pair (conservative)
            return "checked", d
        k = int(np.argmax(g.reach * hw))
        for half in (0, 1):
            a2, b2 = a.copy(), b.copy()
            if half:
                a2[k] = c[k]
            else:
                b2[k] = c[k]
            heapq.heappush(heap, (lb, n * 2 + half, a2, b2))  # the weakest boxes first: witnesses early
    return "never", proven


def classify_self_pairs(arm, threshold: float = SELF_PAIR_THRESHOLD, samples: int = _SAMPLES,
                        seed: int = 0) -> tuple[SelfPair, ...]:
    """Classify every capsule pair of ``arm`` (see the module docstring); deterministic for a seed.

    Args:
        arm: a :class:`~dualpuma.kinematics.arm.Arm`.
        threshold: the distance separating ``adjacent``/``never`` from ``checked`` [m].
        samples: configurations drawn uniformly inside the joint limits for the ``adjacent`` test.
        seed: the sampling seed.
    """
    caps = arm.capsules
    lim = np.asarray(arm.limits, float)
    rng = np.random.default_rng(seed)
    Q = rng.uniform(lim[:, 0], lim[:, 1], (samples, lim.shape[0]))
    out = []
    for ia, ib in itertools.combinations(range(len(caps)), 2):
        if caps[ia].joint > caps[ib].joint:
            ia, ib = ib, ia
        a, b = caps[ia], caps[ib]
        g = _PairGeometry(arm, ia, ib)
        if a.joint == b.joint:
            out.append(SelfPair(a.name, b.name, "rigid", g.distance(np.zeros(len(g.joints)))))
            continue
        sub = Q[:, g.iq]
        dmax = -np.inf
        for q in sub:
            dmax = max(dmax, g.distance(q))
            if dmax >= threshold:
                break
        if dmax < threshold:
            out.append(SelfPair(a.name, b.name, "adjacent", dmax))
            continue
        kind, bound = _branch_and_bound(g, lim[g.iq, 0].copy(), lim[g.iq, 1].copy(), threshold)
        out.append(SelfPair(a.name, b.name, kind, bound))
    return tuple(out)


#: where the verdicts for the known robots are stored (derived, then checked by tests/test_pairs.py)
TABLE_FILE = "self_pairs.json"
_derived: dict[str, tuple[SelfPair, ...]] = {}
_derived_lock = threading.Lock()


def geometry_signature(arm, limits: bool = True) -> tuple[str, FloatArray]:
    """What the verdicts depend on: the arm's capsule names and one vector of its joint placements,
    joint limits (unless ``limits`` is False: what a contact map depends on, :mod:`.contact`) and
    capsules (joint, radius, length, placement)."""
    m = arm.model
    parts = [np.array([m.jointPlacements[j].homogeneous for j in range(1, m.njoints)]).ravel()]
    if limits:
        parts.append(np.asarray(arm.limits, float).ravel())
    for c in arm.capsules:
        parts.append(np.concatenate([[c.joint, c.radius, c.length], np.asarray(c.placement, float).ravel()]))
    return "|".join(c.name for c in arm.capsules), np.concatenate(parts)


def fingerprint(arm) -> str:
    """A digest of :func:`geometry_signature` (rounded to 1e-9): the key of verdicts derived at run time."""
    return _digest(*geometry_signature(arm))


def _digest(names: str, vec: FloatArray) -> str:
    data = np.round(vec, 9) + 0.0  # + 0.0: -0.0 and 0.0 hash alike
    return hashlib.sha256(data.tobytes() + names.encode()).hexdigest()[:16]


#: a stored verdict serves an arm whose geometry vector is within this of the one it was derived for
#: [m, or dimensionless for rotation entries]: capsules fitted to meshes differ by more than rounding
#: between versions of the mesh tools, and a shift of 1e-6 moves a distance by a few micrometres at most
GEOMETRY_TOL = 1e-6


def _load_table() -> tuple[dict[str, tuple[SelfPair, ...]], dict[str, tuple[str, FloatArray]]]:
    doc = json.loads((resources.files("dualpuma.model") / "data" / TABLE_FILE).read_text(encoding="utf-8"))
    table = {r: tuple(SelfPair(a, b, k, float(d)) for a, b, k, d in e["pairs"]) for r, e in doc["robots"].items()}
    geometry = {r: (e["capsules"], np.array(e["geometry"], dtype=float)) for r, e in doc["robots"].items()}
    return table, geometry


#: verdicts of :func:`classify_self_pairs` for the known robots (threshold 50 mm, 20,000 samples,
#: seed 0), from :data:`TABLE_FILE`; tests/test_pairs.py re-derives them
SELF_PAIR_TABLE, _GEOMETRY = _load_table()


def stored_for(arm) -> bool:
    """Do the stored verdicts of ``arm.robot`` serve this arm: the same capsules, and a geometry
    vector (:func:`geometry_signature`) within :data:`GEOMETRY_TOL` of the one they were derived for?"""
    return _serves(arm.robot, *geometry_signature(arm))


def _serves(robot: str, names: str, vec: FloatArray) -> bool:
    stored = _GEOMETRY.get(robot)
    return stored is not None and same_geometry((names, vec), stored)


def same_geometry(a: tuple[str, FloatArray], b: tuple[str, FloatArray]) -> bool:
    """Are two :func:`geometry_signature` values alike: the same capsule names and vectors within
    :data:`GEOMETRY_TOL`?"""
    return a[0] == b[0] and a[1].shape == b[1].shape and bool(np.all(np.abs(a[1] - b[1]) <= GEOMETRY_TOL))


def stored_robot(arm, stored: dict[str, tuple[str, FloatArray]], limits: bool = True) -> str | None:
    """The robot of ``stored`` (robot name -> :func:`geometry_signature` with ``limits``) whose
    geometry is ``arm``'s: its own name first, then any other (a known arm loaded from its URDF file
    has another name), None if none."""
    sig = geometry_signature(arm, limits)
    for robot in sorted(stored, key=lambda r: r != arm.robot):
        if same_geometry(sig, stored[robot]):
            return robot
    return None


def verdicts(arm) -> tuple[SelfPair, ...]:
    """The self-pair verdicts of ``arm``: the stored ones of a known robot whose geometry is
    ``arm``'s (:func:`stored_robot`: a known arm read from its URDF file too), else derived once per
    geometry (a few seconds) and kept."""
    robot = stored_robot(arm, _GEOMETRY)
    if robot is not None:
        return SELF_PAIR_TABLE[robot]
    fp = _digest(*geometry_signature(arm))
    with _derived_lock:
        if fp not in _derived:
            _derived[fp] = classify_self_pairs(arm)
        return _derived[fp]


def derive_table(arms) -> dict:
    """The :data:`TABLE_FILE` document for ``arms`` (Arm objects, each under its ``robot`` name):
    their verdicts by :func:`classify_self_pairs` and the geometry they were derived for
    (:func:`geometry_signature`)."""
    robots = {}
    for a in arms:
        names, vec = geometry_signature(a)
        robots[a.robot] = {"capsules": names, "geometry": vec.tolist(),
                           "pairs": [[v.a, v.b, v.kind, round(v.bound, 6)] for v in classify_self_pairs(a)]}
    return {"threshold": SELF_PAIR_THRESHOLD, "samples": _SAMPLES, "seed": 0, "robots": robots}


def self_pairs(arm, margin: float = 0.0) -> tuple[tuple[str, str], ...]:
    """Capsule pairs of ``arm`` to check: the ``checked`` ones, plus ``never`` ones whose proven
    bound is below ``margin`` [m] (a margin above :data:`SELF_PAIR_THRESHOLD`)."""
    return tuple((v.a, v.b) for v in verdicts(arm)
                 if v.kind == "checked" or (v.kind == "never" and v.bound < margin))


def reach_radius(model: pin.Model, offsets: list[float], joint: int, placement: FloatArray, length: float,
                 radius: float) -> float:
    """Upper bound of the distance [m] from an arm's base origin to any point of a capsule (of
    ``length`` and ``radius`` placed at ``placement`` on ``joint``; ``offsets``: each joint's
    distance from its parent joint, by joint index): two arms' capsules whose bases are farther
    apart than both bounds and a margin never come within it (:class:`~.world.World`'s arm–arm pairs)."""
    r = 0.0
    j = joint
    while j > 0:
        r += offsets[j]
        j = model.parents[j]
    return r + float(np.linalg.norm(placement[:3, 3])) + 0.5 * length + radius


def excluded_bound(arm, margin: float = 0.0) -> float:
    """The smallest proven distance [m] of the ``never`` pairs :func:`self_pairs` leaves out for
    ``margin`` (inf if none): every margin up to it is fully checked inside ``arm``."""
    return min((v.bound for v in verdicts(arm) if v.kind == "never" and v.bound >= margin), default=math.inf)


def constant_to_floor(model: pin.Model, geom: pin.GeometryObject, floor_normal: FloatArray) -> bool:
    """True if the geometry's distance to a floor with this (world) normal can never change: it
    is fixed to the world, or it is round (capsule, sphere, cylinder) on the axis of a joint of the
    world whose axis is parallel to the normal (a column turning about the vertical)."""
    j = geom.parentJoint
    if j == 0:
        return True
    if model.parents[j] != 0:
        return False
    M = model.jointPlacements[j].homogeneous
    axis = M[:3, :3] @ joint_axis(model, j)
    if _cross_norm(axis, np.asarray(floor_normal, float)) > 1e-9:
        return False
    G = geom.placement.homogeneous
    round_ = isinstance(geom.geometry, (coal.Capsule, coal.Sphere, coal.Cylinder))
    return round_ and _on_axis(G, np.zeros(3), joint_axis(model, j))
