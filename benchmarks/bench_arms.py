"""Any two arms (groups "arms-*"): the UR closed form beside the PUMA's (one pose, all eight
branches; a batch of 100,000 poses), the numeric provider's cost per pose for arms with no closed
form (a test arm and the Unitree Z1; warm from the previous pose as along a path, and cold), and
Striving on a UR5 pair and a PUMA + UR5 pair beside the PUMA pair on the same run. make bench."""

from pathlib import Path

import numpy as np
import pytest

from dualpuma import Arm, World, example_cell, plan, puma

rng = np.random.default_rng(0)
UR5 = Arm.load("ur5")
Q_UR = rng.uniform(UR5.limits[:, 0], UR5.limits[:, 1], (100_000, 6))
T_UR = UR5.fk(Q_UR)
Q_PUMA = rng.uniform(puma.JOINT_LIMITS[:, 0], puma.JOINT_LIMITS[:, 1], (100_000, 6))
T_PUMA = puma.fk(Q_PUMA)


def cycle(n):
    it = iter(range(10**12))
    return lambda: next(it) % n


@pytest.mark.benchmark(group="arms-ik")
@pytest.mark.parametrize("robot", ["puma560", "ur5"])
def test_ik_all_single_pose(benchmark, robot):
    arm, T = (Arm.puma560(), T_PUMA) if robot == "puma560" else (UR5, T_UR)
    nxt = cycle(256)
    sols, _valid = benchmark(lambda: arm.ik_all(T[nxt()]))
    assert sols.shape == (8, 6)


@pytest.mark.benchmark(group="arms-ik-batch")
@pytest.mark.parametrize("robot", ["puma560", "ur5"])
def test_ik_all_batch_100k(benchmark, robot):
    arm, T = (Arm.puma560(), T_PUMA) if robot == "puma560" else (UR5, T_UR)
    _sols, valid = benchmark.pedantic(arm.ik_all, args=(T,), rounds=5, iterations=1, warmup_rounds=1)
    benchmark.extra_info["poses_per_s"] = len(T) / benchmark.stats.stats.median
    assert valid.any(axis=1).mean() > 0.999


def _numeric_arm(name):
    if name == "arm6":
        return Arm.from_urdf(Path(__file__).resolve().parents[1] / "tests" / "data" / "arm6.urdf", "tool")
    return Arm.load(name)


@pytest.mark.benchmark(group="arms-ik-numeric")
@pytest.mark.parametrize("name", ["arm6", "z1"])
@pytest.mark.parametrize("start", ["warm", "cold"])
def test_numeric_provider_per_pose(benchmark, name, start):
    """Per pose: warm = seeded from a joint vector ~1 deg away (the previous pose of a path);
    cold = no hint (the deterministic restarts)."""
    arm = _numeric_arm(name)
    qs = np.random.default_rng(1).uniform(0.8 * arm.limits[:, 0], 0.8 * arm.limits[:, 1], (64, 6))
    poses = arm.fk(qs)
    nxt = cycle(64)

    def run():
        i = nxt()
        return arm.ik(poses[i], q_near=qs[i] + 0.02 if start == "warm" else None)

    r = benchmark(run)
    assert r.ok


@pytest.mark.benchmark(group="arms-striving")
@pytest.mark.parametrize("name", ["default", "mixed_puma_ur5", "ur5_pair"])
def test_striving_run(benchmark, name):
    """A 37-step straight run with a -10 deg turn (5 mm steps) in each cell."""
    cell = example_cell(name)
    world = World(cell)
    A = cell.T_world_object_start
    B = A.copy()
    B[:3, 3] += (-0.15, 0.0, 0.1)
    from dualpuma.lie import rot_to_rpy, rpy_to_rot
    from dualpuma.planning import StrivingParams

    B[:3, :3] = rpy_to_rot(rot_to_rpy(A[:3, :3]) + np.radians([0.0, 0.0, -10.0]))
    params = StrivingParams(step=0.005, min_step=0.001)
    p = benchmark(plan, cell, A, B, params, world=world)
    benchmark.extra_info["steps"] = p.n_steps
    assert p.reached, p.reason


@pytest.mark.benchmark(group="arms-load")
@pytest.mark.parametrize("robot", ["puma560", "ur5", "z1"])
def test_cli_fk_cold(benchmark, robot):
    """``dualpuma fk --robot NAME`` as a user runs it: a new process, the arm loaded from its URDF
    (a Z1's capsules are fitted to its collision meshes: before the twentieth session its circle
    search made this 5.1 s, now 1.6 s)."""
    import subprocess
    import sys

    def run():
        return subprocess.run([sys.executable, "-m", "dualpuma", "fk", "--robot", robot, "--q", "0", "10", "-20", "0",
                               "30", "0", "--json"], check=True, capture_output=True, text=True, timeout=300)

    r = benchmark.pedantic(run, rounds=3, iterations=1)
    assert '"T_base_frame"' in r.stdout
