"""Cell files: the TOML form of a :class:`~dualpuma.model.cell.Cell`, and the cells shipped with
the package.

Schema (every key optional unless marked; SI units; poses as ``xyz`` [m] plus either ``rpy``
[rad] (roll, pitch, yaw: ``Rz(yaw) Ry(pitch) Rx(roll)``) or a 3x3 ``rotation``; an angle beyond
a turn, 2 pi, is refused as most likely degrees, the message giving the radians to write)::

    name = "my cell"
    floor_z = 0.0                     # [m]
    safety_margin = 0.02              # [m], at most model.MAX_MARGIN = 1 m
    [left]                            # required, likewise [right]
    robot = "puma560"                 # a name from dualpuma.KNOWN_ROBOTS, or
                                      # { urdf = "arm.urdf", tip = "tool0" } (relative to this file)
    base = { xyz = [1.0, 0.0, 0.6604], rpy = [0.0, 0.0, -1.5708] }
    q_home = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]   # [rad]
    [bar]                             # required
    shape = "box"                     # box (size = full extents), capsule (radius, length), sphere (radius)
    size = [0.75, 0.05, 0.05]
    pose = { xyz = [0.0, 0.0, 0.12] } # bar frame in the object frame
    [object_start]                    # the object (bar) frame at the start
    xyz = [1.5, -0.2, 0.23]
    [grasp_left]                      # hand frame in the object frame; default: from q_home (eq. 5.5);
                                      # given, q_home must hold the bar with it at object_start
    [[obstacles]]                     # any number of these tables
    name = "box"
    shape = "box"
    size = [0.1, 0.4, 0.2]
    pose = { xyz = [1.3, -0.25, 0.1] }
    velocity = [0.0, 0.0, 0.0]        # [m/s], between t_start and t_end [s]

A complete example, checked by the tests: docs/cells.md.

Reading is strict: an unknown key, a wrong type, a non-finite number or an impossible value is a
:class:`~dualpuma.errors.CellError` naming the file, the key and the problem (a leading UTF-8
byte-order mark is skipped; a file name's leading ``~`` is expanded). Writing uses ``tomli-w``
(every string escaped, floats written to round-trip exactly) through an atomic write that never
replaces a file unless asked; a URDF robot in the saved file's folder or below is written relative
to it.
"""

from __future__ import annotations

import math
import os
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np
import numpy.typing as npt
import tomli_w

from ..checks import flag, instance, rotations, text
from ..errors import CellError, CellFileError, DualpumaError, FileError, RobotError
from ..files import atomic_write, read_limited, user_path
from ..kinematics.arm import Arm, RobotSpec
from ..kinematics.urdf import mesh_files
from ..lie import rot_to_rpy, rpy_to_rot
from .cell import MAX_EXTENT, MAX_OBSTACLES, SIZE_COUNTS, ArmMount, Bar, Cell, Grasp, Obstacle

__all__ = [
    "EXAMPLE_CELLS",
    "MAX_CELL_BYTES",
    "cell_from_spec",
    "cell_from_toml",
    "cell_to_toml",
    "example_cell",
    "load_cell",
    "save_cell",
]

FloatArray = npt.NDArray[np.float64]

#: cells shipped with the package (src/dualpuma/model/data/cells/*.toml)
EXAMPLE_CELLS = ("default", "routine7_box", "routine8_overhang", "agv", "ur5_pair", "mixed_puma_ur5")
MAX_CELL_BYTES = 1 << 20  #: largest cell file read [bytes]
_TOP = {"name", "floor_z", "safety_margin", "left", "right", "bar", "grasp_left", "grasp_right", "object_start",
        "obstacles"}


# ----------------------------------------------------------------------------- reading
def _keys(d: object, allowed: set[str], where: str) -> dict:
    if not isinstance(d, dict):
        raise CellError(f"{where}: expected a table, got {type(d).__name__}")
    extra = set(d) - allowed
    if extra:
        raise CellError(f"{where}: unknown key(s) {sorted(extra)}; allowed {sorted(allowed)}")
    return d


def _num(d: dict, key: str, default: float, where: str) -> float:
    v = d.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise CellError(f"{where}{key}: expected a number, got {v!r}"[:300])
    try:
        return float(v)
    except OverflowError:
        raise CellError(f"{where}{key}: {v} is beyond the float range") from None


_SIZES = {"box": "3 full extents", "sphere": "[radius]", "capsule": "[radius, length]"}


