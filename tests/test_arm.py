"""Arm: Pinocchio FK/Jacobian checks, numeric IK for UR5, errors."""

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from dualpuma import Arm, puma
from dualpuma.errors import JointError, ParameterError, PoseError, RobotError
from dualpuma.kinematics import example_robot_data_dir


def fd_jacobian(arm, q, frame, h=1e-6):
    """Central-difference world-aligned Jacobian: d(position)/dq and the rotation's angular rate."""
    J = np.zeros((6, 6))
    T0 = arm.fk(q, frame)
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = h
        Tp, Tm = arm.fk(q + dq, frame), arm.fk(q - dq, frame)
        J[:3, i] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        J[3:, i] = (pin.log3(Tp[:3, :3] @ T0[:3, :3].T) - pin.log3(Tm[:3, :3] @ T0[:3, :3].T)) / (2 * h)
    return J


@pytest.mark.parametrize("frame", ["wrist", "flange", "gripper", "link3"])
def test_jacobian_matches_finite_differences(puma_arm, rng, frame):
    for q in rng.uniform(puma.JOINT_LIMITS[:, 0], puma.JOINT_LIMITS[:, 1], size=(20, 6)):
        J = puma_arm.jacobian(q, frame)
        np.testing.assert_allclose(J, fd_jacobian(puma_arm, q, frame), atol=1e-7)
        # local = world-aligned expressed in the frame's own axes
        R = puma_arm.fk(q, frame)[:3, :3]
        Jl = puma_arm.jacobian(q, frame, reference="local")
        np.testing.assert_allclose(Jl[:3], R.T @ J[:3], atol=1e-12)
        np.testing.assert_allclose(Jl[3:], R.T @ J[3:], atol=1e-12)


def test_manipulability_vanishes_at_wrist_singularity(puma_arm):
    q = np.array([0.3, -0.5, -0.9, 0.4, 0.7, -0.2])
    m = puma_arm.manipulability(q)
    J = puma_arm.jacobian(q)
    assert m == pytest.approx(np.sqrt(np.linalg.det(J @ J.T)), rel=1e-12)
    q[4] = 0.0
    assert puma_arm.manipulability(q) < 1e-12 < m


def test_batched_fk_matches_single(puma_arm, rng):
    Q = rng.uniform(-3, 3, size=(50, 6))
    Tb = puma_arm.fk(Q)
    assert Tb.shape == (50, 4, 4)
    for q, T in zip(Q, Tb):
        np.testing.assert_array_equal(T, puma_arm.fk(q))
    np.testing.assert_allclose(Tb, puma.fk(Q), atol=1e-12)
    assert puma_arm.fk(Q.reshape(5, 10, 6)).shape == (5, 10, 4, 4)


def test_arm_ik_matches_closed_form(puma_arm, rng):
    q = rng.uniform(puma.JOINT_LIMITS[:, 0], puma.JOINT_LIMITS[:, 1])
    r = puma_arm.ik(puma_arm.fk(q), q_near=q)
    assert r.ok and np.abs(r.q - q).max() < 1e-8
    _S, V = puma_arm.ik_all(puma_arm.fk(q))
    assert V.shape == (8,) and V.any()


def test_ur5_closed_form_ik_round_trip(ur5_arm, rng):
    """The UR5 gets the UR closed form (parameters read from its model): every pose comes back,
    on the branch of the joints it came from, checked by Pinocchio's FK of its own URDF."""
    assert ur5_arm.analytic and "UR closed form" in ur5_arm.solver.name
    lo, hi = ur5_arm.limits[:, 0], ur5_arm.limits[:, 1]
    for q in rng.uniform(np.maximum(lo, -np.pi), np.minimum(hi, np.pi), size=(10, 6)):
        T = ur5_arm.fk(q)
        r = ur5_arm.ik(T)  # no hint: the first valid branch
        assert r.ok, r.reason
        np.testing.assert_allclose(ur5_arm.fk(r.q), T, atol=1e-9)
        assert ur5_arm.within_limits(r.q)
        r2 = ur5_arm.ik(T, q_near=q + 0.05)  # a hint gives the nearby solution
        assert r2.ok and np.abs(r2.q - q).max() < 1e-6 and r2.branch == ur5_arm.branch_of(q)


