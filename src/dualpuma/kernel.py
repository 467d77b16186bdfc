"""Vectorised exact clearance for batches of configurations (the batch path of clearance).

:class:`ClearanceKernel` returns the same minimum signed distance and arg-min pair as
``pin.computeDistances`` over a :class:`~dualpuma.world.World`'s collision pairs, for N
configurations at once, with numpy arrays instead of one C++ call per configuration:

1. **Kinematics.** Every joint of the World's Pinocchio model (revolute or prismatic about x, y, z
   or an unaligned axis), then every collision geometry's world placement (joint placement x
   geometry placement, as ``updateGeometryPlacements``). The bar is placed by
   ``T_world_object @ T_object_bar`` when that is given; moving obstacles by their pose at t.
2. **Closed forms**, exact up to rounding:

   * capsule–capsule (a sphere is a capsule of length 0): segment–segment distance minus the
     radii (:func:`segment_segment`);
   * capsule–halfspace and box–halfspace: the lowest point along the normal;
   * capsule–box: the signed segment–box distance (:func:`segment_box`).

3. **Bounds first, exact work only where it can matter.** Each solid pair gets a lower bound from
   the distance between the geometries' bounding spheres (for capsule–box pairs, from the
   capsule's centre to the axis of the box's bounding capsule) and an upper bound from balls inside
   them. An entry (configuration, pair) is evaluated exactly only if its lower bound does not
   exceed the configuration's best upper bound so far; capsule–box entries pass one more filter
   (segment to the box's bounding capsule, and one point of the segment to the box). Box–box pairs
   (the bar against a box obstacle) and shape pairs without a closed form here are answered by coal
   itself (``coal.distance``, a fresh request each time), again only where their bound could be
   the minimum. Skipped entries are provably above the minimum, so the result is exact; the
   returned pair is the first (in ``world.pair_ids`` order) holding the computed minimum.

The kernel is checked against coal and against independent references in tests/test_kernel.py.
Work is done in blocks of configurations with preallocated buffers (numpy's fresh allocations above
128 KiB cost more than the arithmetic on them), single-threaded: element-wise numpy and
``einsum`` only, no BLAS.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import coal
import numpy as np
import numpy.typing as npt

from .errors import JointError, ParameterError, PoseError

__all__ = ["ClearanceKernel", "KernelUnsupported", "point_box", "segment_box", "segment_segment"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

_TINY = 1e-300  #: guards 0/0 in the closed forms [m^2]
_NEAR_PARALLEL = 1e-6  #: sin^2 of the angle below which segments also get the end point checks
_SLACK = 1e-12  #: a bound within this of the best upper bound is still evaluated [m]
_COAL_SLACK = 1e-9  #: same, against coal's answers (its GJK/EPA tolerances are relative) [m]
_SEG_CHUNK = 4096  #: entries per segment–segment call (temporaries stay small)
_BOX_CHUNK = 512  #: entries per segment–box call (its temporaries are 24 x larger)


class KernelUnsupported(ParameterError):
    """The World holds a joint type the vectorised kinematics does not model."""


# ----------------------------------------------------------------------------- closed forms
def segment_segment(
    p0: FloatArray,
    d1: FloatArray,
    q0: FloatArray,
    d2: FloatArray,
    a: npt.ArrayLike,
    e: npt.ArrayLike,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Exact distance between segments ``p0 + s d1`` and ``q0 + t d2`` (s, t in [0, 1]), vectorised.

    Minimises the convex quadratic |p0 + s d1 - q0 - t d2|^2 over the unit square in three clamped
    steps: s from the unconstrained stationary point, t optimal for that s, then s optimal for that
    t. At the joint minimum each coordinate is optimal for the other, so the third step keeps an
    interior solution and repairs a clamped t (the classic closest-point algorithm, branch-free).
    Parallel segments take s = 0 or 1 first, which the next two steps turn into a closest pair.
    Zero-length segments (spheres) keep their parameter at 0.

    Args:
        p0, q0: segment starts [m], shape (3, ...) (component first), broadcastable.
        d1, d2: segment vectors (end - start) [m], shape (3, ...).
        a, e: |d1|^2 and |d2|^2 [m^2], broadcastable to the result (known per pair).

    Returns:
        ``(distance [m], s, t)``, each of the broadcast shape without the leading 3.
    """
    r = p0 - q0
    b = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2]
    c = d1[0] * r[0] + d1[1] * r[1] + d1[2] * r[2]
    f = d2[0] * r[0] + d2[1] * r[1] + d2[2] * r[2]
    a = np.asarray(a, dtype=np.float64)
    e = np.asarray(e, dtype=np.float64)
    inv_a = np.divide(1.0, a, out=np.zeros(a.shape), where=a > 0)
    inv_e = np.divide(1.0, e, out=np.zeros(e.shape), where=e > 0)
    ae = a * e
    den = ae - b * b  # = a e sin^2(angle)
    s = b * f
    s -= c * e
    s /= den + _TINY
    np.clip(s, 0.0, 1.0, out=s)
    t = b * s
    t += f
    t *= inv_e
    np.clip(t, 0.0, 1.0, out=t)
    s = b * t
    s -= c
    s *= inv_a
    np.clip(s, 0.0, 1.0, out=s)
    acc = np.zeros(s.shape)
    for k in range(3):
        x = r[k] + s * d1[k]
        x -= t * d2[k]
        x *= x
        acc += x
    dist = np.sqrt(acc, out=acc)
    near = np.flatnonzero((den <= _NEAR_PARALLEL * ae) & (ae > 0.0))
    if near.size:
        _parallel_fix(near, p0, d1, q0, d2, dist, s, t)
    return dist, s, t


