"""Cell: seed default numbers, TOML round trip, CellError cases, no silent overwrite."""

import re

import numpy as np
import pytest

from dualpuma import puma
from dualpuma.errors import CellError
from dualpuma.model import Cell, load_cell, save_cell


def test_default_layout():
    c = Cell.default()
    b = c.right.T_world_base[:3, 3] - c.left.T_world_base[:3, 3]
    assert np.linalg.norm(b) == pytest.approx(1.0, abs=1e-12) and c.left.T_world_base[2, 3] == pytest.approx(0.6604)
    for s in ("left", "right"):
        m = getattr(c, s)
        np.testing.assert_allclose(m.T_world_base @ puma.fk(m.q_home), c.T_world_object_start @ getattr(c, f"grasp_{s}").T_object_hand, atol=1e-12)


def test_round_trip_exact(tmp_path):
    c = Cell.default()
    p = save_cell(c, tmp_path / "c.toml")
    c2 = load_cell(p)
    for a, b in ((c.grasp_left.T_object_hand, c2.grasp_left.T_object_hand), (c.T_world_object_start, c2.T_world_object_start), (c.left.q_home, c2.left.q_home)):
        assert np.array_equal(a, b)
    with pytest.raises(CellError, match="overwrite"):
        save_cell(c, p)
    assert load_cell(save_cell(c, p, overwrite=True)).name == c.name


@pytest.mark.parametrize(
    "edit, key",
    [
        (lambda t: t.replace('robot = "puma560"', 'robot = "puma600"', 1), "robot"),
        (lambda t: t.replace("floor_z = 0.0", "floor_z = 0.0\ncolour = 3"), "unknown key"),
        (lambda t: t.replace("size = [0.75, 0.05, 0.05]", "size = [0.75, -0.05, 0.05]"), "bar.size"),
        (lambda t: t.replace("size = [0.75, 0.05, 0.05]", 'size = [0.75, "a", 0.05]'), "bar.size"),
        (lambda t: t.replace("safety_margin = 0.02", "safety_margin = nan"), "safety_margin"),
        (lambda t: t.replace("[bar]", "[bar\n"), "TOML"),
        (lambda t: t.replace("rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]", "rotation = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]", 1), "orthonormal"),
        (lambda t: t.replace("safety_margin = 0.02", 'safety_margin = "x"'), "safety_margin"),
    ],
)
def test_cell_errors_name_file_and_key(tmp_path, edit, key):
    from importlib import resources

    text = (resources.files("dualpuma.model") / "data" / "cells" / "default.toml").read_text()  # a hand-written form
    assert edit(text) != text  # the edit applies
    p = tmp_path / "bad.toml"
    p.write_text(edit(text))
    with pytest.raises(CellError) as e:
        load_cell(p)
    assert "bad.toml" in str(e.value) and key in str(e.value)


