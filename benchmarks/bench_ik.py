"""IK / FK benchmarks (group "ik"). Run: make bench  (or pytest benchmarks --benchmark-only).

Ratios are the figures: Robotics Toolbox's Puma560().ikine_a runs on the same poses in the same
session when roboticstoolbox-python is importable (it is never a dependency of dualpuma).
"""

import numpy as np
import pinocchio as pin
import pytest

from dualpuma import Arm, puma

rng = np.random.default_rng(0)
Q = rng.uniform(puma.JOINT_LIMITS[:, 0], puma.JOINT_LIMITS[:, 1], size=(100_000, 6))
T = puma.fk(Q)


@pytest.mark.benchmark(group="ik")
def test_ik_all_single_pose(benchmark):
    poses = T[:256]
    it = iter(range(10**9))

    def run():
        return puma.ik_all(poses[next(it) & 255])

    sols, _valid = benchmark(run)
    assert sols.shape == (8, 6)


@pytest.mark.benchmark(group="ik")
def test_ik_single_branch(benchmark):
    pose = T[0]
    r = benchmark(puma.ik, pose, config=(1, 1, 1))
    assert r.status in ("ok", "joint_limits", "unreachable")


@pytest.mark.benchmark(group="ik")
def test_ik_all_batch_100k(benchmark):
    _sols, valid = benchmark.pedantic(puma.ik_all, args=(T,), rounds=10, iterations=1, warmup_rounds=1)
    benchmark.extra_info["poses_per_s"] = len(T) / benchmark.stats.stats.median
    assert valid.any(axis=1).all()


@pytest.mark.benchmark(group="ik")
def test_pinocchio_fk_per_call(benchmark):
    arm = Arm.puma560()
    q = Q[0]
    benchmark(arm.fk, q)


@pytest.mark.benchmark(group="ik")
def test_pinocchio_fk_raw(benchmark):
    arm = Arm.puma560()
    model, data, fid, q = arm.model, arm.data, arm.hand_frame_id, Q[0]

    def run():
        pin.forwardKinematics(model, data, q)
        return pin.updateFramePlacement(model, data, fid)

    benchmark(run)


@pytest.mark.benchmark(group="ik")
def test_pinocchio_jacobian_per_call(benchmark):
    arm = Arm.puma560()
    benchmark(arm.jacobian, Q[0])


@pytest.mark.benchmark(group="ik")
def test_numeric_ik_ur5_per_solve(benchmark):
    arm = Arm.load("ur5")
    lo, hi = arm.limits[:, 0], arm.limits[:, 1]
    qs = np.random.default_rng(1).uniform(np.maximum(lo, -np.pi), np.minimum(hi, np.pi), size=(32, 6))
    poses = arm.fk(qs)
    it = iter(range(10**9))

    def run():
        i = next(it) & 31
        return arm.ik(poses[i], q_near=qs[i] + 0.05)

    r = benchmark(run)
    assert r.ok


@pytest.mark.benchmark(group="ik")
def test_rtb_ikine_a_single_branch(benchmark):
    try:  # the peer is part of the benchmark run: install it, do not skip it
        import roboticstoolbox as rtb
        from spatialmath import SE3
    except ImportError as e:
        pytest.fail(f"the Robotics Toolbox is needed for this benchmark: pip install 'dualpuma[bench]' ({e})")

    robot = rtb.models.DH.Puma560()
    qs = np.random.default_rng(2).uniform(-1, 1, size=(256, 6))
    poses = [SE3(robot.fkine(q)) for q in qs]
    it = iter(range(10**9))

    def run():
        return robot.ikine_a(poses[next(it) & 255], config="lun")

    r = benchmark(run)
    assert r.success  # the peer solved the pose it was timed on
