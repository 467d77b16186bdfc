"""`Arm`: a 6-DOF serial arm loaded from URDF into Pinocchio (FK, Jacobians, IK, capsules).

Arms come by name (:data:`KNOWN_ROBOTS`: the seed's PUMA 560, shipped with the package, and the
example-robot-data UR arms) or from any URDF file (:class:`RobotSpec`: the file and its hand
frame). The arm chooses its IK provider (:mod:`.providers`): the PUMA's closed form, the UR
family's closed form (parameters read from the model; any URDF whose kinematics fit the UR table
gets it), or damped least squares for anything else. Its collision capsules come from the URDF
(:mod:`.capsules`): the PUMA's cylinder-as-capsule convention, capsules fitted around any other
URDF's collision geometry, or joint-to-joint capsules when it has none.
"""

from __future__ import annotations

import hashlib
import math
import os
import threading
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..checks import choice, real, validate_joints, validate_pose
from ..errors import JointError, PoseError, RobotError
from .capsules import Capsule, between_joints, from_collision_geometry, from_cylinders
from .ik import QUIET_FAR_OUT, IKResult, IKStatus
from .limits import LIMIT_TOL
from .providers import URIK, NumericIK, PumaIK
from .urdf import example_robot_data_dir, frame_index, package_dirs, read_arm

__all__ = ["KNOWN_ROBOTS", "Arm", "Capsule", "RobotSpec"]

FloatArray = npt.NDArray[np.float64]

#: robot name -> (URDF path under example-robot-data's robots/, hand frame)
_ERD_ROBOTS: dict[str, tuple[str, str]] = {
    f"{ur}{variant}": (f"ur_description/urdf/{ur}{'_joint_limited' if variant else ''}_robot.urdf", "tool0")
    for ur in ("ur3", "ur5", "ur10")
    for variant in ("", "_joint_limited")
} | {
    "z1": ("z1_description/urdf/z1.urdf", "gripperStator"),  # Unitree Z1; its gripper joint is locked
    "kinova": ("kinova_description/robots/kinova.urdf", "j2s6s200_end_effector"),  # Kinova Jaco2 6-DOF
}
#: every robot known by name (cells: ``robot = "ur5"``)
KNOWN_ROBOTS: tuple[str, ...] = ("puma560", *_ERD_ROBOTS)


@dataclass(frozen=True, slots=True)
class RobotSpec:
    """An arm from a URDF file: ``robot = { urdf = "path/arm.urdf", tip = "tool0" }`` in a cell.

    Attributes:
        urdf: the URDF file (resolved to an absolute path).
        tip: the hand frame's name in the URDF (grasps are given in this frame).
    """

    urdf: Path
    tip: str

    def __post_init__(self) -> None:
        if not isinstance(self.tip, str) or not self.tip:
            raise RobotError(f"tip: expected a frame name, got {self.tip!r}")
        try:
            path = Path(os.fspath(self.urdf)).expanduser().resolve()
            is_file = path.is_file()
        except TypeError:
            raise RobotError(f"urdf: expected a file path, got {type(self.urdf).__name__}") from None
        except (OSError, ValueError, RuntimeError) as exc:  # too long, NUL, a symlink loop
            raise RobotError(f"urdf: not a usable path: {exc}"[:300]) from None
        if not is_file:
            raise RobotError(f"urdf: {path} is not a file")
        object.__setattr__(self, "urdf", path)

    @property
    def name(self) -> str:
        """A display name: the URDF file's stem."""
        return self.urdf.stem


def _puma_urdf_path() -> Path:
    return Path(str(resources.files("dualpuma.kinematics") / "data" / "puma560.urdf"))