@pytest.mark.parametrize("name", ["arm6", "z1", "kinova"])
def test_numeric_ik_round_trip(name, rng):
    """Arms that are neither a PUMA nor UR-like get damped least squares: a generic test arm and
    example-robot-data's Unitree Z1 and Kinova Jaco2 (6-DOF)."""
    arm = Arm.from_urdf(Path(__file__).parent / "data" / "arm6.urdf", "tool") if name == "arm6" else Arm.load(name)
    assert not arm.analytic and "numeric" in arm.solver.name
    lo, hi = arm.limits[:, 0], arm.limits[:, 1]
    for q in rng.uniform(0.8 * lo, 0.8 * hi, size=(10, 6)):
        T = arm.fk(q)
        r = arm.ik(T)  # no hint: restarts
        assert r.ok, r.reason
        np.testing.assert_allclose(arm.fk(r.q), T, atol=1e-9)
        assert arm.within_limits(r.q)
        r2 = arm.ik(T, q_near=q + 0.05)  # a hint converges to the nearby solution
        assert r2.ok and np.abs(r2.q - q).max() < 1e-6


def test_ur5_unreachable_reports_status(ur5_arm):
    T = np.eye(4)
    T[:3, 3] = [3.0, 0.0, 0.0]
    r = ur5_arm.ik(T)
    assert not r.ok and r.status == "unreachable" and r.q is None


def test_unknown_robot_and_frames():
    with pytest.raises(RobotError, match="known robots"):
        Arm.load("puma600")
    arm = Arm.puma560()
    with pytest.raises(RobotError, match="unknown frame"):
        arm.fk(np.zeros(6), "elbow_tip")
    with pytest.raises(ParameterError):
        arm.jacobian(np.zeros(6), reference="global")
    with pytest.raises(JointError):
        arm.jacobian(np.zeros((2, 6)))
    with pytest.raises(JointError):
        arm.fk(np.zeros(7))
    with pytest.raises(PoseError):
        arm.ik(np.full((4, 4), np.nan))
    numeric = Arm.from_urdf(Path(__file__).parent / "data" / "arm6.urdf", "tool")
    with pytest.raises(RobotError):
        numeric.ik_all(np.eye(4))
    with pytest.raises(ParameterError):
        numeric.ik(np.eye(4), config=0)
    with pytest.raises(RobotError, match="hand frame"):
        Arm.from_urdf(Path(__file__).parent / "data" / "arm6.urdf", "no_such_frame")
    with pytest.raises(RobotError, match="not a file"):
        Arm.from_urdf(Path(__file__).parent / "data" / "missing.urdf", "tool")
    panda = example_robot_data_dir() / "panda_description" / "urdf" / "panda.urdf"
    with pytest.raises(RobotError, match="six revolute joints"):  # a 7-DOF arm
        Arm.from_urdf(panda, "panda_hand")


def test_malformed_urdf_is_a_robot_error(tmp_path):
    p = tmp_path / "broken.urdf"
    p.write_text("<robot name='x'><link name='a'>")
    with pytest.raises(RobotError, match="not a readable URDF"):
        Arm.from_urdf(p, "a")
    p.write_text("<robot name='x'><link name='a'/></robot>")
    with pytest.raises(RobotError, match="six revolute joints"):
        Arm.from_urdf(p, "a")


def test_capsules_read_from_urdf(puma_arm):
    names = [c.name for c in puma_arm.capsules]
    assert names == ["pedestal", "column", "shoulder", "upper_arm", "elbow", "forearm", "wrist", "gripper"]
    fore = next(c for c in puma_arm.capsules if c.name == "forearm")
    # the forearm capsule runs from the elbow towards the wrist centre along link 3's y axis
    q = np.zeros(6)
    pin.forwardKinematics(puma_arm.model, puma_arm.data, q)
    a, b = fore.segment(puma_arm.data.oMi[fore.joint].homogeneous)
    wrist = puma_arm.fk(q)[:3, 3]
    assert np.linalg.norm(b - wrist) == pytest.approx(0.07, abs=1e-12)
    assert abs(a[2]) < 1e-12 and b[2] < a[2]  # forearm hangs down at q = 0


def test_public_api_names_import():
    import dualpuma

    for name in dualpuma.__all__:
        assert getattr(dualpuma, name) is not None


def test_example_robot_data_is_found_from_its_record_and_from_its_file_list(monkeypatch):
    """The robots/ directory is read off the wheel's RECORD as text (fast); without a RECORD, off
    its file list: the same directory, and every URDF the wheel installs under a robots/ folder
    lies in it (checked against importlib.metadata's own file list)."""
    import importlib.metadata as md

    found = example_robot_data_dir()
    dist = md.distribution("example-robot-data")
    urdfs = [Path(str(dist.locate_file(f))) for f in dist.files or [] if str(f).endswith(".urdf")]
    under = [u for u in urdfs if "robots" in u.parts]
    assert len(under) >= 10 and all(u.is_relative_to(found) for u in under)

    class NoRecord:  # the same distribution without its RECORD
        files = dist.files

        def read_text(self, name):
            return None

        def locate_file(self, f):
            return dist.locate_file(f)

    monkeypatch.setattr(md, "distribution", lambda name: NoRecord())
    assert example_robot_data_dir.__wrapped__() == found


