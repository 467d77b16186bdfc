"""The CLI's units and forms: millimetres and degrees on every flag, vectors given the same way on
every command (separate numbers or one quoted string), fk's output feeds ik, ik says why a branch
has no solution, every --help has a description and an example."""

from __future__ import annotations

import json
import math
import re
import shlex

import numpy as np
import pytest

from dualpuma import puma
from dualpuma.cli import COMMANDS, build_parser, main
from dualpuma.envelope import ideal_envelope
from dualpuma.lie import rpy_to_rot
from dualpuma.units import display_text


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    capsys.readouterr()
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.mark.parametrize(("cmd", "forms"), [
    (["fk", "--json"], (["--q", "10", "20", "30", "0", "45", "0"], ["--q", "10 20 30 0 45 0"], ["--q", "10,20,30,0,45,0"],
                        ["--q", "10", "20 30", "0,45", "0"])),
    (["ik", "--json"], (["--xyz", "500", "150", "-200", "--rpy", "0", "90", "0"], ["--xyz", "500 150 -200", "--rpy", "0 90 0"],
                        ["--xyz", "500,150,-200", "--rpy", "0,90,0"])),
    (["plan", "--json"], (["--by", "-200", "0", "100"], ["--by", "-200 0 100"], ["--by", "-200,0,100"],
                          ["--by=-200,0,100"], ["--by", "-2e2", "0", "1e2"])),
])
def test_vectors_are_given_the_same_way_everywhere(capsys, cmd, forms):
    outs = []
    for form in forms:
        rc, out, err = _run(capsys, *cmd, *form)
        assert rc in (0, 1), err
        d = json.loads(out)
        d.pop("planning_time_s", None)
        outs.append(d)
    assert all(o == outs[0] for o in outs[1:])


@pytest.mark.parametrize("q_deg", [(10.0, 20.0, 30.0, 15.0, 45.0, -30.0),
                                   (10.0, 20.0, 30.0, 0.0, 40.0, 0.0)])  # the hand straight down: pitch 90 deg
def test_fk_prints_units_and_rpy_that_feed_ik(capsys, q_deg):
    q_deg = np.array(q_deg)
    rc, out, _ = _run(capsys, "fk", "--q", *map(str, q_deg))
    assert rc == 0 and "[mm]" in out and "[deg]" in out and "roll" in out and "yaw" in out
    T = puma.fk(np.radians(q_deg))  # the independent answer: the closed-form FK in SI
    cmd = next(line for line in out.splitlines() if "dualpuma ik" in line).split("dualpuma ", 1)[1]
    argv = shlex.split(cmd)
    xyz = np.array([float(v) for v in argv[argv.index("--xyz") + 1 : argv.index("--rpy")]])
    rpy = np.radians([float(v) for v in argv[argv.index("--rpy") + 1 :]])
    np.testing.assert_allclose(xyz / 1000.0, T[:3, 3], atol=1e-12)
    np.testing.assert_allclose(rpy_to_rot(rpy), T[:3, :3], atol=1e-11)
    rc, out, _ = _run(capsys, *argv, "--json")  # ik of fk's output gives the joints back on their branch
    rows = {r["branch"]: r for r in json.loads(out)["solutions"]}
    branch = puma.BRANCH_NAMES[int(puma.branch_of(np.radians(q_deg)))]
    assert rows[branch]["valid"]
    np.testing.assert_allclose(rows[branch]["q_deg"], q_deg, atol=1e-6)


