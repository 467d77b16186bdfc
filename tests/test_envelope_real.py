"""Real coordinated work envelope (dualpuma.envelope): membership against Pinocchio FK, the scalar
closed-form IK and an independent numeric IK; clearance against coal; the volume against a
Monte Carlo estimate with an independent membership and across resolutions; the x-z boundary;
marching squares on shapes of known perimeter and area; bad input."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest

from dualpuma import puma
from dualpuma.envelope import (
    MAX_GRID_POINTS,
    contains_real,
    contour_polylines,
    marching_squares,
    real_envelope,
    solve_real,
)
from dualpuma.errors import ParameterError, PoseError
from dualpuma.kinematics import Arm, hands_from_object
from dualpuma.model import example_cell

BOX_LO, BOX_HI = np.array([0.85, -0.95, -0.3]), np.array([2.15, 0.95, 1.6])  # contains the set


def _world_targets(cell, p: np.ndarray, R: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Hand targets in the world: T_world_object @ T_object_hand (no base frames involved)."""
    T = np.eye(4)
    T[:3, :3] = cell.T_world_object_start[:3, :3] if R is None else R
    T[:3, 3] = p
    return T @ cell.grasp_left.T_object_hand, T @ cell.grasp_right.T_object_hand


def _reference_member(cell, P: np.ndarray, R: np.ndarray | None = None, floor: bool = False) -> np.ndarray:
    """Independent membership: coordination.hands_from_object + the *scalar* closed-form IK per
    point (a separate implementation from the batch kernel the envelope uses), no reach filter."""
    out = np.zeros(len(P), dtype=bool)
    for n, p in enumerate(P):
        T = np.eye(4)
        T[:3, :3] = cell.T_world_object_start[:3, :3] if R is None else R
        T[:3, 3] = p
        TL, TR = hands_from_object(cell, T)
        out[n] = puma.ik_all(TL)[1].any() and puma.ik_all(TR)[1].any()
    return out & (P[:, 2] >= cell.floor_z) if floor else out


def _numeric_ik(arm, T: np.ndarray, rng, seeds=(), restarts: int = 16, iters: int = 100) -> bool:
    """Damped least squares on the Pinocchio model (URDF), joints clipped to the URDF's limits,
    from the given seeds and random in-limit ones: True if the hand reaches T to 1e-10."""
    lo, hi = arm.limits[:, 0], arm.limits[:, 1]
    target = pin.SE3(T[:3, :3], T[:3, 3])
    starts = [np.clip(s, lo, hi) for s in seeds if np.all(np.isfinite(s))]
    starts += [rng.uniform(lo, hi) for _ in range(restarts)]
    for q in starts:
        for _ in range(iters):
            pin.forwardKinematics(arm.model, arm.data, q)
            M = pin.updateFramePlacement(arm.model, arm.data, arm.hand_frame_id)
            err = pin.log6(M.actInv(target)).vector
            if np.linalg.norm(err) < 1e-10:
                return True
            J = pin.computeFrameJacobian(arm.model, arm.data, q, arm.hand_frame_id, pin.LOCAL)
            q = np.clip(q + J.T @ np.linalg.solve(J @ J.T + 1e-8 * np.eye(6), err), lo, hi)
    return False


@pytest.fixture(scope="module")
def sample(cell):
    rng = np.random.default_rng(5)
    P = rng.uniform(BOX_LO, BOX_HI, (600, 3))
    return P, solve_real(cell, P)


def test_inside_points_joints_reach_the_grasps_by_pinocchio_fk(cell, sample, puma_arm):
    P, sol = sample
    assert 100 < sol.inside.sum() < 500  # both classes well represented
    assert np.all(np.isnan(sol.q_left[~sol.inside])) and np.all(sol.orientation[~sol.inside] == -1)
    for side, Q in (("left", sol.q_left), ("right", sol.q_right)):
        T_wb = getattr(cell, side).T_world_base
        for p, q in zip(P[sol.inside], Q[sol.inside]):
            target = _world_targets(cell, p)[0 if side == "left" else 1]
            np.testing.assert_allclose(T_wb @ puma_arm.fk(q), target, atol=1e-9)
            assert np.all(q >= puma_arm.limits[:, 0] - 1e-12) and np.all(q <= puma_arm.limits[:, 1] + 1e-12)


def test_membership_equals_scalar_ik_everywhere(cell, sample):
    """Both directions: no point lost by the reach-shell prefilter, chunking or the affine targets."""
    P, sol = sample
    np.testing.assert_array_equal(sol.inside, _reference_member(cell, P))


