"""The clearance kernel's box-frame bounds (collision.bounds.box_bounds) against coal and the
independent reference (tests/geometry_reference.py): every lower bound is at most, and every upper
bound at least, the exact signed distance of its pair — fixed and moving boxes against capsules,
spheres and boxes, random poses, centres inside the box, penetrating, touching and near-touching
capsules parallel to a face, a near-degenerate thin plate — and the lower bound is exact where it
should be (a capsule parallel to a face, beside it)."""

from __future__ import annotations

import coal
import numpy as np
from geometry_reference import capsule_box

from dualpuma.collision.bounds import box_bounds
from dualpuma.collision.classes import PairClasses
from dualpuma.collision.placements import Buffers, Geom

TOL = 1e-9  # [m]
COAL_GJK = 2e-6  # coal's GJK/EPA relative tolerance: its box answers can be this far off [m]
N = 600


def _rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _scene(rng):
    """Geometries (four fixed boxes, a moving box, a capsule, a sphere, a moving box partner), the
    pairs, and N placements (3, 3, G, N), (3, G, N) [m]: the round partners and the moving boxes
    near a randomly chosen box, a third of the capsules parallel to one of its axes."""
    halves = [(0.2, 0.1, 0.05), (0.3, 0.0005, 0.15), (0.05, 0.05, 0.05), (0.4, 0.2, 0.01), (0.15, 0.08, 0.12)]
    G = [Geom("box", 0, _rotation(rng), rng.uniform(-0.5, 0.5, 3), half=np.array(h)) for h in halves[:4]]
    G.append(Geom("box", 1, np.eye(3), np.zeros(3), half=np.array(halves[4])))
    G.append(Geom("round", 1, np.eye(3), np.zeros(3), radius=0.04, half_length=0.18))
    G.append(Geom("round", 2, np.eye(3), np.zeros(3), radius=0.07))
    G.append(Geom("box", 2, np.eye(3), np.zeros(3), half=np.array([0.12, 0.03, 0.06])))
    pairs = [(a, b) for a in range(5) for b in (5, 6, 7)] + [(7, 4)]
    GR = np.zeros((3, 3, len(G), N))
    Gt = np.zeros((3, len(G), N))
    for g in range(4):
        GR[:, :, g], Gt[:, g] = G[g].R[:, :, None], G[g].p[:, None]
    for i in range(N):
        GR[:, :, 4, i], Gt[:, 4, i] = _rotation(rng), rng.uniform(-0.5, 0.5, 3)
        for g in (5, 6, 7):
            j = rng.integers(0, 5)
            Rj, pj, hj = GR[:, :, j, i], Gt[:, j, i], G[j].half
            R = _rotation(rng)
            local = rng.uniform(-1.4, 1.4, 3) * (hj + G[g].radius + 0.05)
            if g == 5 and i % 3 == 0:  # parallel to axis k of box j, beside face k2 (touching to 1e-6)
                k, k2 = rng.choice(3, 2, replace=False)
                R = Rj[:, [(k + 1) % 3, (k + 2) % 3, k]]
                local = rng.uniform(-1.0, 1.0, 3) * hj
                local[k2] = np.sign(rng.normal()) * (hj[k2] + G[g].radius + rng.choice([0.0, 1e-6, -1e-6, 0.02, -0.02]))
                local[k] = rng.uniform(-1.0, 1.0) * (hj[k] + G[g].half_length)
            GR[:, :, g, i], Gt[:, g, i] = R, pj + Rj @ local
    return G, pairs, GR, Gt


def _coal_shape(geo: Geom):
    if geo.kind == "box":
        return coal.Box(*(2.0 * geo.half))
    return coal.Capsule(geo.radius, 2.0 * geo.half_length) if geo.half_length else coal.Sphere(geo.radius)


