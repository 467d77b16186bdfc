"""The box–box closed form of the clearance kernel (collision.forms.box_box) against coal and the
independent reference (tests/geometry_reference.py: alternating projections, separating axes):
random poses, touching, penetrating, parallel faces, an edge along a face, crossing edges."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
from geometry_reference import box_box as ref_box_box
from geometry_reference import pose

from dualpuma.collision.forms import box_box

TOL = 1e-9  # [m]
COAL_GJK = 2e-6  # coal's GJK/EPA relative tolerance: its box answers can be this far off [m]


def _coal(TA, sa, TB, sb) -> float:
    return float(coal.distance(coal.Box(*sa), coal.Transform3s(TA[:3, :3], TA[:3, 3]), coal.Box(*sb),
                               coal.Transform3s(TB[:3, :3], TB[:3, 3]), coal.DistanceRequest(), coal.DistanceResult()))


def _kernel(TAs, sas, TBs, sbs) -> np.ndarray:
    """box_box on world poses: A's rotation and centre in B's frame, half extents."""
    TA, TB = np.asarray(TAs), np.asarray(TBs)
    R = np.einsum("mlj,mlk->jkm", TB[:, :3, :3], TA[:, :3, :3])
    t = np.einsum("mlj,ml->jm", TB[:, :3, :3], TA[:, :3, 3] - TB[:, :3, 3])
    return box_box(R, t, np.asarray(sas).T / 2, np.asarray(sbs).T / 2)


def _check(TAs, sas, TBs, sbs) -> np.ndarray:
    """Every entry equals coal to 1e-9 m, or (within coal's tolerance) the reference to 1e-9 m;
    returns coal's values."""
    got = _kernel(TAs, sas, TBs, sbs)
    want = np.array([_coal(*x) for x in zip(TAs, sas, TBs, sbs)])
    for i in np.flatnonzero(np.abs(got - want) > TOL):
        assert abs(got[i] - want[i]) < COAL_GJK, (i, got[i], want[i])
        assert abs(got[i] - ref_box_box(TAs[i], sas[i], TBs[i], sbs[i])) < TOL, i
    return want


def test_random_poses_equal_coal_and_reference():
    rng = np.random.default_rng(21)
    n = 600
    rpy = lambda: pin.rpy.rpyToMatrix(*rng.uniform(-np.pi, np.pi, 3))
    TA = [pose(rpy(), rng.uniform(-0.6, 0.6, 3)) for _ in range(n)]
    TB = [pose(rpy(), rng.uniform(-0.6, 0.6, 3)) for _ in range(n)]
    sa, sb = rng.uniform(0.03, 0.8, (n, 3)), rng.uniform(0.03, 0.8, (n, 3))
    sa[: n // 3, 1:] = 0.05  # bar-like boxes, as the carried bar
    want = _check(TA, sa, TB, sb)
    for i in range(0, n, 10):  # the independent reference on a subset
        assert abs(_kernel(TA[i : i + 1], sa[i : i + 1], TB[i : i + 1], sb[i : i + 1])[0] - ref_box_box(TA[i], sa[i], TB[i], sb[i])) < TOL
    assert (want < -1e-3).sum() > 60 and (want > 1e-3).sum() > 200  # both regimes


def test_special_configurations_equal_coal():
    """Touching faces, parallel faces apart and offset, penetration of aligned boxes, an edge along
    a face, crossing edges, vertex on face, nearly parallel faces: against coal."""
    I = np.eye(3)
    Rz = lambda a: pin.rpy.rpyToMatrix(0.0, 0.0, a)
    Rx = lambda a: pin.rpy.rpyToMatrix(a, 0.0, 0.0)
    s1, s2 = (0.4, 0.2, 0.2), (0.3, 0.3, 0.1)
    cases = [
        (pose(I, (0.0, 0.0, 0.0)), s1, pose(I, (0.0, 0.0, 0.15)), s2),  # faces touching
        (pose(I, (0.0, 0.0, 0.0)), s1, pose(I, (0.3, 0.1, 0.25)), s2),  # parallel faces, offset, apart
        (pose(I, (0.0, 0.0, 0.0)), s1, pose(I, (0.33, 0.22, 0.17)), s2),  # parallel, edge regions
        (pose(I, (0.0, 0.0, 0.0)), s1, pose(I, (0.1, 0.05, 0.1)), s2),  # aligned, penetrating
        (pose(I, (0.0, 0.0, 0.0)), s1, pose(Rz(0.5), (0.05, 0.4, 0.0)), s2),  # rotated about z only
        (pose(I, (0.0, 0.0, 0.0)), s1, pose(Rz(0.7), (0.0, 0.0, 0.32)), s2),  # face on face, turned
        (pose(Rx(np.pi / 4), (0.0, 0.0, 0.0)), (0.8, 0.1, 0.1),
         pose(Rz(np.pi / 2) @ Rx(np.pi / 4), (0.0, 0.0, 0.2)), (0.8, 0.1, 0.1)),  # crossing edges
        (pose(pin.rpy.rpyToMatrix(0.6, 0.5, 0.0), (0.0, 0.0, 0.0)), s1, pose(I, (0.0, 0.0, 0.45)), s2),  # vertex below face
        (pose(Rz(1e-7), (0.0, 0.0, 0.0)), s1, pose(I, (0.31, 0.2, 0.16)), s2),  # nearly parallel
        (pose(Rz(1e-12), (0.0, 0.0, 0.0)), s1, pose(I, (0.31, 0.2, 0.16)), s2),  # parallel to rounding
        (pose(Rx(0.3), (0.0, 0.0, 0.0)), (0.8, 0.05, 0.05), pose(I, (0.1, 0.0, 0.3)), s2),  # bar edge along face
        (pose(I, (0.0, 0.0, 0.0)), s1, pose(I, (0.35, 0.0, 0.0)), s2),  # touching at x = 0.2 - 0.15
    ]
    want = _check(*map(list, zip(*cases)))
    assert abs(want[0]) < TOL and abs(want[-1]) < TOL
    assert want[3] < -0.01 and want[1] > 0.0 and want[6] > 0.0
    # continuity through the parallel configuration (the exactly parallel case takes every edge)
    near = [(pose(Rz(a), (0.0, 0.0, 0.0)), s1, pose(I, (0.33, 0.22, 0.17)), s2) for a in (0.0, 1e-10, -1e-10, 1e-6)]
    d = _kernel(*map(list, zip(*near)))
    assert np.ptp(d[:3]) < 1e-9 and abs(d[3] - d[0]) < 1e-6


def test_each_entry_alone():
    """An entry's distance does not depend on the other entries of the call or on the arrays'
    memory layout: the kernel calls these forms on gathered subsets of its candidates (whose
    layout numpy chooses), and separated entries alone get the separated case worked out. Each
    entry of a mixed call (penetrating, apart, aligned) equals the same entry computed alone, bit
    for bit, for contiguous input and for gathered, non-contiguous views (box_box's einsums used
    to sum in an order that followed the call's size and layout: 11 of these 500 entries were
    1 ulp off in the whole call)."""
    from dualpuma.collision.forms import segment_box

    rng = np.random.default_rng(5)
    m = 500
    h = np.abs(rng.normal(0.3, 0.1, (3, m)))
    hb = np.ascontiguousarray(h[::-1])
    R = np.linalg.qr(rng.normal(size=(m, 3, 3)))[0].transpose(1, 2, 0).copy()
    R[:, :, ::7] = np.eye(3)[:, :, None]  # parallel faces: every edge is measured
    t = rng.normal(0, 0.5, (3, m))
    alone = np.array([box_box(R[:, :, i : i + 1].copy(), t[:, i : i + 1].copy(), h[:, i : i + 1].copy(),
                              hb[:, i : i + 1].copy())[0] for i in range(m)])
    assert (alone < 0).sum() > 50 and (alone > 0).sum() > 50  # both regimes in one call
    sel = np.flatnonzero(rng.uniform(size=m) < 0.5)
    for Rx, tx, ha, hbx, idx in ((R, t, h, hb, slice(None)), (R[:, :, sel], t[:, sel], h[:, sel], hb[:, sel], sel)):
        np.testing.assert_array_equal(box_box(Rx, tx, ha, hbx), alone[idx])
    assert not R[:, :, sel].flags.c_contiguous  # the gathered case is a non-contiguous layout

    A, B = rng.normal(0, 0.4, (3, m)), rng.normal(0, 0.4, (3, m))
    B[:, ::9] = 0.0  # points
    seg_alone = np.array([segment_box(A[:, i : i + 1], B[:, i : i + 1], h[:, i : i + 1])[0] for i in range(m)])
    assert (seg_alone < 0).sum() > 50 and (seg_alone > 0).sum() > 50
    np.testing.assert_array_equal(segment_box(A, B, h), seg_alone)
    np.testing.assert_array_equal(segment_box(A[:, sel], B[:, sel], h[:, sel]), seg_alone[sel])
    np.testing.assert_array_equal(segment_box(A, B, h[:, :1]), [segment_box(A[:, i : i + 1], B[:, i : i + 1], h[:, :1])[0]
                                                              for i in range(m)])