@pytest.mark.parametrize("robot", ["z1", "kinova"])
def test_a_numeric_arm_refuses_a_target_beyond_its_links_at_once_without_overflow(robot):
    """A target 1e200 m away made the damped least squares overflow (numpy RuntimeWarnings on
    stderr) before answering unreachable; it is unreachable at once now, by the sum of the link
    lengths (read here from the URDF's joint origins with Pinocchio), silently. A target inside
    that bound still gets the solver's answer, checked by Pinocchio's FK."""
    import warnings

    import pinocchio as pin

    arm = Arm.load(robot)
    T = np.eye(4)
    T[0, 3] = 1e200
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = arm.ik(T)
    assert r.status == "unreachable" and "beyond the arm's reach" in r.reason and r.q is None
    m = arm.model
    bound = sum(np.linalg.norm(m.jointPlacements[j].translation) for j in range(1, m.njoints))
    bound += np.linalg.norm(m.frames[arm.hand_frame_id].placement.translation)
    T[0, 3] = bound + 1e-6
    assert arm.ik(T).status == "unreachable"
    q = np.array([0.1, 0.4, -0.6, 0.2, 0.3, -0.1])
    Tq = arm.fk(q)
    r = arm.ik(Tq, q_near=q)
    d = m.createData()
    pin.framesForwardKinematics(m, d, r.q)
    assert r.status == "ok" and np.abs(d.oMf[arm.hand_frame_id].homogeneous - Tq).max() < 1e-9


def test_within_limits_and_ik_draw_the_limit_at_the_same_place(puma_arm):
    """A joint 1e-10 rad past its limit: ``within_limits`` called it inside (its own 1e-9 rad
    tolerance) while IK of its own FK said ``joint_limits`` (1e-12 rad). Both now use one tolerance;
    the limits are Pinocchio's reading of the URDF."""
    model = pin.buildModelFromUrdf(str(Path(__file__).resolve().parents[1] / "urdf" / "puma560.urdf"))
    q = np.array([0.3, -0.5, -0.4, 0.7, 0.5, -0.2])
    for past, inside in ((1e-10, False), (1e-13, True)):
        q[1] = model.upperPositionLimit[1] + past
        r = puma_arm.ik(puma_arm.fk(q), q_near=q)
        assert bool(puma_arm.within_limits(q)) is inside
        assert (r.status == "ok") is inside, (past, r.status)


def test_ik_of_a_batch_of_one_is_a_pose_error_as_for_puma_ik(puma_arm):
    T = puma_arm.fk(np.zeros(6))[None]
    for solve in (puma_arm.ik, puma.ik):
        with pytest.raises(PoseError, match=r"shape \(4, 4\).*ik_all"):
            solve(T)


@pytest.mark.parametrize("far", [1e150, 1e200, 1e307, 1.7e308])
def test_ik_of_a_target_far_out_is_unreachable_without_numpy_warnings(far):
    """The closed forms' squares overflowed for targets ~1e200 m out: the answer was right, but numpy
    warned, which is an exception under ``-W error`` or pytest's ``filterwarnings = error``."""
    import warnings

    T = puma.fk(np.array([0.3, -0.5, -0.4, 0.7, 0.5, -0.2]))
    T[:3, 3] = far
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert puma.ik(T).status == "unreachable" and "e+" in puma.ik(T).reason and "inf" not in puma.ik(T).reason
        assert not puma.ik_all(np.stack([T, T]))[1].any()
        for robot in ("puma560", "ur5"):
            arm = Arm.load(robot)
            assert arm.ik(T).status == "unreachable"
            assert not arm.ik_all(np.stack([T, T, T]))[1].any()


def test_a_numeric_ik_that_finds_nothing_does_not_claim_the_pose_unreachable():
    """A Z1 pose made by FK of joints inside the limits (so reachable): the restarts miss it and the
    status said "unreachable" (found by a reviewer, 1 of 150 random poses). It says "not_found" now,
    and from the joints' neighbourhood the solver finds it."""
    arm = Arm.load("z1")
    q = np.array([0.4406155, 0.03002372, -2.80005887, -0.47608398, 0.23045395, 2.39980987])
    assert arm.within_limits(q)
    T = arm.fk(q)
    r = arm.ik(T)
    assert r.status == "not_found" and "may still be reachable" in r.reason, r
    near = arm.ik(T, q_near=q + 0.05)
    assert near.status == "ok"
    np.testing.assert_allclose(arm.fk(near.q), T, atol=1e-9)
