"""`Cell`: the frozen description of a work cell (two arm mounts, bar, grasps, obstacles, floor).

The seed's layout (``Cell.default()``) in SI: seed screen units map to world metres by
``p_world = 0.005 * (x, y, z - 5)`` (0.2 units per mm; the floor of the seed's drawing at z = 5 units
becomes z = 0). Shoulders at (1.0, 0, 0.6604) and (2.0, 0, 0.6604); start joints = the seed's FLAG2
values; grasps derived from them as the seed does (eq. 5.5).
"""

from __future__ import annotations

import math
import os
import tempfile
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from .errors import CellError

__all__ = ["ArmMount", "Bar", "Cell", "Grasp", "Obstacle", "load_cell", "save_cell", "seed_units_to_world"]

FloatArray = npt.NDArray[np.float64]
KNOWN_ROBOTS = ("puma560", "ur5", "ur3", "ur10")
SHAPES = ("box", "sphere", "capsule")


MOUNT_YAW = -math.pi / 2  #: base yaw of Cell.default()'s arms (J1 range centred on the work area) [rad]


def seed_units_to_world(p: npt.ArrayLike) -> FloatArray:
    """Seed screen units (x, y, z) -> world metres: 0.005 * (x, y, z - 5)."""
    a = np.asarray(p, float)
    return 0.005 * (a - np.array([0.0, 0.0, 5.0]))


def _ro(a: npt.ArrayLike, shape: tuple[int, ...], where: str) -> FloatArray:
    try:
        arr = np.array(a, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise CellError(f"{where}: expected numbers, got {a!r}") from exc
    if arr.shape != shape:
        raise CellError(f"{where}: expected shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise CellError(f"{where}: contains NaN or inf")
    arr.setflags(write=False)
    return arr


def _pose(T: npt.ArrayLike, where: str) -> FloatArray:
    arr = _ro(T, (4, 4), where)
    R = arr[:3, :3]
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-9 or np.linalg.det(R) < 0:
        raise CellError(f"{where}: rotation is not orthonormal with det +1")
    if np.abs(arr[3] - (0, 0, 0, 1)).max() > 1e-12:
        raise CellError(f"{where}: bottom row must be (0, 0, 0, 1)")
    return arr


@dataclass(frozen=True, slots=True)
class ArmMount:
    """An arm: robot name, shoulder/base pose in the world, home (start) joints [rad]."""

    name: str
    robot: str
    T_world_base: FloatArray
    q_home: FloatArray = field(default_factory=lambda: np.zeros(6))

    def __post_init__(self) -> None:
        if self.robot not in KNOWN_ROBOTS:
            raise CellError(f"{self.name}.robot: unknown robot {self.robot!r}; known: {', '.join(KNOWN_ROBOTS)}")
        object.__setattr__(self, "T_world_base", _pose(self.T_world_base, f"{self.name}.T_world_base"))
        object.__setattr__(self, "q_home", _ro(self.q_home, (6,), f"{self.name}.q_home"))


def _size(shape: str, size: npt.ArrayLike, where: str) -> FloatArray:
    if shape not in SHAPES:
        raise CellError(f"{where}.shape: expected one of {SHAPES}, got {shape!r}")
    n = {"box": 3, "sphere": 1, "capsule": 2}[shape]
    arr = _ro(size, (n,), f"{where}.size")
    if np.any(arr <= 0):
        raise CellError(f"{where}.size: sizes must be positive, got {arr.tolist()}")
    return arr


@dataclass(frozen=True, slots=True)
class Bar:
    """The held bar: box size = full extents [m]; capsule size = (radius, length) along local z."""

    shape: str
    size: FloatArray
    T_object_bar: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "size", _size(self.shape, self.size, "bar"))
        object.__setattr__(self, "T_object_bar", _pose(self.T_object_bar, "bar.T_object_bar"))


@dataclass(frozen=True, slots=True)
class Grasp:
    """Rigid grasp: the hand (wrist-centre) frame in the object frame."""

    T_object_hand: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "T_object_hand", _pose(self.T_object_hand, "grasp.T_object_hand"))