@pytest.mark.parametrize("robot", ["ur5", "z1"])
def test_fk_and_ik_of_other_arms(capsys, robot):
    """--robot: fk's printed ik command gives the joints back (a UR5: on their branch, all eight
    branches reach the pose; a Z1: the numeric solution reaches it), checked by FK of the arm's own
    URDF built here."""
    from urdf_reference import FullUrdf

    from dualpuma.kinematics import Arm

    arm = Arm.load(robot)
    ref = FullUrdf(arm.urdf_path, [arm.model.names[j] for j in range(1, 7)], arm.hand_frame)
    q_deg = np.array([10.0, -80.0, 90.0, -100.0, -90.0, 20.0]) if robot == "ur5" else np.array([5.0, 60, -60, 10, 30, 0])
    rc, out, _ = _run(capsys, "fk", "--robot", robot, "--q", *map(str, q_deg), "--json")
    d = json.loads(out)
    T = ref.fk(np.radians(q_deg))
    np.testing.assert_allclose(np.asarray(d["position_mm"]) / 1000.0, T[:3, 3], atol=1e-12)
    argv = shlex.split(d["ik_command"].split("dualpuma ", 1)[1])
    assert argv[:3] == ["ik", "--robot", robot]
    rc, out, _ = _run(capsys, *argv, "--json")
    res = json.loads(out)
    assert rc == 0 and res["robot"] == robot and res["frame"] == arm.hand_frame
    valid = [r for r in res["solutions"] if r["valid"]]
    assert len(valid) == (8 if robot == "ur5" else 1)
    for r in valid:
        np.testing.assert_allclose(ref.fk(np.radians(r["q_deg"])), T, atol=1e-7)  # q_deg printed to 1e-6 deg
    if robot == "ur5":
        own = next(r for r in valid if r["branch"] == d["branch"])
        np.testing.assert_allclose(own["q_deg"], q_deg, atol=1e-6)
    rc, out, _ = _run(capsys, "ik", "--robot", robot, "--xyz", "3000", "0", "0", "--json")
    assert rc == 1 and not any(r["valid"] for r in json.loads(out)["solutions"])  # no answer: exit 1, as plan


def test_fk_json_has_units_in_its_keys(capsys):
    _rc, out, _ = _run(capsys, "fk", "--q", "0", "0", "0", "0", "0", "0", "--json")
    d = json.loads(out)
    T = puma.fk(np.zeros(6))
    np.testing.assert_allclose(d["position_mm"], T[:3, 3] * 1000.0, atol=1e-9)
    np.testing.assert_allclose(rpy_to_rot(np.radians(d["rpy_deg"])), T[:3, :3], atol=1e-12)
    assert d["ik_command"].startswith("dualpuma ik --xyz ")


def test_ik_says_why_a_branch_has_no_solution(capsys):
    rc, out, _ = _run(capsys, "ik", "--xyz", "2000", "0", "0", "--json")
    rows = json.loads(out)["solutions"]
    assert rc == 1 and all(r["status"] == "unreachable" and "2000.0 mm from the shoulder" in r["reason"] for r in rows)
    rc, out, _ = _run(capsys, "ik", "--xyz", "0", "0", "500")
    assert rc == 1 and out.count("J1 axis") == 8  # too close to the base axis: the shoulder offset is 149.09 mm
    # a pose whose branches split: some valid, some outside the limits (q5 beyond +-100 deg)
    q = np.radians([10.0, 20.0, 30.0, 0.0, 45.0, 0.0])
    T = puma.fk(q)
    rpy = np.degrees([math.atan2(T[2, 1], T[2, 2]), math.asin(-T[2, 0]), math.atan2(T[1, 0], T[0, 0])])
    rc, out, _ = _run(capsys, "ik", "--xyz", *map(str, T[:3, 3] * 1000), "--rpy", *map(str, rpy), "--json")
    rows = json.loads(out)["solutions"]
    sols, valid = puma.ik_all(T)  # the library's own answer, per branch
    for r, s, v in zip(rows, sols, valid):
        assert r["valid"] == bool(v)
        if not v:
            bad = [j + 1 for j in range(6) if not puma.JOINT_LIMITS[j, 0] - 1e-12 <= s[j] <= puma.JOINT_LIMITS[j, 1] + 1e-12]
            assert r["status"] == "joint_limits" and bad
            assert all(f"q{j} = " in r["reason"] for j in bad), r["reason"]
    assert not all(valid) and any(valid) and rc == 0  # some branch valid: exit 0


@pytest.mark.parametrize(("R", "D", "L"), [(1.0, 2.5, 1.0), (0.8, 1.2, 0.5)])
def test_envelope_lengths_are_millimetres(capsys, R, D, L):
    ref = ideal_envelope(R, D, L).volume_m3  # the library in SI
    for names in (("--reach-mm", "--base-distance-mm", "--bar-length-mm"), ("--reach", "--base-distance", "--bar-length")):
        rc, out, err = _run(capsys, "envelope", "--ideal", names[0], str(R * 1000), names[1], str(D * 1000),
                            names[2], str(L * 1000), "--json")
        assert rc == 0, err
        assert json.loads(out)["volume_m3"] == pytest.approx(ref, rel=1e-12)
    rc, _, err = _run(capsys, "envelope", "--ideal", "--reach", "1")  # the old metre value: refused, with a hint
    assert rc == 2 and "millimetres" in err and "--reach 1000" in err


