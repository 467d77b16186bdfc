"""World placements of every collision geometry for many configurations at once (vectorised FK).

:class:`Placements` reads a World's joints (parent, placement, motion axis) and collision
geometries (shape class, sizes, placement in their joint) from Pinocchio/coal once, then computes,
for a block of N configurations, every joint's and every geometry's world rotation and translation
with numpy (what ``pin.updateGeometryPlacements`` does for one configuration): each revolute joint's
local transform by Rodrigues' formula ``M Rot(axis, q) = M + sin(q) M K + (1 - cos q) M K^2`` for
all joints at once, then the chain products (geometries on the universe joint keep their constant
placements, set without products when there are several). The bar is placed by
``T_world_object @ T_object_bar`` when object poses are given, moving obstacles by their pose at
time t. Used by the clearance kernel (:mod:`.kernel`); checked against Pinocchio in
tests/test_kernel.py.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import coal
import numpy as np
import numpy.typing as npt

from ..errors import ParameterError

__all__ = ["Buffers", "Geom", "KernelUnsupported", "Placements", "bounding_capsule"]

FloatArray = npt.NDArray[np.float64]
_FIXED_SPLIT = 4  #: from this many geometries on the universe joint, their placements are set as constants


class KernelUnsupported(ParameterError):
    """The World holds a joint type the vectorised kinematics does not model."""


@dataclass(frozen=True, slots=True)
class _Joint:
    """One joint: parent, placement in the parent, motion kind and axis, index in q."""

    parent: int
    R: FloatArray  # placement rotation (3, 3)
    p: FloatArray  # placement translation (3,)
    revolute: bool
    axis: FloatArray  # unit axis in the joint frame (3,)
    aligned: int  # 0/1/2 for an axis along x/y/z, -1 otherwise
    iq: int


def _joint_of(jm, parent: int, M) -> _Joint:
    name = jm.shortname()
    R = np.array(M.rotation, dtype=np.float64)
    p = np.array(M.translation, dtype=np.float64)
    for k, ax in enumerate("XYZ"):
        if name in (f"JointModelR{ax}", f"JointModelP{ax}"):
            return _Joint(parent, R, p, name[10] == "R", np.eye(3)[k], k, int(jm.idx_q))
    if name in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        axis = np.array(jm.extract().axis, dtype=np.float64)
        return _Joint(
            parent, R, p, "Revolute" in name, axis / np.linalg.norm(axis), -1, int(jm.idx_q)
        )
    raise KernelUnsupported(f"joint type {name} is not modelled by the vectorised kinematics")


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
        size = int(np.prod(shape))
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
        model = world.model
        self.nq = int(model.nq)
        self.joints = [
            _joint_of(model.joints[j], int(model.parents[j]), model.jointPlacements[j]) for j in range(1, model.njoints)
        ]
        self.geoms = [_geom_of(go) for go in world.geom_model.geometryObjects]
        self.shapes = [go.geometry for go in world.geom_model.geometryObjects]
        self.bar = int(world.bar_id)
        self.T_object_bar = np.array(world.T_object_bar, dtype=np.float64)
        self.moving = [
            (int(gid), np.array(ob.T_world_obstacle, dtype=np.float64), np.array(ob.velocity, dtype=np.float64),
             float(ob.t_start), float(ob.t_end))
            for gid, ob in world.moving
        ]
        # joint local transforms: placement M, M K and M K^2 (K = [axis]x; zero for prismatic)
        J = self.joints
        self._jq = np.array([j.iq for j in J], dtype=np.int64)
        Ks = [np.cross(np.eye(3), j.axis) * j.revolute for j in J]
        self._M = np.array([j.R for j in J]).reshape(-1, 3, 3)
        self._MK = np.array([j.R @ K for j, K in zip(J, Ks)]).reshape(-1, 3, 3)
        self._MK2 = np.array([j.R @ K @ K for j, K in zip(J, Ks)]).reshape(-1, 3, 3)
        G = self.geoms
        self._gj = np.array([g.joint for g in G], dtype=np.int64)
        self._gR = np.array([g.R for g in G]).reshape(-1, 3, 3)
        self._gp = np.array([g.p for g in G]).reshape(-1, 3)
        self.half_lengths = np.array([g.half_length for g in G])[None, :, None]  # (1, G, 1) [m]
        # geometries on the universe joint: constant placements (moving obstacles are set after)
        self._fix = np.flatnonzero(self._gj == 0)
        self._var = np.flatnonzero(self._gj != 0)
        self._fix_R = np.moveaxis(self._gR[self._fix], 0, 2)[..., None]  # (3, 3, F, 1)
        self._fix_p = self._gp[self._fix].T[..., None]  # (3, F, 1) [m]
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
        nj = len(self.joints) + 1
        JR = buf("JR", (nj, 3, 3, n))
        Jt = buf("Jt", (nj, 3, n))
        JR[0] = np.eye(3)[:, :, None]
        Jt[0] = 0.0
        L = buf("L", (nj - 1, 3, 3, n))
        tmp = buf("Ltmp", (nj - 1, 3, 3, n))
        q = Q[:, self._jq].T  # (J, n)
        np.multiply(self._MK[..., None], np.sin(q)[:, None, None, :], out=L)
        np.multiply(self._MK2[..., None], (1.0 - np.cos(q))[:, None, None, :], out=tmp)
        L += tmp
        L += self._M[..., None]
        for j, Jn in enumerate(self.joints, start=1):
            Lj = L[j - 1]
            tl = Jn.p[:, None] if Jn.revolute else Jn.p[:, None] + np.multiply.outer(Jn.R @ Jn.axis, Q[:, Jn.iq])
            if Jn.parent == 0:
                JR[j] = Lj
                Jt[j] = tl
            else:
                np.einsum("ikn,kjn->ijn", JR[Jn.parent], Lj, out=JR[j])
                np.einsum("ikn,kn->in", JR[Jn.parent], np.broadcast_to(tl, (3, n)), out=Jt[j])
                Jt[j] += Jt[Jn.parent]
        G = len(self.geoms)
        GR = buf("GR", (3, 3, G, n))
        Gt = buf("Gt", (3, G, n))
        if self._fix.size >= _FIXED_SPLIT:  # constants for the universe joint's, products for the rest
            self._split(JR, Jt, GR, Gt, full_ids)
        else:
            self._all(JR, Jt, GR, Gt, full_ids)
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

    def _all(self, JR, Jt, GR, Gt, full_ids) -> None:
        """Every geometry's rotation (whole for ``full_ids``, or all if None; else its third column)
        and translation from its joint's."""
        n = GR.shape[3]
        JRg = self.buf("JRg", (len(self.geoms), 3, 3, n))
        np.take(JR, self._gj, axis=0, out=JRg)
        if full_ids is None:
            np.einsum("gikn,gkj->ijgn", JRg, self._gR, out=GR)
        else:  # segments need only their axis; whole rotations for the rest
            np.einsum("gikn,gk->ign", JRg, self._gR[:, :, 2], out=GR[:, 2])
            if full_ids.size:
                GR[:, :, full_ids] = np.einsum("gikn,gkj->ijgn", JRg[full_ids], self._gR[full_ids])
        np.einsum("gikn,gk->ign", JRg, self._gp, out=Gt)
        Gt += np.moveaxis(np.take(Jt, self._gj, axis=0), 0, 1)

    def _split(self, JR, Jt, GR, Gt, full_ids) -> None:
        """As :meth:`_all`, with the universe joint's geometries set to their constant placements
        (whole rotations) and the products only for the others."""
        n, var, fix = GR.shape[3], self._var, self._fix
        GR[:, :, fix] = self._fix_R
        Gt[:, fix] = self._fix_p
        if var.size == 0:
            return
        gj, gR = self._gj[var], self._gR[var]
        JRg = self.buf("JRg", (var.size, 3, 3, n))
        np.take(JR, gj, axis=0, out=JRg)
        if full_ids is None:
            GR[:, :, var] = np.einsum("gikn,gkj->ijgn", JRg, gR)
        else:
            GR[:, 2, var] = np.einsum("gikn,gk->ign", JRg, gR[:, :, 2])
            full = np.flatnonzero(np.isin(var, full_ids))
            if full.size:
                GR[:, :, var[full]] = np.einsum("gikn,gkj->ijgn", JRg[full], gR[full])
        t = np.einsum("gikn,gk->ign", JRg, self._gp[var])
        t += np.moveaxis(np.take(Jt, gj, axis=0), 0, 1)
        Gt[:, var] = t
