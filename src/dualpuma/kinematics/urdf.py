"""Reading a URDF as a 6-DOF arm's Pinocchio model (and collision geometry).

The joints from the URDF's root to the hand frame must be six one-DOF revolute joints; every other
joint (a gripper's fingers, a second branch) is locked at its neutral position clamped into its
limits, so the links it carries ride on the arm's last joint. ``continuous`` joints are read as
revolute within +-2 pi (Pinocchio would give them two coordinates, cos and sin). ``package://``
mesh URIs resolve against example-robot-data's share directory and the URDF's parent directories.
"""

from __future__ import annotations

import functools
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import FileError, RobotError
from ..files import read_limited

__all__ = ["ArmModel", "example_robot_data_dir", "frame_index", "joint_axis", "mesh_files", "package_dirs", "read_arm"]


@dataclass(frozen=True)
class ArmModel:
    """What :func:`read_arm` read: the 6-DOF model, its collision geometry (None if not asked
    for), and the locked URDF joints with their values."""

    model: pin.Model
    geometry: pin.GeometryModel | None
    locked: dict[str, float] = field(default_factory=dict)


@functools.cache
def example_robot_data_dir() -> Path:
    """Directory holding example-robot-data's ``robots/`` (installed by the package's wheel);
    looked up once per process, in the wheel's RECORD as text (its first URDF under ``robots/``:
    about 1 ms; making path objects of all its ~1,000 files, ``dist.files``, cost ~15 ms, which
    every first plan of a process paid), else in ``dist.files``.

    Raises:
        RobotError: example-robot-data is not installed.
    """
    import importlib.metadata as md

    try:
        dist = md.distribution("example-robot-data")
    except md.PackageNotFoundError as exc:  # pragma: no cover - it is a hard dependency
        raise RobotError("example-robot-data is not installed (pip install example-robot-data)") from exc

    def listed():  # the RECORD's URDFs first; the whole file list only if they are not there
        record = dist.read_text("RECORD") or ""
        yield from (line.rsplit(",", 2)[0] for line in record.splitlines() if "robots/" in line and ".urdf," in line)
        yield from (str(f) for f in dist.files or [])

    for f in listed():
        parts = Path(f).parts
        if "robots" in parts and parts[-1].endswith(".urdf"):
            root = Path(str(dist.locate_file(f)))
            while root.name != "robots":
                root = root.parent
            return root
    raise RobotError("example-robot-data is installed but its robots/ directory was not found")


def frame_index(model: pin.Model, name: str) -> int:
    """Index of the frame called ``name`` (``model.nframes`` if there is none). A URDF may give a
    link and a joint the same name; then the link's (body) frame is the one meant."""
    hits = [i for i, f in enumerate(model.frames) if f.name == name]
    if len(hits) > 1:
        hits = [i for i in hits if model.frames[i].type == pin.FrameType.BODY] or hits
    return hits[0] if hits else model.nframes


def package_dirs(urdf: Path) -> list[str]:
    """Where ``package://`` URIs of a URDF are looked for: example-robot-data's share directory
    and the URDF's own parent directories."""
    dirs = [str(p) for p in list(urdf.parents)[:4]]
    try:
        dirs.insert(0, str(example_robot_data_dir().parent.parent))
    except RobotError:  # pragma: no cover
        pass
    return dirs


_MAX_TURN = 4.0 * math.pi  # revolute limits beyond two turns each way are taken for degrees [rad]


def _limit_text(lower: float, upper: float, kind: str) -> tuple[str, str]:
    """Two limits as they are shown in messages: degrees for a revolute joint, millimetres for a
    prismatic one; one decimal, or as many as it takes to tell them apart."""
    scale, unit = (1000.0, "mm") if kind == "prismatic" else (180.0 / math.pi, "deg")
    lo, hi = lower * scale, upper * scale
    digits = next((d for d in range(1, 13) if f"{lo:.{d}f}" != f"{hi:.{d}f}"), 1)
    return f"{lo:.{digits}f} {unit}", f"{hi:.{digits}f} {unit}"