def _help_examples(capsys) -> list[str]:
    out = []
    for name in [m.__name__.rsplit(".", 1)[-1] for m in COMMANDS if not m.__name__.endswith("serve")]:
        _rc, text, _ = _run(capsys, name, "--help")
        out += [line.strip() for line in text.split("examples:", 1)[1].splitlines() if line.strip()]
    return out


def test_every_help_example_runs_as_written(capsys, monkeypatch, tmp_path):
    """A reader copies an example from --help: it must do what it shows, exit 0 (three did not: a
    plan that froze without --fallback, twice, and an IK pose no branch reaches). serve's examples
    start a server and are covered by the viewer's tests."""
    monkeypatch.chdir(tmp_path)  # --out plan.npz, plan.json, timed.npz land here
    examples = _help_examples(capsys)
    assert len(examples) >= 12
    for example in examples:
        argv = shlex.split(example)
        assert argv[0] == "dualpuma"
        rc, out, err = _run(capsys, *argv[1:])
        assert rc == 0 and out and not err, f"{example}: exit {rc}, {err or out[:300]}"
        if "--json" in argv:
            json.loads(out)


def test_every_help_has_a_description_and_an_example(capsys):
    parser = build_parser()
    names = [m.__name__.rsplit(".", 1)[-1] for m in COMMANDS if not m.__name__.endswith("serve")]  # serve: viewer's
    for name in names:
        rc, out, _ = _run(capsys, name, "--help")
        assert rc == 0
        _usage, rest = out.split("\n\n", 1)
        description = rest.split("\n\n", 1)[0]
        assert len(description) > 40 and "examples:" in out and f"dualpuma {name}" in out.split("examples:")[1], name
    assert parser.format_help().count("examples:") == 1


def test_planner_text_is_shown_in_millimetres_and_json_stays_si(capsys):
    """Routine 6's refusal is written by the planner in metres (an API value); the human output
    shows every length in mm, --json keeps the planner's own text. The expected numbers are read
    from the JSON (SI) and converted here."""
    rc, out, _ = _run(capsys, "routine", "6", "--json")
    d = json.loads(out)
    metres = [float(x) for x in re.findall(r"(\d+\.\d+) m\b", d["reason"])]
    assert len(metres) == 3  # clearance, buffer, closing rate
    rc, out, _ = _run(capsys, "routine", "6")
    assert rc == 0
    status = next(line for line in out.splitlines() if "status:" in line)
    shown = [float(x) for x in re.findall(r"(\d+(?:\.\d+)?) mm\b", status)]
    np.testing.assert_allclose(shown, [1000.0 * m for m in metres], rtol=0, atol=0.051)
    assert not re.search(r"\d m\b", out.split("  note:")[0])  # no length left in metres before the prose note


@pytest.mark.parametrize(("text", "shown"), [
    ("clearance 0.0033 m below 0.010 m (right/elbow – obstacle/slab)", "clearance 3.3 mm below 10 mm (right/elbow – obstacle/slab)"),
    ("the 0.175 m buffer, closing by 0.0064 m per step", "the 175 mm buffer, closing by 6.4 mm per step"),
    ("-0.0300 m", "-30.0 mm"),
    ("2 m away", "2000 mm away"),
    ("0.5 m/s, 3 mm, step 12, 5 deg, 0.2 s", "0.5 m/s, 3 mm, step 12, 5 deg, 0.2 s"),  # not lengths in metres
    ("plan_0.5 m.toml", "plan_0.5 m.toml"),  # part of a word
    # an IK message's vector (the viewer showed it in metres)
    ("wrist centre [0.7619, -0.1662, -0.4331] m is outside the arm's reach",
     "wrist centre [761.9, -166.2, -433.1] mm is outside the arm's reach"),
    ("[1, 2] m/s and [0.5] m", "[1, 2] m/s and [500] mm"),
    # angles: radians in the API, degrees where a person reads them (two decimals fewer)
    ("q6 = -6.7955 rad not in [-4.6426, 4.6426] rad", "q6 = -389.35 deg not in [-266.00, 266.00] deg"),
    ("would move 0.3491 rad in one step (max 0.0873 rad)", "would move 20.00 deg in one step (max 5.00 deg)"),
    ("2 rad/s, 1.5 rad/s^2, 3 radians, grad 0.5 rad", "2 rad/s, 1.5 rad/s^2, 3 radians, grad 29 deg"),
    # a number's exponent is part of it (1e-05 rad was shown as 1e-286 deg), and "run-2 rad" is a name
    ("a move of 1e-05 rad, 3.5e-3 m and 1e+06 m", "a move of 0.000573 deg, 3.5 mm and 1e+09 mm"),
    ("run-2 rad.json, plan_0.5 m.toml", "run-2 rad.json, plan_0.5 m.toml"),
])
def test_display_text_rewrites_metres_and_radians_only(text, shown):
    assert display_text(text) == shown


