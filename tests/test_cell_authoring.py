"""What a person writing cell files by hand meets (a new user wrote ~80 cells and loaded them through
every door: the API, the CLI, the viewer's data directory). Each test here failed on the code before
it: the file was taken silently in a wrong sense, or refused with a message that did not say why."""

from __future__ import annotations

import dataclasses
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dualpuma import Cell, load_cell, save_cell
from dualpuma.errors import CellError, CellFileError, FileError
from dualpuma.kinematics import Arm
from dualpuma.model import MAX_MARGIN, ArmMount, Obstacle, cell_to_toml

ROOT = Path(__file__).resolve().parents[1]

# the seed's layout written by hand: grasps derived from the home joints (no [grasp_*] tables)
GOOD = """
name = "by hand"
[left]
robot = "puma560"
base = { xyz = [1.0, 0.0, 0.6604], rpy = [0.0, 0.0, -1.5707963267948966] }
q_home = [1.0584963267948966, 0.1847, -0.8479, 0.0, 0.6632, -0.5123]
[right]
robot = "puma560"
base = { xyz = [2.0, 0.0, 0.6604], rpy = [0.0, 0.0, -1.5707963267948966] }
q_home = [-0.19950367320510343, 0.1833, 0.3838, 0.0, -0.5671, -1.7703]
[bar]
shape = "box"
size = [0.75, 0.05, 0.05]
pose = { xyz = [0.0, 0.0, 0.12] }
[object_start]
xyz = [1.8864844492377473, -0.20091003041380878, 0.2273249109362449]
rpy = [3.141592653589793, 0.0, 0.0]
"""
BALL = '[[obstacles]]\nname = "ball"\nshape = "sphere"\nsize = [0.08]\npose = { xyz = [1.5, -0.9, 0.6] }\n'


def _load(tmp_path: Path, text: str, name: str = "c.toml"):
    (tmp_path / name).write_text(text, encoding="utf-8")
    return load_cell(tmp_path / name)


def test_a_saved_cell_edited_by_hand_says_its_home_joints_no_longer_hold_the_bar(tmp_path):
    """A saved cell writes its grasps; moving a base by 0.1 m in the file then left home joints that
    do not hold the bar. It loaded, and every plan failed "q_start does not hold the bar" (no q_start
    was given). It is now refused at load, naming the arm, the 0.1 m and the way out; the same cell
    built in Python is refused alike; without the grasp tables the file loads (grasps derived)."""
    path = save_cell(Cell.default(), tmp_path / "saved.toml")
    text = path.read_text()
    moved = text.replace("[right.base]\nxyz = [\n    2.0,", "[right.base]\nxyz = [\n    2.1,")
    assert moved != text
    (tmp_path / "moved.toml").write_text(moved)
    with pytest.raises(CellError, match=r"moved\.toml: right\.q_home: at its home joints the right hand is 0\.100000 m "
                                        r"off its grasp .*remove grasp_right to derive it again"):
        load_cell(tmp_path / "moved.toml")
    c = Cell.default()
    T = c.right.T_world_base.copy()
    T[0, 3] += 0.1
    with pytest.raises(CellError, match=r"right\.q_home: .* 0\.100000 m off its grasp"):
        dataclasses.replace(c, right=dataclasses.replace(c.right, T_world_base=T))
    # the way out the message gives: without [grasp_right] (the file's last table) the grasp is derived
    assert re.findall(r"^\[([a-z_.]+)\]$", moved, re.MULTILINE)[-1] == "grasp_right"
    cell = _load(tmp_path, moved[: moved.index("[grasp_right]")], "derived.toml")
    hand = cell.T_world_object_start @ cell.grasp_right.T_object_hand
    np.testing.assert_allclose(hand[:3, 3] - (c.T_world_object_start @ c.grasp_right.T_object_hand)[:3, 3],
                               [0.1, 0.0, 0.0], atol=1e-12)


