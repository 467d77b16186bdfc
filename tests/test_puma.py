"""Closed-form PUMA kinematics: seed FK, Pinocchio URDF, all-branch IK, singularities, bad input."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from seed_reference import (
    FLAG2_LEFT,
    FLAG2_RIGHT,
    ROUTINE1_LEFT,
    ROUTINE1_RIGHT,
    seed_calctran,
    seed_invkin_arm,
)
from urdf_reference import fk_many

from dualpuma import puma
from dualpuma.errors import JointError, PoseError

LIM = puma.JOINT_LIMITS
ROOT = Path(__file__).resolve().parents[1]


def random_q(rng, n):
    return rng.uniform(LIM[:, 0], LIM[:, 1], size=(n, 6))


def pin_fk_many(arm, Q, frame="wrist"):
    model, data = arm.model, arm.model.createData()
    return fk_many(model, data, model.getFrameId(frame), Q)


def angle_diff(a, b):
    return np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))


# ---------------------------------------------------------------- (a) FK: URDF == seed CalcTran
def test_pinocchio_fk_equals_seed_calctran(puma_arm, rng):
    Q = rng.uniform(-2 * np.pi, 2 * np.pi, size=(10_000, 6))
    T_pin = pin_fk_many(puma_arm, Q)
    T_seed = np.array([seed_calctran(q) for q in Q])
    assert np.abs(T_pin - T_seed).max() <= 1e-12
    assert np.abs(puma.fk(Q) - T_seed).max() <= 1e-12


def test_fk_at_zero_matches_seed_geometry():
    T = puma.fk(np.zeros(6))
    # upper arm along +x, forearm hanging down, approach pointing down
    np.testing.assert_allclose(T[:3, 3], [puma.A2 + puma.A3, puma.D2, -puma.D4], atol=1e-15)
    np.testing.assert_allclose(T[:3, :3], np.diag([1.0, -1.0, -1.0]), atol=1e-15)


def test_flange_and_gripper_frames(puma_arm, rng):
    q = random_q(rng, 1)[0]
    Tw = puma_arm.fk(q, "wrist")
    for frame, dist in (("flange", puma.D_FLANGE), ("gripper", 0.12)):
        Tf = puma_arm.fk(q, frame)
        np.testing.assert_allclose(Tf[:3, 3], Tw[:3, 3] + dist * Tw[:3, 2], atol=1e-14)
        np.testing.assert_allclose(Tf[:3, :3], Tw[:3, :3], atol=1e-14)


def test_flag2_start_reproduces_seed_object_frame():
    """The seed's routine 2-8 start: the bar's frame (377.3, -40.18, 50.47) screen units is the
    midpoint of both wrists (bases at x = 200, 400; shoulders at z = 137.08; 0.2 units per mm)."""
    pl = seed_calctran(np.array(FLAG2_LEFT))[:3, 3] * 1000 * 0.2 + [200, 0, 137.08]
    pr = puma.fk(np.array(FLAG2_RIGHT))[:3, 3] * 1000 * 0.2 + [400, 0, 137.08]
    np.testing.assert_allclose((pl + pr) / 2, [377.3, -40.18, 50.47], atol=0.02)


def test_urdf_is_generated_file_and_loads_from_anywhere(tmp_path):
    gen = subprocess.run([sys.executable, str(ROOT / "urdf" / "make_puma560.py")], capture_output=True, text=True, check=True)
    assert gen.stdout == (ROOT / "urdf" / "puma560.urdf").read_text()
    code = "import dualpuma, numpy as np; a = dualpuma.Arm.puma560(); print(a.fk(np.zeros(6))[2, 3])"
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, check=True)
    assert abs(float(out.stdout) + puma.D4) < 1e-12


def _surface(geom, rng, n=300):
    """Points on a visual primitive's surface in its own frame, its edges and corners included."""
    import coal

    if isinstance(geom, coal.Sphere):
        v = rng.normal(size=(n, 3))
        return v / np.linalg.norm(v, axis=1, keepdims=True) * geom.radius
    if isinstance(geom, coal.Box):
        P = rng.uniform(-1.0, 1.0, (n, 3))
        face = rng.integers(0, 3, n)
        P[np.arange(n), face] = np.sign(P[np.arange(n), face])
        corners = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
        return np.vstack([P, corners]) * geom.halfSide
    assert isinstance(geom, coal.Cylinder), type(geom)
    a, r, h = rng.uniform(0, 2 * np.pi, n), geom.radius, geom.halfLength
    rim = np.stack([r * np.cos(a), r * np.sin(a), np.where(np.arange(n) % 2, h, -h)], axis=1)
    side = rim.copy()
    side[:, 2] = rng.uniform(-h, h, n)
    caps = rim * np.sqrt(rng.uniform(0.0, 1.0, (n, 1))) * [1, 1, 0] + rim * [0, 0, 1]  # points on the end discs
    return np.vstack([rim, side, caps])