@pytest.mark.parametrize(("value", "shown"), [
    (0.01997, "19.97 mm below 20 mm"),  # was "20.0 mm below 20 mm": the rounding hid that it is below
    (0.019951, "19.95 mm below 20 mm"),
    (0.0190, "19.0 mm below 20 mm"),  # four decimals where they show it
    (-0.005, "-5.0 mm below 20 mm"),
])
def test_a_clearance_just_below_the_margin_reads_below_it(value, shown):
    from dualpuma.units import below_text

    text = display_text(f"clearance {below_text(value, 0.02)} m below 0.020 m")
    assert text == f"clearance {shown}"
    assert float(text.split()[1]) / 1000.0 < 0.02 and float(text.split()[1]) / 1000.0 == pytest.approx(value, abs=5e-6)


def test_a_plan_refused_just_below_the_margin_says_by_how_much():
    """Through the planner: a margin 1e-7 m above the start's clearance (from World.clearance)
    gives an invalid start whose reason, in mm, reads below the margin. (The start's 46.5 mm is more
    than the default cell's World checks every pair for: the cell gets that margin, so that its
    World checks them.)"""
    import dataclasses

    from dualpuma import Cell, StrivingParams, World, plan

    cell = Cell.default()
    d = World(cell).clearance(cell.left.q_home, cell.right.q_home).distance
    margin = d + 1e-7
    cell = dataclasses.replace(cell, safety_margin=margin)
    w = World(cell)
    assert w.clearance(cell.left.q_home, cell.right.q_home).distance == d  # the pairs it adds are farther
    p = plan(cell, cell.T_world_object_start, cell.T_world_object_start, StrivingParams(margin=margin), world=w)
    assert p.status == "invalid_start"
    shown = float(display_text(p.reason).split("start clearance ")[1].split(" mm")[0]) / 1000.0
    assert shown < margin and shown == pytest.approx(d, abs=5e-5)  # four decimals or more, never at or above it


def test_ik_does_not_call_a_bound_on_the_reach_the_reach(capsys):
    """A UR5 target 1000 mm from the base that no branch reaches was told "the arm reaches at most
    1328.7 mm" (a bound, not the reach); inside the bound the line now says only that the branch
    has no solution there; beyond it, that the point is outside the bound."""
    assert main(["ik", "--robot", "ur5", "--xyz", "1000", "0", "0"]) == 1
    out = capsys.readouterr().out
    assert out.count("no solution on this branch (the hand is 1000.0 mm from the base)") == 8 and "at most" not in out
    assert main(["ik", "--robot", "ur5", "--xyz", "3000", "0", "0"]) == 1
    out = capsys.readouterr().out
    assert out.count("the hand is 3000.0 mm from the base, outside the 0.0-") == 8


