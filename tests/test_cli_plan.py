"""`dualpuma plan`: goal at the CLI edge (mm, deg), JSON output, files never overwritten silently."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys

import numpy as np

from dualpuma import Cell, Plan, plan


def same_plan(a: Plan, b: Plan) -> bool:
    """The same plan computed in another process: every field equal, bit for bit (coal's box
    support keeps a factor from its first call in a process, coal-library/coal#894, which
    dualpuma fixes at import; before, capsule–box clearances differed in their last bits)."""
    return a.equals(b)


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "dualpuma.cli", "plan", *args], check=False, capture_output=True, text=True,
                          timeout=120, cwd=cwd)


def test_plan_by_offset_matches_the_api(tmp_path):
    out = tmp_path / "p.json"
    r = _cli("--by", "-200", "0", "100", "--rpy", "0", "0", "-10", "--json", "--out", str(out))
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    c = Cell.default()
    A = c.T_world_object_start
    from dualpuma.lie import rot_to_rpy, rpy_to_rot

    B = A.copy()
    B[:3, 3] += (-0.2, 0.0, 0.1)
    B[:3, :3] = rpy_to_rot(rot_to_rpy(A[:3, :3]) + np.radians([0.0, 0.0, -10.0]))
    ref = plan(c, A, B)
    assert d["status"] == ref.status == "reached" and d["steps"] == ref.n_steps
    saved = Plan.from_json(out.read_text())
    assert same_plan(saved, ref)
    again = _cli("--by", "-200", "0", "100", "--out", str(out))
    assert again.returncode == 2 and "--force" in again.stderr and "Traceback" not in again.stderr
    assert same_plan(Plan.from_json(out.read_text()), ref)  # untouched
    # -100 mm x and 50 mm -y (was -100 mm x only): straight -x from the start brings robot 2's wrist within
    # 15 mm of its own pedestal, refused since self-collision is checked (issue 13)
    assert _cli("--by", "-100", "-50", "0", "--out", str(out), "--force").returncode == 0
    assert Plan.from_json(out.read_text()).n_steps == 3


def test_plan_failures_exit_codes(tmp_path):
    far = _cli("--by", "0", "-3000", "0")
    assert far.returncode == 1 and "invalid_goal" in far.stdout
    bad = _cli("--cell", str(tmp_path / "missing.toml"), "--by", "0", "0", "0")
    assert bad.returncode == 2 and "missing.toml" in bad.stderr and "Traceback" not in bad.stderr
    nan = _cli("--by", "0", "0", "nan")
    assert nan.returncode == 2 and "finite" in nan.stderr
    npz = tmp_path / "p.npz"
    r = _cli("--cell", "routine7_box", "--to", "1500", "-200", "475", "--out", str(npz))
    from dualpuma import example_cell

    c = example_cell("routine7_box")
    B = c.T_world_object_start.copy()
    B[:3, 3] = (1.5, -0.2, 0.475)
    ref = plan(c, c.T_world_object_start, B)
    assert r.returncode == (0 if ref.reached else 1) and same_plan(Plan.load_npz(npz), ref)


def test_a_frozen_plan_points_to_the_fallback():
    """The README's first plan (-200 mm x, +100 mm z from the start) freezes in Striving: the human
    output says so and names --fallback; with --fallback the hint is gone and the exit code follows
    the API's plan with the fallback on."""
    from dualpuma import StrivingParams

    c = Cell.default()
    A = c.T_world_object_start
    B = A.copy()
    B[:3, 3] += (-0.2, 0.0, 0.1)
    ref = plan(c, A, B)
    r = _cli("--by", "-200", "0", "100")
    assert ref.status == "frozen" and r.returncode == 1 and r.stdout.startswith("frozen")
    assert r.stdout.rstrip().splitlines()[-1].strip().startswith("(Striving froze: --fallback")
    ref_f = plan(c, A, B, StrivingParams(fallback=True))
    f = _cli("--by", "-200", "0", "100", "--fallback")
    assert f.returncode == (0 if ref_f.reached else 1) and f.stdout.startswith(ref_f.status)
    assert "--fallback searches" not in f.stdout