def test_every_drawn_part_lies_inside_the_collision_capsules():
    """What the viewer draws (the URDF's visuals) is never closer to anything than what the planner
    checks: every visual primitive's surface, edges and corners lie inside the union of the arm's
    collision capsules, at random joint values (placements by Pinocchio; the capsule test in numpy,
    point to segment; the URDF's collision cylinders are capsules)."""
    import pinocchio as pin

    urdf = str(ROOT / "urdf" / "puma560.urdf")
    model = pin.buildModelFromUrdf(urdf)
    vis, col = (pin.buildGeomFromUrdf(model, urdf, t) for t in (pin.GeometryType.VISUAL, pin.GeometryType.COLLISION))
    data, vd, cd = model.createData(), pin.GeometryData(vis), pin.GeometryData(col)
    rng = np.random.default_rng(5)
    points = [_surface(go.geometry, rng) for go in vis.geometryObjects]
    assert len(points) >= 20 and len(col.geometryObjects) == 8
    worst = {}
    for q in [np.zeros(6), *random_q(rng, 60)]:
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, vis, vd)
        pin.updateGeometryPlacements(model, data, col, cd)
        caps = [(M.translation - go.geometry.halfLength * M.rotation[:, 2], M.translation + go.geometry.halfLength
                 * M.rotation[:, 2], go.geometry.radius) for go, M in zip(col.geometryObjects, cd.oMg)]
        for go, M, X in zip(vis.geometryObjects, vd.oMg, points):
            Y = X @ M.rotation.T + M.translation
            out = np.full(len(Y), np.inf)
            for a, b, r in caps:
                s = np.clip((Y - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
                out = np.minimum(out, np.linalg.norm(Y - a - s[:, None] * (b - a), axis=1) - r)
            worst[go.name] = max(worst.get(go.name, -np.inf), float(out.max()))
    assert max(worst.values()) <= 0.0, {k: round(v * 1e3, 1) for k, v in worst.items() if v > 0}  # [mm]


# ---------------------------------------------------------------- joint limits
def test_limits_contain_seed_joint_values():
    inside = lambda q: bool(np.all((np.asarray(q) >= LIM[:, 0]) & (np.asarray(q) <= LIM[:, 1])))
    assert inside(FLAG2_LEFT) and inside(FLAG2_RIGHT)
    assert all(inside(q) for q in ROUTINE1_LEFT.values())
    assert inside(ROUTINE1_RIGHT["drill"])
    # The one exception, documented in docs/kinematics.md: the seed commands robot 2's wrist bend
    # to 105.1 deg in routine 1's hover phase, beyond the PUMA's +-100 deg.
    hover = np.asarray(ROUTINE1_RIGHT["hover"])
    bad = np.nonzero((hover < LIM[:, 0]) | (hover > LIM[:, 1]))[0].tolist()
    assert bad == [4] and math.degrees(hover[4]) == pytest.approx(105.1, abs=0.05)


# ---------------------------------------------------------------- (b) IK round trip
def test_ik_all_round_trip_100k(puma_arm, rng):
    Q = random_q(rng, 100_000)
    T = puma.fk(Q)
    S, V = puma.ik_all(T, q_near=Q)
    assert S.shape == (100_000, 8, 6) and V.shape == (100_000, 8)
    # every valid branch reproduces the pose through Pinocchio's FK of the URDF
    idx = np.argwhere(V)
    T_back = pin_fk_many(puma_arm, S[V])
    err = np.abs(T_back - T[idx[:, 0]]).max()
    assert err <= 1e-9
    # valid solutions lie inside the limits
    assert np.all(S[V] >= LIM[:, 0] - 1e-12) and np.all(S[V] <= LIM[:, 1] + 1e-12)
    # the branch q belongs to is valid and equals q (mod 2 pi)
    b = puma.branch_of(Q)
    rows = np.arange(len(Q))
    assert V[rows, b].all()
    assert angle_diff(S[rows, b], Q).max() <= 1e-8
    # unreachable branches are NaN, never plausible numbers
    assert not np.isnan(S[V]).any()


def test_branch_order_matches_seed_chars():
    rng = np.random.default_rng(7)
    for q in random_q(rng, 200):
        T = puma.fk(q)
        S, _V = puma.ik_all(T, q_near=q)
        for b in range(8):
            chars = (1 - 2 * (b >> 2 & 1), 1 - 2 * (b >> 1 & 1), 1 - 2 * (b & 1))
            assert puma.config_to_branch(*chars) == b
            ref = seed_invkin_arm(T, chars)
            if np.isnan(ref).any():
                continue
            assert angle_diff(ref, S[b]).max() < 1e-9


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6))
def test_ik_scalar_matches_batch(u):
    q = LIM[:, 0] + (np.asarray(u) + 1.0) / 2.0 * (LIM[:, 1] - LIM[:, 0])
    T = puma.fk(q)
    S1, V1 = puma.ik_all(T, q_near=q)
    S2, V2 = puma.ik_all(T[None], q_near=q[None])
    np.testing.assert_array_equal(V1, V2[0])
    # the same solutions: identical poses; angles equal up to rounding, which q4 and q6 amplify
    # (as ~1e-17 / |sin q5|) next to the wrist singularity
    np.testing.assert_allclose(puma.fk(S1[V1]), puma.fk(S2[0][V2[0]]), atol=1e-12)
    tol = 1e-9 + 1e-15 / max(abs(math.sin(q[4])), 1e-12)
    assert angle_diff(S1[V1], S2[0][V2[0]]).max() <= tol