class Arm:
    """A 6-DOF serial arm: Pinocchio model, hand frame, joint limits, capsules and IK.

    Build with :meth:`puma560`, :meth:`load` (a name or a :class:`RobotSpec`) or
    :meth:`from_urdf`. The model is read-only; the ``pin.Data`` that FK writes into is kept per
    thread (:attr:`data` is the calling thread's), so an Arm may be used from several threads.

    Attributes:
        robot: the display name (``"puma560"``, ``"ur5"``, a URDF's stem).
        solver: the IK provider (:mod:`.providers`); ``analytic`` tells whether it is a closed form.
        capsules: collision capsules in joint frames; ``capsule_source`` says where they came from.
        package_dirs: where ``package://`` URIs of the URDF resolve (for meshes).
    """

    def __init__(
        self,
        robot: str,
        model: pin.Model,
        hand_frame: str,
        capsules: list[Capsule],
        urdf_path: Path,
        *,
        solver: object,
        capsule_source: str = "urdf",
        locked_joints: dict[str, float] | None = None,
    ) -> None:
        if model.nq != 6 or model.nv != 6:
            raise RobotError(f"{robot}: expected a 6-DOF serial arm, model has nq={model.nq}, nv={model.nv}")
        self.robot = robot
        self.model = model
        self._local = threading.local()
        self.urdf_path = urdf_path
        self.hand_frame = hand_frame
        self.hand_frame_id = frame_index(model, hand_frame)
        if self.hand_frame_id >= model.nframes:
            raise RobotError(f"{robot}: hand frame {hand_frame!r} not in the model")
        self.capsules: tuple[Capsule, ...] = tuple(capsules)
        lim = np.column_stack([model.lowerPositionLimit, model.upperPositionLimit]).astype(float)
        lim.setflags(write=False)
        self.limits: FloatArray = lim
        self.solver = solver
        self.analytic = bool(getattr(solver, "closed_form", False))
        self.capsule_source = capsule_source
        #: URDF joints outside the six (a gripper's, a finger's) and the value they are locked at [rad or m]
        self.locked_joints: dict[str, float] = dict(locked_joints or {})
        self.package_dirs = package_dirs(Path(urdf_path))
        reach = sum(float(np.linalg.norm(model.jointPlacements[j].translation)) for j in range(1, model.njoints))
        reach += float(np.linalg.norm(model.frames[self.hand_frame_id].placement.translation))
        #: (r_min, r_max) [m]: the hand frame's origin is this far from the base origin (necessary)
        self.reach_shell: tuple[float, float] = getattr(solver, "reach_shell", (0.0, reach + 1e-9))
        #: the shoulder (3,) in the base frame [m]: the point of joint 1's axis nearest joint 2's
        #: origin (the PUMA 560: the base origin; a UR5: 89 mm above it), whatever joint 1's angle
        self.shoulder: FloatArray = _shoulder(model)

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
    def load(cls, robot: str | RobotSpec) -> Arm:
        """Load a robot by name (``"puma560"``, an example-robot-data arm: ``"ur5"``...) or from a
        :class:`RobotSpec` (any 6-DOF URDF and its hand frame).

        Raises:
            RobotError: unknown name (the message lists the known ones), or a URDF that is not a
                6-DOF serial arm or lacks the hand frame.
        """
        if isinstance(robot, RobotSpec):
            return _load_urdf(str(robot.urdf), robot.tip).copy()
        if not isinstance(robot, str) or robot not in KNOWN_ROBOTS:
            raise RobotError(f"unknown robot {robot!r}; known robots: {', '.join(KNOWN_ROBOTS)}")
        return _load_cached(robot).copy()

    @classmethod
    def from_urdf(cls, urdf: str | os.PathLike, tip: str) -> Arm:
        """Load a 6-DOF arm from a URDF file; ``tip`` is its hand frame.

        Raises:
            RobotError: missing file, not a 6-DOF serial arm, unknown tip frame.
        """
        return cls.load(RobotSpec(urdf, tip))

    def copy(self) -> Arm:
        """A new Arm sharing the (read-only) model, capsules and IK provider (what the constructor
        derived from them is taken over, not derived again; per-thread data and lists are its own)."""
        arm = object.__new__(Arm)
        vars(arm).update(vars(self), _local=threading.local(), locked_joints=dict(self.locked_joints),
                         package_dirs=list(self.package_dirs))
        return arm

    def __repr__(self) -> str:
        return f"Arm({self.robot!r}, hand={self.hand_frame!r}, ik={self.solver.name!r})"

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
        fid = frame_index(self.model, frame)
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

    def within_limits(self, q: npt.ArrayLike, tol: float = LIMIT_TOL) -> npt.NDArray[np.bool_]:
        """True where every joint of ``q`` (shape (..., 6)) lies inside the limits (+- tol [rad]; by
        default :data:`~.limits.LIMIT_TOL`, the tolerance IK and the planners use, so a configuration
        this calls inside is inside for them too).

        Raises:
            JointError: malformed ``q``. ParameterError: ``tol`` not a finite number in [0, pi].
        """
        tol = real(tol, "tol", lo=0.0, hi=np.pi, unit="rad")
        qa = validate_joints(q)
        return np.all((qa >= self.limits[:, 0] - tol) & (qa <= self.limits[:, 1] + tol), axis=-1)

    # ------------------------------------------------------------------ inverse kinematics
    @QUIET_FAR_OUT
    def ik(
        self,
        T_base_hand: npt.ArrayLike,
        *,
        config: int | tuple | None = None,
        q_near: npt.ArrayLike | None = None,
    ) -> IKResult:
        """IK of the hand frame with the arm's provider (closed form, or damped least squares).

        Args:
            T_base_hand: target (4, 4) [m].
            config: closed forms only: a branch index 0..7 or the (shoulder, elbow, wrist) triple
                (see :func:`dualpuma.kinematics.puma.ik`); None: the solution nearest ``q_near``.
            q_near: previous joints [rad]; nearest solution / seed of the numeric IK.

        Returns:
            :class:`~dualpuma.kinematics.ik.IKResult` (``ok``, ``unreachable``, ``joint_limits``; a
            numeric IK also ``not_found``: no solution found, which does not prove there is none).

        Raises:
            PoseError, JointError: malformed input. ParameterError: ``config`` for a numeric arm.
        """
        T = validate_pose(T_base_hand, name="T_base_hand")
        if T.shape != (4, 4):
            batches = "use ik_all for batches" if self.analytic else "solve one pose per call (a numeric arm)"
            raise PoseError(f"T_base_hand: expected one pose of shape (4, 4), got {T.shape}; {batches}")
        qn = None if q_near is None else validate_joints(q_near, name="q_near")
        if qn is not None and qn.shape != (6,):
            raise JointError(f"q_near: expected shape (6,), got {qn.shape}")
        if self.analytic:
            return self.solver.ik(T, config, qn, self.limits)
        dist, hi = math.hypot(*T[:3, 3].tolist()), self.reach_shell[1]  # hypot: no overflow far out
        if not dist <= hi:  # beyond any point the links reach: no iterations (which overflowed far out)
            return IKResult(None, -1, IKStatus.UNREACHABLE,
                            f"the hand frame is {dist:.6g} m from the base, beyond the arm's reach (at most {hi:.3f} m, "
                            "the sum of its link lengths)")
        return self.solver.ik(T, config, qn, self.limits, self.data)

    @QUIET_FAR_OUT
    def ik_all(self, T_base_hand: npt.ArrayLike, *, q_near: npt.ArrayLike | None = None):
        """All eight closed-form branches ``(solutions (..., 8, 6), valid (..., 8))``.

        Raises:
            RobotError: the arm has no closed-form IK. PoseError, JointError: malformed input.
        """
        if not self.analytic:
            raise RobotError(f"{self.robot} has no closed-form IK; use Arm.ik (numeric)")
        T = validate_pose(T_base_hand, name="T_base_hand")
        qn = np.zeros(6) if q_near is None else validate_joints(q_near, name="q_near")
        if T.shape == (4, 4):
            if qn.shape != (6,):
                raise JointError(f"q_near: expected shape (6,) for one pose, got {qn.shape}")
            return self.solver.ik_all(T, qn, self.limits)
        batch = T.shape[:-2]
        try:
            qb = np.broadcast_to(qn, batch + (6,)).reshape(-1, 6)
        except ValueError:
            raise JointError(f"q_near: shape {qn.shape} does not broadcast to {batch + (6,)}") from None
        sols, valid = self.solver.ik_all(T.reshape(-1, 4, 4), qb, self.limits)
        return sols.reshape(batch + (8, 6)), valid.reshape(batch + (8,))

    def branch_of(self, q: npt.ArrayLike) -> int:
        """The closed-form branch (0..7) of one joint vector (6,) [rad].

        Raises:
            RobotError: no closed-form IK. JointError: malformed ``q``.
        """
        if not self.analytic:
            raise RobotError(f"{self.robot} has no closed-form IK, hence no branches")
        qa = validate_joints(q)
        if qa.shape != (6,):
            raise JointError(f"q: expected shape (6,), got {qa.shape}")
        return int(self.solver.branch_of(qa))