@dataclass(frozen=True, slots=True)
class Obstacle:
    """Box (full extents), sphere (radius,) or capsule (radius, length); optional constant velocity
    [m/s] applied between ``t_start`` and ``t_end`` [s] (the seed's AGV scenario)."""

    name: str
    shape: str
    size: FloatArray
    T_world_obstacle: FloatArray
    velocity: FloatArray = field(default_factory=lambda: np.zeros(3))
    t_start: float = 0.0
    t_end: float = math.inf

    def __post_init__(self) -> None:
        w = f"obstacles[{self.name}]"
        object.__setattr__(self, "size", _size(self.shape, self.size, w))
        object.__setattr__(self, "T_world_obstacle", _pose(self.T_world_obstacle, f"{w}.T_world_obstacle"))
        object.__setattr__(self, "velocity", _ro(self.velocity, (3,), f"{w}.velocity"))
        if not (math.isfinite(self.t_start) and self.t_end >= self.t_start) or math.isnan(self.t_end):
            raise CellError(f"{w}: need finite t_start <= t_end, got {self.t_start}, {self.t_end}")

    def pose_at(self, t: float) -> FloatArray:
        """World pose at time ``t`` [s] (moves only inside [t_start, t_end])."""
        dt = min(max(float(t), self.t_start), self.t_end) - self.t_start
        T = self.T_world_obstacle.copy()
        T[:3, 3] += dt * self.velocity
        return T


@dataclass(frozen=True, slots=True)
class Cell:
    """A two-arm work cell (see module docstring)."""

    left: ArmMount
    right: ArmMount
    bar: Bar
    grasp_left: Grasp
    grasp_right: Grasp
    T_world_object_start: FloatArray
    obstacles: tuple[Obstacle, ...] = ()
    floor_z: float = 0.0
    safety_margin: float = 0.02
    name: str = "cell"

    def __post_init__(self) -> None:
        object.__setattr__(self, "T_world_object_start", _pose(self.T_world_object_start, "T_world_object_start"))
        object.__setattr__(self, "obstacles", tuple(self.obstacles))
        names = [o.name for o in self.obstacles]
        if len(set(names)) != len(names):
            raise CellError(f"obstacles: names must be unique, got {names}")
        if not math.isfinite(self.floor_z):
            raise CellError("floor_z: must be finite")
        if not (math.isfinite(self.safety_margin) and self.safety_margin >= 0):
            raise CellError(f"safety_margin: expected a finite value >= 0 [m], got {self.safety_margin}")

    @staticmethod
    def default() -> Cell:
        """The seed's two-PUMA layout in SI (shoulders 1 m apart, 0.6604 m up), no obstacles."""
        from .puma import fk

        # Mounting: the seed has no joint limits, so its q1 = 0 direction is a free choice. We yaw
        # both bases by MOUNT_YAW (-90 deg: J1's zero faces the work area in front, -y) so that
        # J1's +-160 deg range is centred on it; q1 = seed q1 - MOUNT_YAW. Every link's world pose
        # is the seed's (fk(q) starts with Rz(q1) about the base z axis).
        c, s = math.cos(MOUNT_YAW), math.sin(MOUNT_YAW)
        T_wl, T_wr = np.eye(4), np.eye(4)
        T_wl[:2, :2] = T_wr[:2, :2] = [[c, -s], [s, c]]
        T_wl[:3, 3] = seed_units_to_world([200.0, 0.0, 137.08])
        T_wr[:3, 3] = seed_units_to_world([400.0, 0.0, 137.08])
        qL = np.array([-0.5123, 0.1847, -0.8479, 0.0, 0.6632, -0.5123])
        qR = np.array([-1.7703, 0.1833, 0.3838, 0.0, -0.5671, -1.7703])
        qL[0] -= MOUNT_YAW
        qR[0] -= MOUNT_YAW
        HL, HR = T_wl @ fk(qL), T_wr @ fk(qR)
        T_wo = np.eye(4)
        T_wo[:3, :3] = HL[:3, :3]  # the seed: Tro's rotation = robot 1's hand rotation
        T_wo[:3, 3] = 0.5 * (HL[:3, 3] + HR[:3, 3])  # the bar's frame midway between the wrists
        inv = np.linalg.inv(T_wo)
        # bar: box 0.75 m along object x, 5 cm square, its centre 0.12 m along the approach axis
        T_ob = np.eye(4)
        T_ob[2, 3] = 0.12
        return Cell(
            left=ArmMount("left", "puma560", T_wl, qL),
            right=ArmMount("right", "puma560", T_wr, qR),
            bar=Bar("box", np.array([0.75, 0.05, 0.05]), T_ob),
            grasp_left=Grasp(inv @ HL),
            grasp_right=Grasp(inv @ HR),
            T_world_object_start=T_wo,
            name="seed-default",
        )