def test_ik_picks_config_and_nearest(rng):
    for q in random_q(rng, 50):
        T = puma.fk(q)
        b = int(puma.branch_of(q))
        chars = (1 - 2 * (b >> 2 & 1), 1 - 2 * (b >> 1 & 1), 1 - 2 * (b & 1))
        r = puma.ik(T, config=chars, q_near=q)
        assert r.ok and r.branch == b and angle_diff(r.q, q).max() < 1e-8
        r2 = puma.ik(T, q_near=q + 1e-3)
        assert r2.ok and np.abs(r2.q - q).max() < 1e-8


def test_equivalent_angles_nearest_to_q_near():
    # q4 and q6 have 532 deg of travel: q and q + 2 pi are both legal; q_near decides
    q = np.array([0.2, -0.6, -0.8, 2.5, 0.6, -2.8])
    T = puma.fk(q)
    for shift4, shift6 in ((0, 0), (-2 * np.pi, 2 * np.pi)):
        ref = q + [0, 0, 0, shift4, 0, shift6]
        r = puma.ik(T, q_near=ref)
        assert r.ok and np.abs(r.q - ref).max() < 1e-8


# ---------------------------------------------------------------- (c) singular neighbourhoods
@pytest.mark.parametrize("mag", [1e-9, 1e-7, 1e-5, 1e-3])
def test_wrist_near_singular(puma_arm, rng, mag):
    Q = random_q(rng, 2000)
    Q[:, 4] = mag * rng.choice([-1.0, 1.0], size=2000) * rng.uniform(1, 10, 2000) / 10
    T = puma.fk(Q)
    S, V = puma.ik_all(T, q_near=Q)
    assert V.any(axis=1).all()
    T_back = pin_fk_many(puma_arm, S[V])
    assert np.abs(T_back - T[np.argwhere(V)[:, 0]]).max() <= 1e-9
    b = puma.branch_of(Q)
    own = S[np.arange(len(Q)), b]
    # q4 and q6 individually are ill-conditioned here; q4 + q6 and the other joints are not
    assert angle_diff(own[:, [0, 1, 2, 4]], Q[:, [0, 1, 2, 4]]).max() < 1e-8
    assert angle_diff(own[:, 3] + own[:, 5], Q[:, 3] + Q[:, 5]).max() < 1e-8


