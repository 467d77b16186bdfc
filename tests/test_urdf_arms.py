"""Arms read from URDF files (``Arm.from_urdf``, ``robot = { urdf, tip }``): joint limits that are
not a range, chains with joints that are not revolute, and the cache of an edited file."""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from dualpuma import Arm
from dualpuma.cli import main
from dualpuma.errors import CellError, RobotError
from dualpuma.kinematics.numeric import DLSSolver
from dualpuma.model import load_cell

ARM6 = Path(__file__).parent / "data" / "arm6.urdf"
J2_LIMIT = 'lower="-2.0" upper="2.0" effort="10"'  # the second joint's <limit> in arm6.urdf


def arm6(tmp_path: Path, old: str = J2_LIMIT, new: str = J2_LIMIT, name: str = "arm.urdf") -> Path:
    """A copy of tests/data/arm6.urdf in ``tmp_path`` with ``old`` replaced by ``new``."""
    text = ARM6.read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new), encoding="utf-8")
    return path


def with_j2(tmp_path: Path, lower: str, upper: str) -> Path:
    return arm6(tmp_path, new=f'lower="{lower}" upper="{upper}" effort="10"')


# ---------------------------------------------------------------------- limits that are not a range
def test_lower_limit_above_upper_is_a_robot_error_naming_the_joint(tmp_path):
    """lower > upper reached numpy's ``rng.uniform`` (a bare ValueError: high - low < 0)."""
    with pytest.raises(RobotError, match=re.escape(
            "joint 'j2': its lower limit (114.6 deg) must not exceed its upper limit (-114.6 deg)")):
        Arm.from_urdf(with_j2(tmp_path, "2.0", "-2.0"), "tool")


def test_limits_that_differ_below_a_tenth_of_a_degree_are_shown_apart(tmp_path):
    with pytest.raises(RobotError, match=re.escape("(57.29579 deg) must not exceed its upper limit (57.29578 deg)")):
        Arm.from_urdf(with_j2(tmp_path, "1.0000001", "1.0"), "tool")


def test_prismatic_limits_are_shown_in_millimetres(tmp_path):
    path = arm6(tmp_path, '<joint name="j6" type="revolute">', '<joint name="j6" type="prismatic">')
    path.write_text(path.read_text().replace('lower="-3.0" upper="3.0" effort="5" velocity="3"/>\n  </joint>\n'
                                             '  <link name="link6">',
                                             'lower="0.02" upper="0.01" effort="5" velocity="3"/>\n  </joint>\n'
                                             '  <link name="link6">'))
    with pytest.raises(RobotError, match=re.escape("joint 'j6': its lower limit (20.0 mm) must not exceed its upper "
                                                   "limit (10.0 mm)")):
        Arm.from_urdf(path, "tool")


@pytest.mark.parametrize(("lower", "upper", "bad"), [("nan", "2.0", "lower"), ("-inf", "inf", "lower"),
                                                     ("-2.0", "inf", "upper"), ("-2.0", "1e999", "upper"),
                                                     ("-2.0", "two", "upper")])
def test_limits_that_are_not_finite_numbers_name_the_joint(tmp_path, lower, upper, bad):
    """Pinocchio's parser refused these with 'does not contain a valid URDF model' (its reason
    only on stderr); the message names the joint and the value."""
    value = {"lower": lower, "upper": upper}[bad]
    with pytest.raises(RobotError, match=re.escape(f"joint 'j2': its {bad} limit {value!r} is not a finite number")):
        Arm.from_urdf(with_j2(tmp_path, lower, upper), "tool")


def test_a_joint_of_the_six_that_cannot_move_is_refused(tmp_path):
    """lower == upper: the arm would have five degrees of freedom; its IK (numeric or closed form)
    could reach almost no pose, and a plan would fail far from the cause. Refused at loading."""
    with pytest.raises(RobotError, match=re.escape(
            "joint 'j2' cannot move: its lower and upper limits are both 57.3 deg; each of the six joints from the "
            "base to 'tool' needs a range (lower < upper)")):
        Arm.from_urdf(with_j2(tmp_path, "1.0", "1.0"), "tool")


def test_a_locked_joint_outside_the_six_may_have_equal_limits_but_not_inverted_ones(tmp_path):
    """A finger outside the chain is locked at its neutral position clamped into its limits:
    lower == upper is fine (it is locked there), lower > upper is not a valid URDF."""
    finger = ('<joint name="finger" type="prismatic"><parent link="link6"/><child link="finger_link"/>'
              '<axis xyz="1 0 0"/><limit lower="{lo}" upper="{hi}" effort="1" velocity="1"/></joint>'
              '<link name="finger_link"/>\n</robot>')
    ok = arm6(tmp_path, "</robot>", finger.format(lo="0.01", hi="0.01"), name="ok.urdf")
    assert Arm.from_urdf(ok, "tool").locked_joints == {"finger": pytest.approx(0.01)}
    bad = arm6(tmp_path, "</robot>", finger.format(lo="0.02", hi="0.01"), name="bad.urdf")
    with pytest.raises(RobotError, match="joint 'finger': its lower limit"):
        Arm.from_urdf(bad, "tool")


