"""The vectorised clearance kernel (dualpuma.kernel) against coal and independent references.

References used here share no code with the kernel: tests/geometry_reference.py (segment–segment by
the stationary point plus the four edge problems, capsule–box by golden-section search and a
separating-axis depth), brute-force sampling, and Pinocchio/coal themselves (world.clearance,
updateGeometryPlacements, computeDistances).
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import coal
import numpy as np
import pinocchio as pin
import pytest
from geometry_reference import (
    box_surface_samples,
    capsule_box,
    capsule_capsule,
    pose,
    segment_segment,
)

from dualpuma import puma
from dualpuma.collision import ClearanceKernel, KernelUnsupported, point_box, segment_box
from dualpuma.collision import segment_segment as k_segseg
from dualpuma.errors import JointError, ParameterError, PoseError
from dualpuma.model import ArmMount, Bar, Cell, Obstacle, World

LIM = puma.JOINT_LIMITS
TOL = 1e-9  # [m]
COAL_GJK = 2e-6  # coal's GJK/EPA stop at a relative tolerance of 1e-6: its box answers can be this far off



def _cells() -> dict[str, Cell]:
    base = Cell.default()
    obstacles = (
        Obstacle("crate", "box", (0.3, 0.2, 0.25), pose(pin.rpy.rpyToMatrix(0.1, 0.2, 0.3), (1.5, 0.35, 0.35))),
        Obstacle("ball", "sphere", (0.12,), pose(p=(1.45, -0.45, 0.5))),
        Obstacle("post", "capsule", (0.05, 0.5), pose(pin.rpy.rpyToMatrix(0.4, 0.0, 0.2), (1.5, -0.2, 0.25))),
        Obstacle("agv", "box", (0.4, 0.4, 0.3), pose(p=(0.8, -0.5, 0.15)), velocity=(0.5, 0.1, 0.0), t_start=0.5, t_end=3.0),
        Obstacle("drone", "capsule", (0.06, 0.3), pose(pin.rpy.rpyToMatrix(1.0, 0.2, 0.0), (1.3, -0.4, 0.2)),
                 velocity=(0.1, 0.0, 0.05), t_start=0.0, t_end=5.0),
    )  # fmt: skip
    flip = pose(pin.rpy.rpyToMatrix(0.0, np.pi / 2, 0.0))  # capsule axis (z) along the bar (object x)
    return {
        "default": base,
        "obstacles": dataclasses.replace(base, obstacles=obstacles),
        "capsule_bar": dataclasses.replace(base, bar=Bar("capsule", (0.03, 0.7), base.bar.T_object_bar @ flip), obstacles=obstacles),
        "sphere_bar": dataclasses.replace(base, bar=Bar("sphere", (0.1,), base.bar.T_object_bar), obstacles=obstacles[:3]),
        "ur5": dataclasses.replace(
            base, left=_ur5(base, "left"), right=_ur5(base, "right"), obstacles=obstacles[:3],
        ),
    }  # fmt: skip


def _ur5(base: Cell, side: str) -> ArmMount:
    """A UR5 on the PUMA's base, its home joints holding the bar at the PUMA's grasp (a cell's must)."""
    from dualpuma.kinematics import Arm

    T_wb = getattr(base, side).T_world_base
    H = np.linalg.inv(T_wb) @ base.T_world_object_start @ getattr(base, f"grasp_{side}").T_object_hand
    sols, ok = Arm.load("ur5").ik_all(H)
    return ArmMount(side, "ur5", T_wb, sols[np.flatnonzero(ok)[0]])


CELLS = _cells()


@pytest.fixture(scope="module")
def worlds():
    return {name: World(cell) for name, cell in CELLS.items()}


def _batch(cell: Cell, rng: np.random.Generator, n: int, *, near_home: bool, with_pose: bool):
    """Joints (n, 12), optional random bar frames (n, 4, 4) and times (n,) for a cell."""
    if near_home:
        Q = np.hstack([cell.left.q_home + rng.normal(0, 0.4, (n, 6)), cell.right.q_home + rng.normal(0, 0.4, (n, 6))])
    else:
        Q = np.hstack([rng.uniform(LIM[:, 0], LIM[:, 1], (n, 6)), rng.uniform(LIM[:, 0], LIM[:, 1], (n, 6))])
    Tw = None
    if with_pose:
        Tw = np.array(
            [pose(pin.rpy.rpyToMatrix(*rng.uniform(-np.pi, np.pi, 3)), rng.uniform([0.9, -0.7, -0.1], [2.1, 0.7, 1.0])) for _ in range(n)]
        )
    return Q, Tw, rng.uniform(0.0, 4.0, n)


def _world_shapes(world: World, M: np.ndarray, i: int, g: int):
    """Geometry g at configuration i as an independent-reference shape from its placement (4, 4)."""
    info = world.geoms[g]
    T = M[i, g]
    if info.shape == "capsule":
        h = 0.5 * info.size[1] * T[:3, 2]
        return "capsule", (T[:3, 3] - h, T[:3, 3] + h, info.size[0])
    if info.shape == "sphere":
        return "capsule", (T[:3, 3], T[:3, 3], info.size[0])
    if info.shape == "box":
        return "box", (T, info.size)
    return info.shape, T


def _reference_pair(world: World, M: np.ndarray, i: int, a: int, b: int) -> float | None:
    """Independent distance of one pair (None for box–box: no exact reference here)."""
    A, B = _world_shapes(world, M, i, a), _world_shapes(world, M, i, b)
    if A[0] != "capsule" and B[0] == "capsule":
        A, B = B, A
    if A[0] == "box" and B[0] == "halfspace":
        A, B = B, A
    if A[0] == "capsule" and B[0] == "capsule":
        return capsule_capsule(A[1], B[1])
    if A[0] == "capsule" and B[0] == "box":
        return capsule_box(A[1], *B[1])
    if A[0] == "capsule" and B[0] == "halfspace":
        p0, p1, r = A[1]
        return float(min(p0[2], p1[2]) - r - world.cell.floor_z)  # the floor: z = floor_z, normal +z
    if A[0] == "halfspace" and B[0] == "box":
        T, size = B[1]
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * (np.asarray(size) / 2)
        return float((corners @ T[:3, :3].T + T[:3, 3])[:, 2].min() - world.cell.floor_z)
    return None


# ----------------------------------------------------------------------------- closed forms
def test_segment_segment_matches_reference_and_brute_force():
    rng = np.random.default_rng(2)
    n = 3000
    p0, p1, q0, q1 = rng.normal(size=(4, 3, n))
    p1[:, :300] = p0[:, :300]  # first segment a point
    q1[:, 300:600] = q0[:, 300:600]  # second segment a point
    p1[:, 600:700], q1[:, 600:700] = p0[:, 600:700], q0[:, 600:700]  # both points
    d = q1[:, 700:1100] - q0[:, 700:1100]
    p1[:, 700:1100] = p0[:, 700:1100] + rng.uniform(-2, 2, 400) * d  # parallel (either direction)
    p0[:, 900:1100] = q0[:, 900:1100] + rng.uniform(-1, 1, 200) * d[:, 200:]  # ... and collinear, overlapping
    p1[:, 900:1100] = p0[:, 900:1100] + rng.uniform(-2, 2, 200) * d[:, 200:]
    e = q1[:, 1100:1300] - q0[:, 1100:1300]
    p1[:, 1100:1300] = p0[:, 1100:1300] + e + 1e-9 * rng.normal(size=(3, 200))  # nearly parallel
    D1, D2 = p1 - p0, q1 - q0
    got, s, t = k_segseg(p0, D1, q0, D2, (D1 * D1).sum(0), (D2 * D2).sum(0))
    ref = np.array([segment_segment(p0[:, i], p1[:, i], q0[:, i], q1[:, i]) for i in range(n)])
    np.testing.assert_allclose(got, ref, atol=1e-12, rtol=0)
    # the returned parameters are a closest pair
    assert np.all((s >= 0) & (s <= 1) & (t >= 0) & (t <= 1))
    np.testing.assert_allclose(np.linalg.norm(p0 + s * D1 - q0 - t * D2, axis=0), got, atol=1e-12)
    # brute force on a dense grid never beats the exact value, and comes close to it
    g = np.linspace(0, 1, 401)
    for i in range(0, n, 97):
        P = p0[:, i, None] + g * D1[:, i, None]
        Q = q0[:, i, None] + g * D2[:, i, None]
        brute = np.min(np.linalg.norm(P[:, :, None] - Q[:, None, :], axis=0))
        assert got[i] <= brute + 1e-12 and brute - got[i] < 0.02


def _random_segment_box(rng, n):
    h = rng.uniform(0.02, 0.4, (3, n))
    A = rng.uniform(-0.6, 0.6, (3, n))
    B = rng.normal(0, 0.4, (3, n))
    B[:, : n // 10] = 0.0  # points
    axis = rng.integers(0, 3, n)
    for i in range(n // 10, n // 5):  # parallel to a box axis
        v = np.zeros(3)
        v[axis[i]] = rng.uniform(-1, 1)
        B[:, i] = v
    A[:, n // 5 : n // 4] = rng.uniform(-1, 1, (3, n // 4 - n // 5)) * 0.5 * h[:, n // 5 : n // 4]  # start inside
    return A, B, h


def test_segment_box_matches_reference():
    rng = np.random.default_rng(3)
    n = 1500
    A, B, h = _random_segment_box(rng, n)
    got = segment_box(A, B, h)
    ref = np.array([capsule_box((A[:, i], A[:, i] + B[:, i], 0.0), np.eye(4), 2 * h[:, i]) for i in range(n)])
    np.testing.assert_allclose(got, ref, atol=TOL, rtol=0)
    assert (ref < 0).sum() > 200 and (ref > 0).sum() > 200  # both regimes exercised


def test_segment_box_against_sampling():
    """Apart: dense samples of segment and box surface; meeting: the overlap of the projections
    over many directions (an upper bound of the penetration depth that approaches it)."""
    rng = np.random.default_rng(4)
    n = 120
    A, B, h = _random_segment_box(rng, n)
    got = segment_box(A, B, h)
    dirs = rng.normal(size=(20000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    for i in range(n):
        seg = A[:, i] + np.linspace(0, 1, 300)[:, None] * B[:, i]
        if got[i] > 0:
            surf = box_surface_samples(np.eye(4), 2 * h[:, i], n=40)
            brute = np.min(np.linalg.norm(seg[:, None] - surf[None], axis=-1))
            assert not np.all(np.abs(seg) <= h[:, i], axis=1).any()
            assert got[i] <= brute + 1e-12 and brute - got[i] < 0.02
        else:
            proj = dirs @ np.stack([A[:, i], A[:, i] + B[:, i]], axis=1)  # (K, 2)
            box_r = np.abs(dirs) @ h[:, i]
            overlap = np.minimum(proj.max(axis=1) + box_r, box_r - proj.min(axis=1))
            assert -got[i] <= overlap.min() + 1e-12 and overlap.min() + got[i] < 0.01


def test_point_box_signed():
    h = np.array([0.1, 0.2, 0.3])[:, None]
    x = np.array([[0.0, 0.05, 0.3, 0.0], [0.0, 0.0, 0.0, 0.5], [0.0, 0.0, 0.0, 0.7]])
    np.testing.assert_allclose(point_box(x, h), [-0.1, -0.05, 0.2, np.hypot(0.3, 0.4)], atol=1e-15)


# ----------------------------------------------------------------------------- kinematics
@pytest.mark.parametrize("name", list(CELLS))
def test_geometry_placements_equal_pinocchio(worlds, name):
    w = worlds[name]
    k = ClearanceKernel(w, block=37)
    rng = np.random.default_rng(5)
    Q, Tw, t = _batch(CELLS[name], rng, 120, near_home=False, with_pose=True)
    for Tw_i in (None, Tw):
        M = k.geometry_placements(Q, Tw_i, t)
        for i in range(0, 120, 7):
            w.clearance(Q[i, :6], Q[i, 6:], None if Tw_i is None else Tw_i[i], t[i])  # sets geom_data.oMg
            ref = np.array([w.geom_data.oMg[g].homogeneous for g in range(len(w.geoms))])
            np.testing.assert_allclose(M[i], ref, atol=1e-12)


def _stub_world(joints):
    """A World-like object: one chain of the given joints, a capsule on each, a sphere, a box, a floor."""
    model = pin.Model()
    rng = np.random.default_rng(6)
    parent = 0
    for j, jm in enumerate(joints):
        M = pin.SE3(pin.rpy.rpyToMatrix(*rng.uniform(-1, 1, 3)), rng.uniform(-0.3, 0.3, 3))
        parent = model.addJoint(parent, jm, M, f"j{j}")
    gm = pin.GeometryModel()
    for j in range(1, model.njoints):
        M = pin.SE3(pin.rpy.rpyToMatrix(*rng.uniform(-1, 1, 3)), rng.uniform(-0.1, 0.1, 3))
        gm.addGeometryObject(pin.GeometryObject(f"c{j}", j, M, coal.Capsule(0.05, 0.3)))
    gm.addGeometryObject(pin.GeometryObject("ball", 0, pin.SE3(np.eye(3), np.array([0.2, 0.1, 0.3])), coal.Sphere(0.1)))
    bar = gm.addGeometryObject(pin.GeometryObject("box", model.njoints - 1, pin.SE3.Identity(), coal.Box(0.3, 0.1, 0.05)))
    floor = gm.addGeometryObject(pin.GeometryObject("floor", 0, pin.SE3.Identity(), coal.Halfspace(np.array([0.0, 0.0, 1.0]), -0.4)))
    pairs = [(a, b) for a in range(gm.ngeoms) for b in range(a + 2, gm.ngeoms) if a != floor]
    pairs += [(j - 1, floor) for j in range(1, model.njoints)] + [(bar, floor)]
    pairs = sorted(set(pairs))
    for a, b in pairs:
        gm.addCollisionPair(pin.CollisionPair(a, b))
    return SimpleNamespace(model=model, geom_model=gm, bar_id=bar, T_object_bar=np.eye(4), moving=[], pair_ids=pairs)


def test_any_revolute_or_prismatic_chain_matches_pinocchio():
    """Unaligned revolute and prismatic axes, x/y/z joints: placements and minimum distance."""
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    joints = [pin.JointModelRZ(), pin.JointModelRevoluteUnaligned(axis), pin.JointModelPX(), pin.JointModelRX(),
              pin.JointModelPrismaticUnaligned(axis[::-1].copy()), pin.JointModelRY(), pin.JointModelPY()]  # fmt: skip
    w = _stub_world(joints)
    k = ClearanceKernel(w, block=64)
    rng = np.random.default_rng(7)
    Q = rng.uniform(-2.0, 2.0, (300, w.model.nq))
    M = k.geometry_placements(Q)
    d, idx = k(Q)
    data, gd = w.model.createData(), pin.GeometryData(w.geom_model)
    for i in range(300):
        kk = pin.computeDistances(w.model, data, w.geom_model, gd, Q[i])
        ref = np.array([gd.oMg[g].homogeneous for g in range(w.geom_model.ngeoms)])
        np.testing.assert_allclose(M[i], ref, atol=1e-12)
        per_pair = np.array([r.min_distance for r in gd.distanceResults])
        assert abs(d[i] - gd.distanceResults[kk].min_distance) < COAL_GJK
        assert abs(per_pair[idx[i]] - per_pair.min()) < COAL_GJK


def test_unsupported_joint_is_refused():
    w = _stub_world([pin.JointModelRZ(), pin.JointModelSpherical()])
    with pytest.raises(KernelUnsupported, match="JointModelSpherical"):
        ClearanceKernel(w)


# ----------------------------------------------------------------------------- against coal
def _coal_exception_ok(world, M, i, k, got, coal_d) -> bool:
    """A kernel/coal difference above TOL is accepted only for a box pair, within coal's GJK/EPA
    tolerance, and with the kernel equal to the independent reference to TOL."""
    a, b = world.pair_ids[k]
    if "box" not in (world.geoms[a].shape, world.geoms[b].shape) or abs(got - coal_d) > COAL_GJK:
        return False
    ref = _reference_pair(world, M, i, a, b)
    return ref is not None and abs(got - ref) < TOL


@pytest.mark.parametrize("name", list(CELLS))
def test_minimum_equals_coal(worlds, name):
    """The batch minimum equals world.clearance's (coal) to 1e-9 m on 1,200 configurations per
    cell (uniform over the joint limits, near the start, random bar poses and times), penetrating
    ones included; the returned pair holds the minimum."""
    w, cell = worlds[name], CELLS[name]
    k = ClearanceKernel(w, block=256)
    rng = np.random.default_rng(8)
    n_pen = n_exc = 0
    for near_home, with_pose in ((False, False), (True, False), (False, True)):
        Q, Tw, t = _batch(cell, rng, 400, near_home=near_home, with_pose=with_pose)
        d, idx = k(Q, Tw, t)
        M = k.geometry_placements(Q, Tw, t)
        for i in range(Q.shape[0]):
            c = w.clearance(Q[i, :6], Q[i, 6:], None if Tw is None else Tw[i], t[i], per_pair=True)
            n_pen += c.distance < 0
            ok = abs(d[i] - c.distance) <= TOL and abs(c.pair_distances[idx[i]] - c.distance) <= TOL
            if not ok:
                # coal's own tolerance: the kernel must then equal the independent reference
                assert _coal_exception_ok(w, M, i, int(idx[i]), d[i], c.pair_distances[idx[i]]), (name, i, d[i], c.distance)
                assert c.distance - COAL_GJK <= d[i] <= c.distance + COAL_GJK
                n_exc += 1
    assert n_pen > 150, n_pen  # penetrations are part of the check
    assert n_exc <= 3, n_exc


@pytest.mark.parametrize("name", ["obstacles", "capsule_bar", "ur5"])
def test_every_pair_equals_coal_and_reference(worlds, name):
    """All pairs (no pruning): closed forms vs coal to 1e-9 m (capsule–box within coal's GJK
    tolerance where the independent reference sides with the kernel), and vs the independent
    references to 1e-9 m."""
    w, cell = worlds[name], CELLS[name]
    k = ClearanceKernel(w)
    rng = np.random.default_rng(9)
    Q, Tw, t = _batch(cell, rng, 300, near_home=False, with_pose=True)
    D = k.pair_distances(Q, Tw, t)
    M = k.geometry_placements(Q, Tw, t)
    kinds = set()
    n_exc = 0
    for i in range(Q.shape[0]):
        c = w.clearance(Q[i, :6], Q[i, 6:], Tw[i], t[i], per_pair=True)
        for kk in np.flatnonzero(np.abs(D[i] - c.pair_distances) > TOL):
            assert _coal_exception_ok(w, M, i, int(kk), D[i, kk], c.pair_distances[kk]), (i, w.pair_names[kk])
            n_exc += 1
        if i % 5 == 0:
            for kk, (a, b) in enumerate(w.pair_ids):
                ref = _reference_pair(w, M, i, a, b)
                if ref is not None:
                    assert abs(D[i, kk] - ref) < TOL, (i, w.pair_names[kk], D[i, kk], ref)
                    kinds.add(tuple(sorted((w.geoms[a].shape, w.geoms[b].shape))) + (ref < 0,))
    assert n_exc <= 0.001 * D.size
    assert ("capsule", "capsule", True) in kinds and ("box", "capsule", True) in kinds  # penetrations checked
    assert ("box", "capsule", False) in kinds and kinds & {("capsule", "halfspace", True), ("capsule", "halfspace", False)}


@pytest.mark.parametrize("name", ["routine8_overhang", "slot_field"])
def test_culled_minimum_equals_full_evaluation(name):
    """The bounds-first minimum (most pairs never evaluated exactly) is bitwise the minimum, and the
    pair the first one holding it, of the every-pair evaluation (no culling), and equals coal's
    minimum (world.clearance) to 1e-9 m; near the start, uniform, with bar poses, penetrations
    included."""
    from dualpuma.model.cell_file import example_cell
    from dualpuma.scenarios import slot_field_cell

    cell = slot_field_cell()[0] if name == "slot_field" else example_cell(name)
    w = World(cell)
    k = ClearanceKernel(w, block=512)
    rng = np.random.default_rng(11)
    n_pen = 0
    for near_home, with_pose, n in ((True, False, 1500), (False, False, 600), (True, True, 600)):
        Q, Tw, t = _batch(cell, rng, n, near_home=near_home, with_pose=with_pose)
        if near_home and not with_pose:  # the planner's regime: close to the start
            Q = np.hstack([cell.left.q_home + rng.normal(0, 0.2, (n, 6)), cell.right.q_home + rng.normal(0, 0.2, (n, 6))])
        d, idx = k(Q, Tw, t)
        D = k.pair_distances(Q, Tw, t)
        np.testing.assert_array_equal(d, D.min(axis=1))
        np.testing.assert_array_equal(idx, D.argmin(axis=1))  # the first pair holding the minimum
        n_pen += int((d < 0).sum())
        M = k.geometry_placements(Q, Tw, t)
        for i in range(0, n, 5):
            c = w.clearance(Q[i, :6], Q[i, 6:], None if Tw is None else Tw[i], t[i], per_pair=True)
            if abs(d[i] - c.distance) > TOL:  # coal's own GJK tolerance: the reference must side with the kernel
                assert _coal_exception_ok(w, M, i, int(idx[i]), d[i], c.pair_distances[idx[i]]), (name, i, d[i], c.distance)
    assert n_pen > 100, n_pen


def test_moving_obstacles_follow_time(worlds):
    w = worlds["obstacles"]
    k = ClearanceKernel(w)
    cell = CELLS["obstacles"]
    times = np.linspace(-1.0, 6.0, 71)
    Q = np.tile(np.concatenate([cell.left.q_home, cell.right.q_home]), (71, 1))
    M = k.geometry_placements(Q, t=times)
    ids = {g.name: i for i, g in enumerate(w.geoms)}
    for ob in cell.obstacles:
        for i, ti in enumerate(times):
            np.testing.assert_allclose(M[i, ids[f"obstacle/{ob.name}"]], ob.pose_at(ti), atol=1e-15)
    d, _ = k(Q, t=times)
    ref = [w.clearance(Q[i, :6], Q[i, 6:], t=ti).distance for i, ti in enumerate(times)]
    np.testing.assert_allclose(d, ref, atol=TOL)


def test_results_do_not_depend_on_blocks_or_order(worlds):
    w, cell = worlds["obstacles"], CELLS["obstacles"]
    rng = np.random.default_rng(10)
    Q, Tw, t = _batch(cell, rng, 500, near_home=True, with_pose=True)
    d1, i1 = ClearanceKernel(w, block=1024)(Q, Tw, t)
    d2, i2 = ClearanceKernel(w, block=33)(Q[::-1], Tw[::-1], t[::-1])
    np.testing.assert_array_equal(d1, d2[::-1])
    np.testing.assert_array_equal(i1, i2[::-1])


# ----------------------------------------------------------------------------- bad input
def test_bad_input_is_refused(worlds):
    k = ClearanceKernel(worlds["default"])
    q = np.zeros((3, 12))
    for bad in (np.zeros((3, 11)), np.zeros(12), np.zeros((2, 3, 12)), [["a"] * 12]):
        with pytest.raises(JointError):
            k(bad)
    with pytest.raises(JointError, match="NaN"):
        k(np.full((3, 12), np.nan))
    with pytest.raises(JointError, match="NaN"):
        k(np.where(np.eye(3, 12) > 0, np.inf, 0.0))
    with pytest.raises(PoseError):
        k(q, T_world_object=np.tile(np.eye(4), (2, 1, 1)))  # wrong count
    with pytest.raises(PoseError):
        k(q, T_world_object=np.full((3, 4, 4), np.nan))
    with pytest.raises(PoseError):
        k(q, T_world_object=np.tile(2 * np.eye(4), (3, 1, 1)))  # not a rotation
    with pytest.raises(ParameterError, match="finite"):
        k(q, t=[0.0, np.nan, 1.0])
    with pytest.raises(ParameterError, match="times"):
        k(q, t=[0.0, 1.0])
    with pytest.raises(ParameterError, match="block"):
        ClearanceKernel(worlds["default"], block=0)
    d, idx = k(np.zeros((0, 12)))
    assert d.shape == (0,) and idx.shape == (0,)
