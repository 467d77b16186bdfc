"""Contact maps: the link pairs of one arm that are always close but can touch, checked on their meshes.

Some self pairs are closer than :data:`~.pairs.SELF_PAIR_THRESHOLD` in every configuration, so
:func:`~.pairs.classify_self_pairs` calls them ``adjacent`` and the capsule checks leave them out
(their capsules overlap in most configurations). For the PUMA 560 they meet at a joint. For the UR
arms three are two joints apart, and their collision meshes can touch: forearm–wrist_2 (wrist_1
bent back over the forearm), base–upper arm (the upper arm folded down by the base's back) and
wrist_1–wrist_3.

Their meshes' distance depends only on the two joints between them, so it is tabulated once on a
grid of those two joints over a whole turn each (:data:`GRID` cells per turn, periodic): a cell is
*blocked* unless the meshes are proven at least :data:`CONTACT_CLEARANCE` apart everywhere in it.
The proof is by branch and bound, as for the ``never`` self pairs: coal's distance of the two
meshes at a box's centre minus ``R_1 w_1 + R_2 w_2`` (``w_k`` the box's half-widths in the joints,
``R_k`` a bound on the distance of every vertex of the downstream mesh from joint k's axis: no
point moves more than that) is a lower bound over the box; a box below the clearance is split down
to one cell, and one whose centre plus that allowance is still below it is blocked whole.

A motion between two configurations in which neither joint turns back stays in the box their
joints span; it is certified when no blocked cell meets that box (:meth:`ContactMap.box_blocked`:
the box's count of blocked cells from a summed-area table, exact). The
tables of the known robots are derived by :func:`derive_contact_maps` and stored in
:data:`MAP_FILE` with the geometry they were derived for; they serve an arm whose geometry is that
one (:func:`~.pairs.stored_robot`: by geometry, so also a known arm read from its URDF file). Other
arms' close pairs are not mapped (``docs/robots.md``): deriving one takes 10 s to 2 min of coal queries.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from importlib import resources

import coal
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import RobotError
from ..kinematics.urdf import joint_axis
from .pairs import geometry_signature, stored_robot, verdicts

__all__ = ["CONTACT_CLEARANCE", "GRID", "MAP_FILE", "ContactMap", "close_pairs", "contact_maps",
           "derive_contact_maps", "map_file_entries", "write_map_file"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

CONTACT_CLEARANCE = 0.002  #: the meshes of a close pair must stay at least this far apart [m]
GRID = 1024  #: cells per turn of each joint (0.35 deg)
MAP_FILE = "contact_maps.npz"  #: where the known robots' maps are stored (model/data)
_START = 64  # cells per side of the branch and bound's first boxes (22.5 deg)
_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, slots=True)
class ContactMap:
    """The blocked cells of one close pair of an arm over the two joints between its links.

    Attributes:
        a, b: capsule (link) names, ``a`` nearer the base.
        joints: the two joints' indices in the arm's joint vector (0-5).
        cells: (GRID, GRID) bool, True where blocked (row = the first joint, column = the second,
            each from -pi).
        counts: (GRID + 1, GRID + 1) int32, the summed-area table of ``cells``: ``counts[i, j]`` blocked
            cells in rows < i and columns < j (a box's count from four entries).
    """

    a: str
    b: str
    joints: tuple[int, int]
    cells: BoolArray
    counts: npt.NDArray[np.int32]

    @classmethod
    def from_cells(cls, a: str, b: str, joints: tuple[int, int], blocked: BoolArray) -> ContactMap:
        """The map of a (GRID, GRID) blocked-cell array (its summed-area table built here)."""
        cells = np.array(blocked, dtype=bool)  # (a copy: frozen below)
        counts = np.zeros((GRID + 1, GRID + 1), dtype=np.int32)
        counts[1:, 1:] = cells.cumsum(axis=0, dtype=np.int32).cumsum(axis=1, dtype=np.int32)
        cells.setflags(write=False)
        counts.setflags(write=False)
        return cls(a, b, (int(joints[0]), int(joints[1])), cells, counts)

    def blocked(self, Q: FloatArray) -> BoolArray:
        """Per configuration Q (N, 6) [rad] of the arm: is it in a blocked cell?"""
        i, j = (_cell(Q[:, k]) for k in self.joints)
        return self.cells[i, j]

    def box_blocked(self, Qa: FloatArray, Qb: FloatArray, pad: int = 0) -> BoolArray:
        """Per pair of configurations (Qa[n], Qb[n]) (N, 6) [rad]: does a blocked cell meet the box
        their two joints span (each joint's cells between its two values, no turning back), grown by
        ``pad`` cells on every side? Exact: the box's count of blocked cells from the summed-area
        table (a box across the -pi seam in two pieces a joint)."""
        (r0, r1, r2, r3), (c0, c1, c2, c3) = (_pieces(*_span(Qa[:, k], Qb[:, k]), pad) for k in self.joints)
        C = self.counts
        total = np.zeros(Qa.shape[0], dtype=np.int64)
        for a, b in ((r0, r1), (r2, r3)):  # row pieces [a, b)
            for c, d in ((c0, c1), (c2, c3)):  # column pieces [c, d)
                total += C[b, d].astype(np.int64) - C[a, d] - C[b, c] + C[a, c]
        return total > 0


def _pieces(first: npt.NDArray[np.int64], count: npt.NDArray[np.int64], pad: int):
    """The cyclic cells [first - pad, first + count + pad) as two plain ranges [a, b), [c, d) of
    0..GRID (the second empty unless the range crosses the seam)."""
    n = np.minimum(count + 2 * pad, GRID)
    start = (first - pad) % GRID
    end = start + n
    return start, np.minimum(end, GRID), np.zeros_like(start), np.maximum(end - GRID, 0)


def _cell(x: FloatArray) -> npt.NDArray[np.int64]:
    """The grid cell of joint angles x [rad] (any turn)."""
    return np.floor(np.mod(x + math.pi, _TWO_PI) * (GRID / _TWO_PI)).astype(np.int64) % GRID


def _span(x0: FloatArray, x1: FloatArray) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """The cells [first, first + count) (cyclic) a joint passes moving between x0 and x1 [rad]
    without turning back: (first, count), the count at most GRID."""
    u = np.mod(np.minimum(x0, x1) + math.pi, _TWO_PI) * (GRID / _TWO_PI)  # the start in cells, unwrapped from there
    first = np.floor(u).astype(np.int64)
    last = np.floor(u + np.abs(x1 - x0) * (GRID / _TWO_PI)).astype(np.int64)
    return first % GRID, np.minimum(last - first + 1, GRID)


# ----------------------------------------------------------------------------- which pairs
def close_pairs(arm) -> tuple[tuple[str, str, tuple[int, int]], ...]:
    """The ``adjacent`` self pairs of ``arm`` two joints apart: (a, b, (its two joints' indices in
    q)), for an arm whose capsules were fitted to its collision geometry. Pairs on neighbouring
    joints meet at their joint and are not among them; nor are an arm's whose capsules are its
    geometry (the PUMA 560's cylinders: its forearm and wrist meet at the spherical wrist's centre)."""
    if not arm.capsule_source.startswith("fitted"):
        return ()
    caps = {c.name: c for c in arm.capsules}
    out = []
    for v in verdicts(arm):
        if v.kind != "adjacent":
            continue
        ja, jb = caps[v.a].joint, caps[v.b].joint
        if jb - ja == 2 and arm.model.parents[jb] == ja + 1 and arm.model.parents[ja + 1] == ja:
            out.append((v.a, v.b, (arm.model.joints[ja + 1].idx_q, arm.model.joints[jb].idx_q)))
    return tuple(out)


# ----------------------------------------------------------------------------- stored maps
def _file():
    return resources.files("dualpuma.model") / "data" / MAP_FILE


@cache
def _index() -> dict[str, tuple[str, FloatArray]]:
    """The stored robots' geometry signatures (:func:`~.pairs.geometry_signature` without the
    limits: a map covers whole turns of its joints, so the ``_joint_limited`` arms share it)."""
    with _file().open("rb") as f, np.load(f, allow_pickle=False) as z:
        return {r: (str(z[f"{r}/capsules"]), np.asarray(z[f"{r}/geometry"], dtype=float))
                for r in str(z["robots"]).split(",")}


@cache
def _robot_maps(robot: str) -> tuple[ContactMap, ...]:
    """The stored maps of one robot with a blocked cell (a pair proven clear everywhere needs no check)."""
    maps = []
    with _file().open("rb") as f, np.load(f, allow_pickle=False) as z:
        for a, b in (p.split("|") for p in str(z[f"{robot}/pairs"]).split(",") if p):
            key = f"{robot}/{a}|{b}"
            cells = np.unpackbits(z[key + "/cells"])[: GRID * GRID].reshape(GRID, GRID).astype(bool)
            if cells.any():
                maps.append(ContactMap.from_cells(a, b, tuple(int(x) for x in z[key + "/joints"]), cells))
    return tuple(maps)


def contact_maps(arm) -> tuple[ContactMap, ...] | None:
    """The contact maps of ``arm``: the stored ones of a known robot whose geometry is ``arm``'s
    (:func:`~.pairs.stored_robot`: also a known arm read from its URDF file); () when it has no close
    pair two joints apart; None when it has such pairs and no map (they are not checked)."""
    robot = stored_robot(arm, _index(), limits=False)
    if robot is not None:
        return _robot_maps(robot)
    return () if not close_pairs(arm) else None


# ----------------------------------------------------------------------------- derivation
class _MeshPair:
    """coal's distance of the meshes of a close pair as a function of its two joints."""

    def __init__(self, model: pin.Model, geom: pin.GeometryModel, a: str, b: str, joints: tuple[int, int]) -> None:
        by_name = {g.name.removesuffix("_0"): g for g in geom.geometryObjects}
        for name in (a, b):
            if name not in by_name or not callable(getattr(by_name[name].geometry, "vertices", None)):
                raise RobotError(f"contact map {a} – {b}: no collision mesh named {name!r} in the geometry given")
        self.ga, self.gb = by_name[a], by_name[b]
        self.model, self.data, self.iq = model, model.createData(), joints
        jb = self.gb.parentJoint
        for j in (self.ga.parentJoint + 1, jb):  # periodic in a turn: revolute joints only
            if not model.joints[j].shortname().startswith(("JointModelR", "JointModelRevolute")):
                raise RobotError(f"contact map {a} – {b}: joint {model.names[j]} is not revolute")
        # R of the second joint: the vertices' distance from its axis; of the first: from its origin
        V = np.asarray(self.gb.geometry.vertices(), dtype=float) @ self.gb.placement.rotation.T + self.gb.placement.translation
        u = joint_axis(model, jb)
        r2 = float(np.max(np.linalg.norm(V - np.outer(V @ u, u), axis=1)))
        r1 = float(np.linalg.norm(model.jointPlacements[jb].translation)) + float(np.max(np.linalg.norm(V, axis=1)))
        self.reach = np.array([r1, r2])
        self.request = coal.DistanceRequest()

    def distance(self, x: float, y: float) -> float:
        q = np.zeros(self.model.nq)
        q[self.iq[0]], q[self.iq[1]] = x, y
        pin.forwardKinematics(self.model, self.data, q)
        tf = []
        for g in (self.ga, self.gb):
            M = (pin.SE3.Identity() if g.parentJoint == 0 else self.data.oMi[g.parentJoint]) * g.placement
            tf.append(coal.Transform3s(M.rotation, M.translation))
        return float(coal.distance(self.ga.geometry, tf[0], self.gb.geometry, tf[1], self.request, coal.DistanceResult()))



def _blocked_cells(pair: _MeshPair, clearance: float) -> tuple[BoolArray, int]:
    """Branch and bound over the torus of the two joints: (blocked cells (GRID, GRID), coal queries)."""
    h = _TWO_PI / GRID
    L = float(pair.reach.sum())
    blocked = np.zeros((GRID, GRID), dtype=bool)
    stack = [(i, j, _START) for i in range(0, GRID, _START) for j in range(0, GRID, _START)]
    queries = 0
    while stack:
        i, j, s = stack.pop()
        d = pair.distance(-math.pi + (i + 0.5 * s) * h, -math.pi + (j + 0.5 * s) * h)
        queries += 1
        allowance = L * 0.5 * s * h
        if d - allowance >= clearance:
            continue
        if s == 1 or d + allowance < clearance:  # one cell, or below the clearance all through
            blocked[i : i + s, j : j + s] = True
            continue
        t = s // 2
        stack += [(i, j, t), (i + t, j, t), (i, j + t, t), (i + t, j + t, t)]
    return blocked, queries


def derive_contact_maps(arm, geom: pin.GeometryModel, clearance: float = CONTACT_CLEARANCE) -> dict:
    """Derive the maps of ``arm``'s close pairs (:func:`close_pairs`) from its collision meshes
    ``geom`` (a Pinocchio GeometryModel of the arm's model, e.g. :func:`~dualpuma.kinematics.urdf.read_arm`'s):
    ``{(a, b): (joints, blocked cells (GRID, GRID), coal queries)}``; a pair proven clear
    everywhere has no blocked cell.

    Raises:
        RobotError: a pair's link has no collision mesh in ``geom``, or a joint between is not revolute.
    """
    out = {}
    for a, b, joints in close_pairs(arm):
        blocked, queries = _blocked_cells(_MeshPair(arm.model, geom, a, b, joints), clearance)
        out[(a, b)] = (joints, blocked, queries)
    return out


def map_file_entries(arm, derived: dict) -> dict[str, npt.NDArray]:
    """The :data:`MAP_FILE` arrays of ``arm`` (its :func:`derive_contact_maps` result ``derived``),
    keyed ``robot/...``: its capsules and geometry (:func:`~.pairs.geometry_signature` without the
    limits), its pairs,
    and each pair's joints and packed blocked cells."""
    names, vec = geometry_signature(arm, limits=False)
    r = arm.robot
    out: dict[str, npt.NDArray] = {f"{r}/capsules": np.array(names), f"{r}/geometry": vec,
                                   f"{r}/pairs": np.array(",".join(f"{a}|{b}" for a, b in derived))}
    for (a, b), (joints, blocked, _) in derived.items():
        out[f"{r}/{a}|{b}/joints"] = np.array(joints, dtype=np.int64)
        out[f"{r}/{a}|{b}/cells"] = np.packbits(blocked.ravel())
    return out


def write_map_file(path, entries: dict[str, dict[str, npt.NDArray]]) -> None:
    """Write :data:`MAP_FILE` at ``path`` from each robot's :func:`map_file_entries` (by robot name).
    The shipped file was made by ``benchmarks/make_contact_maps.py`` (about 4 minutes on 2 cores)."""
    arrays: dict[str, npt.NDArray] = {"robots": np.array(",".join(entries))}
    for e in entries.values():
        arrays.update(e)
    np.savez_compressed(path, **arrays)

