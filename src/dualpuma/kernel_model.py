"""The clearance kernel's description of a World (:mod:`dualpuma.kernel`): joints (parent,
placement, axis) and collision geometries (shape class, sizes, placement) read from Pinocchio/coal
once, plus reusable work buffers."""

from __future__ import annotations

from dataclasses import dataclass, field

import coal
import numpy as np
import numpy.typing as npt

from .errors import ParameterError

FloatArray = npt.NDArray[np.float64]


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
class _Geom:
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


def _geom_of(go) -> _Geom:
    shape, M = go.geometry, go.placement
    R, p, j = (
        np.array(M.rotation, dtype=np.float64),
        np.array(M.translation, dtype=np.float64),
        int(go.parentJoint),
    )
    if isinstance(shape, coal.Capsule):
        return _Geom(
            "round", j, R, p, radius=float(shape.radius), half_length=float(shape.halfLength)
        )
    if isinstance(shape, coal.Sphere):
        return _Geom("round", j, R, p, radius=float(shape.radius))
    if isinstance(shape, coal.Box):
        return _Geom("box", j, R, p, half=np.array(shape.halfSide, dtype=np.float64))
    if isinstance(shape, coal.Halfspace):
        return _Geom(
            "halfspace", j, R, p, normal=np.array(shape.n, dtype=np.float64), offset=float(shape.d)
        )
    return _Geom("other", j, R, p)


def _bounding_capsule(half: FloatArray) -> tuple[FloatArray, FloatArray, float]:
    """Thinnest capsule around a box along its longest axis: (start, vector, radius) in its frame."""
    m = int(np.argmax(half))
    start, vec = np.zeros(3), np.zeros(3)
    start[m], vec[m] = -half[m], 2.0 * half[m]
    others = np.delete(half, m)
    return start, vec, float(np.hypot(others[0], others[1]))


class _Buffers:
    """Named reusable arrays (contiguous views of cached flat buffers)."""

    def __init__(self) -> None:
        self._b: dict[str, FloatArray] = {}

    def __call__(self, name: str, shape: tuple[int, ...]) -> FloatArray:
        size = int(np.prod(shape))
        buf = self._b.get(name)
        if buf is None or buf.size < size:
            buf = self._b[name] = np.empty(max(size, 1))
        return buf[:size].reshape(shape)


class _PairTables:
    """Sorting the World's pairs into shape classes and precomputing their constants (a mixin of
    ClearanceKernel: reads ``self._geoms`` and ``self._pairs``, sets the class tables)."""

    def _setup_pairs(self) -> None:
        G = self._geoms
        order = {"box": 0, "halfspace": 1, "other": 2, "round": 3}
        by: dict[str, list[tuple[int, int, int]]] = {
            c: [] for c in ("cc", "cb", "bb", "sx", "ch", "bh", "hx")
        }
        for k, (a, b) in enumerate(self._pairs):
            if order[G[a].kind] > order[G[b].kind]:
                a, b = b, a  # canonical: box < halfspace < other < round
            key = {("round", "round"): "cc", ("box", "round"): "cb", ("box", "box"): "bb", ("halfspace", "round"): "ch",
                   ("box", "halfspace"): "bh"}.get((G[a].kind, G[b].kind))  # fmt: skip
            if key is None:
                key = "hx" if "halfspace" in (G[a].kind, G[b].kind) else "sx"
            if key == "bb" and _bounding_capsule(G[a].half)[2] > _bounding_capsule(G[b].half)[2]:
                a, b = b, a  # the thinner box gets the bounding capsule
            by[key].append((k, a, b))
        # solid pairs (stage A bounds), grouped by class in contiguous ranges
        solid = by["cc"] + by["cb"] + by["bb"] + by["sx"]
        self._range = {}
        s = 0
        for c in ("cc", "cb", "bb", "sx"):
            self._range[c] = (s, s + len(by[c]))
            s += len(by[c])
        self._A_rows = np.array([k for k, _, _ in solid], dtype=np.int64)
        self._A_a = np.array([a for _, a, _ in solid], dtype=np.int64)
        self._A_b = np.array([b for _, _, b in solid], dtype=np.int64)
        self._A_outer = np.array([G[a].outer + G[b].outer for _, a, b in solid])[:, None]
        self._A_inner = np.array([G[a].inner + G[b].inner for _, a, b in solid])[:, None]
        cc = by["cc"]
        self._cc_aa = np.array([(2 * G[a].half_length) ** 2 for _, a, _ in cc])
        self._cc_ee = np.array([(2 * G[b].half_length) ** 2 for _, _, b in cc])
        self._cc_r = np.array([G[a].radius + G[b].radius for _, a, b in cc])
        cb = by["cb"]
        self._cb_r = np.array([G[b].radius for _, _, b in cb])
        self._cb_aa = np.array([(2 * G[b].half_length) ** 2 for _, _, b in cb])
        self._cb_half = np.array([G[a].half for _, a, _ in cb]).reshape(-1, 3).T
        caps = [_bounding_capsule(G[a].half) for _, a, _ in cb]
        self._cb_core0 = np.array([c[0] for c in caps]).reshape(-1, 3).T
        self._cb_cored = np.array([c[1] for c in caps]).reshape(-1, 3).T
        self._cb_rho = np.array([c[2] for c in caps])
        self._cb_ee = (self._cb_cored**2).sum(axis=0)
        self._cb_inv_ee = (1.0 / self._cb_ee)[:, None]
        self._cb_reach = np.array([G[b].outer for _, _, b in cb])[:, None] + self._cb_rho[:, None]
        boxes = sorted({a for _, a, _ in cb})
        self._cb_boxes = [(g, *_bounding_capsule(G[g].half)[:2]) for g in boxes]
        self._cb_box_slot = np.array([boxes.index(a) for _, a, _ in cb], dtype=np.int64)
        bb = by["bb"]
        caps = [_bounding_capsule(G[a].half) for _, a, _ in bb]
        self._bb_core0 = np.array([c[0] for c in caps]).reshape(-1, 3).T
        self._bb_cored = np.array([c[1] for c in caps]).reshape(-1, 3).T
        self._bb_rho = np.array([c[2] for c in caps])
        self._bb_half = np.array([G[b].half for _, _, b in bb]).reshape(-1, 3).T
        ch = by["ch"]
        self._ch_rows = np.array([k for k, _, _ in ch], dtype=np.int64)
        self._ch_h = np.array([self._halfspaces.index(a) for _, a, _ in ch], dtype=np.int64)
        self._ch_g = np.array([b for _, _, b in ch], dtype=np.int64)
        self._ch_r = np.array([G[b].radius for _, _, b in ch])[:, None]
        bh = by["bh"]
        self._bh = [(k, a, self._halfspaces.index(b)) for k, a, b in bh]
        self._coal_always = np.array([k for k, _, _ in by["hx"]], dtype=np.int64)
        in_coal = {g for _, a, b in by["sx"] + by["hx"] + by["bb"] for g in (a, b)}
        self._full_ids = np.array(
            [g for g, geo in enumerate(G) if geo.kind != "round" or g in in_coal], dtype=np.int64
        )
