"""docs/cells.md: its complete example is a cell file that loads, holds the bar at home (checked by
an independent FK of the URDF with Pinocchio), has its obstacles where it says, and can be
planned in; a saved cell without obstacles can have [[obstacles]] appended by hand."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from dualpuma import World, plan
from dualpuma.model import cell_from_toml, example_cell, load_cell, save_cell
from dualpuma.planning import StrivingParams

ROOT = Path(__file__).resolve().parents[1]
DOC = (ROOT / "docs" / "cells.md").read_text()


@pytest.fixture(scope="module")
def cell():
    (text,) = re.findall(r"```toml\n(.*?)```", DOC, flags=re.DOTALL)
    return cell_from_toml(text, source="docs/cells.md")


def test_the_example_loads_with_its_obstacles(cell):
    assert cell.name == "my cell" and [o.name for o in cell.obstacles] == ["crate", "ball"]
    ball = cell.obstacles[1]
    np.testing.assert_allclose(ball.T_world_obstacle[:3, 3], [1.0, -0.9, 0.5])
    np.testing.assert_allclose(ball.velocity, [0.1, 0.0, 0.0])
    assert (ball.t_start, ball.t_end) == (0.0, 6.0)


def test_the_home_joints_hold_the_bar_at_the_start(cell):
    """The grasps derived from q_home: each hand, by Pinocchio's FK of the PUMA URDF from the base
    pose written in the file, is where the object start and the grasp put it."""
    model = pin.buildModelFromUrdf(str(ROOT / "urdf" / "puma560.urdf"))
    data = model.createData()
    fid = model.getFrameId("wrist")
    for side in ("left", "right"):
        arm = getattr(cell, side)
        pin.framesForwardKinematics(model, data, np.asarray(arm.q_home))
        hand = arm.T_world_base @ data.oMf[fid].homogeneous
        grasp = getattr(cell, f"grasp_{side}").T_object_hand
        np.testing.assert_allclose(hand, cell.T_world_object_start @ grasp, atol=1e-9)


def test_the_example_can_be_planned_in(cell):
    world = World(cell)
    assert world.clearance(cell.left.q_home, cell.right.q_home, cell.T_world_object_start, 0.0).distance >= 0.02
    B = cell.T_world_object_start.copy()
    B[:3, 3] += (0.0, -0.05, 0.0)
    p = plan(cell, cell.T_world_object_start, B, StrivingParams(fallback=True), world=world)
    assert p.reached, p.reason


def test_a_saved_cell_without_obstacles_takes_appended_obstacles(tmp_path):
    """save_cell wrote 'obstacles = []', and a [[obstacles]] table appended to the file was then a
    TOML error (a newcomer's first try, found by a helper)."""
    f = save_cell(example_cell("default"), tmp_path / "my_cell.toml")
    assert "obstacles" not in f.read_text()
    with open(f, "a") as out:
        out.write('\n[[obstacles]]\nname = "crate"\nshape = "box"\nsize = [0.3, 0.3, 0.3]\n'
                  'pose = { xyz = [1.5, -0.75, 0.15] }\n')
    assert [o.name for o in load_cell(f).obstacles] == ["crate"]