def test_outside_points_defeat_an_independent_numeric_ik(cell, sample, puma_arm):
    P, sol = sample
    rng = np.random.default_rng(7)
    out = P[~sol.inside]
    # the hardest ones first: outside points nearest to an inside point
    d = np.min(np.linalg.norm(out[:, None] - P[sol.inside][None], axis=2), axis=1)
    for p in out[np.argsort(d)[:20]]:
        ok = []
        for T_wb, T in zip((cell.left.T_world_base, cell.right.T_world_base), _world_targets(cell, p)):
            T_bh = np.linalg.inv(T_wb) @ T
            seeds = puma.ik_all(T_bh, limits=np.tile([-1e3, 1e3], (6, 1)))[0]  # out-of-limit branches too
            ok.append(_numeric_ik(puma_arm, T_bh, rng, seeds))
        assert not all(ok), p


def test_numeric_ik_reference_succeeds_where_solutions_exist(cell, sample, puma_arm):
    """Guard: the numeric reference is not vacuous (random seeds only, no closed-form help)."""
    P, sol = sample
    rng = np.random.default_rng(3)
    found = 0
    for p in P[sol.inside][:8]:
        TL, TR = _world_targets(cell, p)
        found += _numeric_ik(puma_arm, np.linalg.inv(cell.left.T_world_base) @ TL, rng) and _numeric_ik(
            puma_arm, np.linalg.inv(cell.right.T_world_base) @ TR, rng
        )
    assert found >= 7


def test_mixed_pair_membership_by_pinocchio_fk_and_numeric_ik():
    """A PUMA + UR5 cell: inside points' joints reach both grasps by Pinocchio FK within limits;
    the outside points nearest to the inside set defeat the independent numeric IK on one arm."""
    cell = example_cell("mixed_puma_ur5")
    arms = Arm.load(cell.left.robot), Arm.load(cell.right.robot)
    rng = np.random.default_rng(11)
    c = cell.T_world_object_start[:3, 3]
    P = c + rng.uniform(-0.6, 0.6, (300, 3))
    sol = solve_real(cell, P)
    assert 30 < sol.inside.sum() < 270
    for k, (side, Q) in enumerate((("left", sol.q_left), ("right", sol.q_right))):
        T_wb, arm = getattr(cell, side).T_world_base, arms[k]
        for p, q in zip(P[sol.inside], Q[sol.inside]):
            np.testing.assert_allclose(T_wb @ arm.fk(q), _world_targets(cell, p)[k], atol=1e-9)
            assert np.all(q >= arm.limits[:, 0] - 1e-12) and np.all(q <= arm.limits[:, 1] + 1e-12)
    out = P[~sol.inside]
    d = np.min(np.linalg.norm(out[:, None] - P[sol.inside][None], axis=2), axis=1)
    for p in out[np.argsort(d)[:10]]:
        ok = [
            _numeric_ik(arm, np.linalg.inv(getattr(cell, side).T_world_base) @ T, rng)
            for arm, side, T in zip(arms, ("left", "right"), _world_targets(cell, p))
        ]
        assert not all(ok), p


def test_any_of_several_orientations(cell):
    rng = np.random.default_rng(11)
    P = rng.uniform(BOX_LO, BOX_HI, (3000, 3))
    R1 = cell.T_world_object_start[:3, :3]
    R2 = pin.rpy.rpyToMatrix(0.0, 0.0, math.radians(30.0)) @ R1
    a, b = contains_real(cell, P, R1), contains_real(cell, P, R2)
    both = solve_real(cell, P, np.stack([R1, R2]))
    assert (b & ~a).sum() > 20 and (a & ~b).sum() > 20  # the second orientation really adds points
    np.testing.assert_array_equal(both.inside, a | b)
    np.testing.assert_array_equal(both.orientation, np.where(a, 0, np.where(b, 1, -1)))
    k = np.nonzero(both.orientation == 1)[0][:30]
    np.testing.assert_array_equal(_reference_member(cell, P[k], R2), True)
    for i in k:
        TL, _ = _world_targets(cell, P[i], R2)
        np.testing.assert_allclose(cell.left.T_world_base @ puma.fk(both.q_left[i]), TL, atol=1e-9)


