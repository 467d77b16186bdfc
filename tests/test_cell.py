"""Cell: seed default numbers, TOML round trip, CellError cases, no silent overwrite."""

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