def _size(d: dict, where: str) -> FloatArray:
    """``d["size"]`` for ``d["shape"]`` (default box), with a message that says what each shape takes."""
    if "size" not in d:
        raise CellError(f"{where}.size: missing")
    shape, v = _text(d, "shape", "box", f"{where}."), d["size"]
    help_ = "; ".join(f"{k}: {n}" for k, n in _SIZES.items())
    if not isinstance(v, list):
        raise CellError(f"{where}.size: expected a list of numbers [m] ({help_}), got {v!r}"[:300])
    n = SIZE_COUNTS.get(shape)
    if n is not None and len(v) != n:
        unset = "" if "shape" in d else "; shape is not given, so it is a box: write shape = \"sphere\" or \"capsule\""
        raise CellError(f"{where}.size: a {shape} takes {_SIZES[shape]} [m], got {len(v)} numbers{unset}")
    return _vector(v, (len(v),), f"{where}.size")


def _text(d: dict, key: str, default: str, where: str) -> str:
    v = d.get(key, default)
    if not isinstance(v, str):
        raise CellError(f"{where}{key}: expected a string, got {type(v).__name__}")
    return v


def _robot(v: object, where: str, base_dir: Path, urdf_root: Path | None) -> str | RobotSpec:
    """A robot name, or ``{ urdf = "path", tip = "frame" }`` with the path relative to the cell file
    (and, with ``urdf_root``, inside that directory once links are followed)."""
    if isinstance(v, str):
        return v
    if not isinstance(v, dict):
        raise CellError(f"{where}: expected a robot name or a table {{ urdf = \"path\", tip = \"frame\" }}, "
                        f"got {type(v).__name__}")
    d = _keys(v, {"urdf", "tip"}, where)
    if "urdf" not in d or "tip" not in d:
        raise CellError(f"{where}: a URDF robot needs both urdf and tip")
    urdf, tip = _text(d, "urdf", "", f"{where}."), _text(d, "tip", "", f"{where}.")
    path = Path(urdf).expanduser()
    path = path if path.is_absolute() else base_dir / path
    if urdf_root is not None:
        try:
            inside = path.resolve().is_relative_to(urdf_root.resolve())
        except (OSError, ValueError, RuntimeError) as exc:
            raise CellError(f"{where}: not a usable path: {exc}"[:300]) from None
        if not inside:
            raise CellError(f"{where}: {urdf} is outside {urdf_root}; only URDF files inside it may be loaded here")
        if path.is_file():
            _meshes_inside(path, urdf_root, where)
    try:
        return RobotSpec(path, tip)
    except RobotError as exc:
        raise CellError(f"{where}: {exc}") from None


def _meshes_inside(urdf: Path, root: Path, where: str) -> None:
    """Every mesh the URDF names is a file inside ``root`` by a relative path (links followed): the
    meshes are read and drawn for every client, so a URDF in the viewer's data directory must not
    name files elsewhere (absolute, ``package://``, ``../``; found by a reviewer: an outside file's
    vertices were sent to every browser)."""
    try:
        names = mesh_files(urdf)
    except RobotError as exc:
        raise CellError(f"{where}: {exc}") from None
    top = root.resolve()
    for name in names:
        rel = Path(name)
        if "://" in name or rel.is_absolute() or not name:
            inside = False
        else:
            try:
                target = (urdf.parent / rel).resolve()
                inside = target.is_relative_to(top) and target.is_file()
            except (OSError, ValueError, RuntimeError):
                inside = False
        if not inside:
            raise CellError(f"{where}: {urdf.name} names the mesh {name[:200]!r}, which is not a file inside {root} "
                            "by a relative path; only files inside it are read here")


def _pose(d: object, where: str) -> FloatArray:
    d = _keys(d, {"xyz", "rpy", "rotation"}, where)
    if "rpy" in d and "rotation" in d:
        raise CellError(f"{where}: give either rpy or rotation, not both")
    T = np.eye(4)
    T[:3, 3] = _vector(d.get("xyz", [0.0, 0.0, 0.0]), (3,), f"{where}.xyz")
    if np.abs(T[:3, 3]).max() > MAX_EXTENT:
        raise CellError(f"{where}.xyz: position {T[:3, 3].tolist()} m is beyond {MAX_EXTENT:g} m"[:300])
    if "rotation" in d:
        T[:3, :3] = R = _vector(d["rotation"], (3, 3), f"{where}.rotation")
        try:
            rotations(R, f"{where}.rotation", CellError)
        except CellError as exc:  # e.g. written to 6 decimals: say how to write it instead
            u, _, vt = np.linalg.svd(R)
            if np.linalg.det(u @ vt) > 0.0:
                rpy = ", ".join(f"{v:.9g}" for v in rot_to_rpy(u @ vt))
                raise CellError(f"{exc}; write it with more digits, or as rpy = [{rpy}] (the nearest rotation's "
                                f"roll, pitch, yaw [rad])") from None
            raise
    else:
        T[:3, :3] = rpy_to_rot(_radians(d.get("rpy", [0.0, 0.0, 0.0]), (3,), f"{where}.rpy"))
    return T