def _parallel_fix(
    near: IntArray,
    p0: FloatArray,
    d1: FloatArray,
    q0: FloatArray,
    d2: FloatArray,
    dist: FloatArray,
    s: FloatArray,
    t: FloatArray,
) -> None:
    """Nearly parallel segments: the stationary point is ill-conditioned, so also try the four
    end point–segment problems (one of which holds the minimum when it is not interior); keeps the
    best of all in ``dist``, ``s``, ``t`` (flat entries ``near``)."""
    shape = (3,) + dist.shape
    P0, D1, Q0, D2 = (np.broadcast_to(x, shape).reshape(3, -1)[:, near] for x in (p0, d1, q0, d2))
    best, bs, bt = dist.reshape(-1)[near], s.reshape(-1)[near], t.reshape(-1)[near]
    for fixed, other, D_f, D_o, swap in ((P0, Q0, D1, D2, False), (Q0, P0, D2, D1, True)):
        for u in (0.0, 1.0):
            x = fixed + u * D_f - other
            v = np.clip((x * D_o).sum(axis=0) / (D_o * D_o).sum(axis=0), 0.0, 1.0)
            d = np.sqrt(((x - v * D_o) ** 2).sum(axis=0))
            better = d < best
            best = np.where(better, d, best)
            bs = np.where(better, v if swap else u, bs)
            bt = np.where(better, u if swap else v, bt)
    dist.reshape(-1)[near], s.reshape(-1)[near], t.reshape(-1)[near] = best, bs, bt


def point_box(x: FloatArray, h: FloatArray) -> FloatArray:
    """Signed distance from points to a box centred at the origin (negative inside) [m].

    Args:
        x: points in the box frame [m], shape (3, ...).
        h: half extents [m], shape (3, ...) broadcastable.
    """
    q = np.abs(x) - h
    out = np.maximum(q, 0.0)
    return np.sqrt((out * out).sum(axis=0)) + np.minimum(q.max(axis=0), 0.0)


def _box_slope(A: FloatArray, B: FloatArray, h: FloatArray, s: FloatArray) -> FloatArray:
    """Half the s-derivative of the squared distance from ``A + s B`` to the box, at parameters s."""
    x = A + s * B
    psi = x - np.clip(x, -h, h)
    return (B * psi).sum(axis=0)


