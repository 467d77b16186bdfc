"""`dualpuma plan`: goal at the CLI edge (mm, deg), JSON output, files never overwritten silently."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np

from dualpuma import Cell, Plan, plan


def same_plan(a: Plan, b: Plan) -> bool:
    """The same plan computed in another process: every field equal, clearance to 1e-9 m. (coal's
    GJK distances of capsule–box pairs can differ in the last ~1e-11 m between processes with
    different histories even with its warm start off; poses, joints and decisions are identical.)"""
    import dataclasses

    return np.allclose(a.clearance, b.clearance, rtol=0, atol=1e-9) and dataclasses.replace(
        a, clearance=b.clearance).equals(b)


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
