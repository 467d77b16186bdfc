"""The UR family's closed-form IK (dualpuma.kinematics.ur) against Pinocchio's FK of the arms' own
URDFs (example-robot-data), including the singular neighbourhoods; the parameters it reads from
the model against Universal Robots' published table."""

import math

import numpy as np
import pinocchio as pin
import pytest
from urdf_reference import fk_many

from dualpuma.kinematics import Arm, example_robot_data_dir, ur

#: Universal Robots' published DH parameters (d1, a2, a3, d4, d5, d6) [m]
PUBLISHED = {
    "ur3": (0.1519, -0.24365, -0.21325, 0.11235, 0.08535, 0.0819),
    "ur5": (0.089159, -0.425, -0.39225, 0.10915, 0.09465, 0.0823),
    "ur10": (0.1273, -0.612, -0.5723, 0.163941, 0.1157, 0.0922),
}


def urdf_model(name):
    """An independent Pinocchio model of the URDF file itself (not the Arm's)."""
    path = example_robot_data_dir() / f"ur_description/urdf/{name}_robot.urdf"
    model = pin.buildModelFromUrdf(str(path))
    return model, model.createData(), model.getFrameId("tool0")


def wrapped(a, b):
    return np.abs((a - b + np.pi) % (2 * np.pi) - np.pi)


@pytest.mark.parametrize("name", ["ur3", "ur5", "ur10"])
def test_parameters_read_from_the_model_match_the_published_table(name):
    g = Arm.load(name).solver.geometry
    np.testing.assert_allclose((g.d1, g.a2, g.a3, g.d4, g.d5, g.d6), PUBLISHED[name], atol=1e-9)


@pytest.mark.parametrize(("name", "n"), [("ur5", 100_000), ("ur3", 20_000), ("ur10", 20_000)])
def test_every_branch_against_pinocchio_fk(name, n, rng):
    """Random joints within the limits, a tenth of them in singular neighbourhoods (wrist q5 ~ 0,
    elbow q3 ~ 0, exactly singular wrists): FK -> ik_all -> FK of every valid branch equals the
    target to 1e-9, and the sampled joints' own branch gives them back."""
    arm = Arm.load(name)
    model, data, fid = urdf_model(name)
    lim = arm.limits
    Q = rng.uniform(lim[:, 0], lim[:, 1], (n, 6))
    k = n // 30
    Q[:k, 4] = rng.normal(0.0, 1e-4, k)  # near the wrist singularity
    Q[k : 2 * k, 2] = rng.normal(0.0, 1e-4, k)  # near the elbow singularity
    Q[2 * k : 3 * k, 4] = 0.0  # exactly singular: q6 is taken from q_near
    T = fk_many(model, data, fid, Q)
    sols, valid = arm.ik_all(T, q_near=Q)
    assert valid.any(axis=1).all()
    rows, branches = np.nonzero(valid)
    pick = np.random.default_rng(1).choice(len(rows), size=min(len(rows), 60_000), replace=False)
    T_back = fk_many(model, data, fid, sols[rows[pick], branches[pick]])
    assert np.abs(T_back - T[rows[pick]]).max() < 1e-9
    own = np.array([arm.branch_of(q) for q in Q])
    got = sols[np.arange(n), own]
    ok = valid[np.arange(n), own]
    recovered = ok & (wrapped(got, Q).max(axis=1) < 1e-6)
    generic = slice(3 * k, n)
    assert recovered[generic].mean() > 0.9999
    assert recovered[2 * k : 3 * k].all()  # exact singularity: q6 from q_near, the rest exact


def test_scalar_and_batch_paths_agree(rng):
    arm = Arm.load("ur5")
    Q = rng.uniform(-math.pi, math.pi, (300, 6))
    T = arm.fk(Q)
    S, V = arm.ik_all(T, q_near=Q)
    for i in range(300):
        s1, v1 = arm.ik_all(T[i], q_near=Q[i])
        assert np.array_equal(v1, V[i])
        np.testing.assert_allclose(s1[v1], S[i][V[i]], atol=1e-12)


def test_one_branch_per_pose_equals_all_branches(rng):
    arm = Arm.load("ur10")
    g = arm.solver.geometry
    Q = rng.uniform(-math.pi, math.pi, (2000, 6))
    T = arm.fk(Q)
    b = rng.integers(0, 8, 2000)
    q, reach, _h = ur.ik_branch(g, T, b, Q)
    S, V = arm.ik_all(T, q_near=Q)
    ok = V[np.arange(2000), b]
    assert np.array_equal(reach[ok], np.ones(ok.sum(), dtype=bool))
    assert wrapped(q[ok], S[np.arange(2000), b][ok]).max() < 1e-9


def test_unreachable_and_non_ur_models():
    arm = Arm.load("ur5")
    T = np.eye(4)
    T[:3, 3] = (2.0, 0.0, 0.0)
    r = arm.ik(T)
    assert not r.ok and r.status == "unreachable"
    from dualpuma.errors import RobotError

    puma = Arm.puma560()
    with pytest.raises(RobotError, match="not UR-like"):
        ur.geometry_from_model(puma.model, puma.hand_frame_id)


@pytest.mark.parametrize("name", ["ur5", "puma560"])
def test_branches_of_many_joint_vectors_are_where_ik_all_lists_them(name, rng):
    """An arm's ``branches(Q)`` (vectorised) names, for each joint vector, the branch under which
    the closed form's all-branch IK of its own FK lists it (and agrees with ``branch_of``)."""
    arm = Arm.puma560() if name == "puma560" else Arm.load(name)
    lim = arm.limits
    Q = rng.uniform(lim[:, 0] * 0.9, lim[:, 1] * 0.9, (500, 6))
    Q = Q[np.abs(np.sin(Q[:, 4])) > 0.05]  # away from the wrist singularity, where the label is defined
    S, V = arm.ik_all(arm.fk(Q).reshape(-1, 4, 4), q_near=Q)
    gap = np.where(V, np.array([[wrapped(S[i, b], Q[i]).max() for b in range(8)] for i in range(len(Q))]), np.inf)
    listed = gap.argmin(axis=1)
    found = gap.min(axis=1) < 1e-7  # the joint vector is one of its pose's solutions (not at a shoulder/elbow boundary)
    assert found.mean() > 0.95
    got = arm.solver.branches(Q)
    assert np.array_equal(got[found], listed[found])
    assert got.tolist() == [arm.solver.branch_of(q) for q in Q]


def test_two_ur5s_loaded_from_different_files_compare_equal_by_value(tmp_path):
    """The generated dataclass comparison asked numpy for the truth of an array: a cell with the UR5
    by name and a UR5 from a copy of its file made every plan an internal error (ValueError)."""
    from mesh_reference import edited_ur5

    from dualpuma.kinematics import Arm

    a = Arm.load("ur5")
    b = Arm.from_urdf(edited_ur5(tmp_path), "tool0")  # the same kinematics, its own arrays
    assert a.solver.geometry.B is not b.solver.geometry.B
    assert a.solver == b.solver and hash(a.solver) == hash(b.solver)
    assert a.solver != Arm.load("ur10").solver