# ----------------------------------------------------------------------------- TOML
_TOP = {"name", "floor_z", "safety_margin", "left", "right", "bar", "grasp_left", "grasp_right", "object_start", "obstacles"}


def _rpy_pose(d: dict, where: str, path: str) -> FloatArray:
    from .paths import calc_rot

    _keys(d, {"xyz", "rpy", "rotation"}, where, path)
    T = np.eye(4)
    T[:3, 3] = _ro(d.get("xyz", [0, 0, 0]), (3,), f"{path}: {where}.xyz")
    if "rotation" in d:
        T[:3, :3] = _ro(d["rotation"], (3, 3), f"{path}: {where}.rotation")
    else:
        T[:3, :3] = calc_rot(_ro(d.get("rpy", [0, 0, 0]), (3,), f"{path}: {where}.rpy"))
    return _pose(T, f"{path}: {where}")


def _keys(d: object, allowed: set[str], where: str, path: str) -> None:
    if not isinstance(d, dict):
        raise CellError(f"{path}: {where}: expected a table, got {type(d).__name__}")
    extra = set(d) - allowed
    if extra:
        raise CellError(f"{path}: {where}: unknown key(s) {sorted(extra)}; allowed {sorted(allowed)}")


def _num(d: dict, key: str, default: float, where: str, path: str) -> float:
    v = d.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise CellError(f"{path}: {where}{key}: expected a number, got {v!r}")
    return float(v)


