"""The vectorised clearance kernel against coal (per pair) and exact geometric references."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from geometry_reference import box_surface_samples, segment_segment

from dualpuma import Cell, World
from dualpuma.cell import Bar, Obstacle
from dualpuma.clearance import clearance_batch, pair_distances_batch
from dualpuma.errors import JointError, ParameterError, PoseError
from dualpuma.kernel import seg_box, seg_seg
from dualpuma.paths import calc_rot

GJK = 2e-6  # coal answers box pairs by GJK/EPA to about this; capsule pairs are closed-form


def _cells():
    c = Cell.default()
    T1 = np.eye(4)
    T1[:3, 3], T1[:3, :3] = (1.5, -0.5, 0.3), calc_rot([0.3, 0.2, 0.5])
    T2 = np.eye(4)
    T2[:3, 3] = (1.8, -0.45, 0.5)
    T3 = np.eye(4)
    T3[:3, 3], T3[:3, :3] = (1.3, -0.4, 0.2), calc_rot([1.0, 0.2, 0.0])
    obst = (Obstacle("b", "box", [0.2, 0.3, 0.1], T1), Obstacle("s", "sphere", [0.1], T2),
            Obstacle("c", "capsule", [0.05, 0.3], T3, velocity=np.array([0.1, 0.0, 0.05]), t_start=0.0, t_end=5.0))
    flip = np.array([[0, 0, 1, 0], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1.0]])
    return {
        "default": c,
        "obstacles": dataclasses.replace(c, obstacles=obst),
        "capsule_bar": dataclasses.replace(c, bar=Bar("capsule", [0.03, 0.7], c.bar.T_object_bar @ flip), obstacles=obst[:1]),
    }


@pytest.mark.parametrize("name", ["default", "obstacles", "capsule_bar"])
def test_kernel_equals_coal_per_pair(name):
    cell = _cells()[name]
    w = World(cell)
    rng = np.random.default_rng(11)
    n = 1000
    QL = cell.left.q_home + rng.normal(0, 0.5, (n, 6))
    QR = cell.right.q_home + rng.normal(0, 0.5, (n, 6))
    times = rng.uniform(0, 6, n)
    D = pair_distances_batch(w, QL, QR, t=times)
    boxy = np.array([w.geoms[a].shape == "box" or w.geoms[b].shape == "box" for a, b in w.pair_ids])
    n_pen = 0
    for i in range(n):
        ref = w.clearance(QL[i], QR[i], t=times[i], per_pair=True).pair_distances
        err = np.abs(D[i] - ref)
        assert err[~boxy].max() < 1e-9, (i, w.pair_names[int(np.argmax(err * ~boxy))])
        if boxy.any():
            assert err[boxy].max() < GJK, (i, w.pair_names[int(np.argmax(err * boxy))], D[i][boxy], ref[boxy])
        n_pen += int((ref < 0).any())
    assert n_pen > 100  # penetrating configurations are part of the check
    d, k = clearance_batch(w, QL, QR, t=times, method="kernel")
    np.testing.assert_allclose(d, D.min(axis=1), atol=0)
    d_coal, _ = clearance_batch(w, QL, QR, t=times)
    np.testing.assert_allclose(d, d_coal, atol=GJK)


def test_seg_seg_matches_reference():
    rng = np.random.default_rng(2)
    P = rng.normal(size=(4, 3, 2000))
    P[3, :, :200] = P[2, :, :200]  # degenerate: the second segment is a point
    P[1, :, 200:400] = P[0, :, 200:400] + 0.3 * (P[3, :, 200:400] - P[2, :, 200:400])  # parallel
    d = seg_seg(P[0], P[1], P[2], P[3])
    ref = [segment_segment(P[0, :, i], P[1, :, i], P[2, :, i], P[3, :, i]) for i in range(2000)]
    np.testing.assert_allclose(d, ref, atol=1e-12)


def test_seg_box_against_sampling_and_depth():
    rng = np.random.default_rng(3)
    n = 300
    h = rng.uniform(0.05, 0.3, (3, n))
    a = rng.uniform(-0.6, 0.6, (3, n))
    b = a + rng.normal(0, 0.3, (3, n))
    d, ok = seg_box(a, b, h)
    assert ok.mean() > 0.9
    for i in np.flatnonzero(ok):
        T = np.eye(4)
        surf = box_surface_samples(T, 2 * h[:, i], n=40)
        seg = a[:, i][None] + np.linspace(0, 1, 400)[:, None] * (b[:, i] - a[:, i])[None]
        inside = np.all(np.abs(seg) <= h[:, i], axis=1).any()
        if d[i] > 0:
            assert not inside
            approx = np.min(np.linalg.norm(seg[:, None] - surf[None], axis=-1))
            assert d[i] <= approx + 1e-12 and approx - d[i] < 0.02  # sampling is ~1 cm dense
        else:
            assert inside or d[i] > -1e-9


def test_bad_input():
    w = World(Cell.default())
    with pytest.raises(JointError):
        pair_distances_batch(w, np.full((2, 6), np.nan), np.zeros((2, 6)))
    with pytest.raises(ParameterError):
        pair_distances_batch(w, np.zeros((2, 6)), np.zeros((3, 6)))
    with pytest.raises(PoseError):
        pair_distances_batch(w, np.zeros((1, 6)), np.zeros((1, 6)), T_world_object=np.zeros((1, 4, 4)))
    with pytest.raises(ParameterError):
        clearance_batch(w, np.zeros((1, 6)), np.zeros((1, 6)), method="gpu")