def test_a_cell_with_inverted_limits_is_a_cell_error_and_the_cli_says_so(tmp_path, capsys):
    """``load_cell`` wraps the RobotError as it does for other robot problems; ``dualpuma plan``
    exits 2 with that line (it exited 70, 'internal error')."""
    with_j2(tmp_path, "2.0", "-2.0")
    cells = resources.files("dualpuma.model") / "data" / "cells"
    text = (cells / "mixed_puma_ur5.toml").read_text(encoding="utf-8")
    assert 'robot = "ur5"' in text
    cell = tmp_path / "thatcell.toml"
    cell.write_text(text.replace('robot = "ur5"', 'robot = { urdf = "arm.urdf", tip = "tool" }'), encoding="utf-8")
    with pytest.raises(CellError, match=r"right\.robot: .*joint 'j2': its lower limit \(114\.6 deg\) must not exceed"):
        load_cell(cell)
    capsys.readouterr()
    assert main(["plan", "--cell", str(cell), "--by", "10", "0", "0"]) == 2
    err = capsys.readouterr().err
    assert "joint 'j2': its lower limit (114.6 deg) must not exceed its upper limit (-114.6 deg)" in err, err
    assert "internal error" not in err


def test_the_numeric_solver_refuses_limits_that_are_not_a_range():
    """Its own guard, for a model built without :func:`read_arm` (it raised numpy's ValueError)."""
    arm = Arm.from_urdf(ARM6, "tool")
    lim = np.array(arm.limits)
    lim[1] = (2.0, -2.0)
    with pytest.raises(RobotError, match=re.escape("joint 'j2': its limits must be finite with the lower not "
                                                   "exceeding the upper, got lower 114.6 deg, upper -114.6 deg")):
        DLSSolver(arm.model, arm.hand_frame_id, lim)
    lim[1] = (np.nan, 2.0)
    with pytest.raises(RobotError, match="joint 'j2'"):
        DLSSolver(arm.model, arm.hand_frame_id, lim)


# ---------------------------------------------------------------------- joints that are not revolute
def test_a_prismatic_joint_in_the_chain_is_named(tmp_path):
    """The message said 'expected six revolute joints ..., got 6: [j1 ... j6]'."""
    path = arm6(tmp_path, '<joint name="j3" type="revolute">', '<joint name="j3" type="prismatic">')
    with pytest.raises(RobotError, match=re.escape(
            "joint 'j3' is prismatic: expected six revolute joints from the base to 'tool'")) as info:
        Arm.from_urdf(path, "tool")
    assert "got 6" not in str(info.value)


def test_several_joints_that_are_not_revolute_are_all_named_with_their_types(tmp_path):
    path = arm6(tmp_path, '<joint name="j3" type="revolute">', '<joint name="j3" type="planar">')
    path.write_text(path.read_text().replace('<joint name="j5" type="revolute">', '<joint name="j5" type="floating">'))
    with pytest.raises(RobotError, match=re.escape(
            "joints 'j3' (planar), 'j5' (floating) are not revolute: expected six revolute joints from the base "
            "to 'tool'")):
        Arm.from_urdf(path, "tool")


def test_a_chain_of_the_wrong_length_still_lists_its_joints(tmp_path):
    path = arm6(tmp_path)
    with pytest.raises(RobotError, match=re.escape(
            "expected six revolute joints from the base to 'link5', got 5: ['j1', 'j2', 'j3', 'j4', 'j5']")):
        Arm.from_urdf(path, "link5")


def test_continuous_joints_are_still_revolute(tmp_path):
    path = arm6(tmp_path, '<joint name="j4" type="revolute">', '<joint name="j4" type="continuous">')
    arm = Arm.from_urdf(path, "tool")
    assert arm.limits[3] == pytest.approx((-2.0 * np.pi, 2.0 * np.pi))