def load_cell(path: str | os.PathLike) -> Cell:
    """Load a cell from TOML (schema: see ``dump_cell_toml``'s output / the shipped example).

    Raises:
        CellError: unreadable file, TOML syntax, unknown/missing keys, wrong types, bad values;
            the message names the file, the key and the problem.
    """
    p = Path(path)
    try:
        doc = tomllib.loads(p.read_text())
    except OSError as exc:
        raise CellError(f"{p}: cannot read: {exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise CellError(f"{p}: TOML syntax: {exc}") from exc
    _keys(doc, _TOP, "top level", str(p))
    try:
        arms = {}
        for side in ("left", "right"):
            if side not in doc:
                raise CellError(f"{p}: missing table [{side}]")
            a = doc[side]
            _keys(a, {"robot", "base", "q_home"}, side, str(p))
            arms[side] = ArmMount(side, str(a.get("robot", "puma560")), _rpy_pose(a.get("base", {}), f"{side}.base", str(p)), a.get("q_home", [0.0] * 6))
        b = doc.get("bar")
        if b is None:
            raise CellError(f"{p}: missing table [bar]")
        _keys(b, {"shape", "size", "pose"}, "bar", str(p))
        bar = Bar(str(b.get("shape", "box")), b.get("size"), _rpy_pose(b.get("pose", {}), "bar.pose", str(p)))
        T_wo = _rpy_pose(doc.get("object_start", {}), "object_start", str(p))
        grasps = {}
        for side in ("left", "right"):
            g = doc.get(f"grasp_{side}")
            if g is None:  # derive from the home joints (eq. 5.5)
                arm = arms[side]
                if arm.robot != "puma560":
                    raise CellError(f"{p}: grasp_{side}: required for robot {arm.robot!r}")
                from .puma import fk

                grasps[side] = Grasp(np.linalg.inv(T_wo) @ arm.T_world_base @ fk(arm.q_home))
            else:
                grasps[side] = Grasp(_rpy_pose(g, f"grasp_{side}", str(p)))
        obs = []
        for i, o in enumerate(doc.get("obstacles", [])):
            _keys(o, {"name", "shape", "size", "pose", "velocity", "t_start", "t_end"}, f"obstacles[{i}]", str(p))
            obs.append(
                Obstacle(
                    str(o.get("name", f"obstacle{i}")),
                    str(o.get("shape", "box")),
                    o.get("size"),
                    _rpy_pose(o.get("pose", {}), f"obstacles[{i}].pose", str(p)),
                    o.get("velocity", [0.0, 0.0, 0.0]),
                    _num(o, "t_start", 0.0, f"obstacles[{i}].", str(p)),
                    _num(o, "t_end", math.inf, f"obstacles[{i}].", str(p)),
                )
            )
        return Cell(
            arms["left"], arms["right"], bar, grasps["left"], grasps["right"], T_wo, tuple(obs),
            _num(doc, "floor_z", 0.0, "", str(p)), _num(doc, "safety_margin", 0.02, "", str(p)), str(doc.get("name", p.stem)),
        )
    except CellError as exc:
        msg = str(exc)
        raise CellError(msg if msg.startswith(str(p)) else f"{p}: {msg}") from None


def _fmt(a: npt.ArrayLike) -> str:
    arr = np.asarray(a, float)
    if arr.ndim == 2:
        return "[" + ", ".join(_fmt(r) for r in arr) + "]"
    return "[" + ", ".join(repr(float(v)) if math.isfinite(v) else ("inf" if v > 0 else "-inf") for v in arr) + "]"


def _pose_toml(T: FloatArray) -> str:
    return f"{{ xyz = {_fmt(T[:3, 3])}, rotation = {_fmt(T[:3, :3])} }}"


def dump_cell_toml(cell: Cell) -> str:
    """TOML text of a cell (exact round trip through :func:`load_cell`)."""
    lines = [f"name = {cell.name!r}".replace("'", '"'), f"floor_z = {cell.floor_z!r}", f"safety_margin = {cell.safety_margin!r}", ""]
    for side in ("left", "right"):
        a = getattr(cell, side)
        lines += [f"[{side}]", f'robot = "{a.robot}"', f"base = {_pose_toml(a.T_world_base)}", f"q_home = {_fmt(a.q_home)}", ""]
    lines += ["[bar]", f'shape = "{cell.bar.shape}"', f"size = {_fmt(cell.bar.size)}", f"pose = {_pose_toml(cell.bar.T_object_bar)}", ""]
    lines += [f"object_start = {_pose_toml(cell.T_world_object_start)}".replace("object_start = ", "[object_start]\n").replace("{ ", "").replace(" }", "").replace(", rotation", "\nrotation"), ""]
    for side in ("left", "right"):
        T = getattr(cell, f"grasp_{side}").T_object_hand
        lines += [f"[grasp_{side}]", f"xyz = {_fmt(T[:3, 3])}", f"rotation = {_fmt(T[:3, :3])}", ""]
    for o in cell.obstacles:
        lines += ["[[obstacles]]", f'name = "{o.name}"', f'shape = "{o.shape}"', f"size = {_fmt(o.size)}", f"pose = {_pose_toml(o.T_world_obstacle)}", f"velocity = {_fmt(o.velocity)}", f"t_start = {o.t_start!r}"]
        lines += [f"t_end = {'inf' if math.isinf(o.t_end) else repr(o.t_end)}", ""]
    return "\n".join(lines)


def save_cell(cell: Cell, path: str | os.PathLike, overwrite: bool = False) -> Path:
    """Write ``cell`` as TOML atomically; refuses to replace an existing file unless ``overwrite``.

    Raises:
        CellError: the file exists and ``overwrite`` is False.
    """
    p = Path(path)
    if p.exists() and not overwrite:
        raise CellError(f"{p}: exists; pass overwrite=True to replace it")
    fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=p.name, suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        f.write(dump_cell_toml(cell))
    os.replace(tmp, p)
    return p


#: cells shipped with the package (src/dualpuma/data/cells/*.toml)
EXAMPLE_CELLS = ("default", "routine7_box", "routine8_overhang", "agv")


def example_cell(name: str = "default") -> Cell:
    """Load a shipped example cell: ``default`` (the seed's layout), ``routine7_box``,
    ``routine8_overhang`` (the routines' obstacle fields) or ``agv`` (a box driving past at 0.25 m/s).

    Raises:
        CellError: unknown name.
    """
    from importlib import resources

    if name not in EXAMPLE_CELLS:
        raise CellError(f"example_cell: unknown name {name!r}; known: {', '.join(EXAMPLE_CELLS)}")
    with resources.as_file(resources.files("dualpuma") / "data" / "cells" / f"{name}.toml") as path:
        return load_cell(path)


def cell_from_spec(spec: str | os.PathLike | None) -> Cell:
    """The cell a CLI flag names: None -> ``Cell.default()``; an example name (``agv``...) unless a
    file of that name exists; otherwise a TOML file (:func:`load_cell`, CellError on any problem)."""
    if spec is None:
        return Cell.default()
    if str(spec) in EXAMPLE_CELLS and not Path(spec).exists():
        return example_cell(str(spec))
    return load_cell(spec)