def test_ik_refuses_coordinates_far_beyond_any_arm_without_overflow(capsys):
    """``ik --xyz 1e308 0 0`` printed numpy overflow warnings and a position of inf mm; it is bad
    input now (within ±1e6 mm, the cells' 1000 m), for every kind of solver."""
    import warnings

    for robot in ("puma560", "ur5", "z1"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert main(["ik", "--robot", robot, "--xyz", "1e308", "0", "0"]) == 2
        err = capsys.readouterr().err
        assert "--xyz: expected coordinates within ±1e+06 mm" in err and "Warning" not in err
    assert main(["ik", "--xyz", "1e6", "0", "0"]) == 1  # the bound itself: unreachable, not refused
    assert "1000000.0 mm from the shoulder" in capsys.readouterr().out


def test_fk_refuses_joint_angles_beyond_a_hundred_turns(capsys):
    """``fk --q 1e308 ...`` printed a 309-digit angle and a pose of sin(1e306 rad); it is bad
    input now. 36,000 deg itself is accepted and gives the pose at q = 0 (a hundred turns)."""
    assert main(["fk", "--q", "1e308", "0", "0", "0", "0", "0"]) == 2
    assert "--q: expected angles within ±36000 deg (100 turns)" in capsys.readouterr().err
    for argv in (["plan", "--by", "0", "0", "0", "--rpy", "1e20", "0", "0"], ["ik", "--xyz", "500", "0", "0", "--rpy", "0", "0", "-4e4"]):
        assert main(argv) == 2  # --rpy 1e20 planned 'reached'
        assert "--rpy: expected angles within ±36000 deg (100 turns)" in capsys.readouterr().err
    assert main(["fk", "--q", "36000", "0", "0", "0", "0", "0", "--json"]) == 0
    far = json.loads(capsys.readouterr().out)
    assert main(["fk", "--q", "0", "0", "0", "0", "0", "0", "--json"]) == 0
    zero = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(far["T_base_frame"], zero["T_base_frame"], atol=1e-12)


def test_small_things_a_command_line_user_met(capsys, tmp_path, monkeypatch):
    """--version; a flag's prefix is not the flag (--j was taken as --json) and the subcommand says
    it does not know it; --out - is not a file named '-'; 8 values for --v-max name both counts it
    takes; an empty --cell says so (it was '.: not a regular file'); 1 step, not '1 steps'."""
    monkeypatch.chdir(tmp_path)
    rc, out, _ = _run(capsys, "--version")
    assert rc == 0 and re.fullmatch(r"dualpuma \d+\.\d+\.\d+\n", out)
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "dualpuma", "--version"], check=False, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0 and r.stdout == out  # python -m dualpuma is the command too (it had no __main__)
    for argv, msg in ((["plan", "--by", "0", "0", "0", "--j"], "dualpuma plan: error: unrecognized arguments: --j"),
                      (["plan", "--by", "0", "0", "0", "--out", "-"], "-: not a file name (--json prints to stdout)"),
                      (["plan", "--by", "0", "0", "0", "--trajectory", "--v-max", *["90"] * 8],
                       "expected 6 numbers (both arms) or 12 (left then right), got 8"),
                      (["plan", "--cell", "", "--by", "0", "0", "0"], "cell: an empty name")):
        rc, out, err = _run(capsys, *argv)
        assert rc == 2 and msg in err and not out, (argv, err)
    assert not (tmp_path / "-").exists()
    rc, out, _ = _run(capsys, "plan", "--by", "0", "0", "0")
    assert rc == 0 and "\n  1 step, 0 mm" in out


def test_fk_says_which_joints_are_outside_their_limits(capsys):
    """fk is geometry and computes any pose, but the arm cannot take joints beyond its limits: the
    output names them (it said nothing). The limits are read here from the URDF by Pinocchio."""
    import pinocchio as pin

    from dualpuma.kinematics import Arm

    model = pin.buildModelFromUrdf(str(Arm.load("puma560").urdf_path))
    lo, hi = np.degrees(model.lowerPositionLimit[:6]), np.degrees(model.upperPositionLimit[:6])
    q = np.array([35999.0, 60.0, 0.0, 0.0, 0.0, 0.0])
    want = [j + 1 for j in range(6) if not lo[j] <= q[j] <= hi[j]]
    assert want == [1, 2]
    rc, out, _ = _run(capsys, "fk", "--q", *map(str, q), "--json")
    d = json.loads(out)
    assert rc == 0 and [o["joint"] for o in d["outside_limits"]] == want
    np.testing.assert_allclose([o["limits_deg"] for o in d["outside_limits"]], [[lo[0], hi[0]], [lo[1], hi[1]]], atol=1e-9)
    rc, out, _ = _run(capsys, "fk", "--q", *map(str, q))
    assert rc == 0 and "note: q1 = 35999 deg is outside its limits" in out and "note: q2 = 60 deg" in out
    rc, out, _ = _run(capsys, "fk", "--q", "10", "20", "30", "0", "45", "0", "--json")
    assert json.loads(out)["outside_limits"] == []