def test_time_limit_ends_the_fallback_search_and_says_so():
    """--time-limit S with --fallback: a search that has not met the goal stops after S seconds and
    the status says so (the seed's routine-7 box, where Striving hands over and the straight SE(3)
    edge is refused, so the search needs iterations: a limit of 1 us has passed before the first;
    with 50 ms the search finds a path in a few on an idle host); without --fallback, or outside
    (0, 86400] s: exit 2, one line."""
    r = _cli("--cell", "routine7_box", "--to", "1500", "-200", "475", "--fallback", "--time-limit", "1e-6", "--json")
    d = json.loads(r.stdout)
    assert r.returncode == 1 and d["status"] == "frozen", d["reason"]
    assert "no path found within the time limit of 1e-06 s (0 iterations)" in d["reason"], d["reason"]
    for args, msg in ((("--time-limit", "1"), "give --fallback too"), (("--fallback", "--time-limit", "0"), "(0, 86400]"),
                      (("--fallback", "--time-limit", "nan"), "(0, 86400]")):
        bad = _cli("--by", "-100", "-50", "50", *args)
        assert bad.returncode == 2 and msg in bad.stderr and "Traceback" not in bad.stderr, bad.stderr


def test_a_closed_stdout_ends_the_command_quietly():
    """`dualpuma plan ... | head`: the reader has gone before the output is written; the command
    stops with 141 (as a tool ended by SIGPIPE would) and nothing on stderr. It used to report an
    internal BrokenPipeError with exit code 70."""
    for extra in ((), ("--json",)):
        p = subprocess.Popen([sys.executable, "-m", "dualpuma.cli", "plan", "--by", "-200", "0", "100", *extra],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        p.stdout.close()  # long before the plan is printed (the import alone takes longer)
        err = p.stderr.read()
        p.stderr.close()
        assert p.wait(timeout=120) == 141, err
        assert err == b""


def test_an_unwritable_or_closed_stdout(tmp_path):
    """`> /dev/full`: one line, exit 2 (it was an 'internal error', exit 70). `>&-` (stdout closed
    before the start): the plan is made, its --out file written, the exit code is the plan's (it
    was a traceback and exit 1)."""
    for argv in (("fk", "--q", "10", "20", "30", "0", "45", "0"), ("plan", "--by", "0", "-50", "0", "--json")):
        with open("/dev/full", "w") as full:
            r = subprocess.run([sys.executable, "-m", "dualpuma.cli", *argv], stdout=full, stderr=subprocess.PIPE,
                               text=True, timeout=120, check=False)
        assert r.returncode == 2 and r.stderr.strip() == "dualpuma: error: cannot write the output: No space left on device"
    out = tmp_path / "p.json"
    r = subprocess.run(["sh", "-c", f'exec "{sys.executable}" -m dualpuma.cli plan --by 0 -50 0 --out "{out}" >&-'],
                       capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 0 and r.stderr == "" and Plan.from_json(out.read_text()).reached


def _closure_by_urdf(cell, qL, qR) -> float:
    """The right hand's distance from its grasp on the bar the left hand holds [m], by FK of each
    arm's own URDF built here (tests/urdf_reference.py), not by dualpuma's models."""
    from urdf_reference import FullUrdf

    from dualpuma.kinematics import Arm

    out = []
    for side, q in (("left", qL), ("right", qR)):
        arm = Arm.load(getattr(cell, side).robot)
        ref = FullUrdf(arm.urdf_path, [arm.model.names[j] for j in range(1, 7)], arm.hand_frame)
        out.append(getattr(cell, side).T_world_base @ ref.fk(q))
    want = out[0] @ np.linalg.inv(cell.grasp_left.T_object_hand) @ cell.grasp_right.T_object_hand
    return float(np.linalg.norm(out[1][:3, 3] - want[:3, 3]))


def test_plan_trajectory_in_json_and_file(tmp_path):
    """--trajectory: the JSON carries the timed trajectory (the same one the --out file holds),
    sampled at most 10 ms apart, at rest at both ends, within the PUMA's nominal limits, the hands
    on the bar within 0.5 mm (independent FK) and at the plan's goal at the end."""
    from dualpuma.planning import PUMA_QD_MAX, PUMA_QDD_MAX

    out = tmp_path / "timed.json"
    r = _cli("--by", "-100", "-50", "50", "--trajectory", "--json", "--out", str(out))
    assert r.returncode == 0, r.stderr
    tr = json.loads(r.stdout)["trajectory"]
    saved = Plan.from_json(out.read_text())
    assert saved.trajectory is not None and tr["certified"] is True
    np.testing.assert_array_equal(saved.trajectory.t, tr["t"])
    t, qL, qR = np.array(tr["t"]), np.array(tr["q_left"]), np.array(tr["q_right"])
    assert np.all(np.diff(t) > 0) and np.all(np.diff(t) <= 0.01 + 1e-12)
    np.testing.assert_allclose(qL[-1], saved.q_left[-1], atol=1e-9)
    qd = np.hstack([tr["qd_left"], tr["qd_right"]])
    assert np.abs(qd[0]).max() < 1e-9 and np.abs(qd[-1]).max() < 1e-6
    assert np.all(np.abs(qd) <= np.tile(PUMA_QD_MAX, 2) * (1 + 1e-9))
    assert np.all(np.abs(np.hstack([tr["qdd_left"], tr["qdd_right"]])) <= np.tile(PUMA_QDD_MAX, 2) * (1 + 1e-9))
    cell = Cell.default()
    for k in range(0, len(t), 7):
        assert _closure_by_urdf(cell, qL[k], qR[k]) <= 0.5e-3
    text = _cli("--by", "-100", "-50", "50", "--trajectory")
    assert text.returncode == 0 and "timed:" in text.stdout and "certified" in text.stdout
    # limits without --trajectory, or malformed: one-line errors
    for args, msg in ((("--v-max", "100"), "--trajectory"), (("--trajectory", "--v-max", "1", "2"), "6 numbers"),
                      (("--trajectory", "--a-max", "10", "10", "10", "10", "10", "-10"), "--a-max: limits must be in [0.0573, 572957.7] deg/s^2")):
        r = _cli("--by", "-100", "-50", "50", *args)
        assert r.returncode == 2 and msg in r.stderr and "Traceback" not in r.stderr


def test_plan_trajectory_on_a_controller_clock(tmp_path):
    """--period 0.004: the trajectory in the JSON and the --out file has a sample every 4 ms from
    the start (a 250 Hz controller), the hands on the bar within 0.5 mm (independent FK) at the
    samples and halfway between them; the text says so; a period too long for the closed chain, or
    one outside 0.1 ms .. 1 s, or without --trajectory: exit 2, one line, no traceback."""
    out = tmp_path / "clock.npz"
    r = _cli("--by", "-100", "-50", "50", "--trajectory", "--period", "0.004", "--json", "--out", str(out))
    assert r.returncode == 0, r.stderr
    tr = json.loads(r.stdout)["trajectory"]
    t, qL, qR = np.array(tr["t"]), np.array(tr["q_left"]), np.array(tr["q_right"])
    assert tr["period"] == 0.004 and tr["certified"] is True and np.abs(np.diff(t) - 0.004).max() <= 1e-12
    np.testing.assert_array_equal(Plan.load_npz(out).trajectory.t, t)
    cell = Cell.default()
    for k in range(0, len(t) - 1, 9):
        assert _closure_by_urdf(cell, qL[k], qR[k]) <= 0.5e-3
        assert _closure_by_urdf(cell, 0.5 * (qL[k] + qL[k + 1]), 0.5 * (qR[k] + qR[k + 1])) <= 0.5e-3
    text = _cli("--by", "-100", "-50", "50", "--trajectory", "--period", "0.004")
    assert text.returncode == 0 and "samples every 0.004 s" in text.stdout
    for args, msg in ((("--trajectory", "--period", "0.5"), "a period of 0.25 s keeps it"),
                      (("--trajectory", "--period", "0"), "--period"), (("--trajectory", "--period", "2"), "--period"),
                      (("--period", "0.004"), "--trajectory")):
        bad = _cli("--by", "-100", "-50", "50", *args)
        assert bad.returncode == 2 and msg in bad.stderr and "Traceback" not in bad.stderr, bad.stderr


def test_plan_trajectory_of_a_mixed_pair():
    """A PUMA + UR5: the UR5's URDF gives velocity limits but no accelerations, so --a-max is asked
    for; with it, the timed motion keeps the bar within 0.5 mm (FK of both URDFs)."""
    from dualpuma import example_cell

    r = _cli("--cell", "mixed_puma_ur5", "--by", "-100", "0", "50", "--trajectory")
    assert r.returncode == 2 and "--a-max" in r.stderr and "ur5" in r.stderr
    r = _cli("--cell", "mixed_puma_ur5", "--by", "-100", "0", "50", "--trajectory", "--json",
             "--a-max", "45", "40", "75", "70", "90", "80")
    assert r.returncode == 0, r.stderr
    tr = json.loads(r.stdout)["trajectory"]
    assert tr["certified"] and "ur5 URDF velocity limits" in tr["limits_source"]
    np.testing.assert_allclose(tr["v_max"][6:], [3.15, 3.15, 3.15, 3.2, 3.2, 3.2])  # the UR5 URDF's
    np.testing.assert_allclose(tr["a_max"], np.radians([45, 40, 75, 70, 90, 80] * 2))
    cell = example_cell("mixed_puma_ur5")
    qL, qR = np.array(tr["q_left"]), np.array(tr["q_right"])
    for k in range(0, len(qL), 5):
        assert _closure_by_urdf(cell, qL[k], qR[k]) <= 0.5e-3


def test_plan_trajectory_waits_for_a_moving_obstacle(tmp_path):
    """A cell file with a ball that rises through the bar's path at t = 0.5..1.0 s: the timed
    motion waits at the start (exit 0, certified, the wait in the JSON and in the text); with
    --max-wait 0 --max-slowdown 1 the fastest timing meets the ball (exit 1, NOT certified)."""
    from dualpuma.model import cell_to_toml
    from dualpuma.scenarios import rising_ball_cell

    cell, _, _ = rising_ball_cell(0.5, 1.0)
    path = tmp_path / "ball.toml"
    path.write_text(cell_to_toml(cell))
    r = _cli("--cell", str(path), "--by", "0", "-150", "50", "--trajectory", "--json")
    assert r.returncode == 0, r.stderr
    tr = json.loads(r.stdout)["trajectory"]
    assert tr["certified"] is True and tr["start_delay"] > 0 and tr["time_scale"] == 1.0
    t, qL = np.array(tr["t"]), np.array(tr["q_left"])
    assert np.all(qL[t < t[0] + tr["start_delay"]] == qL[0])  # at rest while it waits
    text = _cli("--cell", str(path), "--by", "0", "-150", "50", "--trajectory")
    assert text.returncode == 0 and "waits" in text.stdout and "to let a moving obstacle pass" in text.stdout
    fast = _cli("--cell", str(path), "--by", "0", "-150", "50", "--trajectory", "--max-wait", "0", "--max-slowdown", "1")
    assert fast.returncode == 1 and "NOT certified" in fast.stdout and "waits" not in fast.stdout
    # untimed, the plan reaches on its own clock, which the fastest timing cannot keep (above): it says so
    untimed = _cli("--cell", str(path), "--by", "0", "-150", "50")
    assert untimed.returncode == 0 and "moving obstacles were checked on the plan's clock (0.1 s per step)" in untimed.stdout
    assert "--trajectory checks them" in json.loads(_cli("--cell", str(path), "--by", "0", "-150", "50", "--json").stdout)["warnings"][0]
    # a ball that parks in the path: no timing helps; the reason says how much slower a clock to plan
    # with, and planned with it (--step-time) Striving freezes at the ball instead of reaching
    parked = tmp_path / "parked.toml"
    parked.write_text(cell_to_toml(rising_ball_cell(0.45, 0.6)[0]))
    r = _cli("--cell", str(parked), "--by", "0", "-150", "50", "--trajectory")
    m = re.search(r"passes its rows up to ([0-9.]+)x sooner than the arms can reach them", r.stdout)
    assert r.returncode == 1 and "NOT certified" in r.stdout and m, r.stdout
    slow = _cli("--cell", str(parked), "--by", "0", "-150", "50", "--trajectory", "--step-time",
                f"{0.1 * float(m.group(1)):.2f}", "--json")
    d = json.loads(slow.stdout)
    assert slow.returncode == 1 and d["status"] == "frozen" and "obstacle/ball" in d["reason"]
    for args, msg in ((("--max-wait", "2"), "--trajectory"), (("--trajectory", "--max-wait", "-1"), "--max-wait"),
                      (("--trajectory", "--max-slowdown", "0.5"), "--max-slowdown"), (("--step-time", "0"), "--step-time")):
        bad = _cli("--cell", str(path), "--by", "0", "-150", "50", *args)
        assert bad.returncode == 2 and msg in bad.stderr and "Traceback" not in bad.stderr


def test_step_mm_plans_what_it_accepts_and_refuses_the_rest_in_mm():
    short = _cli("--by", "-100", "-50", "50", "--step-mm", "1", "--json")  # was refused: min_step 5 mm > step
    assert short.returncode == 0, short.stderr
    d = json.loads(short.stdout)
    assert d["status"] == "reached" and d["steps"] >= math.ceil(float(np.linalg.norm([100.0, 50.0, 50.0])))
    for v in ("25001", "100000"):  # was accepted, then an invalid_input plan about substeps
        r = _cli("--by", "-100", "-50", "50", "--step-mm", v)
        assert r.returncode == 2 and "--step-mm: expected a length in [0.1, 25000] [mm]" in r.stderr, r.stderr
    r = _cli("--by", "-100", "-50", "50", "--step-mm", "1e-9")  # was an internal error: MemoryError (4 TiB)
    assert r.returncode == 2 and "--step-mm: expected a length in [0.1, 25000] [mm], got 1e-09" in r.stderr, r.stderr


def test_out_naming_a_directory_says_so_at_once(tmp_path):
    r = _cli("--by", "-100", "-50", "50", "--out", str(tmp_path))
    assert r.returncode == 2 and "not a regular file" in r.stderr and "--force" not in r.stderr, r.stderr


def test_an_uncertified_timing_names_the_flag_that_sets_step_time(tmp_path):
    from dualpuma import save_cell
    from dualpuma.scenarios import rising_ball_cell

    cell = save_cell(rising_ball_cell(0.5, 0.6)[0], tmp_path / "ball.toml")  # a ball rising through the path
    r = _cli("--cell", str(cell), "--by", "0", "-150", "50", "--trajectory")
    assert r.returncode == 1 and "NOT certified" in r.stdout and "a step_time 5.0x as long" in r.stdout, r.stdout
    assert "(--step-time sets step_time: 0.1 s now)" in r.stdout


def test_joint_limit_flags_are_checked_in_the_degrees_they_are_given_in():
    """--a-max/--v-max take degrees; a value out of range was refused in rad/s^2 (time_plan's
    unit). The range is JOINT_LIMIT_RANGE converted, [1e-3, 1e4] rad = [0.0572958, 572957.795] deg,
    shown rounded inwards so that both ends shown are taken (572958 was shown and refused)."""
    lo, hi = math.degrees(1e-3), math.degrees(1e4)
    assert lo <= 0.0573 and 572957.7 <= hi < 572957.8  # the range shown, rounded inwards
    for flag, unit in (("--a-max", "deg/s^2"), ("--v-max", "deg/s")):
        for v in ("1e308", "0.05", "0", "572957.8"):
            r = _cli("--by", "-100", "-50", "50", "--trajectory", flag, v, "1", "1", "1", "1", "1")
            assert r.returncode == 2 and f"{flag}: limits must be in [0.0573, 572957.7] {unit}" in r.stderr, r.stderr
            assert "rad" not in r.stderr
    ok = _cli("--by", "-100", "-50", "50", "--trajectory", "--json", "--a-max", "0.0573", "400", "400", "400", "400",
              "572957.7")  # both ends of the range shown are taken
    assert ok.returncode == 0 and json.loads(ok.stdout)["trajectory"] is not None, ok.stderr


def test_plan_warns_when_an_arms_close_link_pairs_have_no_contact_map(tmp_path):
    """The right UR5 of ur5_pair read from an edited copy of its file (its wrist_2 collision mesh 1 mm
    along its link: a geometry no stored map was derived for): `dualpuma plan` says its
    always-close link pairs are not checked on their meshes; the stored UR5 does not."""
    import re

    from mesh_reference import edited_ur5

    from dualpuma.model import cell_to_toml, example_cell

    text = cell_to_toml(example_cell("ur5_pair"))
    right = text.index("[right]")
    line = re.compile(r'^robot = .*$', re.MULTILINE).search(text, right)
    urdf = edited_ur5(tmp_path)
    cell = tmp_path / "edited.toml"
    cell.write_text(text[: line.start()] + f'robot = {{ urdf = "{urdf}", tip = "tool0" }}' + text[line.end():])
    r = _cli("--cell", str(cell), "--by", "0", "0", "20", "--json")
    out = json.loads(r.stdout)
    assert any("right arm's always-close link pairs" in w and "not checked" in w for w in out["warnings"]), r.stdout + r.stderr
    r = _cli("--cell", "ur5_pair", "--by", "0", "0", "20", "--json")
    assert not any("always-close" in w for w in json.loads(r.stdout)["warnings"])
