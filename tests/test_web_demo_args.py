"""web_demo/record_routines.py as its user runs it: bad routines or frame rates are refused before
anything is written, and the motion is recorded as the live viewer plays it (timed under the joint
limits; it was recorded at the planner's clock, about 5x faster than the arms can move)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dualpuma.errors import ParameterError
from dualpuma.model import World
from dualpuma.planning import PUMA_QD_MAX, PUMA_QDD_MAX, with_trajectory
from dualpuma.scenarios import routine_cell, run_routine

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "web_demo" / "record_routines.py"


@pytest.mark.parametrize("args", [["--routines", "2", "9"], ["--routines"], ["--fps", "0"], ["--fps", "nan"],
                                  ["--fps", "-1"], ["--fps", "1e9"]])
def test_bad_arguments_exit_2_and_write_nothing(tmp_path, args):
    out = tmp_path / "site"
    r = subprocess.run([sys.executable, str(SCRIPT), "--out", str(out), *args], check=False, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and "record_routines.py: error:" in r.stderr
    assert not out.exists() or not any(out.rglob("*"))


def test_a_routine_is_recorded_at_its_timed_speed(tmp_path):
    spec = importlib.util.spec_from_file_location("record_routines", SCRIPT)
    recorder = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(recorder)
    path, job = recorder.record(2, tmp_path, fps=5.0)
    assert path.stat().st_size > 2000
    p = run_routine(2)
    shown = job.playback.t_end - job.playback.t[0]
    # no faster than the joints' limits allow: rest to rest, a joint moving D needs 2 sqrt(D / a_max)
    # at least, and D / v_max (the plan's clock, 0.5 s, was about 5x too fast)
    Q = np.hstack([p.q_left, p.q_right])
    D = np.abs(Q[-1] - Q[0])
    fastest = float(max(np.max(2.0 * np.sqrt(D / np.tile(PUMA_QDD_MAX, 2))), np.max(D / np.tile(PUMA_QD_MAX, 2))))
    assert shown >= fastest > 4.0 * (p.t[-1] - p.t[0])
    expected = with_trajectory(p, World(routine_cell(2))).trajectory.duration  # as the live viewer times it
    assert shown == pytest.approx(expected, abs=1e-9)
    with pytest.raises(ParameterError, match="routines"):
        recorder.build_site(tmp_path / "other", [2, 0])
    assert not (tmp_path / "other").exists()