def test_clearance_membership_against_coal(cell, world):
    rng = np.random.default_rng(2)
    P = rng.uniform(BOX_LO, BOX_HI, (500, 3))
    kin = contains_real(cell, P)
    sol = solve_real(cell, P, world=world)
    assert np.all(kin[sol.inside])  # clearance only removes points
    removed = np.nonzero(kin & ~sol.inside)[0]
    assert sol.inside.sum() > 50 and len(removed) > 5
    margin = cell.safety_margin
    for i in np.nonzero(sol.inside)[0][:60]:  # the chosen pair clears (coal, not the numpy kernel)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = cell.T_world_object_start[:3, :3], P[i]
        assert world.clearance(sol.q_left[i], sol.q_right[i], T).distance >= margin - 1e-7
    for i in removed[:12]:  # no pair of valid branches clears
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = cell.T_world_object_start[:3, :3], P[i]
        TL, TR = hands_from_object(cell, T)
        (SL, VL), (SR, VR) = puma.ik_all(TL), puma.ik_all(TR)
        for ql in SL[VL]:
            for qr in SR[VR]:
                assert world.clearance(ql, qr, T).distance < margin + 1e-7


def test_clearance_searches_all_branch_pairs(cell, world):
    """Points where the first valid branch pair collides but a later one clears are inside (coal
    confirms both facts), so the clearance envelope is not an artefact of the branch order."""
    rng = np.random.default_rng(4)
    P = rng.uniform(BOX_LO, BOX_HI, (6000, 3))
    sol = solve_real(cell, P, world=world)
    later = []
    for i in np.nonzero(sol.inside)[0]:
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = cell.T_world_object_start[:3, :3], P[i]
        TL, TR = hands_from_object(cell, T)
        (SL, VL), (SR, VR) = puma.ik_all(TL), puma.ik_all(TR)
        first = (SL[np.argmax(VL)], SR[np.argmax(VR)])
        if not np.allclose(np.r_[first], np.r_[sol.q_left[i], sol.q_right[i]]):
            later.append((i, T, first))
    assert len(later) >= 3
    for i, T, first in later[:6]:
        assert world.clearance(*first, T).distance < cell.safety_margin
        assert world.clearance(sol.q_left[i], sol.q_right[i], T).distance >= cell.safety_margin - 1e-7


@pytest.fixture(scope="module")
def env04(cell):
    return real_envelope(cell, 0.04)


def test_volume_converges_across_resolutions(cell, env04):
    b = real_envelope(cell, 0.03)
    assert abs(env04.volume_m3 - b.volume_m3) / b.volume_m3 < 0.01
    assert abs(env04.volume_upper_half_m3 - b.volume_upper_half_m3) / b.volume_upper_half_m3 < 0.01
    assert 0.2 * b.volume_m3 < b.volume_upper_half_m3 < 0.8 * b.volume_m3


def test_volume_against_monte_carlo_with_independent_membership(cell, env04):
    """Uniform points in the box, membership by coordination.hands_from_object + the public batch
    puma.ik_all (neither the envelope's affine targets nor its prefilter); 4-sigma agreement."""
    rng = np.random.default_rng(1)
    n = 300_000
    P = rng.uniform(BOX_LO, BOX_HI, (n, 3))
    T = np.tile(np.asarray(cell.T_world_object_start), (n, 1, 1))
    T[:, :3, 3] = P
    TL, TR = hands_from_object(cell, T)
    inside = puma.ik_all(TL)[1].any(axis=1) & puma.ik_all(TR)[1].any(axis=1) & (P[:, 2] >= cell.floor_z)
    box = float(np.prod(BOX_HI - BOX_LO))
    for flags, vol in ((inside, env04.volume_m3), (inside & (P[:, 2] >= env04.z_split_m), env04.volume_upper_half_m3)):
        f = flags.mean()
        sigma = math.sqrt(f * (1 - f) / n) * box
        assert abs(vol - f * box) < 4 * sigma + 0.002 * vol, (vol, f * box, sigma)


def test_points_and_bounds(cell, env04):
    h = env04.resolution
    assert np.all(contains_real(cell, env04.points)) and np.all(env04.points[:, 2] >= cell.floor_z)
    np.testing.assert_allclose(len(env04.points) * h**3, env04.volume_m3, rtol=1e-12)
    k = (env04.points - env04.bounds[:, 0]) / h - 0.5  # cell centres of the grid
    np.testing.assert_allclose(k, np.round(k), atol=1e-9)
    assert env04.bounds[2, 0] == cell.floor_z and env04.z_split_m == pytest.approx(0.6604)
    # the set lies inside the intersection of both wrist reach spheres, |w| <= r_max: lens volume
    r = math.hypot(puma.D2, puma.A2 + math.hypot(puma.A3, puma.D4))
    c = [cell.T_world_object_start[:3, :3] @ -getattr(cell, f"grasp_{s}").T_object_hand[:3, 3]
         + getattr(cell, s).T_world_base[:3, 3] for s in ("left", "right")]
    d = float(np.linalg.norm(c[0] - c[1]))
    assert env04.volume_m3 < math.pi * (4 * r + d) * (2 * r - d) ** 2 / 12
    no_floor = real_envelope(cell, 0.04, floor=False)
    assert no_floor.volume_m3 > env04.volume_m3 and no_floor.points[:, 2].min() < cell.floor_z