def test_example_cells_ship_and_match_their_sources():
    import dataclasses

    from dualpuma import EXAMPLE_CELLS, example_cell
    from dualpuma.scenarios import routine

    assert set(EXAMPLE_CELLS) == {"default", "routine7_box", "routine8_overhang", "agv",
                                 "ur5_pair", "mixed_puma_ur5"}
    d = example_cell("default")
    ref = Cell.default()
    for a, b in ((d.T_world_object_start, ref.T_world_object_start), (d.left.T_world_base, ref.left.T_world_base),
                 (d.grasp_right.T_object_hand, ref.grasp_right.T_object_hand), (d.right.q_home, ref.right.q_home)):
        assert np.array_equal(a, b)
    for name, n in (("routine7_box", 7), ("routine8_overhang", 8)):
        c, r = example_cell(name), routine(n).cell
        assert [o.name for o in c.obstacles] == [o.name for o in r.obstacles]
        for o, q in zip(c.obstacles, r.obstacles):
            assert np.array_equal(o.size, q.size) and np.array_equal(o.T_world_obstacle, q.T_world_obstacle)
    agv = example_cell("agv").obstacles[0]
    np.testing.assert_allclose(agv.pose_at(4.0)[:3, 3] - agv.pose_at(0.0)[:3, 3], [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(agv.pose_at(100.0), agv.pose_at(8.0))  # stops at t_end
    with pytest.raises(CellError, match="unknown name"):
        example_cell("nope")
    assert dataclasses.replace(d, name="x").name == "x"


# ----------------------------------------------------------------------------- value equality
def _fields_equal(a, b) -> bool:
    """Independent of dualpuma.values: every field of two cells' parts, arrays with numpy's exact
    equality, nested parts and the obstacle tuples field by field."""
    import dataclasses

    if type(a) is not type(b):
        return False
    if isinstance(a, tuple):
        return len(a) == len(b) and all(_fields_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and bool((a == b).all())
    if dataclasses.is_dataclass(a) and not isinstance(a, type) and type(a).__module__.startswith("dualpuma.model"):
        return all(_fields_equal(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    return a == b


def test_cells_compare_and_hash_by_value(tmp_path):
    import dataclasses

    from dualpuma import CellFileError, FileError, example_cell

    c = Cell.default()
    back = load_cell(save_cell(c, tmp_path / "c.toml"))
    assert back is not c and _fields_equal(back, c)
    assert back == c and hash(back) == hash(c)  # was: ValueError (an array's truth value)
    assert not back != c  # noqa: SIM202 - __ne__ too
    assert c.left == Cell.default().left and c.bar == back.bar and c.grasp_right == back.grasp_right
    assert len({c, back, Cell.default()}) == 1
    for other in (example_cell(name) for name in ("agv", "routine7_box", "mixed_puma_ur5")):
        assert not _fields_equal(other, c) and other != c and other == example_cell(other.name)
    moved = dataclasses.replace(c, safety_margin=c.safety_margin + 1e-12)
    assert not _fields_equal(moved, c) and moved != c
    T = c.T_world_object_start.copy()
    T[0, 3] += 1e-15
    assert dataclasses.replace(c, T_world_object_start=T) != c
    flipped = dataclasses.replace(c, floor_z=-0.0)  # -0.0 == 0.0: equal, so the same hash
    assert c.floor_z == 0.0 and flipped == c and hash(flipped) == hash(c)
    assert c != "a cell" and c.left != c.bar
    # a cell file that cannot be read or written is a FileError (an OSError) and a CellError
    for call in (lambda: save_cell(c, tmp_path / "c.toml"), lambda: load_cell(tmp_path / "missing.toml"),
                 lambda: save_cell(c, tmp_path / "no" / "c.toml"), lambda: load_cell(tmp_path)):
        with pytest.raises(CellFileError) as info:
            call()
        assert isinstance(info.value, FileError) and isinstance(info.value, OSError)
        assert isinstance(info.value, CellError)


@pytest.mark.parametrize(("robot", "says"), [
    ('"puma999"', "unknown robot 'puma999'; known: puma560"),
    ("5", "expected a robot name or a table"),
])
def test_a_bad_robot_in_a_cell_file_is_named_with_the_toml_to_write(robot, says):
    from dualpuma.model.cell_file import cell_from_toml, cell_to_toml

    text = cell_to_toml(Cell.default()).replace('robot = "puma560"', f"robot = {robot}", 1)
    with pytest.raises(CellError) as info:
        cell_from_toml(text)
    msg = str(info.value)
    assert "left.robot" in msg and says in msg
    assert '{ urdf = "path", tip = "frame" }' in msg and "{{" not in msg  # the TOML a user would write


# ---------------------------------------------------------------- a hand must hold the bar
_MIXED = """
name = "mixed"
[left]
robot = "puma560"
base = { xyz = [1.0, 0.0, 0.6604], rpy = [0.0, 0.0, -1.5707963267948966] }
q_home = [1.0585, 0.1847, -0.8479, 0.0, 0.6632, -0.5123]
[right]
robot = "ur5"
base = { xyz = [2.3, -0.3, 0.9], rpy = [0.4, -0.3, 2.8] }
q_home = [0.3, -1.2, 1.5, -1.0, -1.4, 0.2]
[bar]
shape = "box"
size = [0.75, 0.05, 0.05]
pose = { xyz = [0.0, 0.0, 0.12] }
[object_start]
xyz = [1.9, -0.35, 0.35]
rpy = [3.14159, 0, 0]
"""  # the right arm's home joints put its hand 1.1 m from the bar (a user's file, tilted UR5 base)
_GRASP_RIGHT = "[grasp_right]\nxyz = [0.3, 0.0, 0.215]\n"  # given explicitly: at the bar
_FAR_HOME = "q_home = [0.3, -1.2, 1.5, -1.0, -1.4, 0.2]"
#: the same cell with right home joints that hold the bar at _GRASP_RIGHT (a UR5 IK solution)
_HELD = _MIXED.replace(_FAR_HOME, "q_home = [1.475204691954656, 1.465213986145449, 0.5216978465538762, "
                                  "0.009160185169930557, 1.3091577421771985, -0.43272705023337366]")
_OBSTACLE = '[[obstacles]]\nname = "o"\nshape = "sphere"\nsize = [0.1]\npose = { xyz = [1.5, -0.8, 0.3] }\n'


def _coal_gap(T_world_bar: np.ndarray, size, p_world) -> float:
    """A point's distance from a box bar's surface, by coal (a tiny sphere against the box)."""
    import coal

    req, res = coal.DistanceRequest(), coal.DistanceResult()
    coal.distance(coal.Box(*size), coal.Transform3s(T_world_bar[:3, :3], T_world_bar[:3, 3]),
                  coal.Sphere(1e-9), coal.Transform3s(np.eye(3), np.asarray(p_world, float)), req, res)
    return res.min_distance + 1e-9


def _hand_gap(cell: Cell, side: str) -> float:
    T_wb = cell.T_world_object_start @ cell.bar.T_object_bar
    return _coal_gap(T_wb, cell.bar.size, (cell.T_world_object_start @ getattr(cell, f"grasp_{side}").T_object_hand)[:3, 3])


def test_a_cell_whose_hand_is_far_from_the_bar_is_refused(tmp_path):
    """A cell file whose UR5 home joints put the hand 1.1 m from the bar (the grasp is derived from
    q_home) is refused naming the hand and its distance, which coal confirms; with home joints that
    hold the bar at a grasp given there the file loads. The shipped cells' hands are 0.095 m from the
    bar."""
    import dataclasses

    from dualpuma.kinematics import Arm
    from dualpuma.model import MAX_GRASP_GAP, Grasp, example_cell

    for name in ("default", "ur5_pair", "mixed_puma_ur5", "agv"):
        c = example_cell(name)
        assert [_hand_gap(c, s) for s in ("left", "right")] == pytest.approx([0.095, 0.095], abs=1e-4)
    (tmp_path / "far.toml").write_text(_MIXED)
    with pytest.raises(CellError, match=r"far\.toml: grasp_right: the right hand frame is \d+\.\d+ m") as e:
        load_cell(tmp_path / "far.toml")
    shown = float(str(e.value).split("frame is ")[1].split(" m")[0])
    (tmp_path / "ok.toml").write_text(_HELD + _GRASP_RIGHT)
    c = load_cell(tmp_path / "ok.toml")
    q_far = [0.3, -1.2, 1.5, -1.0, -1.4, 0.2]
    p_hand = (c.right.T_world_base @ Arm.load("ur5").fk(q_far))[:3, 3]  # where the far home puts it
    expected = _coal_gap(c.T_world_object_start @ c.bar.T_object_bar, c.bar.size, p_hand)
    assert expected > 1.0 and shown == pytest.approx(expected, abs=6e-4)
    # the limit itself: a hand moved along the bar past its end, just inside and just beyond it
    base = Cell.default()
    for past, refused in ((MAX_GRASP_GAP - 1e-3, False), (MAX_GRASP_GAP + 1e-3, True)):
        T = np.eye(4)
        T[:3, 3] = base.bar.T_object_bar[:3, :3] @ [0.375 + past, 0.0, 0.0] + base.bar.T_object_bar[:3, 3]
        # the left base moved with the grasp, so that its home joints still hold the bar there
        mount = dataclasses.replace(base.left, T_world_base=base.T_world_object_start @ T @ np.linalg.inv(
            Arm.load("puma560").fk(base.left.q_home)))
        if refused:
            with pytest.raises(CellError, match="grasp_left: the left hand frame is 0.501 m"):
                dataclasses.replace(base, left=mount, grasp_left=Grasp(T))
        else:
            moved = dataclasses.replace(base, left=mount, grasp_left=Grasp(T))
            assert _hand_gap(moved, "left") == pytest.approx(past, abs=1e-6)


@pytest.mark.parametrize(("old", "new", "says"), [
    ("size = [0.75, 0.05, 0.05]", "size = [1e300, 0.05, 0.05]", "bar.size: sizes must be in (0, 1000] m"),
    ("xyz = [1.0, 0.0, 0.6604]", "xyz = [1e300, 0.0, 0.6604]", "left.base.xyz: position [1e+300, 0.0, 0.6604] m is beyond 1000 m"),
    ("size = [0.1]", "size = [1e300]", "size: sizes must be in (0, 1000] m"),
    ("xyz = [1.5, -0.8, 0.3]", "xyz = [1e300, -0.8, 0.3]", "obstacles[0].pose.xyz: position"),
    ("size = [0.1]\n", "size = [0.1]\nvelocity = [0.0, 1e300, 0.0]\n", "velocity: faster than 1000 m/s along an axis"),
])
def test_sizes_positions_and_speeds_beyond_1000_m_are_refused(tmp_path, old, new, says):
    """A size, coordinate or speed of 1e300 loaded silently before (printing -inf clearances and
    numpy overflow warnings); each is refused naming the key. The file without the edit loads."""
    text = _HELD + _GRASP_RIGHT + _OBSTACLE
    (tmp_path / "c.toml").write_text(text)
    load_cell(tmp_path / "c.toml")
    assert text.count(old) == 1
    (tmp_path / "c.toml").write_text(text.replace(old, new))
    with pytest.raises(CellError, match=re.escape(says)):
        load_cell(tmp_path / "c.toml")


def test_a_rotation_written_to_six_decimals_is_refused_with_the_rpy_to_write(tmp_path):
    """A rotation copied to 6 decimals (|R^T R - I| = 7e-7) is not a rotation to the tolerance; the
    message gives the roll, pitch, yaw of the nearest rotation, and that rpy loads (to 1e-6 of the
    matrix written)."""
    from dualpuma.lie import rpy_to_rot

    R6 = [[0.866025, -0.5, 0.0], [0.5, 0.866025, 0.0], [0.0, 0.0, 1.0]]
    text = _HELD + _GRASP_RIGHT + _OBSTACLE
    (tmp_path / "c.toml").write_text(text.replace('pose = { xyz = [1.5, -0.8, 0.3] }',
                                                  f'pose = {{ xyz = [1.5, -0.8, 0.3], rotation = {R6} }}'))
    with pytest.raises(CellError, match=r"obstacles\[0\]\.pose\.rotation: .*write it with more digits, or as "
                                        r"rpy = \[(.*)\]") as e:
        load_cell(tmp_path / "c.toml")
    rpy = [float(v) for v in re.search(r"rpy = \[(.*?)\]", str(e.value)).group(1).split(",")]
    np.testing.assert_allclose(rpy, [0.0, 0.0, np.pi / 6], atol=1e-6)
    (tmp_path / "c.toml").write_text(text.replace('pose = { xyz = [1.5, -0.8, 0.3] }',
                                                  f'pose = {{ xyz = [1.5, -0.8, 0.3], rpy = {rpy} }}'))
    o = load_cell(tmp_path / "c.toml").obstacles[0]
    np.testing.assert_allclose(o.T_world_obstacle[:3, :3], R6, atol=1e-6)
    np.testing.assert_allclose(rpy_to_rot(rpy), R6, atol=1e-6)


def test_more_obstacles_than_a_world_can_be_built_with_are_refused(tmp_path):
    """A cell of 10,000 obstacles was accepted and its World did not build in 15 minutes; 1,000
    (MAX_OBSTACLES) are accepted from Python and from a file, 1,001 are refused from both."""
    import dataclasses

    from dualpuma.model import MAX_OBSTACLES, Obstacle

    assert MAX_OBSTACLES == 1000
    base = Cell.default()
    obs = [Obstacle(f"o{i}", "sphere", [0.01], np.eye(4) + np.pad([[3.0 + 0.03 * (i % 30)], [2.0 + 0.03 * (i // 30)], [0.5]],
                                                                  ((0, 1), (3, 0)))) for i in range(MAX_OBSTACLES + 1)]
    assert len(dataclasses.replace(base, obstacles=tuple(obs[:-1])).obstacles) == 1000
    with pytest.raises(CellError, match="obstacles: 1001 obstacles, more than 1000"):
        dataclasses.replace(base, obstacles=tuple(obs))
    text = (_HELD + _GRASP_RIGHT + "".join(
        f'[[obstacles]]\nname = "o{i}"\nshape = "sphere"\nsize = [0.01]\npose = {{ xyz = [3.0, {i * 0.03}, 0.5] }}\n'
        for i in range(MAX_OBSTACLES + 1)))
    (tmp_path / "many.toml").write_text(text)
    with pytest.raises(CellError, match="obstacles: expected an array of at most 1000 tables"):
        load_cell(tmp_path / "many.toml")
