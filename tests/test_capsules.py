"""Capsules of arms other than the PUMA, fitted around their URDF collision geometry
(dualpuma.kinematics.capsules): they contain every mesh vertex, and coal's distances to them are
lower bounds of coal's distances to the meshes themselves (the capsules are conservative)."""

import math
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest
from urdf_reference import FullUrdf

from dualpuma.kinematics import Arm, fit_capsule
from dualpuma.kinematics.capsules import Capsule


def point_segment(X, a, b):
    ab = b - a
    s = np.clip((X - a) @ ab / max(ab @ ab, 1e-300), 0.0, 1.0)
    return np.linalg.norm(X - (a + s[:, None] * ab), axis=1)


@pytest.mark.parametrize("shape", ["rod", "blob", "plate", "single"])
def test_fit_contains_every_point(shape, rng):
    X = {"rod": rng.normal(0, [0.02, 0.03, 0.4], (500, 3)), "blob": rng.normal(0, 0.05, (300, 3)),
         "plate": rng.uniform([-0.1, -0.1, -0.005], [0.1, 0.1, 0.005], (400, 3)), "single": np.ones((1, 3))}[shape]
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    X = X @ R.T + rng.normal(0, 1, 3)
    M, r, length = fit_capsule(X, pad=0.0)
    a, b = M[:3, 3] - 0.5 * length * M[:3, 2], M[:3, 3] + 0.5 * length * M[:3, 2]
    assert point_segment(X, a, b).max() <= r + 1e-12
    if shape == "rod":  # the axis found is the rod's, the radius far below its length
        assert abs(M[:3, 2] @ R[:, 2]) > 0.99 and r < 0.2 * length


def brute_force_circle(Q):
    """The smallest circle containing 2-D points Q, over every circle through two or three of them."""
    best = math.inf
    n = len(Q)
    for i in range(n):
        for j in range(i + 1, n):
            c = 0.5 * (Q[i] + Q[j])
            cands = [(c, np.linalg.norm(Q[i] - c))]
            for k in range(j + 1, n):
                A = 2.0 * np.array([Q[j] - Q[i], Q[k] - Q[i]])
                if abs(np.linalg.det(A)) > 1e-14:
                    cc = np.linalg.solve(A, [Q[j] @ Q[j] - Q[i] @ Q[i], Q[k] @ Q[k] - Q[i] @ Q[i]])
                    cands.append((cc, np.linalg.norm(Q[i] - cc)))
            for cc, r in cands:
                if r < best and np.linalg.norm(Q - cc, axis=1).max() <= r * (1 + 1e-12):
                    best = r
    return best


@pytest.mark.parametrize("seed", range(4))
def test_fit_radius_is_the_smallest_enclosing_circle(seed):
    """Two equal layers of a 2-D blob at z = -0.5 and +0.5 m: the capsule's axis is z and its radius
    (no pad) the smallest circle around the blob, found here over every circle through two or three
    points. (The circle search scans with numpy since the twentieth session: a Kinova took 9 s.)"""
    Q = np.random.default_rng(seed).normal(0.0, [0.05, 0.03], (22, 2))
    X = np.vstack([np.column_stack([Q, np.full(len(Q), z)]) for z in (-0.5, 0.5)])
    M, r, length = fit_capsule(X, pad=0.0)
    assert abs(M[2, 2]) > 1.0 - 1e-12
    assert r == pytest.approx(brute_force_circle(Q), rel=1e-9, abs=1e-15)
    assert length == pytest.approx(1.0, abs=1e-9)  # the points on the circle need the whole 1 m


def mesh_geometry(arm):
    """The arm's URDF collision geometry loaded by Pinocchio itself (an independent path)."""
    gm = pin.buildGeomFromUrdf(arm.model, str(arm.urdf_path), pin.COLLISION, package_dirs=arm.package_dirs)
    return [go for go in gm.geometryObjects if hasattr(go.geometry, "vertices")]