# ---------------------------------------------------------------------- what an integrator's own URDF hit
@pytest.mark.parametrize(("old", "new", "message"), [
    # Pinocchio's parser said only "The XML stream does not contain a valid URDF model" (and urdfdom
    # wrote more lines to stderr)
    ('<limit lower="-2.0" upper="2.0" effort="10" velocity="2"/>', "", "joint 'j2' (revolute) has no <limit>"),
    ('<origin xyz="0 0.08 0.1"/>', '<origin xyz="0 nan 0.1"/>', "joint 'j2': its origin xyz='0 nan 0.1' is not three"),
    # a zero axis loaded, and FK returned a "rotation" of determinant 0.45
    ('<axis xyz="0 1 0"/>\n    <limit lower="-2.0"', '<axis xyz="0 0 0"/>\n    <limit lower="-2.0"', "joint 'j2': its axis is zero"),
    # limits in degrees loaded as +-9740 deg
    ('lower="-2.0" upper="2.0" effort="10"', 'lower="-170" upper="170" effort="10"', "more than two turns each way (degrees?"),
    # a mimic joint in the chain was taken as independent (IK broke the coupling)
    ('<limit lower="-3.0" upper="3.0" effort="5" velocity="3"/>\n  </joint>\n  <link name="link4">',
     '<limit lower="-3.0" upper="3.0" effort="5" velocity="3"/><mimic joint="j3"/>\n  </joint>\n  <link name="link4">',
     "joint 'j4' is revolute mimicking 'j3'"),
])
def test_urdf_joints_that_cannot_be_a_six_joint_arm_are_refused_saying_why(tmp_path, old, new, message):
    with pytest.raises(RobotError, match=re.escape(message)):
        Arm.from_urdf(arm6(tmp_path, old, new), "tool")
    # a <transmission> naming the joint (as most ROS arm URDFs have) changes nothing: its <joint>
    # element had overwritten the mimic mark
    trans = ('<transmission name="t4"><type>transmission_interface/SimpleTransmission</type>'
             '<joint name="j4"><hardwareInterface>PositionJointInterface</hardwareInterface></joint></transmission>\n</robot>')
    path = arm6(tmp_path, old, new, name="with_transmission.urdf")
    path.write_text(path.read_text().replace("</robot>", trans))
    with pytest.raises(RobotError, match=re.escape(message)):
        Arm.from_urdf(path, "tool")


def test_limits_off_the_chain_are_not_read_as_degrees(tmp_path):
    """A revolute joint beyond the hand frame is locked: its limits (a 'no limit' 1e16 of an SDF
    export) do not matter and were refused as degrees; in the chain they are."""
    spin = ('<joint name="spin" type="revolute"><parent link="link6"/><child link="spin_link"/>'
            '<axis xyz="0 0 1"/><limit lower="-1e16" upper="1e16" effort="1" velocity="1"/></joint>'
            '<link name="spin_link"/>\n</robot>')
    arm = Arm.from_urdf(arm6(tmp_path, "</robot>", spin, name="spin.urdf"), "tool")
    assert arm.locked_joints == {"spin": 0.0}


def test_a_urdf_named_like_a_known_robot_is_not_taken_for_it(tmp_path):
    """A URDF file named puma560.urdf was timed with the PUMA 560's nominal rate limits, and the
    viewer drew the PUMA's envelope arcs for it (the PUMA is recognised by its name): a URDF arm's
    name is never a known robot's."""
    arm = Arm.from_urdf(arm6(tmp_path, name="puma560.urdf"), "tool")
    assert arm.robot == "puma560 from puma560.urdf" and not arm.analytic


# ---------------------------------------------------------------------- the cache of URDF files
def test_an_edited_urdf_is_loaded_afresh(tmp_path):
    """URDFs were cached by path: an edit on disk (a limit, a link length) went unseen by later
    loads in the same process (a viewer, a notebook)."""
    path = arm6(tmp_path)
    q = np.array([0.3, -0.4, 0.5, 0.2, 0.6, -0.1])
    before = Arm.from_urdf(path, "tool")
    assert before.limits[1] == pytest.approx((-2.0, 2.0))
    fk_before = before.fk(q)

    path.write_text(path.read_text().replace(J2_LIMIT, 'lower="-1.0" upper="1.5" effort="10"')
                    .replace('<origin xyz="0 -0.06 0.4"/>', '<origin xyz="0 -0.06 0.5"/>'))  # a longer upper arm
    after = Arm.from_urdf(path, "tool")
    assert after.limits[1] == pytest.approx((-1.0, 1.5))
    assert not np.allclose(after.fk(q), fk_before)
    assert np.allclose(before.fk(q), fk_before)  # an Arm already loaded keeps its model
    r = after.ik(after.fk(q), q_near=q)
    assert r.ok and np.allclose(after.fk(r.q), after.fk(q), atol=1e-9)

    path.write_text(path.read_text().replace('lower="-1.0" upper="1.5"', 'lower="2.0" upper="-2.0"'))
    with pytest.raises(RobotError, match="joint 'j2'"):  # an edit that breaks the file is seen as well
        Arm.from_urdf(path, "tool")


def test_an_unchanged_urdf_is_not_read_as_a_model_again(tmp_path):
    """Loading the same bytes twice shares the model (the cache is keyed by the content)."""
    path = arm6(tmp_path)
    a, b = Arm.from_urdf(path, "tool"), Arm.from_urdf(path, "tool")
    assert a is not b and a.model is b.model and a.solver is b.solver
    path.write_text(path.read_text())  # rewritten with the same bytes: still the same model
    assert Arm.from_urdf(path, "tool").model is a.model
