"""The clearance kernel's sorting of a World's collision pairs into shape classes.

Each pair (a, b) is put in canonical order (box < halfspace < other < round) and into a class by
its shapes, with the constants its closed form needs precomputed once:

* ``cc`` capsule/sphere–capsule/sphere, ``cb`` box–capsule, ``bb`` box–box (closed form), ``sx`` other
  solids (coal), ``ch`` halfspace–capsule, ``bh`` box–halfspace, ``hx`` other halfspace pairs (coal).

The solid classes are stored contiguously (``ranges``), cc and sx first (the *centre* rows, bounded
by their bounding balls), then cb and bb (the *box* rows, bounded in box a's frame: see
:mod:`.bounds`); ``rows[k]`` is the World's pair index of solid entry k. Centre rows with a *fixed*
geometry (on the universe joint and not varying: its world placement is its placement) are grouped
by the other geometry, so that the kernel bounds a group with one small matrix product. Box rows are
grouped (and stored contiguously within their class) by partner b where box a is fixed, by box a
where it moves. Used by :mod:`.kernel` and :mod:`.bounds` only.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .placements import Geom, bounding_capsule

__all__ = ["PairClasses"]

FloatArray = npt.NDArray[np.float64]
_ORDER = {"box": 0, "halfspace": 1, "other": 2, "round": 3}
GROUP_MIN = 4  #: fewest pairs of one geometry with fixed partners worth a matrix product (else gathers)
_CLASS = {("round", "round"): "cc", ("box", "round"): "cb", ("box", "box"): "bb", ("halfspace", "round"): "ch",
          ("box", "halfspace"): "bh"}


class PairClasses:
    """Tables of a World's pairs by shape class (see the module docstring).

    Args:
        geoms: the World's geometries (:class:`~.placements.Geom`).
        pairs: the World's pairs (index pairs into ``geoms``), in the World's order.
        varying: geometries on the universe joint whose placement still changes (the bar, moving
            obstacles); every other universe-joint geometry is fixed.
    """

    def __init__(self, geoms: list[Geom], pairs: list[tuple[int, int]], varying: set[int] = frozenset()) -> None:
        G = geoms
        self.halfspaces = [i for i, g in enumerate(G) if g.kind == "halfspace"]
        by: dict[str, list[tuple[int, int, int]]] = {c: [] for c in ("cc", "cb", "bb", "sx", "ch", "bh", "hx")}
        for k, (a, b) in enumerate(pairs):
            if _ORDER[G[a].kind] > _ORDER[G[b].kind]:
                a, b = b, a
            key = _CLASS.get((G[a].kind, G[b].kind))
            if key is None:
                key = "hx" if "halfspace" in (G[a].kind, G[b].kind) else "sx"
            if key == "bb" and bounding_capsule(G[a].half)[2] > bounding_capsule(G[b].half)[2]:
                a, b = b, a  # the thinner box gets the bounding capsule
            by[key].append((k, a, b))
        fixed = {i for i, g in enumerate(G) if g.joint == 0 and i not in varying}
        for c in ("cb", "bb"):  # box groups made contiguous: by partner of a fixed box, else by box
            groups: dict[tuple[int, int], list[tuple[int, int, int]]] = {}
            for x in by[c]:
                groups.setdefault((0, x[2]) if x[1] in fixed else (1, x[1]), []).append(x)
            by[c] = [x for xs in groups.values() for x in xs]
        solid = by["cc"] + by["sx"] + by["cb"] + by["bb"]
        self.ranges: dict[str, tuple[int, int]] = {}
        s = 0
        for c in ("cc", "sx", "cb", "bb"):
            self.ranges[c] = (s, s + len(by[c]))
            s += len(by[c])
        self.n_centre = self.ranges["sx"][1]  # centre rows [0, n_centre), box rows after
        # solid pairs: World pair index, geometries; centre rows: bounding / inscribed ball radii
        self.rows = np.array([k for k, _, _ in solid], dtype=np.int64)
        self.a = np.array([a for _, a, _ in solid], dtype=np.int64)
        self.b = np.array([b for _, _, b in solid], dtype=np.int64)
        centre = solid[: self.n_centre]
        self.outer = np.array([G[a].outer + G[b].outer for _, a, b in centre])[:, None]
        self.inner = np.array([G[a].inner + G[b].inner for _, a, b in centre])[:, None]
        cc = by["cc"]  # capsule-capsule: squared segment lengths, radius sums
        self.cc_aa = np.array([(2 * G[a].half_length) ** 2 for _, a, _ in cc])
        self.cc_ee = np.array([(2 * G[b].half_length) ** 2 for _, _, b in cc])
        self.cc_r = np.array([G[a].radius + G[b].radius for _, a, b in cc])
        cb = by["cb"]  # box-capsule: the box's half extents and bounding capsule (its "core")
        self.cb_r = np.array([G[b].radius for _, _, b in cb])
        self.cb_aa = np.array([(2 * G[b].half_length) ** 2 for _, _, b in cb])
        self.cb_half = np.array([G[a].half for _, a, _ in cb]).reshape(-1, 3).T
        caps = [bounding_capsule(G[a].half) for _, a, _ in cb]
        self.cb_core0 = np.array([c[0] for c in caps]).reshape(-1, 3).T
        self.cb_cored = np.array([c[1] for c in caps]).reshape(-1, 3).T
        self.cb_rho = np.array([c[2] for c in caps])
        self.cb_ee = (self.cb_cored**2).sum(axis=0)
        bb = by["bb"]  # box-box: the thinner box's bounding capsule, the other's half extents
        caps = [bounding_capsule(G[a].half) for _, a, _ in bb]
        self.bb_core0 = np.array([c[0] for c in caps]).reshape(-1, 3).T
        self.bb_cored = np.array([c[1] for c in caps]).reshape(-1, 3).T
        self.bb_rho = np.array([c[2] for c in caps])
        self.bb_half = np.array([G[b].half for _, _, b in bb]).reshape(-1, 3).T
        self.bb_half_a = np.array([G[a].half for _, a, _ in bb]).reshape(-1, 3).T
        ch = by["ch"]  # halfspace-capsule
        self.ch_rows = np.array([k for k, _, _ in ch], dtype=np.int64)
        self.ch_h = np.array([self.halfspaces.index(a) for _, a, _ in ch], dtype=np.int64)
        self.ch_g = np.array([b for _, _, b in ch], dtype=np.int64)
        self.ch_r = np.array([G[b].radius for _, _, b in ch])[:, None]
        self.bh = [(k, a, self.halfspaces.index(b)) for k, a, b in by["bh"]]  # box-halfspace
        self.coal_always = np.array([k for k, _, _ in by["hx"]], dtype=np.int64)
        in_coal = {g for _, a, b in by["sx"] + by["hx"] + by["bb"] for g in (a, b)}
        # geometries whose whole rotation is needed (not only a round geometry's axis)
        self.full_ids = np.array([g for g, geo in enumerate(G) if geo.kind != "round" or g in in_coal], dtype=np.int64)
        self._group_fixed(G, fixed)
        self._group_boxes(G, fixed)

    def _group_fixed(self, G: list[Geom], fixed: set[int]) -> None:
        """Groups of centre rows whose partner is fixed, by the other geometry (groups of at least
        :data:`GROUP_MIN`; the other rows are ``fixed_dense``)."""
        groups: dict[int, list[tuple[int, int]]] = {}
        dense = []
        for j, (a, b) in enumerate(zip(self.a[: self.n_centre].tolist(), self.b[: self.n_centre].tolist())):
            if b in fixed:
                groups.setdefault(a, []).append((j, b))
            elif a in fixed:
                groups.setdefault(b, []).append((j, a))
            else:
                dense.append(j)
        for g in [g for g, m in groups.items() if len(m) < GROUP_MIN]:
            dense += [j for j, _ in groups.pop(g)]
        self.fixed_dense = np.array(sorted(dense), dtype=np.int64)
        self.fixed_free = np.array(sorted(groups), dtype=np.int64)
        # per free geometry: centre rows, fixed partners' centres (m, 3) and squared norms (m, 1) [m, m^2]
        self.fixed_groups = []
        for g in self.fixed_free.tolist():
            F = np.array([G[f].p for _, f in groups[g]]).reshape(-1, 3)
            self.fixed_groups.append((g, np.array([j for j, _ in groups[g]], dtype=np.int64), F, (F * F).sum(axis=1)[:, None]))
        self.fixed_f_max = max([float(F2.max()) for *_, F2 in self.fixed_groups], default=0.0)

    def _group_boxes(self, G: list[Geom], fixed: set[int]) -> None:
        """Groups of box rows (contiguous: ``(start, stop)`` relative to the first box row) for
        :func:`~.bounds.box_bounds`. Per row: half extents of box a (3, B, 1), partner b's radius
        about its axis (a capsule's or sphere's radius; a box's bounding-ball radius) and inscribed
        radius (B, 1) [m]. ``box_fixed``: fixed boxes by partner, with the matrix (6m, 4) that takes
        the partner's centre [c; 1] to x - h and -x - h, x = R^T (c - p) the centre in a box's frame
        (row k m + j: axis k of the group's box j) [m], R^T / 2 (3m, 3) for a capsule's axis vector
        (None for other partners), and the same (6, 4) matrix for the group's common box
        (:func:`_group_lift`; None for a group of one); ``box_moving``: a moving box (its geometry) and its
        partners."""
        s0, rows = self.n_centre, range(self.n_centre, self.rows.size)
        pb = [G[int(self.b[j])] for j in rows]
        self.box_half = np.array([G[int(self.a[j])].half for j in rows]).reshape(-1, 3).T[:, :, None]
        self.box_rad = np.array([g.radius if g.kind == "round" else g.outer for g in pb])[:, None]
        self.box_inner = np.array([g.inner for g in pb])[:, None]
        self.box_fixed, self.box_moving = [], []
        key = [(0, b) if a in fixed else (1, a) for a, b in zip(self.a.tolist(), self.b.tolist())]
        for c in ("cb", "bb"):
            s, e = self.ranges[c]
            while s < e:
                t = s + 1
                while t < e and key[t] == key[s]:
                    t += 1
                a, b = int(self.a[s]), int(self.b[s])
                span = (s - s0, t - s0)
                if a in fixed:  # fixed boxes, one partner
                    boxes = [G[int(x)] for x in self.a[s:t]]
                    Rt = np.vstack([np.array([x.R[:, k] for x in boxes]) for k in range(3)])  # (3m, 3)
                    off = np.concatenate([[x.R[:, k] @ x.p for x in boxes] for k in range(3)])[:, None]
                    h = self.box_half[:, span[0] : span[1], 0].reshape(-1, 1)
                    lift = np.block([[Rt, -off - h], [-Rt, off - h]])  # (6m, 4)
                    seg = G[b].kind == "round" and G[b].half_length > 0.0
                    self.box_fixed.append((b, span, lift, 0.5 * Rt if seg else None, _group_lift(boxes)))
                else:  # one moving box, its partners
                    self.box_moving.append((a, span, self.b[s:t].copy()))
                s = t


GROUP_PAD = 1e-9  #: the common box of a group of fixed boxes is widened by this, over its rounding [m]


def _group_lift(boxes: list[Geom]) -> FloatArray | None:
    """For fixed boxes (two or more), the matrix (6, 4) taking a point [c; 1] to x - H and -x - H,
    x = c - C, of their common world-axis-aligned bounding box (centre C, half extents H, widened by
    :data:`GROUP_PAD`) [m]; None for fewer than two boxes."""
    if len(boxes) < 2:
        return None
    ext = np.array([np.abs(x.R) @ x.half for x in boxes])  # each box's world half extents
    ps = np.array([x.p for x in boxes])
    hi, lo = (ps + ext).max(axis=0), (ps - ext).min(axis=0)
    C, H = 0.5 * (hi + lo), 0.5 * (hi - lo) + GROUP_PAD
    return np.block([[np.eye(3), (-C - H)[:, None]], [-np.eye(3), (C - H)[:, None]]])