def test_box_bounds_bracket_the_exact_distance():
    rng = np.random.default_rng(21)
    G, pairs, GR, Gt = _scene(rng)
    tb = PairClasses(G, pairs, varying=set())
    assert tb.box_fixed and tb.box_moving  # both paths exercised
    half_len = np.array([g.half_length for g in G])[None, :, None]
    D = 2.0 * GR[:, 2] * half_len
    B = tb.rows.size - tb.n_centre
    assert B == len(pairs)  # every pair has a box
    lower, upper = np.empty((B, N)), np.empty((B, N))
    box_bounds(tb, GR, Gt, D, lower, upper, Buffers())
    shapes = [_coal_shape(g) for g in G]
    req = coal.DistanceRequest()
    exact = np.empty((B, N))
    for r in range(B):
        a, b = int(tb.a[tb.n_centre + r]), int(tb.b[tb.n_centre + r])
        for i in range(N):
            tf = [coal.Transform3s(np.ascontiguousarray(GR[:, :, g, i]), np.ascontiguousarray(Gt[:, g, i])) for g in (a, b)]
            exact[r, i] = coal.distance(shapes[a], tf[0], shapes[b], tf[1], req, coal.DistanceResult())
    assert (lower <= exact + COAL_GJK).all() and (upper >= exact - COAL_GJK).all()
    # capsule rows: against the independent reference where coal is near a bound, and where the
    # bound should be exact (the capsule beside a face and parallel to it)
    caps = [r for r in range(B) if int(tb.b[tb.n_centre + r]) == 5]
    n_tight = n_pen = 0
    for r in caps:
        a = int(tb.a[tb.n_centre + r])
        for i in range(N):
            near = min(exact[r, i] - lower[r, i], upper[r, i] - exact[r, i]) < 1e-5
            if not near and i % 3:
                continue
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = GR[:, :, a, i], Gt[:, a, i]
            h = 0.5 * D[:, 5, i]
            ref = capsule_box((Gt[:, 5, i] - h, Gt[:, 5, i] + h, G[5].radius), T, 2.0 * G[a].half)
            assert lower[r, i] <= ref + TOL and upper[r, i] >= ref - TOL, (r, i, lower[r, i], ref, upper[r, i])
            if abs(lower[r, i] - ref) < TOL:
                n_tight += 1
                n_pen += ref < 0
    assert n_tight > 100 and n_pen > 10, (n_tight, n_pen)
    assert (exact < 0).sum() > 0.1 * exact.size and (exact > 0).sum() > 0.3 * exact.size


def test_group_bound_of_fixed_boxes_is_a_lower_bound():
    """With a cap of -inf every group of fixed boxes is culled: each of its rows holds the group's
    bound (its common bounding box against the partner), which must not exceed any box's distance;
    with the boxes axis-aligned the common box shares faces with them, so the bound is often tight.
    A cap of +inf computes every per-box bound, as without a cap."""
    for seed, aligned in ((22, False), (23, True)):
        rng = np.random.default_rng(seed)
        G, pairs, GR, Gt = _scene(rng)
        if aligned:
            for g in range(4):
                G[g] = Geom("box", 0, np.eye(3), G[g].p, half=G[g].half)
                GR[:, :, g] = np.eye(3)[:, :, None]
        tb = PairClasses(G, pairs, varying=set())
        assert all(group is not None for *_, group in tb.box_fixed)
        D = 2.0 * GR[:, 2] * np.array([g.half_length for g in G])[None, :, None]
        B = tb.rows.size - tb.n_centre
        lower, upper = np.empty((B, N)), np.empty((B, N))
        box_bounds(tb, GR, Gt, D, lower, upper, Buffers(), cap=np.full(N, -np.inf))
        full_lo, full_up = np.empty((B, N)), np.empty((B, N))
        box_bounds(tb, GR, Gt, D, full_lo, full_up, Buffers())
        lo2, up2 = np.empty((B, N)), np.empty((B, N))
        box_bounds(tb, GR, Gt, D, lo2, up2, Buffers(), cap=np.full(N, np.inf))
        np.testing.assert_array_equal(lo2, full_lo)
        np.testing.assert_array_equal(up2, full_up)
        shapes = [_coal_shape(g) for g in G]
        req = coal.DistanceRequest()
        n_tight = 0
        for r in range(B):
            a, b = int(tb.a[tb.n_centre + r]), int(tb.b[tb.n_centre + r])
            if a >= 4:
                continue  # a moving box: no group
            for i in range(N):
                tf = [coal.Transform3s(np.ascontiguousarray(GR[:, :, g, i]), np.ascontiguousarray(Gt[:, g, i])) for g in (a, b)]
                d = coal.distance(shapes[a], tf[0], shapes[b], tf[1], req, coal.DistanceResult())
                assert lower[r, i] <= d + COAL_GJK, (r, i, lower[r, i], d)
                n_tight += d - lower[r, i] < 1e-6
        assert not aligned or n_tight > 20, n_tight