def test_wrist_exactly_singular_keeps_q4_from_q_near(rng):
    for q in random_q(rng, 100):
        q[4] = 0.0
        T = puma.fk(q)
        q_near = q.copy()
        q_near[3] = min(q[3] + 0.3, LIM[3, 1])  # the seed keeps theta4's old value
        r = puma.ik(T, config=int(puma.branch_of(q)), q_near=q_near)
        assert r.ok and r.wrist_singular
        assert r.q[3] == pytest.approx(q_near[3], abs=1e-12)
        # q4 + q6 is what the pose fixes: q6 absorbs the change
        assert angle_diff(r.q[3] + r.q[5], q[3] + q[5]) < 1e-9
        np.testing.assert_allclose(puma.fk(r.q), T, atol=1e-12)


def test_elbow_stretched(puma_arm, rng):
    Q = random_q(rng, 2000)
    gamma = math.atan2(puma.A3, puma.D4)
    Q[:, 2] = gamma - np.pi / 2 + rng.uniform(-1e-7, 1e-7, 2000)  # cos(gamma - q3) ~ 0: straight arm
    Q[:, 2] = np.clip(Q[:, 2], LIM[2, 0], LIM[2, 1])
    T = puma.fk(Q)
    S, V = puma.ik_all(T, q_near=Q)
    assert V.any(axis=1).all()
    assert np.abs(pin_fk_many(puma_arm, S[V]) - T[np.argwhere(V)[:, 0]]).max() <= 1e-9


def test_wrist_centre_near_shoulder_axis(puma_arm, rng):
    """r = 0: the wrist centre on the cylinder of radius d2 about joint 1 (shoulder singularity)."""
    out = []
    for q in random_q(rng, 3000):
        c3, s3 = math.cos(q[2]), math.sin(q[2])
        # solve a2 c2 + a3 c23 - d4 s23 = eps for q2: (a2 + a3 c3 - d4 s3) c2 - (a3 s3 + d4 c3) s2 = eps
        A, B = puma.A2 + puma.A3 * c3 - puma.D4 * s3, -(puma.A3 * s3 + puma.D4 * c3)
        eps = rng.uniform(-1e-6, 1e-6)
        ang = math.atan2(B, A)
        q[1] = math.acos(np.clip(eps / math.hypot(A, B), -1, 1)) - ang
        q[1] = (q[1] - LIM[1, 0]) % (2 * np.pi) + LIM[1, 0]
        if LIM[1, 0] <= q[1] <= LIM[1, 1]:
            out.append(q)
    Q = np.array(out)
    assert len(Q) > 200
    T = puma.fk(Q)
    S, V = puma.ik_all(T, q_near=Q)
    assert V.any(axis=1).all()
    assert np.abs(pin_fk_many(puma_arm, S[V]) - T[np.argwhere(V)[:, 0]]).max() <= 1e-9


# ---------------------------------------------------------------- unreachable + (f) bad input
def test_unreachable_is_a_status_not_nan():
    T = np.eye(4)
    T[:3, 3] = [2.0, 0.0, 0.0]  # beyond a2 + |d4| + ...
    S, V = puma.ik_all(T)
    assert not V.any() and np.isnan(S).all()
    r = puma.ik(T)
    assert not r.ok and r.status == "unreachable" and r.q is None and "reach" in r.reason
    T[:3, 3] = [0.0, 0.0, 0.0]  # inside the d2 cylinder about joint 1
    assert puma.ik(T).status == "unreachable"