def segment_box(A: FloatArray, B: FloatArray, h: FloatArray) -> FloatArray:
    """Exact signed distance between the segment ``A + s B`` (s in [0, 1]) and a box, vectorised.

    Apart: the squared distance from ``A + s B`` to the box is convex and piecewise quadratic in s,
    with breakpoints where a coordinate crosses a face plane (at most six). Its derivative is
    monotone and piecewise linear, so its values at 0, 1 and the breakpoints bracket its root inside
    one linear piece, where interpolation finds it exactly. Meeting: the penetration depth is the
    smallest overlap over the separating axes of a segment and a box — the three face normals and
    the three cross products of the segment with the box edges (complete for this pair of
    polytopes) — returned as a negative distance.

    Args:
        A: segment start in the box frame [m], shape (3, M).
        B: segment vector (end - start) in the box frame [m], shape (3, M).
        h: box half extents [m], shape (3, M) or (3, 1).

    Returns:
        Signed distance (M,) [m] (negative = penetration depth).
    """
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    h = np.broadcast_to(np.asarray(h, dtype=np.float64), A.shape)
    m = A.shape[1]
    inv_b = B / (
        B * B + _TINY
    )  # 0 where B = 0 (no crossing: the extra candidate s = 0 is harmless)
    S = np.empty((8, m))
    S[0] = 0.0
    S[1] = 1.0
    S[2:5] = (h - A) * inv_b
    S[5:8] = (-h - A) * inv_b
    np.clip(S[2:], 0.0, 1.0, out=S[2:])
    gp = _box_slope(A[:, None], B[:, None], h[:, None], S[None])  # (8, M), nondecreasing in s
    s_lo = np.maximum((S - 2.0 * (gp > 0.0)).max(axis=0), 0.0)  # last candidate with slope <= 0
    s_hi = np.minimum((S + 2.0 * (gp < 0.0)).min(axis=0), 1.0)  # first candidate with slope >= 0
    g_lo = _box_slope(A, B, h, s_lo)
    g_hi = _box_slope(A, B, h, s_hi)
    span = g_hi - g_lo
    frac = np.divide(-g_lo, span, out=np.zeros(m), where=span > 0.0)
    s = np.clip(s_lo + np.clip(frac, 0.0, 1.0) * (s_hi - s_lo), 0.0, 1.0)
    apart = np.maximum(point_box(A + s * B, h), 0.0)
    E = A + B
    depth = (h + np.minimum(-np.minimum(A, E), np.maximum(A, E))).min(axis=0)
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        # axis n = B x e_i = (.., B_k, -B_j) on (j, k); the box projects to +-(h_j|n_j| + h_k|n_k|)
        norm = np.sqrt(B[j] * B[j] + B[k] * B[k])
        num = h[j] * np.abs(B[k]) + h[k] * np.abs(B[j]) - np.abs(B[k] * A[j] - B[j] * A[k])
        depth = np.minimum(depth, np.divide(num, norm, out=np.full(m, np.inf), where=norm > 0.0))
    return np.where(depth > 0.0, -depth, apart)


# ----------------------------------------------------------------------------- model description
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


