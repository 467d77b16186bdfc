"""`Arm`: a 6-DOF serial arm loaded from URDF into Pinocchio (FK, Jacobians, IK, capsules).

The PUMA 560 (``Arm.puma560()``) uses the seed's convention (urdf/puma560.urdf) and the closed-form
IK of :mod:`dualpuma.kinematics.puma`. Any other 6-DOF arm from example-robot-data
(``Arm.load("ur5")``) gets a numerical IK (:mod:`dualpuma.kinematics.numeric`) behind the same
:meth:`Arm.ik`.

The robots known by name are listed once, in :data:`KNOWN_ROBOTS`.
"""

from __future__ import annotations

import threading
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..checks import choice, real, validate_joints, validate_pose
from ..errors import JointError, ParameterError, RobotError
from . import puma
from .ik import IKResult
from .numeric import solve_dls

__all__ = ["KNOWN_ROBOTS", "Arm", "Capsule", "example_robot_data_dir"]

FloatArray = npt.NDArray[np.float64]

#: robot name -> (package-relative URDF path under example-robot-data's robots/, hand frame)
_ERD_ROBOTS: dict[str, tuple[str, str]] = {
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "tool0"),
    "ur3": ("ur_description/urdf/ur3_robot.urdf", "tool0"),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", "tool0"),
}
KNOWN_ROBOTS: tuple[str, ...] = ("puma560", *_ERD_ROBOTS)
_GENERIC_CAPSULE_RADIUS = 0.05  # [m] capsule radius between joint origins for non-PUMA arms


