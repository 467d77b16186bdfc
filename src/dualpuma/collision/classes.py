"""The clearance kernel's sorting of a World's collision pairs into shape classes.

Each pair (a, b) is put in canonical order (box < halfspace < other < round) and into a class by
its shapes, with the constants its closed form needs precomputed once:

* ``cc`` capsule/sphere–capsule/sphere, ``cb`` box–capsule, ``bb`` box–box (closed form), ``sx`` other
  solids (coal), ``ch`` halfspace–capsule, ``bh`` box–halfspace, ``hx`` other halfspace pairs (coal).

The solid classes (cc, cb, bb, sx) are stored contiguously (``ranges``) for the kernel's bounds
stage; ``rows[k]`` is the World's pair index of solid entry k. Solid pairs with a *fixed* geometry
(on the universe joint and not varying: its world placement is its placement) are grouped by the
other geometry, so that the kernel bounds a group with one small matrix product. Used by
:mod:`.kernel` only.
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
        solid = by["cc"] + by["cb"] + by["bb"] + by["sx"]
        self.ranges: dict[str, tuple[int, int]] = {}
        s = 0
        for c in ("cc", "cb", "bb", "sx"):
            self.ranges[c] = (s, s + len(by[c]))
            s += len(by[c])
        # solid pairs: World pair index, geometries, bounding / inscribed ball radii
        self.rows = np.array([k for k, _, _ in solid], dtype=np.int64)
        self.a = np.array([a for _, a, _ in solid], dtype=np.int64)
        self.b = np.array([b for _, _, b in solid], dtype=np.int64)
        self.outer = np.array([G[a].outer + G[b].outer for _, a, b in solid])[:, None]
        self.inner = np.array([G[a].inner + G[b].inner for _, a, b in solid])[:, None]
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
        # box–capsule and box–box entries (the axis range, cb then bb): the partner's centre to
        # the axis of box a's bounding capsule bounds them (1/|axis|^2, reach = partner's outer + rho)
        ax = cb + by["bb"]
        self.axis_range = (self.ranges["cb"][0], self.ranges["bb"][1])
        caps = [bounding_capsule(G[a].half) for _, a, _ in ax]
        self.ax_core0 = np.array([c[0] for c in caps]).reshape(-1, 3).T
        self.ax_cored = np.array([c[1] for c in caps]).reshape(-1, 3).T
        self.ax_inv_ee = (1.0 / (self.ax_cored**2).sum(axis=0))[:, None]
        self.ax_reach = np.array([G[b].outer + c[2] for (_, _, b), c in zip(ax, caps)]).reshape(-1, 1)
        boxes = sorted({a for _, a, _ in ax})
        self.ax_boxes = [(g, *bounding_capsule(G[g].half)[:2]) for g in boxes]
        self.ax_box_slot = np.array([boxes.index(a) for _, a, _ in ax], dtype=np.int64)
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
        self._group_fixed(G, {i for i, g in enumerate(G) if g.joint == 0 and i not in varying})

    def _group_fixed(self, G: list[Geom], fixed: set[int]) -> None:
        """Groups of solid entries whose partner is fixed, by the other geometry (groups of at least
        :data:`GROUP_MIN`; the other entries are ``fixed_dense``)."""
        groups: dict[int, list[tuple[int, int]]] = {}
        dense = []
        for j, (a, b) in enumerate(zip(self.a.tolist(), self.b.tolist())):
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
        # per free geometry: solid entries, fixed partners' centres (m, 3) and squared norms (m, 1) [m, m^2]
        self.fixed_groups = []
        for g in self.fixed_free.tolist():
            F = np.array([G[f].p for _, f in groups[g]]).reshape(-1, 3)
            self.fixed_groups.append((g, np.array([j for j, _ in groups[g]], dtype=np.int64), F, (F * F).sum(axis=1)[:, None]))
        self.fixed_f_max = max([float(F2.max()) for *_, F2 in self.fixed_groups], default=0.0)
        # axis-range entries with a fixed box a, by partner: their entries (a slice if contiguous),
        # the world axis (start S, vector V) of the box's bounding capsule as [V; -2 S] (2m, 3),
        # S.V, |S|^2, |V|^2, 1/|V|^2 (m, 1) [m^2, m^-2] and the bound's reach (m, 1) [m]
        s, e = self.axis_range
        by_cap: dict[int, list[int]] = {}
        for k in range(e - s):
            if int(self.a[s + k]) in fixed:
                by_cap.setdefault(int(self.b[s + k]), []).append(k)
        by_cap = {g: ks for g, ks in by_cap.items() if len(ks) >= GROUP_MIN}
        self.ax_groups = []
        self.ax_s_max = 0.0
        for g, ks in sorted(by_cap.items()):
            box = [G[int(self.a[s + k])] for k in ks]
            S = np.array([x.R @ self.ax_core0[:, k] + x.p for k, x in zip(ks, box)])
            V = np.array([x.R @ self.ax_cored[:, k] for k, x in zip(ks, box)])
            kk = np.array(ks, dtype=np.int64)
            ss, vv = (S * S).sum(axis=1)[:, None], (V * V).sum(axis=1)[:, None]
            self.ax_s_max = max(self.ax_s_max, float(ss.max()), float(vv.max()))
            rows = slice(ks[0], ks[-1] + 1) if ks == list(range(ks[0], ks[-1] + 1)) else kk
            self.ax_groups.append((g, rows, np.vstack([V, -2.0 * S]), (S * V).sum(axis=1)[:, None], ss, vv, 1.0 / vv, self.ax_reach[kk]))
        grouped = {k for ks in by_cap.values() for k in ks}
        self.ax_rest = np.array([k for k in range(e - s) if k not in grouped], dtype=np.int64)