@pytest.mark.parametrize("name", ["ur5", "ur10"])
def test_ur_capsules_contain_every_collision_vertex(name):
    arm = Arm.load(name)
    assert arm.capsule_source.startswith("fitted")
    for go in mesh_geometry(arm):
        V = np.asarray(go.geometry.vertices())
        P = go.placement.homogeneous
        X = V @ P[:3, :3].T + P[:3, 3]  # in the joint frame
        caps = [c for c in arm.capsules if c.joint == go.parentJoint]
        d = np.min([point_segment(X, *c.segment(np.eye(4))) - c.radius for c in caps], axis=0)
        assert d.max() <= -0.0009, (go.name, d.max())  # inside, with the 1 mm pad


def test_capsule_distances_are_lower_bounds_of_the_mesh_distances(rng):
    """For random placements of each UR5 link and a random box, coal's capsule-box distance is at
    most coal's mesh-box distance (never optimistic)."""
    arm = Arm.load("ur5")
    meshes = {go.parentJoint: go for go in mesh_geometry(arm)}
    worst = -np.inf
    for _ in range(1500):
        cap = arm.capsules[int(rng.integers(len(arm.capsules)))]
        go = meshes[cap.joint]
        Rq = pin.Quaternion(*rng.normal(size=4)).normalized().toRotationMatrix()
        T_joint = pin.SE3(Rq, rng.normal(0, 0.05, 3))
        box = coal.Box(*rng.uniform(0.02, 0.4, 3))
        T_box = coal.Transform3s(pin.Quaternion(*rng.normal(size=4)).normalized().toRotationMatrix(),
                                 rng.normal(0, 0.35, 3))
        M = T_joint * pin.SE3(cap.placement)
        d_cap = coal.distance(coal.Capsule(cap.radius, cap.length), coal.Transform3s(M.rotation, M.translation), box,
                              T_box, coal.DistanceRequest(), coal.DistanceResult())
        Mm = T_joint * go.placement
        d_mesh = coal.distance(go.geometry, coal.Transform3s(Mm.rotation, Mm.translation), box, T_box,
                               coal.DistanceRequest(), coal.DistanceResult())
        if d_mesh > 0:
            worst = max(worst, d_cap - d_mesh)
    assert worst <= 1e-6


def test_arm_without_collision_geometry_gets_joint_to_joint_capsules(tmp_path):
    src = (Path(__file__).parent / "data" / "arm6.urdf").read_text()
    import re

    bare = re.sub(r"<collision>.*?</collision>", "", src, flags=re.DOTALL)
    p = tmp_path / "bare.urdf"
    p.write_text(bare)
    arm = Arm.from_urdf(p, "tool")
    assert arm.capsule_source.startswith("joint to joint") and all(isinstance(c, Capsule) for c in arm.capsules)
    assert len(arm.capsules) >= 5


def _shape_surface_points(geometry) -> np.ndarray | None:
    """Points on a collision shape's surface, in its own frame (independent of the fitting code)."""
    if hasattr(geometry, "vertices"):
        return np.asarray(geometry.vertices())
    if isinstance(geometry, coal.Cylinder):
        a = np.linspace(0.0, 2 * np.pi, 97)
        r, h = geometry.radius, geometry.halfLength
        rim = np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros_like(a)])
        return np.vstack([rim + [0, 0, h], rim - [0, 0, h]])
    return None


@pytest.mark.parametrize("name", ["z1", "kinova"])
def test_reduced_arm_matches_its_full_urdf(name, rng):
    """Arms whose URDF has more than the six arm joints (Z1: a gripper joint; Kinova Jaco2: finger
    links and continuous joints): the 6-joint arm's hand pose equals the full URDF model's, and
    every collision shape of the full model lies inside the arm's capsules at random joints."""
    arm = Arm.load(name)
    ref = FullUrdf(arm.urdf_path, [arm.model.names[j] for j in range(1, 7)], arm.hand_frame, arm.package_dirs)
    assert ref.model.nq > 6  # the case under test
    _, placements = ref.collision()
    rdata = arm.model.createData()
    n_points = 0
    for _ in range(25):
        q = rng.uniform(arm.limits[:, 0], arm.limits[:, 1])
        np.testing.assert_allclose(arm.fk(q), ref.fk(q), atol=1e-12)
        pin.forwardKinematics(arm.model, rdata, q)
        segs = [(c.segment(rdata.oMi[c.joint].homogeneous), c.radius) for c in arm.capsules]
        for go, M in placements(q):
            X = _shape_surface_points(go.geometry)
            if X is None:
                continue
            W = X @ M[:3, :3].T + M[:3, 3]
            d = np.min([point_segment(W, *s) - r for s, r in segs], axis=0)
            assert d.max() <= 1e-9, (go.name, d.max())
            n_points += len(W)
    assert n_points > 10_000