def _build(name: str, path: Path, hand: str, *, puma: bool, data: bytes | None = None) -> Arm:
    """A URDF as an Arm (:func:`.urdf.read_arm`): its IK provider and its capsules chosen.
    ``data``: the file's bytes if already read."""
    if puma:
        model = read_arm(path, hand, geometry=False, data=data).model
        return Arm(name, model, hand, from_cylinders(model, path), path, solver=PumaIK(), capsule_source="cylinders")
    read = read_arm(path, hand, data=data)
    model, geom = read.model, read.geometry
    fid = frame_index(model, hand)
    try:
        solver: object = URIK(model, fid)
    except RobotError:
        lim = np.column_stack([model.lowerPositionLimit, model.upperPositionLimit]).astype(float)
        solver = NumericIK(model, fid, lim)
    caps = from_collision_geometry(geom)
    source = "fitted to the collision geometry"
    if not caps:
        caps, source = between_joints(model, fid), "joint to joint (no collision geometry)"
    return Arm(name, model, hand, caps, path, solver=solver, capsule_source=source, locked_joints=read.locked)


@cache
def _load_cached(robot: str) -> Arm:
    """A robot known by name, loaded once per process (its URDF is package data)."""
    if robot == "puma560":
        return _build("puma560", _puma_urdf_path(), "wrist", puma=True)
    rel, hand = _ERD_ROBOTS[robot]
    return _build(robot, example_robot_data_dir() / rel, hand, puma=False)