def test_xz_boundary_separates_inside_from_outside(cell, env04):
    """Every boundary point has independent-membership inside and outside points within 2 µm."""
    assert len(env04.xz_polylines) >= 1
    total = sum(len(line) - 1 for line in env04.xz_polylines)
    assert total == len(env04.xz_segments) > 100
    for line in env04.xz_polylines:
        np.testing.assert_array_equal(line[0], line[-1])  # closed
        np.testing.assert_allclose(line[:, 1], env04.y_slice_m)
    pts = np.concatenate([line[:-1] for line in env04.xz_polylines])[::7]
    eps = 2e-6
    for p in pts:
        probes = p + eps * np.array([[1, 0, 0], [-1, 0, 0], [0, 0, 1], [0, 0, -1]])
        m = _reference_member(cell, probes, floor=True)
        assert m.any() and not m.all(), p


def test_marching_squares_disc_perimeter_and_area():
    xs = np.linspace(-1, 1, 161)
    ys = np.linspace(-0.9, 1.1, 171)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    r0 = 0.55
    field = r0 - np.hypot(X - 0.1, Y)  # signed distance: linear interpolation is near exact
    (line,) = contour_polylines(field, xs, ys, 0.0)
    np.testing.assert_array_equal(line[0], line[-1])
    per = np.linalg.norm(np.diff(line, axis=0), axis=1).sum()
    area = 0.5 * abs(np.sum(line[:-1, 0] * line[1:, 1] - line[1:, 0] * line[:-1, 1]))
    assert per == pytest.approx(2 * math.pi * r0, rel=2e-3)
    assert area == pytest.approx(math.pi * r0**2, rel=2e-3)
    np.testing.assert_allclose(np.hypot(line[:, 0] - 0.1, line[:, 1]), r0, atol=2e-4)
    segs = marching_squares(field, xs, ys, 0.0)
    assert len(segs) == len(line) - 1
    # binary field (what a membership grid gives): crossings at edge midpoints, half a step off
    b = marching_squares((field > 0).astype(float), xs, ys)
    h = xs[1] - xs[0]
    assert np.all(np.abs(np.hypot(b[..., 0] - 0.1, b[..., 1]) - r0) <= 0.75 * h)


def test_marching_squares_annulus_saddle_and_open_contours():
    xs = ys = np.linspace(-1, 1, 101)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    R = np.hypot(X, Y)
    lines = contour_polylines(((R > 0.3) & (R < 0.7)).astype(float), xs, ys)
    assert len(lines) == 2 and all(np.array_equal(line[0], line[-1]) for line in lines)
    radii = sorted(np.hypot(line[:, 0], line[:, 1]).mean() for line in lines)
    assert radii == pytest.approx([0.3, 0.7], abs=0.01)
    # a 2x2 saddle: centre mean 0.5 + 0.25 > 0.5 joins the two inside corners (two segments, one cell)
    def pairing(s):
        return {frozenset(map(tuple, seg.round(12).tolist())) for seg in s}

    joined = {frozenset({(0.5, 0.0), (1.0, 0.25)}), frozenset({(0.25, 1.0), (0.0, 0.5)})}  # cut c1, c3 off
    assert pairing(marching_squares([[1.0, 0.0], [0.0, 2.0]], [0, 1], [0, 1])) == joined
    # centre mean 0.5 < level 0.75: the two inside corners stay apart (cut c0 and c2 off)
    apart = {frozenset({(0.25, 0.0), (0.0, 0.25)}), frozenset({(1.0, 0.75), (0.75, 1.0)})}
    assert pairing(marching_squares([[1.0, 0.0], [0.0, 1.0]], [0, 1], [0, 1], 0.75)) == apart
    # a half plane: one open polyline from border to border
    (line,) = contour_polylines(X, xs, ys, 0.123)
    np.testing.assert_allclose(line[:, 0], 0.123, atol=1e-12)
    assert {line[0, 1], line[-1, 1]} == {-1.0, 1.0}
    assert marching_squares(np.zeros((3, 3)), [0, 1, 2], [0, 1, 2]).shape == (0, 2, 2)