def _radians(v: object, shape: tuple[int, ...], where: str) -> FloatArray:
    """Angles [rad]; one beyond a turn (2 pi) is refused as most likely written in degrees."""
    arr = _vector(v, shape, where)
    if np.abs(arr).max(initial=0.0) > 2.0 * math.pi + 1e-9:
        rad = ", ".join(f"{x:.9g}" for x in np.radians(arr))
        raise CellError(f"{where}: {arr.tolist()} has an angle beyond a turn (2 pi = 6.283); angles in a cell file "
                        f"are radians: if these are degrees, write [{rad}]"[:400])
    return arr


def _vector(v: object, shape: tuple[int, ...], where: str) -> FloatArray:
    ok = isinstance(v, list) and all(
        (isinstance(x, (int, float)) and not isinstance(x, bool)) if len(shape) == 1 else isinstance(x, list)
        for x in v
    )
    if len(shape) == 2 and ok:
        ok = all(isinstance(x, (int, float)) and not isinstance(x, bool) for row in v for x in row)  # type: ignore[union-attr]
    if not ok:
        raise CellError(f"{where}: expected an array of numbers of shape {shape}, got {v!r}"[:300])
    try:
        arr = np.array(v, dtype=np.float64)
    except (ValueError, OverflowError):  # ragged rows; an integer beyond the float range
        raise CellError(f"{where}: expected an array of finite numbers of shape {shape}"[:300]) from None
    if arr.shape != shape:
        raise CellError(f"{where}: expected shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise CellError(f"{where}: contains NaN or inf")
    return arr


def _cell_from_doc(doc: dict, default_name: str, base_dir: Path, urdf_root: Path | None) -> Cell:
    _keys(doc, _TOP, "top level")
    arms = {}
    for side in ("left", "right"):
        if side not in doc:
            raise CellError(f"missing table [{side}]")
        a = _keys(doc[side], {"robot", "base", "q_home"}, side)
        arms[side] = ArmMount(side, _robot(a.get("robot", "puma560"), f"{side}.robot", base_dir, urdf_root),
                              _pose(a.get("base", {}), f"{side}.base"),
                              _radians(a.get("q_home", [0.0] * 6), (6,), f"{side}.q_home"))
    if "bar" not in doc:
        raise CellError("missing table [bar]")
    b = _keys(doc["bar"], {"shape", "size", "pose"}, "bar")
    bar = Bar(_text(b, "shape", "box", "bar."), _size(b, "bar"), _pose(b.get("pose", {}), "bar.pose"))
    T_wo = _pose(doc.get("object_start", {}), "object_start")
    grasps = {}
    for side in ("left", "right"):
        g = doc.get(f"grasp_{side}")
        if g is None:  # derive from the home joints (eq. 5.5)
            arm = arms[side]
            try:
                T_base_hand = Arm.load(arm.robot).fk(arm.q_home)
            except RobotError as exc:
                raise CellError(f"{side}.robot: {exc}") from None
            grasps[side] = Grasp(np.linalg.inv(T_wo) @ arm.T_world_base @ T_base_hand)
        else:
            grasps[side] = Grasp(_pose(g, f"grasp_{side}"))
    raw = doc.get("obstacles", [])
    if not isinstance(raw, list) or len(raw) > MAX_OBSTACLES:
        raise CellError(f"obstacles: expected an array of at most {MAX_OBSTACLES} tables")
    obs = []
    for i, o in enumerate(raw):
        w = f"obstacles[{i}]"
        o = _keys(o, {"name", "shape", "size", "pose", "velocity", "t_start", "t_end"}, w)
        size = _size(o, w)
        try:
            obs.append(Obstacle(
                _text(o, "name", f"obstacle{i}", f"{w}."), _text(o, "shape", "box", f"{w}."),
                size, _pose(o.get("pose", {}), f"{w}.pose"),
                _vector(o.get("velocity", [0.0, 0.0, 0.0]), (3,), f"{w}.velocity"),
                _num(o, "t_start", 0.0, f"{w}."), _num(o, "t_end", math.inf, f"{w}."),
            ))
        except CellError as exc:  # the Obstacle names itself by its name; the file's reader counts
            raise CellError(str(exc) if str(exc).startswith(w) else f"{w}: {exc}") from None
    try:
        return Cell(arms["left"], arms["right"], bar, grasps["left"], grasps["right"], T_wo, tuple(obs),
                    _num(doc, "floor_z", 0.0, ""), _num(doc, "safety_margin", 0.02, ""),
                    _text(doc, "name", default_name, ""))
    except CellError as exc:  # a hand far from the bar, or home joints off their grasp: say what defaulted
        for side in ("left", "right"):
            if "base" not in doc[side] and str(exc).startswith((f"grasp_{side}:", f"{side}.q_home:")):
                raise CellError(f"{exc} ({side}.base is not given: that arm stands at the world origin)") from None
        raise


def cell_from_toml(toml_text: str, *, source: str = "cell", base_dir: str | os.PathLike | None = None,
                   urdf_root: str | os.PathLike | None = None) -> Cell:
    """A cell from TOML text (the module's schema).

    Args:
        base_dir: relative URDF paths of ``robot = { urdf = ... }`` are taken from here (default:
            the current directory).
        urdf_root: if given, a URDF robot must lie inside this directory (links followed); the
            viewer passes its data directory so that a cell it loads reads no file outside it.

    Raises:
        CellError: TOML syntax, unknown/missing keys, wrong types, bad values; the message starts
            with ``source`` and names the key.
    """
    source = text(source, "source", max_len=4096, error=CellError)
    if not isinstance(toml_text, str):
        raise CellError(f"{source}: expected TOML text (str), got {type(toml_text).__name__}")
    if len(toml_text) > MAX_CELL_BYTES:
        raise CellError(f"{source}: {len(toml_text)} characters, more than the {MAX_CELL_BYTES} accepted")
    try:
        base_dir = Path.cwd() if base_dir is None else Path(base_dir)
        urdf_root = None if urdf_root is None else Path(urdf_root)
    except TypeError:
        raise CellError(f"{source}: base_dir and urdf_root must be directory paths") from None
    try:
        doc = tomllib.loads(toml_text)
        return _cell_from_doc(doc, Path(source).stem, base_dir, urdf_root)
    except tomllib.TOMLDecodeError as exc:
        raise CellError(f"{source}: TOML syntax: {exc}") from None
    except RecursionError:
        raise CellError(f"{source}: nested too deeply") from None
    except DualpumaError as exc:  # CellError, or a PoseError/ParameterError of a value inside
        raise CellError(f"{source}: {exc}") from None


def load_cell(path: str | os.PathLike) -> Cell:
    """Load a cell from a TOML file (schema: the module docstring; at most :data:`MAX_CELL_BYTES`).

    Raises:
        CellFileError: (a CellError and a FileError) missing, not a regular file or too large.
        CellError: not UTF-8; TOML syntax; unknown/missing keys, wrong
            types, bad values. The message names the file, the key and the problem.
    """
    if isinstance(path, str) and "\n" in path:
        raise CellFileError(f"load_cell takes a file name, and this is text of {len(path)} characters "
                            f"starting {path[:40]!r}: for TOML text use cell_from_toml(text)")
    try:
        p = user_path(path)
        data = read_limited(p, limit=MAX_CELL_BYTES)
    except FileError as exc:
        raise CellFileError(str(exc)) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CellError(f"{p}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    text = text.removeprefix("\ufeff")  # the byte-order mark some Windows editors write
    return cell_from_toml(text, source=str(p), base_dir=p.resolve().parent)


# ----------------------------------------------------------------------------- writing
def _pose_table(T: npt.ArrayLike) -> dict:
    T = np.asarray(T, dtype=np.float64)
    return {"xyz": [float(v) for v in T[:3, 3]], "rotation": [[float(v) for v in row] for row in T[:3, :3]]}


def _urdf_text(urdf: Path, base_dir: Path | None) -> str:
    """A URDF's path as a cell file in ``base_dir`` writes it: relative when the URDF lies in that
    directory or below it (the folder can move with it), otherwise absolute."""
    if base_dir is not None:
        try:
            return Path(urdf).resolve().relative_to(base_dir.resolve()).as_posix()
        except (ValueError, OSError, RuntimeError):
            pass
    return str(urdf)


def cell_to_toml(cell: Cell, *, base_dir: str | os.PathLike | None = None) -> str:
    """TOML text of a cell; :func:`cell_from_toml` (with the same ``base_dir``) gives back an equal
    cell (floats exactly).

    Args:
        base_dir: the directory the text will be a file in: a URDF robot inside it is written
            relative to it, as a cell file reads it (default: every URDF path absolute).

    Raises:
        CellError: not a Cell.
    """
    instance(cell, Cell, "cell", CellError)
    try:
        base = None if base_dir is None else user_path(base_dir)
    except FileError as exc:
        raise CellError(f"base_dir: {exc}") from None
    doc: dict = {"name": cell.name, "floor_z": float(cell.floor_z), "safety_margin": float(cell.safety_margin)}
    for side in ("left", "right"):
        a = getattr(cell, side)
        robot = a.robot if isinstance(a.robot, str) else {"urdf": _urdf_text(a.robot.urdf, base), "tip": a.robot.tip}
        doc[side] = {"robot": robot, "base": _pose_table(a.T_world_base), "q_home": [float(v) for v in a.q_home]}
    doc["bar"] = {"shape": cell.bar.shape, "size": [float(v) for v in cell.bar.size],
                  "pose": _pose_table(cell.bar.T_object_bar)}
    doc["object_start"] = _pose_table(cell.T_world_object_start)
    for side in ("left", "right"):
        doc[f"grasp_{side}"] = _pose_table(getattr(cell, f"grasp_{side}").T_object_hand)
    if cell.obstacles:  # none: no key, so that [[obstacles]] tables can be appended to the file by hand
        doc["obstacles"] = [
            {"name": o.name, "shape": o.shape, "size": [float(v) for v in o.size], "pose": _pose_table(o.T_world_obstacle),
             "velocity": [float(v) for v in o.velocity], "t_start": float(o.t_start), "t_end": float(o.t_end)}
            for o in cell.obstacles
        ]
    return tomli_w.dumps(doc)


def save_cell(cell: Cell, path: str | os.PathLike, overwrite: bool = False) -> Path:
    """Write ``cell`` as TOML atomically; never replaces an existing file unless ``overwrite``.

    Raises:
        CellError: not a Cell.
        CellFileError: (a CellError and a FileError) the file exists and ``overwrite`` is False;
            the directory is missing or not writable; the target is not a regular file.
    """
    instance(cell, Cell, "cell", CellError)
    overwrite = flag(overwrite, "overwrite")
    try:
        p = user_path(path)
        return atomic_write(p, cell_to_toml(cell, base_dir=p.absolute().parent).encode("utf-8"), overwrite=overwrite)
    except FileError as exc:
        raise CellFileError(str(exc)) from None


# ----------------------------------------------------------------------------- shipped cells
def example_cell(name: str = "default") -> Cell:
    """Load a shipped example cell: ``default`` (the seed's layout), ``routine7_box``,
    ``routine8_overhang`` (the routines' obstacle fields) or ``agv`` (a box driving past at 0.25 m/s).

    Raises:
        CellError: unknown name.
    """
    if not isinstance(name, str) or name not in EXAMPLE_CELLS:
        raise CellError(f"example_cell: unknown name {name!r:.80}; known: {', '.join(EXAMPLE_CELLS)}")
    body = (resources.files("dualpuma.model") / "data" / "cells" / f"{name}.toml").read_text(encoding="utf-8")
    return cell_from_toml(body, source=f"{name}.toml")


def cell_from_spec(spec: str | os.PathLike | None) -> Cell:
    """The cell a CLI flag names: None -> ``Cell.default()``; a string that is an example's name
    (``agv``...) -> that example, whatever files the working directory holds (a file ``./agv`` used
    to take its place silently, and a folder ``./default`` made ``--cell default`` fail): a file of
    such a name is given with its folder, ``./agv``; anything else (and any ``os.PathLike``) -> a
    TOML file (:func:`load_cell`, CellError on any problem)."""
    if spec is None:
        return Cell.default()
    if not isinstance(spec, (str, os.PathLike)):
        raise CellError(f"cell: expected a file name or an example name, got {type(spec).__name__}")
    if isinstance(spec, str) and spec in EXAMPLE_CELLS:
        return example_cell(spec)
    if isinstance(spec, str) and not spec.strip():
        raise CellError(f"cell: an empty name; give a cell file or an example name ({', '.join(EXAMPLE_CELLS)})")
    return load_cell(spec)
