"""IK providers: what an arm's inverse kinematics offers to the rest of dualpuma.

Every :class:`~dualpuma.kinematics.arm.Arm` has one, chosen by the arm:

* :class:`PumaIK` — the PUMA 560's closed form (:mod:`.puma`);
* :class:`URIK` — the UR family's closed form (:mod:`.ur`), parameters read from the arm's model;
* :class:`NumericIK` — damped least squares (:mod:`.numeric`) for any other 6-DOF arm.

A **closed-form** provider (``closed_form = True``) has eight branches, index ``4 s + 2 e + w``
(shoulder, elbow, wrist; the wrist bit is the sign of q5, and ``b ^ 1`` is the wrist partner that
a path through q5 = 0 continues on) and offers, on trusted input:

* ``ik_all(T, q_near, limits)`` — all branches of one pose (4, 4) or a batch (N, 4, 4):
  ``(solutions (..., 8, 6), valid (..., 8))``, unreachable rows NaN, angles wrapped into the limits
  nearest to ``q_near``;
* ``ik_branch(T, branch, q_ref, limits)`` — one branch per pose (M, 4, 4), raw angles (not
  wrapped), reachability and |sin q5| (the paths' fast path);
* ``branch_of(q)`` — the branch of one joint vector; ``branches(Q)`` of many (K, 6) at once.

A **numeric** provider has no branches: ``solve(T, q_near, limits, data)`` returns an
:class:`~dualpuma.kinematics.ik.IKResult` whose solution is the one nearest ``q_near`` it finds
(branch continuity by seeding). ``ik(T, config, q_near, limits)`` exists on all three.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import JointError, ParameterError
from . import puma, ur
from .ik import IKResult, select_branch
from .numeric import DLSSolver

__all__ = ["URIK", "NumericIK", "PumaIK", "wrist_partner"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


def _branch_index(config) -> int | None:
    if config is None:
        return None
    if isinstance(config, (int, np.integer)) and not isinstance(config, bool):
        if not 0 <= int(config) <= 7:
            raise JointError(f"config: branch index must be 0..7, got {config}")
        return int(config)
    if isinstance(config, (tuple, list)) and len(config) == 3:
        return puma.config_to_branch(*config)
    raise JointError(f"config: expected a branch index 0..7 or (shoulder, elbow, wrist), got {config!r}")


_RHO3 = float(np.hypot(puma.A3, puma.D4))  # |elbow -> wrist centre| [m]
_W_OFF = puma.D2**2 + puma.A2**2 + _RHO3**2


class PumaIK:
    """The PUMA 560's closed form (see :mod:`.puma`).

    Attributes:
        reach_shell: (r_min, r_max) [m]: the wrist centre (the hand frame's origin) of any reachable
            pose is this far from the shoulder (with 1e-9 m^2 slack): a necessary condition.
    """

    name = "puma560 closed form"
    closed_form = True
    singular_joint = 3  # where |sin q5| ~ 0, q4 comes from the reference joints
    reach_shell = (float(np.sqrt(_W_OFF - 2.0 * puma.A2 * _RHO3 - 1e-9)),
                   float(np.sqrt(_W_OFF + 2.0 * puma.A2 * _RHO3 + 1e-9)))

    def ik_all(self, T: FloatArray, q_near: FloatArray, limits: FloatArray) -> tuple[FloatArray, BoolArray]:
        return puma.ik_all_unchecked(T, q_near, limits)  # trusted input (module docstring)

    def ik_branch(self, T: FloatArray, branch: npt.NDArray[np.int64], q_ref: FloatArray,
                  limits: FloatArray) -> tuple[FloatArray, BoolArray, FloatArray]:
        s_sh = np.where(branch & 4, -1.0, 1.0)
        s_el = np.where(branch & 2, -1.0, 1.0)
        q4_ref = np.minimum(np.maximum(q_ref[:, 3], limits[3, 0]), limits[3, 1])  # (np.clip costs more)
        return puma.ik_branch(T, s_sh, s_el, (branch & 1).astype(bool), q4_ref)

    def branch_of(self, q: FloatArray) -> int:
        sh, el, flip = puma.branch_signs(q)
        return 4 * (sh < 0) + 2 * (el < 0) + int(flip)

    def branches(self, Q: FloatArray) -> npt.NDArray[np.int64]:
        return puma.branches(Q)

    def ik(self, T: FloatArray, config, q_near: FloatArray | None, limits: FloatArray) -> IKResult:
        return puma.ik(T, config=config, q_near=q_near, limits=limits)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, PumaIK)

    def __hash__(self) -> int:
        return hash(PumaIK)


class URIK:
    """The UR family's closed form (see :mod:`.ur`) for one arm's geometry.

    Raises:
        RobotError: the model is not UR-like (:func:`.ur.geometry_from_model`).
    """

    closed_form = True
    singular_joint = 5  # where |sin q5| ~ 0, q6 comes from the reference joints

    def __init__(self, model: pin.Model, hand_frame_id: int) -> None:
        self.geometry = ur.geometry_from_model(model, hand_frame_id)
        g = self.geometry
        self.name = f"UR closed form (d1={g.d1:.4f}, a2={g.a2:.4f}, a3={g.a3:.4f} m)"

    def ik_all(self, T: FloatArray, q_near: FloatArray, limits: FloatArray) -> tuple[FloatArray, BoolArray]:
        return ur.ik_all(self.geometry, T, q_near, limits)

    def ik_branch(self, T: FloatArray, branch: npt.NDArray[np.int64], q_ref: FloatArray,
                  limits: FloatArray) -> tuple[FloatArray, BoolArray, FloatArray]:
        return ur.ik_branch(self.geometry, T, branch, q_ref)

    def branch_of(self, q: FloatArray) -> int:
        return ur.branch_of(self.geometry, q)

    def branches(self, Q: FloatArray) -> npt.NDArray[np.int64]:
        return ur.branches(self.geometry, Q)

    def ik(self, T: FloatArray, config, q_near: FloatArray | None, limits: FloatArray) -> IKResult:
        ref = np.zeros(6) if q_near is None else q_near
        sols, valid = ur.ik_all(self.geometry, T, ref, limits)
        return select_branch(sols, valid, _branch_index(config), q_near, limits, "the hand")

    def __eq__(self, other: object) -> bool:
        return isinstance(other, URIK) and self.geometry == other.geometry

    def __hash__(self) -> int:
        g = self.geometry
        return hash((URIK, g.d1, g.a2, g.a3, g.d4, g.d5, g.d6))


class NumericIK:
    """Damped least squares for any 6-DOF arm (see :mod:`.numeric`); no branches."""

    closed_form = False
    name = "numeric (damped least squares)"

    def __init__(self, model: pin.Model, frame_id: int, limits: FloatArray) -> None:
        self.solver = DLSSolver(model, frame_id, limits)

    def solve(self, T: FloatArray, q_near: FloatArray | None, limits: FloatArray, data: pin.Data) -> IKResult:
        return self.solver.solve(data, T, q_near, limits)

    def ik(self, T: FloatArray, config, q_near: FloatArray | None, limits: FloatArray, data: pin.Data) -> IKResult:
        if config is not None:
            raise ParameterError("config: branch selection exists only for arms with a closed-form IK")
        return self.solve(T, q_near, limits, data)


def wrist_partner(branch: int) -> int:
    """The branch a path continues on through the wrist singularity (wrist bit toggled)."""
    return branch ^ 1