def _check_limit(joint: ET.Element, path: Path) -> None:
    """A revolute or prismatic joint's ``<limit>``: finite numbers with lower <= upper (URDF's
    default for a missing bound is 0).

    Raises:
        RobotError: a bound that is not a finite number, or lower > upper.
    """
    limit = joint.find("limit")
    name, bounds = joint.get("name"), {}
    if limit is None:  # Pinocchio's parser refused it saying only "does not contain a valid URDF model"
        raise RobotError(f"{path}: joint {name!r} ({joint.get('type')}) has no <limit>: give its lower and upper limits")
    for key in ("lower", "upper"):
        raw = limit.get(key, "0")
        try:
            bounds[key] = float(raw)
        except ValueError:
            bounds[key] = math.nan
        if not math.isfinite(bounds[key]):
            raise RobotError(f"{path}: joint {name!r}: its {key} limit {raw!r} is not a finite number")
    if bounds["lower"] > bounds["upper"]:
        lo, hi = _limit_text(bounds["lower"], bounds["upper"], joint.get("type", ""))
        raise RobotError(f"{path}: joint {name!r}: its lower limit ({lo}) must not exceed its upper limit ({hi})")


def _check_numbers(joint: ET.Element, path: Path) -> None:
    """A joint's ``<origin>`` and ``<axis>``: finite numbers, a moving joint's axis not zero (a zero
    axis gave FK that is not a rotation; a fixed joint's axis means nothing: Kinova's are zero).

    Raises:
        RobotError: otherwise.
    """
    name = joint.get("name")
    for tag, keys in (("origin", ("xyz", "rpy")), ("axis", ("xyz",))):
        el = joint.find(tag)
        for key in keys:
            raw = None if el is None else el.get(key)
            if raw is None:
                continue
            try:
                v = [float(x) for x in raw.split()]
            except ValueError:
                v = [math.nan]
            if len(v) != 3 or not all(math.isfinite(x) for x in v):
                raise RobotError(f"{path}: joint {name!r}: its {tag} {key}={raw!r} is not three finite numbers")
            if tag == "axis" and math.hypot(*v) < 1e-12 and joint.get("type") in ("revolute", "continuous", "prismatic"):
                raise RobotError(f"{path}: joint {name!r}: its axis is zero")


def _urdf_text(path: Path, data: bytes | None = None) -> tuple[str, dict[str, str]]:
    """The URDF's XML with every ``continuous`` joint made ``revolute`` within +-2 pi (Pinocchio
    gives a continuous joint two coordinates, cos and sin; dualpuma's arms have one per joint), and
    each joint's URDF type by name. ``data``: the file's bytes if the caller has read them.

    Raises:
        RobotError: unreadable file, malformed XML, or a revolute or prismatic joint whose limits
            are not finite with lower <= upper.
    """
    try:
        text = path.read_text(encoding="utf-8") if data is None else data.decode("utf-8")
        root = ET.fromstring(text)
    except (OSError, UnicodeDecodeError, ET.ParseError) as exc:
        raise RobotError(f"{path}: not a readable URDF: {exc}") from None
    types: dict[str, str] = {}
    for joint in root.findall("joint"):  # the robot's joints (a <transmission> names joints too)
        kind = joint.get("type", "")
        mimic = joint.find("mimic")
        types[joint.get("name", "")] = kind if mimic is None else f"{kind} mimicking {mimic.get('joint')!r}"
        _check_numbers(joint, path)
        if kind == "continuous":
            joint.set("type", "revolute")
            limit = joint.find("limit")
            if limit is None:
                limit = ET.SubElement(joint, "limit", effort="0", velocity="0")
            limit.set("lower", repr(-2.0 * math.pi))
            limit.set("upper", repr(2.0 * math.pi))
        elif kind in ("revolute", "prismatic"):
            _check_limit(joint, path)
    return ET.tostring(root, encoding="unicode"), types


def mesh_files(path: Path, data: bytes | None = None) -> list[str]:
    """The file names the URDF's meshes (visual and collision) give, as written (relative, absolute,
    ``package://`` or ``file://``). ``data``: the file's bytes if the caller has read them.

    Raises:
        RobotError: unreadable file or malformed XML.
    """
    try:
        text = (read_limited(path) if data is None else data).decode("utf-8")
        root = ET.fromstring(text)
    except (FileError, UnicodeDecodeError, ET.ParseError) as exc:
        raise RobotError(f"{path}: not a readable URDF: {exc}") from None
    return [m.get("filename", "") for m in root.iter("mesh")]


