"""The arms holding the bar along its path between two poses: the SE(3) geodesic (translation
linear, rotation along the shortest arc) that both a planner's steps and a timed trajectory follow.

* :func:`follow_geodesic` solves both arms at equal steps along it, continuing their IK branches
  (what :func:`~dualpuma.planning.timing.time_plan` samples);
* :func:`first_unfollowed` finds the planner's steps the closed chain does not follow between their
  checked poses (a false wrist crossing, a joint beyond its limit on the way);
* :func:`hold_bar` solves both arms at many poses at once, each continuing its own nearby joints
  (the bisection of :mod:`dualpuma.planning.certify` along the bar's path).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ..lie import slerp
from .continuity import continue_poses
from .dual import SIDES, closed_arms, solve_path_unchecked

__all__ = ["FOLLOW_MATCH", "FOLLOW_SAMPLES", "LIMIT_EXCURSION", "LIMIT_NEAR", "WRIST_SWING", "first_unfollowed",
           "follow_geodesic", "follow_geodesic_why", "hold_bar"]

FloatArray = npt.NDArray[np.float64]
FOLLOW_SAMPLES = 128  #: poses per step at which a wrist crossing is followed (:func:`first_unfollowed`)
FOLLOW_MATCH = 1e-6  #: a dense continuation ends at given joints when within this of them [rad]
#: why a step refused by :func:`first_unfollowed` is refused
WRIST_SWING = ("the bar passes near a wrist singularity (q5 = 0): holding it, the wrist would swing q4 and q6 by "
               "about 180 deg within one step")
#: why a step refused by :func:`first_unfollowed` for a joint limit is refused
LIMIT_EXCURSION = ("between the checked poses the bar's path takes a joint beyond its limit (the arms hold the bar "
                   "within the limits at the step's ends but not along the way)")
LIMIT_NEAR = math.radians(0.25)  #: a step with a joint this close to a limit is followed densely [rad]


def follow_geodesic(world, A: FloatArray, B: FloatArray, q_a: FloatArray, n: int, max_step: float,
                    q_b: FloatArray | None = None) -> FloatArray | None:
    """Both arms' joints (n, 12) (left then right) at ``n`` equal steps along the bar's geodesic
    A -> B (translation linear, rotation along the shortest arc; the last pose is B), continued
    from ``q_a`` (12,) at A by IK on their branches (:func:`~.dual.solve_path_unchecked`), or None where
    some pose has no continuation within ``max_step`` [rad]. With ``q_b`` (12,) also None unless
    the continuation ends at ``q_b`` (within :data:`FOLLOW_MATCH`; the last row is then ``q_b``
    exactly). Trusted input."""
    return follow_geodesic_why(world, A, B, q_a, n, max_step, q_b)[0]


def follow_geodesic_why(world, A: FloatArray, B: FloatArray, q_a: FloatArray, n: int, max_step: float,
                        q_b: FloatArray | None = None) -> tuple[FloatArray | None, str]:
    """:func:`follow_geodesic`, and why it gives None ("" when it does not): :data:`LIMIT_EXCURSION`,
    :data:`WRIST_SWING` (the continuation does not end at ``q_b``) or the continuation's own reason."""
    sol = solve_path_unchecked(world, slerp(A, B, np.arange(1, n + 1) / n), (q_a[:6], q_a[6:]), max_step)
    if sol.n_ok < n:
        return None, (LIMIT_EXCURSION if "joint_limits" in sol.status
                      else f"between the checked poses the arms cannot hold the bar: {sol.reason}")
    Q = np.hstack([sol.q_left, sol.q_right])
    if q_b is not None:
        if np.abs(Q[-1] - q_b).max() > FOLLOW_MATCH:
            return None, WRIST_SWING
        Q[-1] = q_b
    return Q, ""