def test_an_arm_without_a_base_is_said_to_stand_at_the_origin(tmp_path):
    text = GOOD.replace('base = { xyz = [2.0, 0.0, 0.6604], rpy = [0.0, 0.0, -1.5707963267948966] }\n', "")
    with pytest.raises(CellError, match=r"grasp_right: the right hand frame is .* \(right\.base is not given: that "
                                        r"arm stands at the world origin\)"):
        _load(tmp_path, text)


@pytest.mark.parametrize(("old", "new", "key"), [
    ("rpy = [0.0, 0.0, -1.5707963267948966] }\nq_home = [-0.1995", "rpy = [0.0, 0.0, -90.0] }\nq_home = [-0.1995",
     "right.base.rpy"),
    ("rpy = [3.141592653589793, 0.0, 0.0]", "rpy = [180.0, 0.0, 0.0]", "object_start.rpy"),
    ("q_home = [-0.19950367320510343, 0.1833, 0.3838, 0.0, -0.5671, -1.7703]",
     "q_home = [-11.43, 10.5, 21.99, 0.0, -32.49, -101.43]", "right.q_home"),
])
def test_angles_in_degrees_are_refused_with_the_radians_to_write(tmp_path, old, new, key):
    """rpy = [0, 0, -90] was read as -90 rad (-116.6 deg) and planned "reached" in a wrong layout.
    An angle beyond a turn is refused, the message giving the same angles in radians; written as
    given there, the file loads with the rotation those degrees mean."""
    assert GOOD.count(old) == 1
    with pytest.raises(CellError, match=re.escape(key) + r": .*beyond a turn .*are radians: if these are degrees, "
                                        r"write \[(.*)\]") as e:
        _load(tmp_path, GOOD.replace(old, new))
    written = re.search(r"write \[(.*)\]", str(e.value)).group(1)
    given = [float(v) for v in re.search(r"\[(.*?)\]", new[new.index("[") :]).group(1).split(",")]
    np.testing.assert_allclose([float(v) for v in written.split(",")], [math.radians(v) for v in given], atol=1e-8)
    if key != "right.q_home":  # degrees of q_home rounded to 0.01 do not hold the bar to a micrometre
        _load(tmp_path, GOOD.replace(old, new.replace(new[new.index("[") : new.index("]") + 1], f"[{written}]")))


def test_a_margin_in_millimetres_is_refused(tmp_path):
    with pytest.raises(CellError, match=r"safety_margin: 20 m is more than 1 m; the margin is in metres \(20 mm is 0\.02\)"):
        _load(tmp_path, "safety_margin = 20\n" + GOOD)
    assert _load(tmp_path, f"safety_margin = {MAX_MARGIN}\n" + GOOD).safety_margin == 1.0


def test_names_that_a_terminal_would_act_on_are_refused(tmp_path):
    """An obstacle named "ball)\\nreached\\n  fake: all clear\\x1b[8m" printed fake result lines
    and hid text in `dualpuma plan`'s output; control characters and bidirectional overrides are
    refused in every name, from a file and from Python; other Unicode stays welcome."""
    for bad, code in (("ball)\\nreached", "000A"), ("x\\u001b[8m", "001B"), ("abc\\u202edcba", "202E")):
        with pytest.raises(CellError, match=rf"obstacles\[0\]: obstacle name: character \d+ is a control character "
                                            rf"\(U\+{code}\)"):
            _load(tmp_path, GOOD + BALL.replace('"ball"', f'"{bad}"'))
    with pytest.raises(CellError, match=r"name: character 4 is a control character \(U\+0007\)"):
        _load(tmp_path, 'name = "bad\\u0007"\n' + GOOD.replace('name = "by hand"\n', ""))
    with pytest.raises(CellError, match=r"U\+001B"):
        Obstacle("o\x1b", "sphere", [0.1], np.eye(4))
    with pytest.raises(CellError, match=r"U\+0009"):
        ArmMount("le\tft", "puma560", np.eye(4))
    assert _load(tmp_path, GOOD + BALL.replace('"ball"', '"Kugel é 漢字 🙂"')).obstacles[0].name == "Kugel é 漢字 🙂"