def _six_joint_chain(model: pin.Model, hand: str, path: Path, types: dict[str, str]) -> list[int]:
    """The joints from the base to the hand frame: exactly six one-DOF revolute joints, each with
    a range (lower < upper). ``types``: the URDF type of each joint, by name (for the messages).

    Raises:
        RobotError: unknown hand frame; a joint of the chain that is not revolute (named, with its
            type); not six joints; a joint of the six that cannot move (lower = upper).
    """
    fid = frame_index(model, hand)
    if fid >= model.nframes:
        raise RobotError(f"{path}: hand frame {hand!r} not in the model; frames: {[f.name for f in model.frames]}")
    chain = [int(j) for j in model.supports[model.frames[fid].parentJoint] if j > 0]
    names = [model.names[j] for j in chain]
    expected = f"expected six revolute joints from the base to {hand!r}"
    got = "" if len(chain) == 6 else f" (the chain has {len(chain)}: {names})"
    odd = [(model.names[j], types.get(model.names[j]) or model.joints[j].shortname()) for j in chain
           if not (model.joints[j].shortname().startswith("JointModelR") and model.nqs[j] == 1)
           or " mimicking " in types.get(model.names[j], "")]  # a mimic joint is not one of six independent ones
    if len(odd) == 1:
        raise RobotError(f"{path}: joint {odd[0][0]!r} is {odd[0][1]}: {expected}{got}")
    if odd:
        listed = ", ".join(f"{n!r} ({k})" for n, k in odd)
        raise RobotError(f"{path}: joints {listed} are not revolute: {expected}{got}")
    if len(chain) != 6:
        raise RobotError(f"{path}: {expected}, got {len(chain)}: {names}")
    for j in chain:
        lower, upper = (float(lim[model.idx_qs[j]]) for lim in (model.lowerPositionLimit, model.upperPositionLimit))
        if max(abs(lower), abs(upper)) > _MAX_TURN:  # a joint off the chain is locked: its limits do not matter
            raise RobotError(f"{path}: joint {model.names[j]!r}: limits {lower:g} .. {upper:g} rad are more than two turns "
                             "each way (degrees? a URDF's revolute limits are in radians; dualpuma's joints turn at most "
                             "4 pi)")
        if not lower < upper:  # lower > upper and non-finite limits were refused in the XML
            lo, _ = _limit_text(lower, upper, "revolute")
            raise RobotError(f"{path}: joint {model.names[j]!r} cannot move: its lower and upper limits are both "
                             f"{lo}; each of the six joints from the base to {hand!r} needs a range (lower < upper)")
    return chain


def read_arm(path: Path, hand: str, *, geometry: bool = True, data: bytes | None = None) -> ArmModel:
    """The 6-DOF arm of a URDF file, from its root to the frame ``hand`` (see the module docstring).
    ``data``: the file's bytes if the caller has read them (then the file is not read again).

    Raises:
        RobotError: unreadable or malformed file, a joint's limits not finite or lower > upper,
            unknown ``hand`` frame, not six revolute joints from the root to it (the message names
            the joints that are not revolute), one of the six that cannot move (lower = upper),
            collision geometry that cannot be loaded.
    """
    xml, types = _urdf_text(path, data)
    try:
        model = pin.buildModelFromXML(xml)
    except (ValueError, RuntimeError) as exc:
        raise RobotError(f"{path}: not a loadable URDF: {exc}") from None
    chain = _six_joint_chain(model, hand, path, types)
    geom = None
    if geometry:
        try:
            geom = pin.buildGeomFromUrdfString(model, xml, pin.COLLISION, package_dirs=package_dirs(path))
        except (ValueError, RuntimeError) as exc:
            raise RobotError(f"{path}: cannot load its collision geometry: {exc}") from None
    locked = [j for j in range(1, model.njoints) if j not in chain]
    if not locked:
        return ArmModel(model, geom)
    q_ref = np.clip(pin.neutral(model), model.lowerPositionLimit, model.upperPositionLimit)
    fixed = {model.names[j]: float(q_ref[model.idx_qs[j]]) for j in locked if model.nqs[j] == 1}
    if geom is None:
        return ArmModel(pin.buildReducedModel(model, locked, q_ref), None, fixed)
    model, (geom,) = pin.buildReducedModel(model, [geom], locked, q_ref)
    return ArmModel(model, geom, fixed)


def joint_axis(model: pin.Model, j: int) -> npt.NDArray[np.float64]:
    """The axis (3,) of joint ``j`` of a Pinocchio model, in the joint's own frame: a revolute or
    prismatic joint along x, y or z, or an unaligned one's own axis."""
    name = model.joints[j].shortname()
    for k, ax in enumerate("XYZ"):
        if name.endswith(("R" + ax, "P" + ax)):
            return np.eye(3)[k]
    return np.asarray(model.joints[j].extract().axis, dtype=float)
