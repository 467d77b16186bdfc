"""Collision capsules of an arm's links, from its URDF.

Every arm link is modelled by capsules (a segment and a radius) attached to a joint frame: the
clearance kernel has exact closed forms for them, and a capsule is a conservative, smooth stand-in
for a link. Three sources, in order of preference:

* **The project's convention** (urdf/puma560.urdf): a ``<collision>`` whose geometry is a
  ``<cylinder>`` *is* a capsule of that radius and length (:func:`from_cylinders`).
* **Any URDF's collision geometry** (meshes, boxes, cylinders, spheres): one capsule per
  collision element that contains all of it (:func:`from_collision_geometry`, :func:`fit_capsule`):
  for a mesh, every vertex; for a box, its corners; for a cylinder, its two rims. The fit tries
  the principal axes of the points and the joint frame's axes, takes the minimum enclosing circle
  of the points projected along each, and keeps the smallest capsule; its radius is then padded
  by :data:`PAD` (coal's GJK works to ~1e-6 relative tolerance). A capsule containing a body's
  points contains their convex hull, so its distances are lower bounds of the body's (tested with
  coal against the meshes).
* **No collision geometry**: a capsule from each joint origin to the next (:func:`between_joints`),
  a coarse fallback, reported as such.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import coal
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..checks import as_array, real
from ..errors import ParameterError
from ..values import value_class

__all__ = ["PAD", "Capsule", "between_joints", "fit_capsule", "from_collision_geometry", "from_cylinders"]

FloatArray = npt.NDArray[np.float64]

PAD = 0.001  #: radius added to fitted capsules [m]
_GENERIC_RADIUS = 0.05  # [m] radius of the joint-to-joint fallback capsules
_MAX_COORD = 1e4  # [m] fit_capsule's points (squares stay far from overflow)


@value_class
@dataclass(frozen=True, slots=True)
class Capsule:
    """A collision capsule rigidly attached to a joint's frame.

    Attributes:
        name: role, e.g. ``"forearm"``.
        joint: Pinocchio joint index the capsule moves with (0 = the arm's base).
        radius: [m].
        length: segment length between the two cap centres [m].
        placement: (4, 4) pose of the capsule centre in the joint frame; the segment lies along
            its local z axis.
    """

    name: str
    joint: int
    radius: float
    length: float
    placement: FloatArray

    def segment(self, T_world_joint: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The capsule's segment end points in the frame that ``T_world_joint`` maps to [m]."""
        M = T_world_joint @ self.placement
        half = 0.5 * self.length * M[:3, 2]
        return M[:3, 3] - half, M[:3, 3] + half


def _frozen(M: FloatArray) -> FloatArray:
    M = np.array(M, dtype=np.float64)
    M.setflags(write=False)
    return M


def from_cylinders(model: pin.Model, urdf: Path) -> list[Capsule]:
    """Every ``<collision>`` cylinder of the URDF read as a capsule (the project's convention)."""
    root = ET.parse(urdf).getroot()
    frame_joint = {f.name: f.parentJoint for f in model.frames}
    caps: list[Capsule] = []
    for link in root.findall("link"):
        lname = link.get("name", "")
        if lname not in frame_joint:
            continue
        M_joint_link = model.frames[model.getFrameId(lname)].placement.homogeneous
        for col in link.findall("collision"):
            cyl = col.find("geometry/cylinder")
            if cyl is None:
                continue
            o = col.find("origin")
            xyz = [float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]
            rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
            M = np.eye(4)
            M[:3, :3] = pin.rpy.rpyToMatrix(*rpy)
            M[:3, 3] = xyz
            caps.append(Capsule(col.get("name") or f"{lname}_{len(caps)}", int(frame_joint[lname]),
                                float(cyl.get("radius")), float(cyl.get("length")), _frozen(M_joint_link @ M)))
    return caps


# ----------------------------------------------------------------------------- fitting
def _circle(points: FloatArray) -> tuple[FloatArray, float]:
    """Minimum enclosing circle of 2-D points (N, 2): (centre, radius). Welzl's algorithm, iterative
    (move-to-front), on a deterministic shuffle.

    Each "next point outside the circle" is found by one numpy pass over the points left, a
    conservative screen whose candidates are then tested one by one with the exact scalar test: the
    same circles as a point-by-point scan, in a fraction of the time (loading a Z1 took 4.5 s and a
    Kinova 9 s point by point, which ``dualpuma fk --robot ...`` paid on every call; 1.6 s each now)."""
    P = points[np.random.default_rng(0).permutation(len(points))]

    def from2(a, b):
        c = 0.5 * (a + b)
        return c, float(np.linalg.norm(a - c))

    def from3(a, b, c):
        bx, by, cx, cy = b[0] - a[0], b[1] - a[1], c[0] - a[0], c[1] - a[1]
        d = 2.0 * (bx * cy - by * cx)
        if abs(d) < 1e-18:  # collinear: the widest pair
            return max((from2(a, b), from2(a, c), from2(b, c)), key=lambda t: t[1])
        ux = (cy * (bx * bx + by * by) - by * (cx * cx + cy * cy)) / d
        uy = (bx * (cx * cx + cy * cy) - cx * (bx * bx + by * by)) / d
        centre = np.array([a[0] + ux, a[1] + uy])
        return centre, float(math.hypot(ux, uy))

    def inside(c, r, p):
        return float(np.linalg.norm(p - c)) <= r * (1 + 1e-12) + 1e-15

    def first_outside(c, r, lo: int, hi: int) -> int:
        """The first index in [lo, hi) whose point ``inside`` refuses, or -1."""
        if hi <= lo:
            return -1
        d = P[lo:hi] - c
        dist = np.sqrt(np.einsum("ij,ij->i", d, d))
        # a few ulps from np.linalg.norm's value: screen with a margin far above that
        maybe = np.flatnonzero(dist > (r * (1 + 1e-12) + 1e-15) * (1.0 - 1e-9))
        for k in maybe.tolist():
            if not inside(c, r, P[lo + k]):
                return lo + k
        return -1

    c, r = P[0].copy(), 0.0
    i = first_outside(c, r, 1, len(P))
    while i >= 0:
        c, r = P[i].copy(), 0.0
        j = first_outside(c, r, 0, i)
        while j >= 0:
            c, r = from2(P[i], P[j])
            k = first_outside(c, r, 0, j)
            while k >= 0:
                c, r = from3(P[i], P[j], P[k])
                k = first_outside(c, r, k + 1, j)
            j = first_outside(c, r, j + 1, i)
        i = first_outside(c, r, i + 1, len(P))
    return c, r


def fit_capsule(points: npt.ArrayLike, pad: float = PAD) -> tuple[FloatArray, float, float]:
    """A small capsule containing every point: ``(placement (4, 4), radius, length)`` with the
    segment along the placement's z axis, centred at its origin [m].

    Candidate axes: the points' principal axes and the coordinate axes; for each, the minimum
    enclosing circle of the points projected along it gives the axis line and radius R, and the
    segment is the shortest that keeps every point within R. The smallest volume wins; the radius
    is then padded by ``pad``.

    Args:
        points: (..., 3) [m], at least one, within 10 km of the origin.
        pad: added to the radius [m], 0 to 1.

    Raises:
        ParameterError: no points, non-finite or far-off points, a bad ``pad``.
    """
    X = as_array(points, "points")
    if X.ndim < 1 or X.shape[-1] != 3 or not np.all(np.isfinite(X)):
        raise ParameterError(f"points: expected finite values of shape (..., 3) [m], got shape {X.shape}")
    X = X.reshape(-1, 3)
    if len(X) == 0 or np.abs(X).max() > _MAX_COORD:
        raise ParameterError(f"points: expected at least one point within {_MAX_COORD:g} m of the origin")
    pad = real(pad, "pad", lo=0.0, hi=1.0, unit="m")
    X = np.unique(np.round(X, 12), axis=0)
    centroid = X.mean(axis=0)
    axes = list(np.eye(3))
    if len(X) >= 3:
        axes += list(np.linalg.svd(X - centroid, full_matrices=False)[2])
    best = None
    for d in axes:
        d = d / np.linalg.norm(d)
        e1 = np.cross(d, [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(d, e1)
        uv = np.column_stack([X @ e1, X @ e2])
        c2, R = _circle(uv) if len(X) > 1 else (uv[0], 0.0)
        R = max(R, 1e-9)
        t = X @ d
        rho2 = np.sum((uv - c2) ** 2, axis=1)
        slack = np.sqrt(np.maximum(R * R - rho2, 0.0))
        # every point within R of [t0, t1]: t1 >= t_v - slack_v and t0 <= t_v + slack_v for all v
        t0, t1 = float(np.min(t + slack)), float(np.max(t - slack))
        if t0 > t1:  # a ball of radius R about any axis point in [t1, t0] holds them all
            t0 = t1 = 0.5 * (t0 + t1)
        volume = math.pi * R * R * (t1 - t0) + 4.0 / 3.0 * math.pi * R**3
        if best is None or volume < best[0] - 1e-15:
            best = (volume, d, e1, e2, c2, R, t0, t1)
    _, d, e1, e2, c2, R, t0, t1 = best
    M = np.eye(4)
    M[:3, :3] = np.column_stack([e1, e2, d])
    M[:3, 3] = c2[0] * e1 + c2[1] * e2 + 0.5 * (t0 + t1) * d
    # the fitted radius, checked against the points themselves, then padded
    seg_a, seg_b = M[:3, 3] - 0.5 * (t1 - t0) * d, M[:3, 3] + 0.5 * (t1 - t0) * d
    r_need = float(np.max(_point_segment(X, seg_a, seg_b)))
    return _frozen(M), max(R, r_need) + pad, float(t1 - t0)


def _point_segment(X: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    ab = b - a
    L2 = float(ab @ ab)
    s = np.clip((X - a) @ ab / L2, 0.0, 1.0) if L2 > 0 else np.zeros(len(X))
    return np.linalg.norm(X - (a + s[:, None] * ab), axis=1)


def _shape_points(geom) -> tuple[FloatArray, float] | None:
    """``(points, extra radius)``: the collision shape (in its own frame) is within ``extra
    radius`` of the convex hull of the points (0 but for spheres); None for an unknown shape.
    Mesh vertices come as loaded (Pinocchio applies the URDF's mesh scale when loading)."""
    if isinstance(geom, coal.Box):
        h = np.asarray(geom.halfSide, dtype=np.float64)
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h, 0.0
    if isinstance(geom, coal.Sphere):
        return np.zeros((1, 3)), float(geom.radius)
    if isinstance(geom, coal.Capsule):
        hl = float(geom.halfLength)
        return np.array([[0.0, 0.0, -hl], [0.0, 0.0, hl]]), float(geom.radius)
    if isinstance(geom, coal.Cylinder):
        r, hl = float(geom.radius), float(geom.halfLength)
        ang = np.linspace(0.0, 2 * np.pi, 64, endpoint=False)
        rim = np.column_stack([r * np.cos(ang), r * np.sin(ang), np.zeros(64)]) / math.cos(math.pi / 64)
        return np.vstack([rim + [0, 0, hl], rim - [0, 0, hl]]), 0.0  # polygon circumscribing each rim
    vertices = getattr(geom, "vertices", None)
    if callable(vertices):
        return np.asarray(vertices(), dtype=np.float64).reshape(-1, 3), 0.0
    return None


def from_collision_geometry(gm: pin.GeometryModel) -> list[Capsule]:
    """One fitted capsule per collision object (a URDF's ``<collision>`` element: mesh, box,
    cylinder, sphere), in its parent joint's frame; objects of unknown shape are skipped."""
    caps: list[Capsule] = []
    for go in gm.geometryObjects:
        shape = _shape_points(go.geometry)
        if shape is None:
            continue
        pts, extra = shape
        P = go.placement.homogeneous
        pts_joint = pts @ P[:3, :3].T + P[:3, 3]
        M, r, length = fit_capsule(pts_joint)
        name = go.name.removesuffix("_0")
        caps.append(Capsule(name, int(go.parentJoint), r + extra, length, M))
    # tiny elements (a 1 cm tool marker box) inside a larger capsule of the same joint add nothing
    return [c for c in caps if not _covered(c, caps)]


def _covered(c: Capsule, caps: list[Capsule]) -> bool:
    """Is capsule c inside another capsule of the same joint?"""
    for o in caps:
        if o is c or o.joint != c.joint or o.radius < c.radius:
            continue
        a, b = o.segment(np.eye(4))
        ca, cb = c.segment(np.eye(4))
        if max(_point_segment(np.array([ca, cb]), a, b)) + c.radius <= o.radius:
            return True
    return False


def between_joints(model: pin.Model, tip_frame: int) -> list[Capsule]:
    """Coarse capsules from each joint origin to the next (and to the hand frame), radius 5 cm:
    the fallback for a URDF without collision geometry."""
    caps: list[Capsule] = []
    chain = list(range(1, model.njoints))
    for k, j in enumerate(chain):
        p1 = (model.jointPlacements[chain[k + 1]].translation if k + 1 < len(chain)
              else model.frames[tip_frame].placement.translation)
        length = float(np.linalg.norm(p1))
        if length < 1e-6:
            continue
        z = p1 / length
        x = np.cross(z, [1.0, 0.0, 0.0])
        if np.linalg.norm(x) < 1e-6:
            x = np.cross(z, [0.0, 1.0, 0.0])
        x /= np.linalg.norm(x)
        P = np.eye(4)
        P[:3, :3] = np.column_stack([x, np.cross(z, x), z])
        P[:3, 3] = 0.5 * p1
        caps.append(Capsule(f"{model.names[j]}", j, _GENERIC_RADIUS, length, _frozen(P)))
    return caps