def test_joint_limit_status():
    q = np.array([0.3, -0.4, -0.7, 0.2, 0.5, 0.1])
    T = puma.fk(q)
    tight = LIM.copy()
    tight[0] = [0.5, 1.0]
    r = puma.ik(T, config=int(puma.branch_of(q)), limits=tight)
    assert r.status == "joint_limits" and "[1]" in r.reason


@pytest.mark.parametrize(
    "bad, err",
    [
        (np.full((4, 4), np.nan), PoseError),
        (np.eye(3), PoseError),
        (np.diag([2.0, 1.0, 1.0, 1.0]), PoseError),  # not orthonormal
        (np.diag([-1.0, 1.0, 1.0, 1.0]), PoseError),  # reflection, det -1
        (np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1.0]]), PoseError),
        (np.stack([np.eye(4), np.diag([1.0, 1.0, 1.0 + 1e-6, 1.0])]), PoseError),
        (np.array([[1, 0, 0, np.inf], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]), PoseError),
    ],
)
def test_bad_pose_raises(bad, err):
    with pytest.raises(err):
        puma.ik_all(bad)


def test_bad_joints_raise():
    with pytest.raises(JointError):
        puma.fk(np.zeros(5))
    with pytest.raises(JointError):
        puma.fk([0, 0, np.nan, 0, 0, 0])
    with pytest.raises(JointError):
        puma.ik(np.eye(4), config=9)
    with pytest.raises(JointError):
        puma.ik(np.eye(4), config=("left", "sideways", "flip"))
    with pytest.raises(JointError):
        puma.ik_all(np.eye(4), limits=np.zeros((5, 2)))
    with pytest.raises(PoseError):
        puma.ik(np.stack([np.eye(4)] * 2))


def _gap(a: float, lo: float, hi: float) -> float:
    """The distance of angle a [rad] from the range [lo, hi]."""
    return max(lo - a, a - hi, 0.0)


def test_a_branch_outside_the_limits_holds_the_equivalent_angles_nearest_them():
    """ik_all's rows outside the limits hold, for each joint whose range is narrower than a turn,
    the equivalent angle nearest that range (the docstring's promise; the flip branch's q5 was
    237.7 deg for [-100, 100] where -122.3 is nearer), and every reachable row, valid or not, is a
    solution: Pinocchio's FK of it (from the URDF) gives the pose back."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(ROOT / "urdf" / "puma560.urdf"))
    data, fid = model.createData(), model.getFrameId("wrist")
    lim = np.column_stack([model.lowerPositionLimit, model.upperPositionLimit])
    rng = np.random.default_rng(11)
    Q = rng.uniform(lim[:, 0], lim[:, 1], (300, 6))
    Q[:, 4] = rng.uniform(math.radians(101.0), math.radians(175.0), 300) * rng.choice([-1.0, 1.0], 300)  # q5 outside
    T = fk_many(model, data, fid, Q)
    sols, valid = puma.ik_all(T)
    checked = 0
    for i in range(len(Q)):
        for b in range(8):
            q = sols[i, b]
            if np.isnan(q).any():
                continue
            np.testing.assert_allclose(fk_many(model, data, fid, q[None])[0], T[i], atol=1e-9)
            if valid[i, b]:
                continue
            for j in range(6):
                lo, hi = lim[j]
                if hi - lo >= 2 * math.pi:
                    continue
                best = min(_gap(q[j] + 2 * math.pi * k, lo, hi) for k in range(-3, 4))
                assert _gap(q[j], lo, hi) == pytest.approx(best, abs=1e-12), (i, b, j, math.degrees(q[j]))
                checked += 1
    assert checked > 500


def test_a_batch_with_poses_on_the_shoulder_axis_is_silent():
    """ik_all on a batch of identity poses (the wrist on the shoulder axis: no solution) printed
    numpy's divide-by-zero and invalid-value warnings; one such pose alone was already silent."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sols, valid = puma.ik_all(np.stack([np.eye(4)] * 3))
        _, valid_one = puma.ik_all(np.eye(4))
    assert not valid.any() and not valid_one.any()
    assert sols.shape == (3, 8, 6)
