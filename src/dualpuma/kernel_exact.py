"""The exact stage of the clearance kernel (:mod:`dualpuma.kernel`): after the bounds, the
(configuration, pair) entries that can still be the minimum are evaluated with the closed forms of
:mod:`dualpuma.kernel_forms` (capsule–capsule, capsule–box) or by coal (box–box and shapes without a
closed form here). A mixin of :class:`~dualpuma.kernel.ClearanceKernel`, which owns the pair tables
it reads."""

from __future__ import annotations

import coal
import numpy as np
import numpy.typing as npt

from .kernel_forms import point_box, segment_box, segment_segment

FloatArray = npt.NDArray[np.float64]

_SLACK = 1e-12  #: a bound within this of the best upper bound is still evaluated [m]
_COAL_SLACK = 1e-9  #: same, against coal's answers (its GJK/EPA tolerances are relative) [m]
_SEG_CHUNK = 4096  #: entries per segment–segment call (temporaries stay small)
_BOX_CHUNK = 512  #: entries per segment–box call (its temporaries are 24 x larger)


class _ExactStage:
    """Exact evaluation of candidate entries (methods of ClearanceKernel)."""

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
