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
import pinocchio as pin

from ..errors import RobotError

__all__ = ["ArmModel", "example_robot_data_dir", "frame_index", "package_dirs", "read_arm"]


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


def _urdf_text(path: Path) -> str:
    """The URDF's XML with every ``continuous`` joint made ``revolute`` within +-2 pi (Pinocchio
    gives a continuous joint two coordinates, cos and sin; dualpuma's arms have one per joint).

    Raises:
        RobotError: unreadable file or malformed XML.
    """
    try:
        root = ET.fromstring(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ET.ParseError) as exc:
        raise RobotError(f"{path}: not a readable URDF: {exc}") from None
    for joint in root.iter("joint"):
        if joint.get("type") == "continuous":
            joint.set("type", "revolute")
            limit = joint.find("limit")
            if limit is None:
                limit = ET.SubElement(joint, "limit", effort="0", velocity="0")
            limit.set("lower", repr(-2.0 * math.pi))
            limit.set("upper", repr(2.0 * math.pi))
    return ET.tostring(root, encoding="unicode")


def _six_joint_chain(model: pin.Model, hand: str, path: Path) -> list[int]:
    """The joints from the base to the hand frame: exactly six one-DOF revolute joints."""
    fid = frame_index(model, hand)
    if fid >= model.nframes:
        raise RobotError(f"{path}: hand frame {hand!r} not in the model; frames: {[f.name for f in model.frames]}")
    chain = [int(j) for j in model.supports[model.frames[fid].parentJoint] if j > 0]
    kinds = [model.joints[j].shortname() for j in chain]
    if len(chain) != 6 or not all(k.startswith("JointModelR") and model.nqs[j] == 1 for k, j in zip(kinds, chain)):
        raise RobotError(f"{path}: expected six revolute joints from the base to {hand!r}, got "
                         f"{len(chain)}: {[model.names[j] for j in chain]}")
    return chain


def read_arm(path: Path, hand: str, *, geometry: bool = True) -> ArmModel:
    """The 6-DOF arm of a URDF file, from its root to the frame ``hand`` (see the module docstring).

    Raises:
        RobotError: unreadable or malformed file, unknown ``hand`` frame, not six revolute joints
            from the root to it, collision geometry that cannot be loaded.
    """
    xml = _urdf_text(path)
    try:
        model = pin.buildModelFromXML(xml)
    except (ValueError, RuntimeError) as exc:
        raise RobotError(f"{path}: not a loadable URDF: {exc}") from None
    chain = _six_joint_chain(model, hand, path)
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