# ----------------------------------------------------------------------------- the kernel
class ClearanceKernel:
    """Exact minimum signed distance over a World's collision pairs for many configurations.

    Build once per World (about a millisecond) and call it with batches; see the module docstring
    for the method. Like the World, not thread-safe (it owns reusable work buffers): one kernel
    per thread. Results do not depend on earlier calls, on the block size or on the order of the
    configurations.

    Args:
        world: the :class:`~dualpuma.world.World`; its model, geometry model and pairs are read
            (never modified).
        block: configurations per internal block.

    Raises:
        KernelUnsupported: the model has a joint other than revolute/prismatic (x, y, z or an
            unaligned axis); use the per-configuration loop for such a World.
        ParameterError: block < 1.
    """

    def __init__(self, world, block: int = 1024) -> None:
        if int(block) < 1:
            raise ParameterError(
                f"block: expected a positive number of configurations, got {block}"
            )
        self.world = world
        self.block = int(block)
        model = world.model
        self.nq = int(model.nq)
        self._joints = [
            _joint_of(model.joints[j], int(model.parents[j]), model.jointPlacements[j])
            for j in range(1, model.njoints)
        ]
        self._geoms = [_geom_of(go) for go in world.geom_model.geometryObjects]
        self._bar = int(world.bar_id)
        self._T_object_bar = np.array(world.T_object_bar, dtype=np.float64)
        self._moving = [
            (int(gid), np.array(ob.T_world_obstacle, dtype=np.float64), np.array(ob.velocity, dtype=np.float64),
             float(ob.t_start), float(ob.t_end))
            for gid, ob in world.moving
        ]  # fmt: skip
        # joint local transforms: placement M, M K and M K^2 (K = [axis]x; zero for prismatic)
        self._jq = np.array([J.iq for J in self._joints], dtype=np.int64)
        self._M = np.array([J.R for J in self._joints]).reshape(-1, 3, 3)
        Ks = [np.cross(np.eye(3), J.axis) * J.revolute for J in self._joints]  # = [axis]x
        self._MK = np.array([J.R @ K for J, K in zip(self._joints, Ks)]).reshape(-1, 3, 3)
        self._MK2 = np.array([J.R @ K @ K for J, K in zip(self._joints, Ks)]).reshape(-1, 3, 3)
        self._gj = np.array([g.joint for g in self._geoms], dtype=np.int64)
        self._gR = np.array([g.R for g in self._geoms]).reshape(-1, 3, 3)
        self._gp = np.array([g.p for g in self._geoms]).reshape(-1, 3)
        self._hl = np.array([g.half_length for g in self._geoms])[None, :, None]
        self._halfspaces = [i for i, g in enumerate(self._geoms) if g.kind == "halfspace"]
        self._pairs = [(int(a), int(b)) for a, b in world.pair_ids]
        self.n_pairs = len(self._pairs)
        self._setup_pairs()
        self._buf = _Buffers()
        self._shapes = [go.geometry for go in world.geom_model.geometryObjects]
        self._exhaustive = False

    # ------------------------------------------------------------------ set-up
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

    # ------------------------------------------------------------------ placements
    def _placements(
        self, Q: FloatArray, Tw: FloatArray | None, t: FloatArray, full: bool = False
    ) -> tuple[FloatArray, FloatArray]:
        """World rotations (3, 3, G, n) and translations (3, G, n) of every geometry (for capsules
        and spheres outside coal's pairs only the third column, their axis, unless ``full``)."""
        n = Q.shape[0]
        buf = self._buf
        nj = len(self._joints) + 1
        JR = buf("JR", (nj, 3, 3, n))
        Jt = buf("Jt", (nj, 3, n))
        JR[0] = np.eye(3)[:, :, None]
        Jt[0] = 0.0
        # local transforms placement * motion(q) of every joint at once: for a revolute joint
        # M Rot(axis, q) = M + sin(q) M K + (1 - cos(q)) M K^2 (Rodrigues, K = [axis]x)
        L = buf("L", (nj - 1, 3, 3, n))
        tmp = buf("Ltmp", (nj - 1, 3, 3, n))
        q = Q[:, self._jq].T  # (J, n)
        np.multiply(self._MK[..., None], np.sin(q)[:, None, None, :], out=L)
        np.multiply(self._MK2[..., None], (1.0 - np.cos(q))[:, None, None, :], out=tmp)
        L += tmp
        L += self._M[..., None]
        for j, J in enumerate(self._joints, start=1):
            Lj = L[j - 1]
            tl = (
                J.p[:, None]
                if J.revolute
                else J.p[:, None] + np.multiply.outer(J.R @ J.axis, Q[:, J.iq])
            )
            if J.parent == 0:
                JR[j] = Lj
                Jt[j] = tl
            else:
                np.einsum("ikn,kjn->ijn", JR[J.parent], Lj, out=JR[j])
                np.einsum("ikn,kn->in", JR[J.parent], np.broadcast_to(tl, (3, n)), out=Jt[j])
                Jt[j] += Jt[J.parent]
        G = len(self._geoms)
        JRg = buf("JRg", (G, 3, 3, n))
        np.take(JR, self._gj, axis=0, out=JRg)
        GR = buf("GR", (3, 3, G, n))
        Gt = buf("Gt", (3, G, n))
        if full:
            np.einsum("gikn,gkj->ijgn", JRg, self._gR, out=GR)
        else:  # segments need only their axis; full rotations for boxes, halfspaces and coal's pairs
            np.einsum("gikn,gk->ign", JRg, self._gR[:, :, 2], out=GR[:, 2])
            f = self._full_ids
            if f.size:
                GR[:, :, f] = np.einsum("gikn,gkj->ijgn", JRg[f], self._gR[f])
        np.einsum("gikn,gk->ign", JRg, self._gp, out=Gt)
        Gt += np.moveaxis(np.take(Jt, self._gj, axis=0), 0, 1)
        if Tw is not None:
            T = self._T_object_bar
            np.einsum("nik,kj->ijn", Tw[:, :3, :3], T[:3, :3], out=GR[:, :, self._bar])
            np.einsum("nik,k->in", Tw[:, :3, :3], T[:3, 3], out=Gt[:, self._bar])
            Gt[:, self._bar] += Tw[:, :3, 3].T
        for gid, T0, v, t0, t1 in self._moving:
            dt = np.minimum(np.maximum(t, t0), t1) - t0  # as Obstacle.pose_at
            GR[:, :, gid] = T0[:3, :3, None]
            Gt[:, gid] = T0[:3, 3, None] + v[:, None] * dt
        return GR, Gt

    # ------------------------------------------------------------------ distances
    def _block(
        self, Q: FloatArray, Tw: FloatArray | None, t: FloatArray, exhaustive: bool = False
    ) -> FloatArray:
        """Signed distances (P, n) of one block: exact where they can be the minimum, else a lower
        bound above it (every entry exact if ``exhaustive``)."""
        self._exhaustive = exhaustive
        n = Q.shape[0]
        buf = self._buf
        GR, Gt = self._placements(Q, Tw, t)
        G = len(self._geoms)
        # round geometries as segments P0 + s D (s in [0, 1]); other geometries: P0 = origin, D = 0
        D = buf("D", (3, G, n))
        np.multiply(GR[:, 2], self._hl, out=D)
        P0 = buf("P0", (3, G, n))
        np.subtract(Gt, D, out=P0)
        D *= 2.0
        dist = buf("dist", (self.n_pairs, n))
        upper = np.full(n, np.inf)  # per configuration: a bound on the minimum, at last the minimum
        # exact halfspace pairs
        if self._halfspaces:
            N, off = self._halfspace_frames(GR, Gt)
        if self._ch_rows.size:
            g, h = self._ch_g, self._ch_h
            lo = buf("ch", (g.size, n))
            tmp = buf("ch2", (g.size, n))
            lo[...] = 0.0
            tmp[...] = 0.0
            for k in range(3):
                lo += N[k, h] * P0[k, g]
                tmp += N[k, h] * D[k, g]
            np.minimum(tmp, 0.0, out=tmp)
            lo += tmp
            lo -= off[h]
            lo -= self._ch_r
            dist[self._ch_rows] = lo
            np.minimum(upper, lo.min(axis=0), out=upper)
        for k, gx, ih in self._bh:
            nrm = N[:, ih]
            reach = sum(
                self._geoms[gx].half[i] * np.abs((GR[:, i, gx] * nrm).sum(axis=0)) for i in range(3)
            )
            d = (nrm * Gt[:, gx]).sum(axis=0) - reach - off[ih]
            dist[k] = d
            np.minimum(upper, d, out=upper)
        # stage A: bounding / inscribed balls of every solid pair
        PA = self._A_rows.size
        if PA:
            ca = buf("ca", (3, PA, n))
            cb = buf("cb", (3, PA, n))
            np.take(Gt, self._A_a, axis=1, out=ca)
            np.take(Gt, self._A_b, axis=1, out=cb)
            ca -= cb
            ca *= ca
            lower = buf("lower", (PA, n))
            np.sum(ca, axis=0, out=lower)
            np.sqrt(lower, out=lower)
            ub = cb[0]
            np.subtract(lower, self._A_inner, out=ub)
            np.minimum(upper, ub.min(axis=0), out=upper)
            lower -= self._A_outer
            self._tighten_cb(Gt, GR, lower)
            self._exact_cc(P0, D, lower, upper)
            self._exact_cb(P0, D, GR, Gt, lower, upper)
            self._refine_bb(GR, Gt, lower, upper)
            dist[self._A_rows] = lower
        if self._coal_always.size:
            for k in self._coal_always:
                for i in range(n):
                    dist[k, i] = self._coal(GR, Gt, int(k), i)
        return dist

    def _tighten_cb(self, Gt: FloatArray, GR: FloatArray, lower: FloatArray) -> None:
        """Capsule–box lower bounds from the capsule's centre to the box's bounding-capsule axis."""
        s, e = self._range["cb"]
        if s == e:
            return
        n, buf = Gt.shape[2], self._buf
        # each box's bounding-capsule axis in the world: start + u vec, u in [0, 1]
        start = buf("cb_start", (3, len(self._cb_boxes), n))
        vec = buf("cb_vec", (3, len(self._cb_boxes), n))
        for j, (g, c0, cd) in enumerate(self._cb_boxes):
            np.einsum("ikn,k->in", GR[:, :, g], c0, out=start[:, j])
            start[:, j] += Gt[:, g]
            np.einsum("ikn,k->in", GR[:, :, g], cd, out=vec[:, j])
        P = e - s
        w = buf("cb_w", (3, P, n))
        v = buf("cb_v", (3, P, n))
        tmp = buf("cb_tmp", (3, P, n))
        np.take(Gt, self._A_b[s:e], axis=1, out=w)  # capsule centres
        np.take(start, self._cb_box_slot, axis=1, out=tmp)
        w -= tmp
        np.take(vec, self._cb_box_slot, axis=1, out=v)
        np.multiply(w, v, out=tmp)
        u = tmp.sum(axis=0)
        u *= self._cb_inv_ee
        np.clip(u, 0.0, 1.0, out=u)
        np.multiply(v, u, out=tmp)
        w -= tmp
        w *= w
        d = np.sqrt(w.sum(axis=0))
        d -= self._cb_reach
        np.maximum(lower[s:e], d, out=lower[s:e])

    def _halfspace_frames(self, GR: FloatArray, Gt: FloatArray) -> tuple[FloatArray, FloatArray]:
        """World normals (3, H, n) and offsets (H, n) of the halfspaces."""
        hs = self._halfspaces
        N = np.stack(
            [np.einsum("ikn,k->in", GR[:, :, g], self._geoms[g].normal) for g in hs], axis=1
        )
        off = np.stack(
            [self._geoms[g].offset + (N[:, i] * Gt[:, g]).sum(axis=0) for i, g in enumerate(hs)]
        )
        return N, off

    def _candidates(self, lower: FloatArray, cls: str, upper: FloatArray, slack: float = _SLACK):
        """Flat (pair, configuration) entries of a class whose lower bound can reach the minimum."""
        s, e = self._range[cls]
        n = upper.shape[0]
        rows = lower[s:e]
        cand = np.arange(rows.size) if self._exhaustive else np.flatnonzero(rows <= upper + slack)
        k = cand // n
        return rows, cand, k, cand - k * n

    def _exact_cc(
        self, P0: FloatArray, D: FloatArray, lower: FloatArray, upper: FloatArray
    ) -> None:
        rows, cand, k, i = self._candidates(lower, "cc", upper)
        if cand.size == 0:
            return
        n = upper.shape[0]
        s = self._range["cc"][0]
        fa = self._A_a[s + k] * n + i
        fb = self._A_b[s + k] * n + i
        P0f, Df = P0.reshape(3, -1), D.reshape(3, -1)
        flat = rows.reshape(-1)
        for c0 in range(0, cand.size, _SEG_CHUNK):
            sl = slice(c0, c0 + _SEG_CHUNK)
            a, b, kk = fa[sl], fb[sl], k[sl]
            d, _, _ = segment_segment(
                P0f[:, a], Df[:, a], P0f[:, b], Df[:, b], self._cc_aa[kk], self._cc_ee[kk]
            )
            d -= self._cc_r[kk]
            flat[cand[sl]] = d
        np.minimum(upper, rows.min(axis=0), out=upper)

    def _to_box_frame(self, P0, D, GR, Gt, fa, fb):
        """Segments (flat round indices fa) in the frames of boxes (flat indices fb): (A, B) (3, M)."""
        R = GR.reshape(3, 3, -1)[:, :, fb]
        rel = P0.reshape(3, -1)[:, fa] - Gt.reshape(3, -1)[:, fb]
        d = D.reshape(3, -1)[:, fa]
        A = np.einsum("kim,km->im", R, rel)
        B = np.einsum("kim,km->im", R, d)
        return A, B

    def _exact_cb(self, P0, D, GR, Gt, lower: FloatArray, upper: FloatArray) -> None:
        rows, cand, k, i = self._candidates(lower, "cb", upper)
        if cand.size == 0:
            return
        n = upper.shape[0]
        s = self._range["cb"][0]
        flat = rows.reshape(-1)
        A, B = self._to_box_frame(P0, D, GR, Gt, self._A_b[s + k] * n + i, self._A_a[s + k] * n + i)
        # second filter: the box's bounding capsule (lower) and one point of the segment (upper)
        core, u, _ = segment_segment(
            A, B, self._cb_core0[:, k], self._cb_cored[:, k], self._cb_aa[k], self._cb_ee[k]
        )
        r = self._cb_r[k]
        lb = core - r - self._cb_rho[k]
        ubs = point_box(A + u * B, self._cb_half[:, k]) - r
        best = np.full(upper.shape, np.inf)
        np.minimum.at(best, i, ubs)
        np.minimum(upper, best, out=upper)
        flat[cand] = lb
        keep = np.arange(cand.size) if self._exhaustive else np.flatnonzero(lb <= upper[i] + _SLACK)
        for c0 in range(0, keep.size, _BOX_CHUNK):
            sel = keep[c0 : c0 + _BOX_CHUNK]
            kk = k[sel]
            flat[cand[sel]] = (
                segment_box(A[:, sel], B[:, sel], self._cb_half[:, kk]) - self._cb_r[kk]
            )
        np.minimum(upper, rows.min(axis=0), out=upper)

    def _refine_bb(self, GR, Gt, lower: FloatArray, upper: FloatArray) -> None:
        """Box–box and other solid pairs: bounds here, the distance from coal where it matters."""
        n = upper.shape[0]
        for cls in ("bb", "sx"):
            rows, cand, k, i = self._candidates(lower, cls, upper, _COAL_SLACK)
            if cand.size == 0:
                continue
            s = self._range[cls][0]
            flat = rows.reshape(-1)
            if cls == "bb":
                # tighter bound: the thinner box's bounding capsule against the other box
                fa, fb = self._A_a[s + k] * n + i, self._A_b[s + k] * n + i
                Ra = GR.reshape(3, 3, -1)[:, :, fa]
                start = Gt.reshape(3, -1)[:, fa] + np.einsum("ikm,km->im", Ra, self._bb_core0[:, k])
                vec = np.einsum("ikm,km->im", Ra, self._bb_cored[:, k])
                Rb = GR.reshape(3, 3, -1)[:, :, fb]
                A = np.einsum("kim,km->im", Rb, start - Gt.reshape(3, -1)[:, fb])
                B = np.einsum("kim,km->im", Rb, vec)
                lb = np.empty(cand.size)
                for c0 in range(0, cand.size, _BOX_CHUNK):
                    sl = slice(c0, c0 + _BOX_CHUNK)
                    lb[sl] = (
                        segment_box(A[:, sl], B[:, sl], self._bb_half[:, k[sl]])
                        - self._bb_rho[k[sl]]
                    )
                flat[cand] = lb
                if not self._exhaustive:
                    sel = np.flatnonzero(lb <= upper[i] + _COAL_SLACK)
                    cand, k, i = cand[sel], k[sel], i[sel]
            for c, kk, ii in zip(cand.tolist(), k.tolist(), i.tolist()):
                if self._exhaustive or flat[c] <= upper[ii] + _COAL_SLACK:
                    d = self._coal(GR, Gt, int(self._A_rows[s + kk]), ii)
                    flat[c] = d
                    upper[ii] = min(upper[ii], d)

    def _coal(self, GR: FloatArray, Gt: FloatArray, k: int, i: int) -> float:
        """coal's signed distance of world pair k at configuration i of the block (a fresh request
        each time: no warm start, so the answer does not depend on earlier queries)."""
        a, b = self._pairs[k]
        tf = [
            coal.Transform3s(
                np.ascontiguousarray(GR[:, :, g, i]), np.ascontiguousarray(Gt[:, g, i])
            )
            for g in (a, b)
        ]
        return float(
            coal.distance(
                self._shapes[a],
                tf[0],
                self._shapes[b],
                tf[1],
                coal.DistanceRequest(),
                coal.DistanceResult(),
            )
        )

    # ------------------------------------------------------------------ public
    def _validate(
        self, Q: npt.ArrayLike, T_world_object: npt.ArrayLike | None, t: npt.ArrayLike | None
    ) -> tuple[FloatArray, FloatArray | None, FloatArray]:
        from .puma import validate_pose

        try:
            arr = np.asarray(Q, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise JointError(f"Q: expected numbers, shape (N, {self.nq}): {exc}") from exc
        if arr.ndim != 2 or arr.shape[1] != self.nq:
            raise JointError(f"Q: expected shape (N, {self.nq}), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise JointError("Q: contains NaN or inf")
        n = arr.shape[0]
        Tw = None
        if T_world_object is not None:
            Tw = validate_pose(T_world_object, name="T_world_object")
            if Tw.shape != (n, 4, 4):
                raise PoseError(f"T_world_object: expected shape ({n}, 4, 4), got {Tw.shape}")
        if t is None:
            times = np.zeros(n)
        else:
            try:
                times = np.broadcast_to(np.asarray(t, dtype=np.float64), (n,))
            except ValueError as exc:
                raise ParameterError(
                    f"t: expected one time or {n} times [s], got shape {np.shape(t)}"
                ) from exc
            if not np.all(np.isfinite(times)):
                raise ParameterError("t: times must be finite")
        return np.ascontiguousarray(arr), Tw, np.ascontiguousarray(times)

    def __call__(
        self,
        Q: npt.ArrayLike,
        T_world_object: npt.ArrayLike | None = None,
        t: npt.ArrayLike | None = None,
    ) -> tuple[FloatArray, IntArray]:
        """Minimum signed distance and the pair achieving it, for N configurations.

        Args:
            Q: joint vectors of the World's model (left arm, then right arm) [rad], shape (N, nq).
            T_world_object: optional bar frames (N, 4, 4) [m] (default: carried by the left hand).
            t: optional time, or times (N,), for moving obstacles [s] (default 0).

        Returns:
            ``(distance (N,) [m], pair index (N,))``: negative distance = penetration depth; the
            index is into ``world.pair_ids`` / ``world.pair_names`` (a pair achieving the minimum).

        Raises:
            JointError: Q of the wrong shape, or not finite.
            PoseError: malformed T_world_object.
            ParameterError: t not finite or of the wrong shape.
        """
        Q, Tw, times = self._validate(Q, T_world_object, t)
        return self.evaluate(Q, Tw, times)

    def evaluate(
        self, Q: FloatArray, Tw: FloatArray | None, times: FloatArray
    ) -> tuple[FloatArray, IntArray]:
        """:meth:`__call__` for inputs already validated (no checks).

        Args:
            Q: finite joint vectors (N, nq) [rad], C-contiguous.
            Tw: None or valid bar frames (N, 4, 4) [m].
            times: finite times (N,) [s].
        """
        n = Q.shape[0]
        dist = np.empty(n)
        idx = np.empty(n, dtype=np.int64)
        for s in range(0, n, self.block):
            e = min(n, s + self.block)
            D = self._block(Q[s:e], None if Tw is None else Tw[s:e], times[s:e])
            best = D.min(axis=0)
            dist[s:e] = best
            idx[s:e] = (D == best).argmax(axis=0)  # the first pair holding the minimum
        return dist, idx

    def pair_distances(
        self,
        Q: npt.ArrayLike,
        T_world_object: npt.ArrayLike | None = None,
        t: npt.ArrayLike | None = None,
    ) -> FloatArray:
        """Every pair's signed distance (no pruning; box–box pairs by coal for every configuration).

        Args:
            Q: joint vectors [rad], shape (N, nq).
            T_world_object: optional bar frames (N, 4, 4) [m].
            t: optional time(s) [s] for moving obstacles.

        Returns:
            (N, P) signed distances [m] in ``world.pair_ids`` order.

        Raises:
            JointError, PoseError, ParameterError: as :meth:`__call__`.
        """
        Q, Tw, times = self._validate(Q, T_world_object, t)
        n = Q.shape[0]
        out = np.empty((n, self.n_pairs))
        for s in range(0, n, self.block):
            e = min(n, s + self.block)
            out[s:e] = self._block(
                Q[s:e], None if Tw is None else Tw[s:e], times[s:e], exhaustive=True
            ).T
        return out

    def geometry_placements(
        self,
        Q: npt.ArrayLike,
        T_world_object: npt.ArrayLike | None = None,
        t: npt.ArrayLike | None = None,
    ) -> FloatArray:
        """World placement of every collision geometry (what ``GeometryData.oMg`` holds).

        Args:
            Q: joint vectors [rad], shape (N, nq).
            T_world_object: optional bar frames (N, 4, 4) [m].
            t: optional time(s) [s] for moving obstacles.

        Returns:
            (N, G, 4, 4) homogeneous transforms [m] (G geometries, ``world.geom_model`` order).

        Raises:
            JointError, PoseError, ParameterError: as :meth:`__call__`.
        """
        Q, Tw, times = self._validate(Q, T_world_object, t)
        n, G = Q.shape[0], len(self._geoms)
        out = np.zeros((n, G, 4, 4))
        out[..., 3, 3] = 1.0
        for s in range(0, n, self.block):
            e = min(n, s + self.block)
            GR, Gt = self._placements(
                Q[s:e], None if Tw is None else Tw[s:e], times[s:e], full=True
            )
            out[s:e, :, :3, :3] = np.moveaxis(GR, (2, 3), (1, 0))
            out[s:e, :, :3, 3] = np.moveaxis(Gt, (1, 2), (1, 0))
        return out
