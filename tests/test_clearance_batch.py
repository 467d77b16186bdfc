"""clearance_batch / pair_distances_batch: the kernel path against the coal loop and world.clearance,
bar poses and moving obstacles, method selection, and bad input."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
from geometry_reference import capsule_box, capsule_capsule, pose

from dualpuma import puma
from dualpuma.collision import BATCH_KERNEL_MIN, batch_kernel, clearance_batch, pair_distances_batch
from dualpuma.errors import JointError, ParameterError, PoseError
from dualpuma.model import Bar, Cell, Obstacle, World

LIM = puma.JOINT_LIMITS
TOL = 1e-9  # [m]
COAL_GJK = 2e-6  # coal's own GJK/EPA tolerance on box pairs (see tests/test_kernel.py)



@pytest.fixture(scope="module")
def cell():
    base = Cell.default()
    obstacles = (
        Obstacle("crate", "box", (0.3, 0.2, 0.25), pose(pin.rpy.rpyToMatrix(0.1, 0.2, 0.3), (1.5, 0.35, 0.35))),
        Obstacle("ball", "sphere", (0.12,), pose(p=(1.45, -0.45, 0.5))),
        Obstacle("post", "capsule", (0.05, 0.5), pose(p=(1.5, -0.2, 0.25))),
        Obstacle("agv", "box", (0.4, 0.4, 0.3), pose(p=(0.0, -0.25, 0.15)), velocity=(1.0, 0.0, 0.0), t_start=0.0, t_end=3.0),
    )
    return dataclasses.replace(base, obstacles=obstacles)


@pytest.fixture(scope="module")
def world(cell):
    return World(cell)


def _random(rng, n):
    QL = rng.uniform(LIM[:, 0], LIM[:, 1], (n, 6))
    QR = rng.uniform(LIM[:, 0], LIM[:, 1], (n, 6))
    Tw = np.array(
        [pose(pin.rpy.rpyToMatrix(*rng.uniform(-np.pi, np.pi, 3)), rng.uniform([0.9, -0.7, -0.1], [2.1, 0.7, 1.0])) for _ in range(n)]
    )
    return QL, QR, Tw, rng.uniform(-0.5, 4.0, n)


def _reference(world, qL, qR, Tw, t, k):
    """Independent distance of pair k (capsules/spheres/boxes; no shared code with the kernel):
    arm segments from World.segments, obstacle poses from Obstacle.pose_at, the bar from T_world_object
    or the left grasp. None for pairs without a reference here (box–box, halfspaces)."""
    segs = world.segments(qL, qR)
    T_wo = world.object_from_left(qL) if Tw is None else Tw
    obstacles = {f"obstacle/{ob.name}": ob for ob in world.cell.obstacles}

    def shape(g):
        info = world.geoms[g]
        if info.name in segs:
            return ("capsule", segs[info.name])
        T = T_wo @ world.T_object_bar if info.kind == "bar" else obstacles[info.name].pose_at(t) if info.kind == "obstacle" else None
        if T is None:
            return (info.shape, None)
        if info.shape == "capsule":
            h = 0.5 * info.size[1] * T[:3, 2]
            return ("capsule", (T[:3, 3] - h, T[:3, 3] + h, info.size[0]))
        if info.shape == "sphere":
            return ("capsule", (T[:3, 3], T[:3, 3], info.size[0]))
        return ("box", (T, info.size))

    A, B = (shape(g) for g in world.pair_ids[k])
    if A[0] == "box":
        A, B = B, A
    if A[0] == "capsule" and B[0] == "capsule":
        return capsule_capsule(A[1], B[1])
    if A[0] == "capsule" and B[0] == "box":
        return capsule_box(A[1], *B[1])
    return None


def _check_against_scalar(world, QL, QR, Tw, t, d, idx):
    """Distance equal to world.clearance's (coal) to 1e-9 m and the returned pair holds the minimum;
    where coal's GJK/EPA tolerance on a box pair shows, the kernel must equal the independent
    reference to 1e-9 m instead."""
    n_exc = 0
    for i in range(len(d)):
        Tw_i, t_i = None if Tw is None else Tw[i], 0.0 if t is None else t[i]
        c = world.clearance(QL[i], QR[i], Tw_i, t_i, per_pair=True)
        if abs(d[i] - c.distance) > TOL or abs(c.pair_distances[idx[i]] - d[i]) > TOL:
            ref = _reference(world, QL[i], QR[i], Tw_i, t_i, int(idx[i]))
            assert ref is not None and abs(ref - d[i]) < TOL and abs(d[i] - c.distance) < COAL_GJK, (i, d[i], c.distance)
            n_exc += 1
    assert n_exc <= 2 + 0.01 * len(d)  # rare: coal is exact on almost every pair


def test_methods_agree_with_world_clearance(world):
    rng = np.random.default_rng(21)
    QL, QR, Tw, t = _random(rng, 600)
    d_auto, i_auto = clearance_batch(world, QL, QR, Tw, t)
    d_kern, i_kern = clearance_batch(world, QL, QR, Tw, t, method="kernel")
    d_coal, _ = clearance_batch(world, QL, QR, Tw, t, method="coal")
    np.testing.assert_array_equal(d_auto, d_kern)  # a 600-batch takes the kernel
    np.testing.assert_array_equal(i_auto, i_kern)
    assert np.abs(d_kern - d_coal).max() < COAL_GJK and np.mean(np.abs(d_kern - d_coal) < TOL) > 0.995
    _check_against_scalar(world, QL, QR, Tw, t, d_kern, i_kern)
    assert (d_kern < 0).sum() > 100  # penetrating configurations included


def test_default_bar_pose_and_no_times(world, cell):
    rng = np.random.default_rng(22)
    QL = cell.left.q_home + rng.normal(0, 0.3, (300, 6))
    QR = cell.right.q_home + rng.normal(0, 0.3, (300, 6))
    d, idx = clearance_batch(world, QL, QR, method="kernel")
    _check_against_scalar(world, QL, QR, None, None, d, idx)


def test_small_batches_and_single_configuration(world, cell):
    qL, qR = cell.left.q_home, cell.right.q_home
    d1, i1 = clearance_batch(world, qL, qR)  # (6,) each: one configuration
    c = world.clearance(qL, qR)
    assert d1.shape == (1,) and abs(d1[0] - c.distance) < TOL and world.pair_names[i1[0]] == c.pair
    for n in (BATCH_KERNEL_MIN - 1, BATCH_KERNEL_MIN):  # either side of the auto switch
        QL, QR = np.tile(qL, (n, 1)), np.tile(qR, (n, 1))
        d, _ = clearance_batch(world, QL, QR)
        np.testing.assert_allclose(d, c.distance, atol=TOL)
    d0, i0 = clearance_batch(world, np.zeros((0, 6)), np.zeros((0, 6)), method="kernel")
    assert d0.shape == (0,) and i0.shape == (0,)


def test_moving_obstacle_by_time(world, cell):
    """The AGV drives through the left pedestal: both methods see it at the same times."""
    qL, qR = cell.left.q_home, cell.right.q_home
    times = np.linspace(0.0, 3.0, 91)
    QL, QR = np.tile(qL, (91, 1)), np.tile(qR, (91, 1))
    d, idx = clearance_batch(world, QL, QR, t=times, method="kernel")
    d_coal, _ = clearance_batch(world, QL, QR, t=times, method="coal")
    np.testing.assert_allclose(d, d_coal, atol=COAL_GJK)
    _check_against_scalar(world, QL, QR, None, times, d, idx)
    D = pair_distances_batch(world, QL, QR, t=times)
    np.testing.assert_array_equal(D.min(axis=1), d)
    agv = world.pair_names.index(("left/pedestal", "obstacle/agv"))
    assert D[0, agv] > 0.1 and D[:, agv].min() < -0.05  # apart at the start, then through the pedestal
    assert any(world.pair_names[k] == ("left/pedestal", "obstacle/agv") for k in idx)


def test_capsule_bar_cell():
    base = Cell.default()
    flip = pose(pin.rpy.rpyToMatrix(0.0, np.pi / 2, 0.0))
    w = World(dataclasses.replace(base, bar=Bar("capsule", (0.03, 0.7), base.bar.T_object_bar @ flip)))
    rng = np.random.default_rng(23)
    QL, QR, Tw, t = _random(rng, 300)
    d, idx = clearance_batch(w, QL, QR, Tw, t)
    _check_against_scalar(w, QL, QR, Tw, t, d, idx)


def test_pair_distances_batch(world):
    rng = np.random.default_rng(24)
    QL, QR, Tw, t = _random(rng, 80)
    D = pair_distances_batch(world, QL, QR, Tw, t)
    assert D.shape == (80, len(world.pair_ids))
    d, _ = clearance_batch(world, QL, QR, Tw, t, method="kernel")
    np.testing.assert_array_equal(D.min(axis=1), d)
    for i in range(0, 80, 9):
        ref = world.clearance(QL[i], QR[i], Tw[i], t[i], per_pair=True).pair_distances
        assert np.abs(D[i] - ref).max() < COAL_GJK


def test_kernel_is_built_once_per_world(world):
    assert batch_kernel(world) is batch_kernel(world)
    assert batch_kernel(World(Cell.default())) is not batch_kernel(world)


def test_bad_input(world):
    z = np.zeros((3, 6))
    for method in ("auto", "kernel", "coal"):
        with pytest.raises(JointError):
            clearance_batch(world, np.full((3, 6), np.nan), z, method=method)
        with pytest.raises(JointError):
            clearance_batch(world, np.zeros((3, 5)), z, method=method)
        with pytest.raises(ParameterError):
            clearance_batch(world, z, np.zeros((2, 6)), method=method)
        with pytest.raises(ParameterError):
            clearance_batch(world, z, z, T_world_object=np.tile(np.eye(4), (2, 1, 1)), method=method)
        with pytest.raises(PoseError):
            clearance_batch(world, z, z, T_world_object=np.full((3, 4, 4), np.nan), method=method)
        with pytest.raises(PoseError):
            clearance_batch(world, z, z, T_world_object=np.ones((3, 4, 4)), method=method)
        with pytest.raises(ParameterError, match="finite"):
            clearance_batch(world, z, z, t=[0.0, np.inf, 1.0], method=method)
        with pytest.raises(ParameterError, match="times"):
            clearance_batch(world, z, z, t=[0.0, 1.0], method=method)
    with pytest.raises(ParameterError, match="method"):
        clearance_batch(world, z, z, method="gpu")
    with pytest.raises(JointError):
        pair_distances_batch(world, np.full((2, 6), np.nan), np.zeros((2, 6)))
