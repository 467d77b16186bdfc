"""World placements of every collision geometry for many configurations at once (vectorised FK).

:class:`Placements` reads a World's collision geometries (shape class, sizes, placement in their
joint) from coal once, then computes, for a block of N configurations, every geometry's world
rotation and translation with numpy (what ``pin.updateGeometryPlacements`` does for one
configuration): the joints' frames by :class:`~.kinematics.JointChain`, then each geometry's
placement as its joint's frame times a constant, written out term by term
(:func:`~.kinematics.constant_product`); geometries on the universe joint keep their constant
placements. The bar is placed by ``T_world_object @ T_object_bar`` when object poses are given,
moving obstacles by their pose at
time t. Used by the clearance kernel (:mod:`.kernel`); checked against Pinocchio in
tests/test_kernel.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import coal
import numpy as np
import numpy.typing as npt

from .kinematics import JointChain, constant_product, product_terms

__all__ = ["Buffers", "Geom", "Placements", "bounding_capsule"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Geom:
    """A collision geometry: shape class and sizes, parent joint and placement in it."""

    kind: str  # "round" (capsule/sphere), "box", "halfspace" or "other"
    joint: int
    R: FloatArray  # placement rotation (3, 3)
    p: FloatArray  # placement translation (3,)
    radius: float = 0.0  # round [m]
    half_length: float = 0.0  # round: half the segment length [m]
    half: FloatArray = field(default_factory=lambda: np.zeros(3))  # box half extents [m]
    normal: FloatArray = field(default_factory=lambda: np.zeros(3))  # halfspace {x: n.x <= offset}
    offset: float = 0.0

    @property
    def outer(self) -> float:
        """Radius of a ball about the origin that contains the geometry [m] (inf if unbounded)."""
        if self.kind == "round":
            return self.radius + self.half_length
        if self.kind == "box":
            return float(np.linalg.norm(self.half))
        return np.inf

    @property
    def inner(self) -> float:
        """Radius of a ball about the origin inside the geometry [m] (-inf if unknown)."""
        if self.kind == "round":
            return self.radius
        if self.kind == "box":
            return float(self.half.min())
        return -np.inf


def _geom_of(go) -> Geom:
    shape, M = go.geometry, go.placement
    R, p, j = (
        np.array(M.rotation, dtype=np.float64),
        np.array(M.translation, dtype=np.float64),
        int(go.parentJoint),
    )
    if isinstance(shape, coal.Capsule):
        return Geom(
            "round", j, R, p, radius=float(shape.radius), half_length=float(shape.halfLength)
        )
    if isinstance(shape, coal.Sphere):
        return Geom("round", j, R, p, radius=float(shape.radius))
    if isinstance(shape, coal.Box):
        return Geom("box", j, R, p, half=np.array(shape.halfSide, dtype=np.float64))
    if isinstance(shape, coal.Halfspace):
        return Geom(
            "halfspace", j, R, p, normal=np.array(shape.n, dtype=np.float64), offset=float(shape.d)
        )
    return Geom("other", j, R, p)


def bounding_capsule(half: FloatArray) -> tuple[FloatArray, FloatArray, float]:
    """Thinnest capsule around a box along its longest axis: (start, vector, radius) in its frame."""
    m = int(np.argmax(half))
    start, vec = np.zeros(3), np.zeros(3)
    start[m], vec[m] = -half[m], 2.0 * half[m]
    others = np.delete(half, m)
    return start, vec, float(np.hypot(others[0], others[1]))


class Buffers:
    """Named reusable arrays (contiguous views of cached flat buffers)."""

    def __init__(self) -> None:
        self._b: dict[str, FloatArray] = {}

    def __call__(self, name: str, shape: tuple[int, ...]) -> FloatArray:
        size = math.prod(shape)
        buf = self._b.get(name)
        if buf is None or buf.size < size:
            buf = self._b[name] = np.empty(max(size, 1))
        return buf[:size].reshape(shape)


class Placements:
    """The joints and collision geometries of a World, and their world placements for blocks of
    configurations (see the module docstring). Not thread-safe (it owns work buffers): one per
    thread, as the kernel that holds it.

    Args:
        world: the :class:`~dualpuma.model.world.World` (read, never modified).

    Raises:
        KernelUnsupported: a joint other than revolute/prismatic (x, y, z or an unaligned axis).
    """

    def __init__(self, world) -> None:
        self.chain = JointChain(world.model)
        self.nq = self.chain.nq
        self.geoms = [_geom_of(go) for go in world.geom_model.geometryObjects]
        self.shapes = [go.geometry for go in world.geom_model.geometryObjects]
        self.bar = int(world.bar_id)
        self.T_object_bar = np.array(world.T_object_bar, dtype=np.float64)
        self.moving = [
            (int(gid), np.array(ob.T_world_obstacle, dtype=np.float64), np.array(ob.velocity, dtype=np.float64),
             float(ob.t_start), float(ob.t_end))
            for gid, ob in world.moving
        ]
        G = self.geoms
        self.half_lengths = np.array([g.half_length for g in G])[None, :, None]  # (1, G, 1) [m]
        # geometries on the universe joint: constant placements (moving obstacles are set after)
        self._fix = np.array([i for i, g in enumerate(G) if g.joint == 0], dtype=np.int64)
        self._var = [i for i, g in enumerate(G) if g.joint != 0]
        self._fix_R = np.array([G[i].R for i in self._fix]).reshape(-1, 3, 3).transpose(1, 2, 0)[..., None]  # (3, 3, F, 1)
        self._fix_p = np.array([G[i].p for i in self._fix]).reshape(-1, 3).T[..., None]  # (3, F, 1) [m]
        # per moving geometry: its joint, and the terms of its rotation's columns and its translation
        self._terms = [(g, G[g].joint, [product_terms(G[g].R[:, c]) for c in range(3)], product_terms(G[g].p))
                       for g in self._var]
        self.buf = Buffers()

    def compute(
        self, Q: FloatArray, Tw: FloatArray | None, t: FloatArray, full_ids: npt.NDArray[np.int64] | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """World rotations (3, 3, G, n) and translations (3, G, n) of every geometry for joints Q
        (n, nq) [rad], bar frames Tw (n, 4, 4) or None, times t (n,) [s] (trusted input). With
        ``full_ids`` only those geometries get whole rotations, the others just their third column
        (a round geometry's axis); None: every rotation whole. Views of reused buffers."""
        n = Q.shape[0]
        buf = self.buf
        JC, Jt = self.chain.compute(Q, buf)
        G = len(self.geoms)
        GR = buf("GR", (3, 3, G, n))
        Gt = buf("Gt", (3, G, n))
        if self._fix.size:
            GR[:, :, self._fix] = self._fix_R
            Gt[:, self._fix] = self._fix_p
        full = set(range(G)) if full_ids is None else set(full_ids.tolist())
        tmp = buf("g_tmp", (3, n))
        for g, j, cols, p_terms in self._terms:
            X = JC[j]
            for col in range(3) if g in full else (2,):
                constant_product(X, cols[col], GR[:, col, g], tmp)
            constant_product(X, p_terms, Gt[:, g], tmp)
            Gt[:, g] += Jt[j]
        if Tw is not None:
            T = self.T_object_bar
            np.einsum("nik,kj->ijn", Tw[:, :3, :3], T[:3, :3], out=GR[:, :, self.bar])
            np.einsum("nik,k->in", Tw[:, :3, :3], T[:3, 3], out=Gt[:, self.bar])
            Gt[:, self.bar] += Tw[:, :3, 3].T
        for gid, T0, v, t0, t1 in self.moving:
            dt = np.minimum(np.maximum(t, t0), t1) - t0  # as Obstacle.pose_at
            GR[:, :, gid] = T0[:3, :3, None]
            Gt[:, gid] = T0[:3, 3, None] + v[:, None] * dt
        return GR, Gt