def _visual_points(geometry) -> tuple[np.ndarray, float]:
    """Points of a visual shape in its own frame, and a radius to add (a sphere's): a mesh's
    vertices, a box's corners, 64 points on each rim of a cylinder (within 0.13 % of its radius
    of the rim between them)."""
    if isinstance(geometry, coal.Box):
        h = np.asarray(geometry.halfSide)
        return np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * h, 0.0
    if isinstance(geometry, coal.Sphere):
        return np.zeros((1, 3)), float(geometry.radius)
    if isinstance(geometry, coal.Cylinder):
        a = np.linspace(0.0, 2 * np.pi, 64, endpoint=False)
        r, hl = float(geometry.radius), float(geometry.halfLength)
        rim = np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros(64)])
        return np.vstack([rim + (0, 0, hl), rim - (0, 0, hl)]), 0.0
    return np.asarray(geometry.vertices()).reshape(-1, 3), 0.0


# the most any point of the arm's visual geometry lies outside all its capsules, over random
# joints [m] (docs/robots.md, "Limits"): (at least, at most)
VISUAL_EXCESS = {"puma560": (-np.inf, 0.0), "ur3": (-np.inf, 0.0), "ur5": (-np.inf, 0.0),
                 "kinova": (0.0, 0.003), "ur10": (0.045, 0.055), "z1": (0.025, 0.04)}


@pytest.mark.parametrize("name", list(VISUAL_EXCESS))
def test_the_visual_geometry_against_the_capsules(name):
    """What the arm looks like (its URDF's visual geometry, loaded and posed by Pinocchio on the full
    URDF model, locked joints at their values) against its collision capsules (posed by the arm's
    own model), at 20 random joint vectors: the PUMA's, UR3's and UR5's visuals lie inside; the
    other arms' URDFs have collision models smaller than their meshes, by the amounts that
    docs/robots.md states."""
    arm = Arm.load(name)
    full = pin.buildModelFromUrdf(str(arm.urdf_path))
    visual = pin.buildGeomFromUrdf(full, str(arm.urdf_path), pin.VISUAL, package_dirs=arm.package_dirs)
    rng = np.random.default_rng(5)
    shapes = []
    for go in visual.geometryObjects:
        X, extra = _visual_points(go.geometry)
        shapes.append((int(go.parentJoint), go.placement.homogeneous, X, extra))
    fd, ad = full.createData(), arm.model.createData()
    lo, hi = np.maximum(arm.limits[:, 0], -np.pi), np.minimum(arm.limits[:, 1], np.pi)
    worst = -np.inf
    for q in rng.uniform(lo, hi, (20, 6)):
        qf = pin.neutral(full)
        values = {arm.model.names[j]: q[arm.model.idx_qs[j]] for j in range(1, arm.model.njoints)}
        for joint, value in (values | arm.locked_joints).items():
            jf = full.getJointId(joint)
            i = full.idx_qs[jf]
            qf[i : i + full.nqs[jf]] = (math.cos(value), math.sin(value)) if full.nqs[jf] == 2 else value  # continuous
        pin.forwardKinematics(full, fd, qf)
        pin.forwardKinematics(arm.model, ad, q)
        segments = [(*c.segment(ad.oMi[c.joint].homogeneous), c.radius) for c in arm.capsules]
        for joint, M, X, extra in shapes:
            T = fd.oMi[joint].homogeneous @ M
            W = X @ T[:3, :3].T + T[:3, 3]
            out = np.min([point_segment(W, a, b) - r for a, b, r in segments], axis=0) + extra
            worst = max(worst, float(out.max()))
    least, most = VISUAL_EXCESS[name]
    assert least < worst <= most, (name, worst)