def test_the_sizes_a_shape_takes_are_said(tmp_path):
    with pytest.raises(CellError, match=re.escape("obstacles[0].size: expected a list of numbers [m] (box: 3 full "
                                                  "extents; sphere: [radius]; capsule: [radius, length]), got 0.08")):
        _load(tmp_path, GOOD + BALL.replace("size = [0.08]", "size = 0.08"))
    with pytest.raises(CellError, match=re.escape('obstacles[0].size: a box takes 3 full extents [m], got 1 numbers; '
                                                  'shape is not given, so it is a box')):
        _load(tmp_path, GOOD + BALL.replace('shape = "sphere"\n', ""))
    with pytest.raises(CellError, match=re.escape("obstacles[0].size: a sphere takes [radius] [m], got 2 numbers")):
        _load(tmp_path, GOOD + BALL.replace("size = [0.08]", "size = [0.08, 0.1]"))


def test_an_obstacle_is_named_by_its_index_in_the_file(tmp_path):
    with pytest.raises(CellError, match=r"obstacles\[0\]: obstacle name: 300 characters"):
        _load(tmp_path, GOOD + BALL.replace('"ball"', '"' + "x" * 300 + '"'))
    with pytest.raises(CellError, match=r"t_start: expected a finite number \[s\], got inf"):
        _load(tmp_path, GOOD + BALL + "t_start = inf\n")


def test_a_byte_order_mark_bytes_paths_and_the_home_directory(tmp_path, monkeypatch):
    """A UTF-8 file with a byte-order mark (Windows Notepad) was a TOML syntax error at line 1;
    load_cell(b"path") raised a TypeError; "~/c.toml" was not expanded (a shell leaves
    --cell=~/c.toml as it is), though a URDF path in a cell was."""
    plain = _load(tmp_path, GOOD)
    (tmp_path / "bom.toml").write_bytes(b"\xef\xbb\xbf" + GOOD.replace("\n", "\r\n").encode())
    assert load_cell(tmp_path / "bom.toml") == plain
    assert load_cell(os.fsencode(tmp_path / "c.toml")) == plain
    monkeypatch.setenv("HOME", str(tmp_path))
    assert load_cell("~/c.toml") == plain
    assert save_cell(plain, "~/saved.toml") == tmp_path / "saved.toml"
    assert load_cell(tmp_path / "saved.toml") == plain
    r = subprocess.run([sys.executable, "-m", "dualpuma.cli", "envelope", "--cell=~/c.toml", "--resolution-mm", "200",
                        "--json"], check=False, capture_output=True, text=True, env={**os.environ, "HOME": str(tmp_path)})
    assert r.returncode == 0, r.stderr
    assert '"cell": "by hand"' in r.stdout


def test_toml_text_given_as_a_path_points_to_cell_from_toml():
    with pytest.raises(CellFileError, match=r"load_cell takes a file name, .*use cell_from_toml\(text\)") as e:
        load_cell(GOOD)
    assert len(str(e.value)) < 200  # not the whole text echoed back


def test_saving_over_a_dangling_link_says_so(tmp_path):
    (tmp_path / "dangling.toml").symlink_to("gone.toml")
    with pytest.raises(FileError, match=r"dangling\.toml: a link to gone\.toml, which does not exist"):
        save_cell(Cell.default(), tmp_path / "dangling.toml")
    assert not (tmp_path / "gone.toml").exists()


