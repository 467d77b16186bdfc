"""Cell files: save -> load gives back the same cell for generated cells (names with quotes,
backslashes, control characters and any unicode; random poses, sizes, velocities, times), and
malformed files — not UTF-8, nested deeply, huge, wrong types, random bytes, a valid file with one
value broken — give a CellError naming the file (and the key), quickly."""

from __future__ import annotations

import math
import time
import tomllib

import numpy as np
import pytest
import tomli_w
from fuzz_targets import FUZZ_RANDOM
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dualpuma import Cell, load_cell, save_cell
from dualpuma.errors import CellError
from dualpuma.kinematics import Arm
from dualpuma.lie import rpy_to_rot
from dualpuma.model import ArmMount, Bar, Grasp, Obstacle, cell_from_toml, cell_to_toml

FIXED = settings(max_examples=60, deadline=None, database=None, derandomize=not FUZZ_RANDOM,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

# printable names: a control character in a name is refused (tests/test_cell.py)
_PRINTABLE = st.characters(codec="utf-8", exclude_categories=("Cc", "Cs"),
                           exclude_characters="\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")
names = st.text(alphabet=_PRINTABLE, max_size=40) | st.sampled_from(
    ['"', "'", "\\", '\\"', "a'b\"c\\d", "]]", "[x]", "a = 1", '""" x', "'''",
    "é ü 漢字 🙂", "\u2028\u2029", "\ufeff", "x" * 200])  # 200: the longest name (model.MAX_NAME)
reals = st.floats(min_value=-50.0, max_value=50.0, allow_nan=False, allow_subnormal=True)
angles = st.floats(min_value=-4.0, max_value=4.0, allow_nan=False)
sizes = st.floats(min_value=1e-6, max_value=10.0, allow_nan=False)


@st.composite
def poses(draw, reach: float = 50.0) -> np.ndarray:
    """A pose whose position's coordinates are within ``reach`` [m]."""
    T = np.eye(4)
    T[:3, :3] = rpy_to_rot([draw(angles) for _ in range(3)])
    T[:3, 3] = [draw(st.floats(min_value=-reach, max_value=reach, allow_nan=False, allow_subnormal=True))
                for _ in range(3)]
    return T


@st.composite
def shaped(draw, prefix: str):
    shape = draw(st.sampled_from(("box", "sphere", "capsule")))
    return shape, [draw(sizes) for _ in range({"box": 3, "sphere": 1, "capsule": 2}[shape])]


@st.composite
def obstacles(draw, name: str) -> Obstacle:
    shape, size = draw(shaped("o"))
    t0 = draw(st.floats(min_value=-100, max_value=100, allow_nan=False))
    t1 = draw(st.one_of(st.just(math.inf), st.floats(min_value=t0, max_value=1e6, allow_nan=False)))
    return Obstacle(name, shape, size, draw(poses()), [draw(reals) for _ in range(3)], t0, t1)


@st.composite
def cells(draw) -> Cell:
    obs_names = draw(st.lists(names, max_size=4, unique=True))
    shape, size = draw(shaped("bar"))
    T_ob = draw(poses())
    # each hand within 0.35 m of the bar's frame origin, so within MAX_GRASP_GAP of its surface
    grasps = [Grasp(T_ob @ draw(poses(0.2))) for _ in range(2)]
    T_wo = draw(poses())
    arms = []
    for side, g in zip(("left", "right"), grasps):  # a base where the home joints hold the bar
        robot, q = draw(st.sampled_from(("puma560", "ur5"))), [draw(angles) for _ in range(6)]
        arms.append(ArmMount(side, robot, T_wo @ g.T_object_hand @ np.linalg.inv(Arm.load(robot).fk(q)), q))
    return Cell(arms[0], arms[1], Bar(shape, size, T_ob), grasps[0], grasps[1],
                T_wo, tuple(draw(obstacles(n)) for n in obs_names), draw(reals),
                draw(st.floats(min_value=0.0, max_value=1.0, allow_nan=False)), draw(names))  # model.MAX_MARGIN


def assert_same_cell(a: Cell, b: Cell) -> None:
    """Field by field: names exactly, every number bit for bit."""
    assert (a.name, a.floor_z, a.safety_margin) == (b.name, b.floor_z, b.safety_margin)
    for side in ("left", "right"):
        x, y = getattr(a, side), getattr(b, side)
        assert x.robot == y.robot
        np.testing.assert_array_equal(x.T_world_base, y.T_world_base)
        np.testing.assert_array_equal(x.q_home, y.q_home)
        np.testing.assert_array_equal(getattr(a, f"grasp_{side}").T_object_hand, getattr(b, f"grasp_{side}").T_object_hand)
    assert a.bar.shape == b.bar.shape
    np.testing.assert_array_equal(a.bar.size, b.bar.size)
    np.testing.assert_array_equal(a.bar.T_object_bar, b.bar.T_object_bar)
    np.testing.assert_array_equal(a.T_world_object_start, b.T_world_object_start)
    assert len(a.obstacles) == len(b.obstacles)
    for o, p in zip(a.obstacles, b.obstacles):
        assert (o.name, o.shape, o.t_start, o.t_end) == (p.name, p.shape, p.t_start, p.t_end)
        for f in ("size", "T_world_obstacle", "velocity"):
            np.testing.assert_array_equal(getattr(o, f), getattr(p, f))


@FIXED
@given(cell=cells())
def test_save_load_round_trip(tmp_path, cell):
    path = save_cell(cell, tmp_path / "c.toml", overwrite=True)
    assert_same_cell(load_cell(path), cell)
    assert_same_cell(cell_from_toml(cell_to_toml(cell)), cell)


def test_numpy_scalars_are_written_as_numbers(tmp_path):
    c = Cell.default()
    o = Obstacle("o", "sphere", np.array([np.float64(0.1)]), np.eye(4), np.zeros(3), np.float64(0.5), np.float64(9.0))
    cell = Cell(c.left, c.right, c.bar, c.grasp_left, c.grasp_right, c.T_world_object_start, (o,),
                np.float64(-0.25), np.float64(0.03), "numpy")
    text = save_cell(cell, tmp_path / "c.toml").read_text()
    assert "np." not in text and "float64" not in text
    assert_same_cell(load_cell(tmp_path / "c.toml"), cell)


# ----------------------------------------------------------------------------- malformed files
GOOD = cell_to_toml(Cell.default())


def _edit(where: str, value: object) -> str:
    """GOOD with the value at ``where`` (``"left.q_home"``, ``"obstacles"``...) replaced: a Python value,
    or ``RAW("...")`` for TOML text tomli-w would not write (``1e400``, ``nan``)."""
    doc = tomllib.loads(GOOD)
    *parents, key = where.split(".")
    d = doc
    for k in parents:
        d = d[k]
    d[key] = "@@RAW@@" if isinstance(value, RAW) else value
    text = tomli_w.dumps(doc)
    return text.replace('"@@RAW@@"', value.text) if isinstance(value, RAW) else text


class RAW:
    def __init__(self, text: str) -> None:
        self.text = text


@pytest.mark.parametrize(
    ("text", "words"),
    [
        (_edit("floor_z", "a"), "floor_z"),
        (_edit("floor_z", RAW("1e400")), "floor_z"),
        (_edit("safety_margin", -1.0), "safety_margin"),
        (_edit("safety_margin", True), "safety_margin"),
        (_edit("name", 5), "name"),
        (_edit("left.robot", 5), "robot"),
        (_edit("right.robot", "kuka"), "robot"),
        (_edit("left.q_home", [1.0, 2.0]), "q_home"),
        (_edit("left.q_home", [1.0, 2.0, 3.0, 4.0, 5.0, 10**400]), "q_home"),
        (_edit("right.q_home", [1, 2, 3, 4, 5, "6"]), "q_home"),
        (_edit("bar.size", [[0.75, 0.05], [0.05]]), "size"),
        (_edit("bar.size", [0.75, 0.05, -0.05]), "size"),
        (_edit("bar.size", "big"), "size"),
        (_edit("bar.shape", "cone"), "shape"),
        (_edit("bar.shape", [1]), "shape"),
        (GOOD.replace("[bar]", "[bar]\ncolour = 'red'"), "colour"),
        (GOOD + "\nextra = 1\n", "extra"),
        (_edit("left.base", 5), "base"),
        (_edit("left.base", {"xyz": [0, 0, 0], "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 2]]}), "base"),
        (_edit("grasp_left", {"xyz": [0, 0, 0], "rpy": [0, 0, 0], "rotation": [[1, 0, 0]]}), "grasp_left"),
        (_edit("object_start.xyz", RAW("[nan, 0, 0]")), "object_start"),
        (_edit("obstacles", [{"name": "a", "shape": "box", "size": [1, 1, 1], "t_start": 5.0, "t_end": 1.0}]), "t_start"),
        (_edit("obstacles", [{"name": "a", "shape": "sphere", "size": [1], "velocity": [math.nan, 0, 0]}]), "velocity"),
        (_edit("obstacles", [{"name": "a", "shape": "sphere", "size": [1], "t_end": "never"}]), "t_end"),
        (_edit("obstacles", [{"name": "a" * 201, "size": [1, 1, 1]}]), "name"),
        (_edit("obstacles", [{"name": "a", "size": [1, 1, 1]}, {"name": "a", "size": [1, 1, 1]}]), "unique"),
        (GOOD + "\nobstacles = 5\n", "obstacles"),
        ("x = ", "TOML"),
        ("[left]\n", "right"),
    ],
)
def test_wrong_values_name_the_file_and_the_key(tmp_path, text, words):
    path = tmp_path / "broken cell.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(CellError) as e:
        load_cell(path)
    assert str(path) in str(e.value) and words in str(e.value), str(e.value)[:300]
    assert "\n" not in str(e.value).strip() or "TOML" in str(e.value)


@pytest.mark.parametrize(
    ("data", "words"),
    [
        (b"name = \"caf\xe9\"\n", "UTF-8"),
        (b"\xff\xfe" + "name = 'x'".encode("utf-16-le"), "UTF-8"),
        (b"a = " + b"[" * 100_000 + b"]" * 100_000, "nested"),
        (b"a = " + b"{b = " * 10_000 + b"1" + b"}" * 10_000, "nested"),
        (b"x" * (1 << 20 + 1), "more than"),
        (bytes(range(256)), "UTF-8"),
    ],
)
def test_malformed_files_fail_quickly(tmp_path, data, words):
    path = tmp_path / "bad.toml"
    path.write_bytes(data)
    t0 = time.perf_counter()
    with pytest.raises(CellError) as e:
        load_cell(path)
    assert time.perf_counter() - t0 < 5.0
    assert str(path) in str(e.value) and words in str(e.value), str(e.value)[:300]


def test_devices_fail_quickly():
    for dev in ("/dev/zero", "/dev/urandom"):
        t0 = time.perf_counter()
        with pytest.raises(CellError, match=dev):
            load_cell(dev)
        assert time.perf_counter() - t0 < 1.0


@FIXED
@given(data=st.binary(max_size=300) | st.text(max_size=300).map(lambda s: s.encode("utf-8", "surrogatepass")))
def test_random_bytes_give_cell_errors(tmp_path, data):
    path = tmp_path / "random.toml"
    path.write_bytes(data)
    with pytest.raises(CellError):
        load_cell(path)


@FIXED
@given(line=st.integers(0, GOOD.count("\n") - 1), junk=st.sampled_from(
    ["", "x", "nan", "inf", "-inf", "1e400", "[", "]", "{", "'", '"', "\\", "true", "[1, 2]", "[[1], [2, 3]]", '"a"',
     "{xyz = 1}", "[]", "-0.0", "99999999999999999999999999999999999999", "1979-05-27", "{}", "[nan, nan, nan]"]))
def test_a_valid_file_with_one_line_broken(tmp_path, line, junk):
    lines = GOOD.split("\n")
    key = lines[line].split("=", 1)[0]
    lines[line] = f"{key}= {junk}" if "=" in lines[line] else junk
    path = tmp_path / "edited.toml"
    path.write_text("\n".join(lines), encoding="utf-8")
    try:
        load_cell(path)  # some edits keep a valid cell (e.g. a zero written as -0.0)
    except CellError as e:
        assert str(path) in str(e)