@pytest.mark.parametrize(
    "args",
    [
        (np.zeros((3, 4)), [0, 1, 2], [0, 1, 2]),
        (np.zeros((3, 3)), [0, 2, 1], [0, 1, 2]),
        (np.full((3, 3), np.nan), [0, 1, 2], [0, 1, 2]),
        (np.zeros((1, 3)), [0], [0, 1, 2]),
    ],
)
def test_marching_squares_bad_input(args):
    with pytest.raises(ParameterError):
        marching_squares(*args)


def test_bad_input(cell, world):
    for bad in (0.0, -1.0, float("nan"), float("inf"), 0.6, "0.1", None):
        with pytest.raises(ParameterError, match="resolution"):
            real_envelope(cell, bad)
    with pytest.raises(ParameterError, match="grid points"):
        real_envelope(cell, 0.0025)
    assert MAX_GRID_POINTS >= 10**7
    for bounds in (((0, 1), (0, 1)), ((0, 1), (0, 1), (1, 0)), ((0, 1), (0, np.nan), (0, 1)), "box",
                   10**400, ((0, 10**400), (0, 1), (0, 1))):  # huge ints: the deep fuzz found an OverflowError
        with pytest.raises(ParameterError, match="bounds"):
            real_envelope(cell, 0.1, bounds=bounds)
    for pts in ([[np.nan, 0, 0]], [[1.0, 2.0]], 3.0):
        with pytest.raises(ParameterError, match="points"):
            contains_real(cell, pts)
    with pytest.raises(PoseError):
        contains_real(cell, [[1.5, -0.2, 0.3]], 2.0 * np.eye(3))
    with pytest.raises(ParameterError, match="R_world_object"):
        contains_real(cell, [[1.5, -0.2, 0.3]], np.eye(4))
    other = dataclasses.replace(cell, name="other")
    with pytest.raises(ParameterError, match="World"):
        contains_real(other, [[1.5, -0.2, 0.3]], world=world)


def test_a_box_of_your_own_counts_its_cut_cells_by_the_part_inside(cell):
    """bounds= that are not a whole number of cells: a 70 mm cube inside the set measured 2.9x its
    volume at h = 50 mm (its last cells counted whole); now exactly the cube's, at every spacing.
    A box below the floor measured one layer above it; it is refused."""
    B = np.array([[1.3, 1.37], [-0.3, -0.23], [0.3, 0.37]])
    corners = np.stack(np.meshgrid(*B, indexing="ij"), -1).reshape(-1, 3)
    assert np.all(contains_real(cell, corners))  # the corners are inside, and (below) every grid cell
    for h in (0.05, 0.04, 0.025, 0.01):
        env = real_envelope(cell, h, bounds=B)
        assert len(env.points) == env.grid_points  # every cell inside
        assert env.volume_m3 == pytest.approx(0.07**3, rel=1e-12)
        assert np.all(env.points >= B[:, 0]) and np.all(env.points <= B[:, 1])
    with pytest.raises(ParameterError, match="below the floor"):
        real_envelope(cell, 0.05, bounds=[[0, 3], [-1, 1], [-2, -1]])
    assert real_envelope(cell, 0.05, bounds=[[0, 3], [-1, 1], [-2, -1]], floor=False).volume_m3 == 0.0
    # a box ending 10 mm above the floor is that 10 mm slab (it was measured as a whole 50 mm layer)
    slab = real_envelope(cell, 0.05, bounds=[[1.3, 1.37], [-0.3, -0.23], [-0.5, 0.01]])
    np.testing.assert_array_equal(slab.bounds[2], [cell.floor_z, 0.01])
    assert slab.volume_m3 <= 0.07 * 0.07 * 0.01 * (1 + 1e-12)


def test_the_upper_half_is_above_the_shoulders_of_ur_arms():
    """z_split was the mean of the bases' heights; a UR5's shoulder is its DH d1 = 89.159 mm above
    its base (Universal Robots' published parameters)."""
    from dualpuma.model import example_cell

    c = example_cell("ur5_pair")
    env = real_envelope(c, 0.05)
    base_z = np.mean([np.asarray(getattr(c, s).T_world_base)[2, 3] for s in ("left", "right")])
    assert env.z_split_m == pytest.approx(base_z + 0.089159, abs=1e-9)
    h = env.resolution
    k = (env.points - env.bounds[:, 0]) / h - 0.5  # the default box contains the set: no cut cell inside it
    np.testing.assert_allclose(k, np.round(k), atol=1e-9)
    # every cell wholly above the split counts whole, the straddling ones in part: bounds on the upper part
    above = env.points[:, 2] - h / 2 >= env.z_split_m
    touching = env.points[:, 2] + h / 2 > env.z_split_m
    assert above.sum() * h**3 <= env.volume_upper_half_m3 <= touching.sum() * h**3