#: (URDF path, tip) -> (SHA-256 of the file's bytes, the Arm built from them): the latest only
_URDF_ARMS: dict[tuple[str, str], tuple[bytes, Arm]] = {}
_URDF_ARMS_LOCK = threading.Lock()


def _load_urdf(path: str, tip: str) -> Arm:
    """The Arm of a URDF file, cached by the file's content: the file is read (once) and hashed on
    every call (tens of microseconds), and built again only if its bytes changed since the last
    call for this (path, tip), so an edited URDF is never served from an older reading. One entry
    per (path, tip) is kept. Mesh files it refers to are not part of the key.

    Raises:
        RobotError: the file cannot be read, or is not a 6-DOF arm with that hand frame.
    """
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise RobotError(f"{p}: not a readable URDF: {exc}") from None
    digest, key = hashlib.sha256(data).digest(), (path, tip)
    with _URDF_ARMS_LOCK:
        hit = _URDF_ARMS.get(key)
    if hit is not None and hit[0] == digest:
        return hit[1]
    # a URDF arm is never named like a known robot (a file puma560.urdf was timed with the PUMA's limits)
    name = p.stem if p.stem not in KNOWN_ROBOTS else f"{p.stem} from {p.name}"
    arm = _build(name, p, tip, puma=False, data=data)  # outside the lock: two threads may both build
    with _URDF_ARMS_LOCK:
        _URDF_ARMS[key] = (digest, arm)
    return arm


def _shoulder(model: pin.Model) -> FloatArray:
    """The point of joint 1's axis nearest joint 2's origin, in the base frame [m] (read-only)."""
    data = model.createData()
    q0 = pin.neutral(model)
    pin.computeJointJacobians(model, data, q0)
    axis = np.array(data.J[3:, 0], dtype=float)  # joint 1's axis (unit, world = base frame)
    o1, o2 = data.oMi[1].translation, data.oMi[2].translation
    p = o1 + axis * float(axis @ (o2 - o1))
    p.setflags(write=False)
    return p
