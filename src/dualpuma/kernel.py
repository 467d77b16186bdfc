"""Vectorised clearance for many configurations (the batch path of :func:`~dualpuma.clearance.clearance_batch`).

Exact closed forms in numpy, all configurations and pairs at once:

* forward kinematics of both arms from the World's Pinocchio joint placements (revolute joints);
* capsule–capsule (and sphere, a capsule of length 0): segment–segment distance minus the radii;
* capsule–box: the squared distance from a segment to a box is convex and piecewise quadratic in the
  segment parameter; a few active-set Newton steps find its minimiser, which is certified by the
  first-order condition (rows that fail the certificate go to coal). A segment that enters the box
  gets its exact penetration depth from the separating-axis theorem (box faces and segment × edges);
* capsule/box–floor: lowest end point / corner.

Pairs without a closed form here (box–box: the bar against a box obstacle) and uncertified rows are
answered by ``coal.distance`` one by one, so every result equals coal's to its own precision.
"""

from __future__ import annotations

import coal
import numpy as np
import numpy.typing as npt

__all__ = ["ClearanceKernel"]

FloatArray = npt.NDArray[np.float64]


def _axis_rot(axis: int, q: FloatArray) -> FloatArray:
    c, s = np.cos(q), np.sin(q)
    R = np.zeros(q.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R[..., axis, axis] = 1.0
    R[..., i, i], R[..., i, j], R[..., j, i], R[..., j, j] = c, -s, s, c
    return R


def _dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def seg_seg(p0, p1, q0, q1) -> FloatArray:
    """Distance between segments [p0, p1] and [q0, q1]; component-first arrays (3, ...) (exact).

    Ericson's clamped closest-point algorithm, written with arithmetic masks (``np.where`` on
    random conditions is several times slower than the arithmetic itself)."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, b, c, f = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2), _dot(d1, r), _dot(d2, r)
    tiny = 1e-300
    a_ok, e_ok = a > tiny, e > tiny
    a_s, e_s = np.maximum(a, tiny), np.maximum(e, tiny)
    den = a * e - b * b
    gen = den > 1e-14 * np.maximum(a * e, tiny)
    s = np.clip((b * f - c * e) / np.maximum(den, tiny), 0.0, 1.0) * gen  # parallel: s = 0
    s_pt = np.clip(-c / a_s, 0.0, 1.0) * a_ok  # the second segment is a point
    s = s * e_ok + s_pt * ~e_ok
    t = (b * s + f) / e_s * e_ok
    t_cl = np.clip(t, 0.0, 1.0)
    s2 = np.clip((b * t_cl - c) / a_s, 0.0, 1.0) * a_ok
    s = s + (t != t_cl) * (s2 - s)
    dx = r + s * d1 - t_cl * d2
    return np.sqrt(_dot(dx, dx))


def seg_box(a: FloatArray, b: FloatArray, h: FloatArray) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Signed distance from segments [a, b] (box-local, component-first (3, ...)) to boxes of half
    extents h (3, ...). Returns ``(distance, certified)``; negative = penetration depth (separating
    axes). Uncertified rows (Newton not converged to the optimality test) must be recomputed."""
    d = b - a
    dd = _dot(d, d)
    ddp = np.maximum(dd, 1e-300)
    t = np.clip(-_dot(a, d) / ddp, 0.0, 1.0) * (dd > 1e-300)
    for _ in range(5):
        s = a + t * d
        act = np.abs(s) > h
        g = act * (a - np.copysign(h, s))
        den = _dot(act * d, d)
        ok_den = den > 1e-300
        t_new = np.clip(-_dot(g, d) / np.maximum(den, 1e-300), 0.0, 1.0)
        t = t + ok_den * (t_new - t)
    s = a + t * d
    ex = s - np.clip(s, -h, h)
    dist = np.sqrt(_dot(ex, ex))
    gr = _dot(ex, d)  # half the derivative of the squared distance
    scale = np.sqrt(ddp) * np.maximum(dist, 1e-12)
    ok = (np.abs(gr) <= 1e-9 * scale) | ((t <= 0.0) & (gr >= 0)) | ((t >= 1.0) & (gr <= 0))
    inside = dist <= 1e-12
    if np.any(inside):
        depth = _sat_depth(np.moveaxis(a[:, inside], 0, -1), np.moveaxis(b[:, inside], 0, -1), np.moveaxis(h[:, inside], 0, -1))
        dist = dist.copy()
        dist[inside] = -depth
        ok = ok | inside
    return dist, ok


def _sat_depth(a: FloatArray, b: FloatArray, h: FloatArray) -> FloatArray:
    """Penetration depth of segments intersecting boxes: the smallest overlap over the candidate
    separating axes (box faces and segment direction x box edges)."""
    d = b - a
    axes = [np.broadcast_to(np.eye(3)[k], a.shape) for k in range(3)]
    axes += [np.cross(d, np.eye(3)[k]) for k in range(3)]
    best = np.full(a.shape[:-1], np.inf)
    for n in axes:
        ln = np.linalg.norm(n, axis=-1)
        good = ln > 1e-9
        n = n / np.where(good, ln, 1.0)[..., None]
        pa, pb = np.einsum("...i,...i->...", a, n), np.einsum("...i,...i->...", b, n)
        rho = np.einsum("...i,...i->...", h, np.abs(n))
        ov = np.minimum(np.maximum(pa, pb) + rho, rho - np.minimum(pa, pb))
        best = np.where(good, np.minimum(best, ov), best)
    return best


class ClearanceKernel:
    """Numpy clearance for a :class:`~dualpuma.world.World` (built once, reused for batches)."""

    def __init__(self, world) -> None:
        self.world = world
        m = world.model
        for j in range(1, m.njoints):
            if m.joints[j].shortname() not in ("JointModelRX", "JointModelRY", "JointModelRZ"):
                raise NotImplementedError("the batch kernel handles revolute joints only")
        self.parents = [int(m.parents[j]) for j in range(m.njoints)]
        self.placements = [m.jointPlacements[j].homogeneous for j in range(m.njoints)]
        self.axes = [("RX", "RY", "RZ").index(m.joints[j].shortname()[-2:]) if j else 0 for j in range(m.njoints)]
        self.idx_q = [int(m.joints[j].idx_q) if j else 0 for j in range(m.njoints)]
        go = world.geom_model.geometryObjects
        self.geom_joint = [int(g.parentJoint) for g in go]
        self.geom_place = [g.placement.homogeneous for g in go]
        self.infos = world.geoms
        self.pairs = np.array(world.pair_ids, dtype=np.int64)
        shape = [i.shape for i in world.geoms]
        seglike = {"capsule", "sphere"}
        kinds = []
        for a, b in world.pair_ids:
            sa, sb = shape[a], shape[b]
            if sa in seglike and sb in seglike:
                kinds.append("ss")
            elif {sa, sb} == {"halfspace"} | ({sa, sb} - {"halfspace"}) and "halfspace" in (sa, sb):
                kinds.append("hs_seg" if (sa in seglike or sb in seglike) else "hs_box")
            elif (sa in seglike and sb == "box") or (sb in seglike and sa == "box"):
                kinds.append("sb")
            else:
                kinds.append("coal")
        self.kinds = np.array(kinds)
        self.sel = {k: np.flatnonzero(self.kinds == k) for k in ("ss", "hs_seg", "hs_box", "sb", "coal")}
        self.half = np.array([0.5 * i.size[1] if i.shape == "capsule" else 0.0 for i in world.geoms])
        self.radius = np.array([i.size[0] if i.shape in seglike else 0.0 for i in world.geoms])
        pa, pb = self.pairs[:, 0], self.pairs[:, 1]
        hs = self.sel["hs_seg"]
        self.hs_geom = np.where([shape[a] == "halfspace" for a in pa[hs]], pb[hs], pa[hs]).astype(np.int64)
        sb = self.sel["sb"]
        first = np.array([shape[a] in seglike for a in pa[sb]], dtype=bool)
        self.sb_seg = np.where(first, pa[sb], pb[sb]).astype(np.int64)
        self.sb_box = np.where(first, pb[sb], pa[sb]).astype(np.int64)
        self.sb_h = np.array([np.asarray(world.geoms[b].size) / 2 for b in self.sb_box]).reshape(-1, 3)

    # ------------------------------------------------------------------ placements
    def _joints(self, Q: FloatArray) -> FloatArray:
        """World transforms (J, N, 4, 4) of every joint."""
        n = Q.shape[0]
        Tj = np.empty((len(self.parents), n, 4, 4))
        Tj[0] = np.eye(4)
        for j in range(1, len(self.parents)):
            R = np.zeros((n, 4, 4))
            R[:, :3, :3] = _axis_rot(self.axes[j], Q[:, self.idx_q[j]])
            R[:, 3, 3] = 1.0
            Tj[j] = Tj[self.parents[j]] @ self.placements[j] @ R
        return Tj

    def _frames_soa(self, Q: FloatArray):
        """Joint rotations (J, 3, 3, N) and positions (J, 3, N), component-first."""
        n = Q.shape[0]
        J = len(self.parents)
        R = np.empty((J, 3, 3, n))
        p = np.empty((J, 3, n))
        R[0] = np.eye(3)[:, :, None]
        p[0] = 0.0
        for j in range(1, J):
            Rp, pp, Pl = R[self.parents[j]], p[self.parents[j]], self.placements[j]
            M = np.einsum("ikn,kj->ijn", Rp, Pl[:3, :3])
            p[j] = pp + np.einsum("ikn,k->in", Rp, Pl[:3, 3])
            c, s_ = np.cos(Q[:, self.idx_q[j]]), np.sin(Q[:, self.idx_q[j]])
            u, v = [(1, 2), (2, 0), (0, 1)][self.axes[j]]
            R[j] = M
            R[j, :, u] = c * M[:, u] + s_ * M[:, v]
            R[j, :, v] = -s_ * M[:, u] + c * M[:, v]
        return R, p

    def placements_batch(self, Q: FloatArray, T_bar: FloatArray | None, times: FloatArray | None) -> FloatArray:
        """World placements (N, G, 4, 4) of every geometry for configurations Q (N, nq)."""
        Tj = self._joints(Q)
        G = np.empty((Q.shape[0], len(self.geom_joint), 4, 4))
        for g, (j, P) in enumerate(zip(self.geom_joint, self.geom_place)):
            G[:, g] = Tj[j] @ P
        self._override(G, T_bar, times)
        return G

    def _override(self, G: FloatArray, T_bar, times) -> None:
        w = self.world
        if T_bar is not None:
            G[:, w.bar_id] = T_bar @ w.T_object_bar
        if times is not None:
            for gid, ob in w.moving:
                dt = np.clip(times, ob.t_start, ob.t_end) - ob.t_start
                G[:, gid] = ob.T_world_obstacle
                G[:, gid, :3, 3] += dt[:, None] * np.asarray(ob.velocity)[None]

    # ------------------------------------------------------------------ distances
    def distances(self, Q: FloatArray, T_bar: FloatArray | None = None, times: FloatArray | None = None) -> FloatArray:
        """Signed distances (P, N) of every pair in ``world.pair_ids`` order [m] (pair-major)."""
        n = Q.shape[0]
        Rj, pj = self._frames_soa(Q)
        ng = len(self.geom_joint)
        GR = np.empty((ng, 3, 3, n))
        Gp = np.empty((ng, 3, n))
        for g, (j, Pl) in enumerate(zip(self.geom_joint, self.geom_place)):
            GR[g] = np.einsum("ikn,kj->ijn", Rj[j], Pl[:3, :3])
            Gp[g] = pj[j] + np.einsum("ikn,k->in", Rj[j], Pl[:3, 3])
        w = self.world
        if T_bar is not None:
            M = T_bar @ w.T_object_bar
            GR[w.bar_id] = np.moveaxis(M[:, :3, :3], 0, -1)
            Gp[w.bar_id] = M[:, :3, 3].T
        if times is not None:
            for gid, ob in w.moving:
                dt = np.clip(times, ob.t_start, ob.t_end) - ob.t_start
                Gp[gid] = ob.T_world_obstacle[:3, 3, None] + np.asarray(ob.velocity)[:, None] * dt[None]
        P = len(self.pairs)
        D = np.empty((P, n))
        pa, pb = self.pairs[:, 0], self.pairs[:, 1]
        ax = GR[:, :, 2, :] * self.half[:, None, None]  # (G, 3, N): capsule axis * half length
        S0 = np.swapaxes(Gp - ax, 0, 1)  # (3, G, N)
        S1 = np.swapaxes(Gp + ax, 0, 1)
        RAD = self.radius[:, None]
        floor_z = float(w.cell.floor_z)
        sel = self.sel["ss"]
        if sel.size:
            a, b = pa[sel], pb[sel]
            D[sel] = seg_seg(S0[:, a], S1[:, a], S0[:, b], S1[:, b]) - RAD[a] - RAD[b]
        sel = self.sel["hs_seg"]
        if sel.size:
            g = self.hs_geom
            D[sel] = np.minimum(S0[2, g], S1[2, g]) - floor_z - RAD[g]
        for k in self.sel["hs_box"]:
            box = pb[k] if self.infos[pa[k]].shape == "halfspace" else pa[k]
            h = np.asarray(self.infos[box].size) / 2
            D[k] = -(np.abs(GR[box, 2]) * h[:, None]).sum(axis=0) + Gp[box, 2] - floor_z  # lowest corner
        sel = self.sel["sb"]
        if sel.size:
            seg, box = self.sb_seg, self.sb_box
            BR, Bp = GR[box], Gp[box]  # (P, 3, 3, N), (P, 3, N)
            la = np.einsum("pjin,jpn->ipn", BR, S0[:, seg] - np.swapaxes(Bp, 0, 1))
            lb = np.einsum("pjin,jpn->ipn", BR, S1[:, seg] - np.swapaxes(Bp, 0, 1))
            h = np.broadcast_to(self.sb_h.T[:, :, None], la.shape)
            dist, ok = seg_box(la, lb, h)
            D[sel] = dist - RAD[seg]
            bad = np.argwhere(~ok)
            if len(bad):
                G = self._placements_from(GR, Gp)
                for c, i in bad:
                    D[sel[c], i] = self._coal(G[:, i], int(pa[sel[c]]), int(pb[sel[c]]))
        if self.sel["coal"].size:
            G = self._placements_from(GR, Gp)
            for k in self.sel["coal"]:
                for i in range(n):
                    D[k, i] = self._coal(G[:, i], int(pa[k]), int(pb[k]))
        return D

    @staticmethod
    def _placements_from(GR: FloatArray, Gp: FloatArray) -> FloatArray:
        G = np.zeros((GR.shape[0], GR.shape[-1], 4, 4))
        G[..., :3, :3] = np.moveaxis(GR, -1, 1)
        G[..., :3, 3] = np.moveaxis(Gp, -1, 1)
        G[..., 3, 3] = 1.0
        return G

    def _coal(self, G: FloatArray, a: int, b: int) -> float:
        go = self.world.geom_model.geometryObjects
        req, res = coal.DistanceRequest(), coal.DistanceResult()
        Ma, Mb = G[a], G[b]
        coal.distance(go[a].geometry, coal.Transform3s(Ma[:3, :3], Ma[:3, 3]), go[b].geometry,
                      coal.Transform3s(Mb[:3, :3], Mb[:3, 3]), req, res)
        return float(res.min_distance)

    def min_distance(self, Q, T_bar=None, times=None, chunk: int = 2048) -> tuple[FloatArray, npt.NDArray[np.int64]]:
        """(minimum signed distance (N,), arg-min pair index (N,)) in chunks."""
        n = Q.shape[0]
        dist, idx = np.empty(n), np.empty(n, dtype=np.int64)
        for s in range(0, n, chunk):
            e = min(n, s + chunk)
            D = self.distances(Q[s:e], None if T_bar is None else T_bar[s:e], None if times is None else times[s:e])
            k = np.argmin(D, axis=0)
            idx[s:e] = k
            dist[s:e] = D[k, np.arange(e - s)]
        return dist, idx