def first_unfollowed(world, P: FloatArray, q_left: FloatArray, q_right: FloatArray, q0: FloatArray,
                     A: FloatArray | None, sub: int, m: int, n: int = FOLLOW_SAMPLES) -> tuple[int, str]:
    """How many of the first ``m`` steps of a run the closed chain follows along the bar's path
    between its checked poses, and why the next one is not: ``(m, "")`` unless some step is a false
    wrist crossing or leaves the joint limits between checked poses.

    The run starts at pose ``A`` (None: the pose the left hand's joints in ``q0`` hold) with joints
    ``q0`` (12,: left then right); P (>= m * sub, 4, 4) are its poses and ``q_left``, ``q_right``
    (>= m * sub, 6) the arms' joints there, step k ending at row ``(k + 1) * sub - 1``. Two kinds
    of step are followed densely:

    * **Wrist crossings.** Where an arm's IK was continued at these poses through sin q5 = 0 onto a
      wrist partner (an arm with a closed form; see
      :func:`~dualpuma.kinematics.continuity.wrist_tracks`), the bar's path may only pass *near*
      the singularity: finer poses then follow the branch around it, q4 and q6 swinging by about
      pi, and the step's small joint change does not hold the bar between its ends
      (:data:`WRIST_SWING`).
    * **Joints near a limit.** Where a joint is within :data:`LIMIT_NEAR` of a limit at the step's
      start or at one of its poses, the bar's path between them may take it beyond the limit and
      back (:data:`LIMIT_EXCURSION`; a random problem's elbow reached 45.02 deg between poses at
      44.98 and 45.00 deg, its limit 45 deg).

    Such a step is followed when both arms' IK continued along the geodesic from its start in ``n``
    equal poses (:func:`follow_geodesic`, the path a timed trajectory follows) stays within the
    limits and ends at its end joints. Returns the index of the first step that is not (``m`` if
    none) and why."""
    if m <= 0:
        return 0, ""
    f = m * sub
    marked = np.zeros(m, dtype=bool)
    for k, (s, q) in enumerate(zip(SIDES, (q_left, q_right))):
        arm = world.arms[s]
        ext = np.vstack([q0[6 * k : 6 * k + 6][None], q[:f]])  # the run's start, then its poses
        lo, hi = arm.limits[:, 0], arm.limits[:, 1]
        near = np.flatnonzero(((ext - lo < LIMIT_NEAR) | (hi - ext < LIMIT_NEAR)).any(axis=1))
        if near.size:  # row r (r >= 1) is a pose of step (r - 1) // sub and, at r % sub == 0, starts step r // sub
            marked[(near[near >= 1] - 1) // sub] = True
            starts = near[near % sub == 0] // sub
            marked[starts[starts < m]] = True
        if not arm.analytic:
            continue
        neg0 = math.sin(q0[4 + 6 * k]) < 0.0
        neg = np.sin(q[:f, 4]) < 0.0
        if neg.all() if neg0 else not neg.any():  # the usual case: q5 keeps its sign
            continue
        c = np.concatenate([[neg0], neg])
        marked[np.flatnonzero(c[1:] != c[:-1]) // sub] = True
    if not marked.any():
        return m, ""
    Q = np.hstack([q_left[:f], q_right[:f]])
    for k in np.flatnonzero(marked).tolist():
        qa = q0 if k == 0 else Q[k * sub - 1]
        Ta = (world.object_from_left(q0[:6]) if A is None else A) if k == 0 else P[k * sub - 1]
        end = (k + 1) * sub - 1
        D, why = follow_geodesic_why(world, Ta, P[end], qa, n, 2.0 * math.pi, Q[end])
        if D is None:
            return k, why
    return m, ""


def hold_bar(world, P: FloatArray, Q_near: FloatArray) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Both arms' joints (K, 12) (left then right) holding the bar at poses P (K, 4, 4), each pose
    continuing the joints ``Q_near[k]`` (12,): on their IK branches, the wrist's partner where the
    wrist is near q5 = 0 and the partner is the nearer, unwrapped to ``Q_near``
    (:func:`~.continuity.continue_poses`; an arm without a closed form: its IK seeded with ``Q_near``). Returns
    ``(Q, ok)``: ok where both arms reach the pose within their joint limits. Trusted input; one
    vectorised IK call per closed-form arm.

    The point of a path between two nearby configurations on it: :mod:`dualpuma.planning.certify`
    bisects the bar's path between checked poses with it."""
    K = P.shape[0]
    Q = np.empty((K, 12))
    ok = np.ones(K, dtype=bool)
    closed, solvers, limits, base_inv, grasp = closed_arms(world)
    if closed:
        qn = np.stack([Q_near[:, 6 * a : 6 * a + 6] for a in closed])
        q, held = continue_poses(solvers, base_inv @ P[None] @ grasp, qn, limits)
        for i, a in enumerate(closed):
            Q[:, 6 * a : 6 * a + 6], ok = q[i], ok & held[i]
    for a, s in enumerate(SIDES):
        if a in closed:
            continue
        arm, cols = world.arms[s], slice(6 * a, 6 * a + 6)
        T_bh = world.T_base_inv[s] @ P @ world.T_object_hand[s]
        for i in range(K):
            r = arm.ik(T_bh[i], q_near=Q_near[i, cols])
            Q[i, cols], ok[i] = (r.q, ok[i] and r.ok) if r.q is not None else (Q_near[i, cols], False)
    return Q, ok