@dataclass(frozen=True, slots=True)
class Capsule:
    """A collision capsule rigidly attached to a joint's frame.

    Attributes:
        name: role, e.g. ``"forearm"``.
        joint: Pinocchio joint index the capsule moves with (0 = the arm's base).
        radius: [m].
        length: segment length between the two cap centres [m].
        placement: (4, 4) pose of the capsule centre in the joint frame; the segment lies along
            its local z axis.
    """

    name: str
    joint: int
    radius: float
    length: float
    placement: FloatArray

    def segment(self, T_world_joint: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The capsule's segment end points in the frame that ``T_world_joint`` maps to [m]."""
        M = T_world_joint @ self.placement
        half = 0.5 * self.length * M[:3, 2]
        return M[:3, 3] - half, M[:3, 3] + half


def example_robot_data_dir() -> Path:
    """Directory holding example-robot-data's ``robots/`` (installed by the package's wheel).

    Raises:
        RobotError: example-robot-data is not installed.
    """
    import importlib.metadata as md

    try:
        dist = md.distribution("example-robot-data")
    except md.PackageNotFoundError as exc:  # pragma: no cover - it is a hard dependency
        raise RobotError("example-robot-data is not installed (pip install example-robot-data)") from exc
    for f in dist.files or []:
        parts = Path(str(f)).parts
        if "robots" in parts and parts[-1].endswith(".urdf"):
            root = Path(str(dist.locate_file(f)))
            while root.name != "robots":
                root = root.parent
            return root
    raise RobotError("example-robot-data is installed but its robots/ directory was not found")


def _puma_urdf_path() -> Path:
    return Path(str(resources.files("dualpuma.kinematics") / "data" / "puma560.urdf"))


def _capsules_from_urdf(model: pin.Model, urdf: Path) -> list[Capsule]:
    """Read every <collision> cylinder as a capsule (the project's URDF convention)."""
    root = ET.parse(urdf).getroot()
    # link -> joint index: the joint whose child is that link (fixed links map to their parent joint)
    frame_joint = {f.name: f.parentJoint for f in model.frames}
    caps: list[Capsule] = []
    for link in root.findall("link"):
        lname = link.get("name", "")
        if lname not in frame_joint:
            continue
        j = frame_joint[lname]
        fid = model.getFrameId(lname)
        M_joint_link = model.frames[fid].placement.homogeneous
        for col in link.findall("collision"):
            cyl = col.find("geometry/cylinder")
            if cyl is None:
                continue
            o = col.find("origin")
            xyz = [float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]
            rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
            M = np.eye(4)
            M[:3, :3] = pin.rpy.rpyToMatrix(*rpy)
            M[:3, 3] = xyz
            P = M_joint_link @ M
            P.setflags(write=False)
            caps.append(
                Capsule(
                    name=col.get("name") or f"{lname}_{len(caps)}",
                    joint=int(j),
                    radius=float(cyl.get("radius")),
                    length=float(cyl.get("length")),
                    placement=P,
                )
            )
    return caps


def _capsules_between_joints(model: pin.Model, tip_frame: int) -> list[Capsule]:
    """Generic capsules: from each joint origin to the next one (and to the hand frame)."""
    caps: list[Capsule] = []
    chain = list(range(1, model.njoints))
    for k, j in enumerate(chain):
        if k + 1 < len(chain):
            p1 = model.jointPlacements[chain[k + 1]].translation
        else:
            p1 = model.frames[tip_frame].placement.translation
        length = float(np.linalg.norm(p1))
        if length < 1e-6:
            continue
        z = p1 / length
        x = np.cross(z, [1.0, 0.0, 0.0])
        if np.linalg.norm(x) < 1e-6:
            x = np.cross(z, [0.0, 1.0, 0.0])
        x /= np.linalg.norm(x)
        P = np.eye(4)
        P[:3, :3] = np.column_stack([x, np.cross(z, x), z])
        P[:3, 3] = 0.5 * p1
        P.setflags(write=False)
        caps.append(Capsule(f"{model.names[j]}", j, _GENERIC_CAPSULE_RADIUS, length, P))
    return caps


class Arm:
    """A 6-DOF serial arm: Pinocchio model, hand frame, joint limits, capsules and IK.

    Build with :meth:`puma560` or :meth:`load`. The model is read-only; the ``pin.Data`` that FK
    writes into is kept per thread (:attr:`data` is the calling thread's), so an Arm may be used
    from several threads.
    """

    def __init__(
        self,
        robot: str,
        model: pin.Model,
        hand_frame: str,
        capsules: list[Capsule],
        urdf_path: Path,
        *,
        analytic: bool,
    ) -> None:
        if model.nq != 6 or model.nv != 6:
            raise RobotError(f"{robot}: expected a 6-DOF serial arm, model has nq={model.nq}, nv={model.nv}")
        self.robot = robot
        self.model = model
        self._local = threading.local()
        self.urdf_path = urdf_path
        self.hand_frame = hand_frame
        self.hand_frame_id = model.getFrameId(hand_frame)
        if self.hand_frame_id >= model.nframes:
            raise RobotError(f"{robot}: hand frame {hand_frame!r} not in the model")
        self.capsules: tuple[Capsule, ...] = tuple(capsules)
        lim = np.column_stack([model.lowerPositionLimit, model.upperPositionLimit]).astype(float)
        lim.setflags(write=False)
        self.limits: FloatArray = lim
        self.analytic = analytic

    @property
    def data(self) -> pin.Data:
        """The calling thread's Pinocchio data of :attr:`model`."""
        try:
            return self._local.data
        except AttributeError:
            self._local.data = self.model.createData()
            return self._local.data

    # ------------------------------------------------------------------ constructors
    @classmethod
    def puma560(cls) -> Arm:
        """The seed's PUMA 560 (urdf/puma560.urdf, shipped as package data); hand = ``wrist``."""
        return _load_cached("puma560").copy()

    @classmethod
    def load(cls, robot: str) -> Arm:
        """Load a known robot by name: ``"puma560"`` or an example-robot-data arm (``"ur5"``...).

        Raises:
            RobotError: unknown name (the message lists the known ones).
        """
        if not isinstance(robot, str) or robot not in KNOWN_ROBOTS:
            raise RobotError(f"unknown robot {robot!r}; known robots: {', '.join(KNOWN_ROBOTS)}")
        return _load_cached(robot).copy()

    def copy(self) -> Arm:
        """A new Arm sharing the (read-only) model and capsules."""
        return Arm(self.robot, self.model, self.hand_frame, list(self.capsules), self.urdf_path,
                   analytic=self.analytic)

    def __repr__(self) -> str:
        kind = "analytic" if self.analytic else "numeric"
        return f"Arm({self.robot!r}, hand={self.hand_frame!r}, ik={kind})"

    # ------------------------------------------------------------------ kinematics
    def frame_id(self, frame: str | None) -> int:
        """Pinocchio frame index of ``frame`` (default: the hand frame).

        Raises:
            RobotError: unknown frame name.
        """
        if frame is None:
            return self.hand_frame_id
        if not isinstance(frame, str):
            raise RobotError(f"frame: expected a frame name (str) or None, got {type(frame).__name__}")
        fid = self.model.getFrameId(frame)
        if fid >= self.model.nframes:
            names = [f.name for f in self.model.frames]
            raise RobotError(f"{self.robot}: unknown frame {frame!r}; frames: {names}")
        return fid

    def fk(self, q: npt.ArrayLike, frame: str | None = None) -> FloatArray:
        """Pose of ``frame`` (default the hand) in the arm's base frame.

        Args:
            q: joints [rad], shape (6,) or (N, 6).
            frame: frame name, e.g. ``"wrist"``, ``"flange"``, ``"gripper"``, ``"link3"``.

        Returns:
            (4, 4) or (N, 4, 4) homogeneous transforms [m].

        Raises:
            JointError: malformed ``q``. RobotError: unknown frame.
        """
        qa = validate_joints(q)
        fid = self.frame_id(frame)
        if qa.ndim == 1:
            data = self.data
            pin.forwardKinematics(self.model, data, qa)
            return pin.updateFramePlacement(self.model, data, fid).homogeneous
        flat = qa.reshape(-1, 6)
        out = np.empty((flat.shape[0], 4, 4))
        model, data = self.model, self.data
        for i, qi in enumerate(flat):
            pin.forwardKinematics(model, data, qi)
            out[i] = pin.updateFramePlacement(model, data, fid).homogeneous
        return out.reshape(qa.shape[:-1] + (4, 4))

    def jacobian(self, q: npt.ArrayLike, frame: str | None = None, *, reference: str = "world_aligned") -> FloatArray:
        """6x6 geometric Jacobian (rows: linear then angular velocity).

        Args:
            q: joints [rad], shape (6,).
            frame: frame name (default the hand).
            reference: ``"world_aligned"`` (origin at the frame, axes of the base frame) or
                ``"local"`` (the frame's own axes).

        Raises:
            JointError, RobotError, ParameterError (unknown ``reference``).
        """
        qa = validate_joints(q)
        if qa.shape != (6,):
            raise JointError(f"q: jacobian takes shape (6,), got {qa.shape}")
        choice(reference, ("world_aligned", "local"), "reference")
        rf = {"world_aligned": pin.LOCAL_WORLD_ALIGNED, "local": pin.LOCAL}[reference]
        return pin.computeFrameJacobian(self.model, self.data, qa, self.frame_id(frame), rf)

    def manipulability(self, q: npt.ArrayLike, frame: str | None = None) -> float:
        """Yoshikawa manipulability sqrt(det(J J^T)) of the world-aligned hand Jacobian.

        For a square 6x6 J this equals |det J|, computed that way (no squaring of round-off).
        """
        return float(abs(np.linalg.det(self.jacobian(q, frame))))

    def within_limits(self, q: npt.ArrayLike, tol: float = 1e-9) -> npt.NDArray[np.bool_]:
        """True where every joint of ``q`` (shape (..., 6)) lies inside the limits (+- tol [rad]).

        Raises:
            JointError: malformed ``q``. ParameterError: ``tol`` not a finite number in [0, pi].
        """
        tol = real(tol, "tol", lo=0.0, hi=np.pi, unit="rad")
        qa = validate_joints(q)
        return np.all((qa >= self.limits[:, 0] - tol) & (qa <= self.limits[:, 1] + tol), axis=-1)

    # ------------------------------------------------------------------ inverse kinematics
    def ik(
        self,
        T_base_hand: npt.ArrayLike,
        *,
        config: int | tuple | None = None,
        q_near: npt.ArrayLike | None = None,
    ) -> IKResult:
        """IK of the hand frame: closed form for the PUMA, damped least squares otherwise.

        Args:
            T_base_hand: target (4, 4) [m].
            config: PUMA only: branch index or the seed's chars triple (see :func:`puma.ik`).
            q_near: previous joints [rad]; nearest solution / seed of the numeric IK.

        Returns:
            :class:`~dualpuma.puma.IKResult` (status ``ok``, ``unreachable``, ``joint_limits``).
        """
        if self.analytic:
            return puma.ik(T_base_hand, config=config, q_near=q_near, limits=self.limits)
        if config is not None:
            raise ParameterError(f"config: branch selection exists only for the analytic PUMA IK, not {self.robot}")
        T = validate_pose(T_base_hand, name="T_base_hand")
        if T.shape != (4, 4):
            raise ParameterError(f"T_base_hand: expected one pose (4, 4), got {T.shape}")
        qn = None if q_near is None else validate_joints(q_near, name="q_near")
        if qn is not None and qn.shape != (6,):
            raise JointError(f"q_near: expected shape (6,), got {qn.shape}")
        return solve_dls(self.model, self.data, self.hand_frame_id, T, qn, self.limits)

    def ik_all(self, T_base_hand: npt.ArrayLike, *, q_near: npt.ArrayLike | None = None):
        """All 8 PUMA branches ``(solutions (..., 8, 6), valid (..., 8))``; PUMA only.

        Raises:
            RobotError: the arm has no closed-form IK.
        """
        if not self.analytic:
            raise RobotError(f"{self.robot} has no closed-form IK; use Arm.ik (numeric)")
        return puma.ik_all(T_base_hand, q_near=q_near, limits=self.limits)


@cache
def _load_cached(robot: str) -> Arm:
    if robot == "puma560":
        path = _puma_urdf_path()
        model = pin.buildModelFromUrdf(str(path))
        return Arm("puma560", model, "wrist", _capsules_from_urdf(model, path), path, analytic=True)
    rel, hand = _ERD_ROBOTS[robot]
    root = example_robot_data_dir()
    path = root / rel
    model = pin.buildModelFromUrdf(str(path))
    tip = model.getFrameId(hand)
    return Arm(robot, model, hand, _capsules_between_joints(model, tip), path, analytic=False)