def test_a_saved_urdf_cell_keeps_its_urdf_relative_so_the_folder_can_move(tmp_path):
    """Saved, a URDF robot's path was written absolute: the project folder moved, the saved cell
    failed ("... is not a file") while the hand-written one loaded. Inside the saved file's folder it
    is written relative to it (as a cell file reads it); outside, absolute."""
    proj = tmp_path / "proj"
    (proj / "arms").mkdir(parents=True)
    shutil.copy(ROOT / "urdf" / "puma560.urdf", proj / "arms" / "my_puma.urdf")
    text = GOOD.replace('robot = "puma560"', 'robot = { urdf = "arms/my_puma.urdf", tip = "wrist" }')
    cell = _load(proj, text, "cell.toml")
    save_cell(cell, proj / "saved.toml")
    assert 'urdf = "arms/my_puma.urdf"' in (proj / "saved.toml").read_text()
    (tmp_path / "elsewhere").mkdir()
    save_cell(cell, tmp_path / "elsewhere" / "saved.toml")
    assert f'urdf = "{(proj / "arms" / "my_puma.urdf").resolve()}"' in (tmp_path / "elsewhere" / "saved.toml").read_text()
    proj.rename(tmp_path / "proj2")
    moved = load_cell(tmp_path / "proj2" / "saved.toml")
    assert moved.left.robot.urdf == (tmp_path / "proj2" / "arms" / "my_puma.urdf").resolve()
    q = np.radians([10.0, -20.0, 30.0, 40.0, 50.0, 60.0])
    np.testing.assert_allclose(Arm.load(moved.left.robot).fk(q), Arm.puma560().fk(q), atol=1e-12)
    # text for no particular file keeps every path absolute, as before
    assert f'urdf = "{(proj / "arms" / "my_puma.urdf").resolve()}"' not in cell_to_toml(moved)
    assert f'urdf = "{(tmp_path / "proj2" / "arms" / "my_puma.urdf").resolve()}"' in cell_to_toml(moved)



def test_the_viewer_says_which_files_of_its_data_directory_it_does_not_list(tmp_path):
    """The cell selector left out "my cell.toml", "cell.v2.toml", "upper.TOML" and a link without a
    word; the files tab now names them and the rule (the rule itself is unchanged: docs/security.md)."""
    from dualpuma.viewer.app import ViewerApp
    from dualpuma.viewer.datadir import DataDir

    data = tmp_path / "data"
    data.mkdir()
    for name in ("my_cell.toml", "my cell.toml", "cell.v2.toml", "upper.TOML", "pick-1.json", "pick 2.json"):
        (data / name).write_text(GOOD)
    (data / "linked.toml").symlink_to(data / "my_cell.toml")
    d = DataDir(data)
    assert d.names(".toml") == ["my_cell.toml"] and d.names(".json") == ["pick-1.json"]
    assert d.unlisted(".toml") == ["cell.v2.toml", "linked.toml", "my cell.toml", "upper.TOML"]
    assert d.unlisted(".json") == ["pick 2.json"]
    app = ViewerApp(Cell.default(), port=0, data_dir=data)
    try:
        shown = app.files.listing.content
    finally:
        app.close()
    assert "waypoint files: pick-1.json" in shown
    assert ("not listed (5; a name of letters, digits, - and \\_, a regular file, not a link): cell.v2.toml, "
            "linked.toml, my cell.toml, upper.TOML, pick 2.json") in shown


def test_an_example_name_means_the_example_whatever_files_are_here(tmp_path, monkeypatch):
    """`--cell agv` with a file ./agv in the working directory loaded the file silently, and a
    folder ./default made `--cell default` fail; an example's name now always means the example,
    and the file is given with its folder (./agv). Checked through the command a user runs."""
    from dualpuma.model import cell_from_spec, example_cell

    monkeypatch.chdir(tmp_path)
    mine = dataclasses.replace(Cell.default(), name="my own agv")
    (tmp_path / "agv").write_text(cell_to_toml(mine))
    (tmp_path / "default").mkdir()
    assert cell_from_spec("agv").name == example_cell("agv").name != "my own agv"
    assert cell_from_spec("./agv").name == "my own agv" and cell_from_spec(tmp_path / "agv").name == "my own agv"
    for spec, name in (("agv", example_cell("agv").name), ("./agv", "my own agv"), ("default", example_cell("default").name)):
        r = subprocess.run([sys.executable, "-m", "dualpuma.cli", "envelope", "--cell", spec, "--resolution-mm", "100", "--json"],
                           capture_output=True, text=True, timeout=120, check=False)
        assert r.returncode == 0, r.stderr
        assert f"'{name}'" in r.stdout or f'"cell": "{name}"' in r.stdout, (spec, r.stdout[:200])
