"""Validated SE(3) edges of the bar for the RRT-Connect fallback (:mod:`.rrt`).

An edge between two object poses is the SE(3) path "translation linear, rotation along the
shortest arc" (:func:`dualpuma.lie.slerp`), cut into ``n`` output steps no longer than ``step``
[m] and ``rot_step`` [rad], each checked at ``substeps`` sub-poses: both arms' IK continuing the
previous joints (same branches, in the limits, no joint moving more than ``max_joint_step``) and
clearance >= the margin, with dual IK and clearance of the whole edge in batched calls; the motion
between output steps is certified (:mod:`.certify`) for a found path as a whole (the search's own
edges only then, lazily: :func:`~.rrt.rrt_connect`) and for every shortcut (``certify``). An edge taken whole by the search is first
screened on the held bar alone (:mod:`dualpuma.collision.held`: no IK), and refused at once where
the bar is certainly closer than the margin to the fixed geometry.
:class:`EdgeChecker` holds one search's state; :class:`Run` is one edge's verdict.
"""

from __future__ import annotations

import itertools
import math
from collections import Counter
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..collision.batch import min_clearance
from ..collision.held import held_screen
from ..errors import ParameterError
from ..kinematics.bar_path import WRIST_SWING, first_unfollowed
from ..kinematics.dual import solve_path_unchecked
from ..lie import angle, n_steps, slerp
from ..model.world import World
from ..units import below_text
from .certify import between_clearance, certify_chords
from .params import FallbackParams, checked_substeps
from .reach import motion_bounds

__all__ = ["ChordMemo", "EdgeChecker", "Run"]

FloatArray = npt.NDArray[np.float64]

#: the screen refuses a bar bound this far below the margin only [m]: the exact clearance, from the
#: joints (which hold the object pose to IK precision), is then certainly below it too
_SCREEN_TOL = 1e-9


@dataclass
class Run:
    """Validation of a run of output steps: ``m`` leading steps valid (fine arrays cover them)."""

    m: int
    P: FloatArray  # (m*sub, 4, 4) fine poses
    qL: FloatArray
    qR: FloatArray
    d: FloatArray
    pair: npt.NDArray[np.int64]
    reason: str = ""
    why: str = ""  # short category for statistics
    ratio: float = 0.0  # refused for a joint step: that step's joint change / max_joint_step


class ChordMemo:
    """The motions between rows (chords, by their ends) one plan has certified along the bar's path
    (:func:`~.certify.certify_chords`), so that a path verified again as a whole, or a shortcut's
    unchanged rest, is not certified twice. A chord is known by
    the exact bytes of its end configurations, their clearances and (moving obstacles) their times:
    certification is a function of those alone for a given World and margin, so a hit is the same
    proof, never an approximation."""

    def __init__(self) -> None:
        self._for: tuple[World, float] | None = None  # the World and margin of its first user
        self.timed = False
        self._known: set[bytes] = set()

    def bind(self, world: World, margin: float) -> None:
        """Use for this World and margin (only: a proof holds for the World and margin it was made for)."""
        if self._for is None:
            self._for, self.timed = (world, float(margin)), bool(world.moving)
        elif self._for[0] is not world or self._for[1] != float(margin):
            raise ParameterError("certified: a chord memo is shared only by checks of one World and margin")

    def keys(self, V: FloatArray, d: FloatArray, times: FloatArray) -> list[bytes]:
        """The key of each chord of V (n + 1, 12) with clearances d (n + 1,) at times (n + 1,)."""
        rows = np.hstack([V, d[:, None]] + ([times[:, None]] if self.timed else []))
        b = [r.tobytes() for r in np.ascontiguousarray(rows)]
        return [x + y for x, y in itertools.pairwise(b)]

    def __contains__(self, key: bytes) -> bool:
        return key in self._known

    def add(self, keys) -> None:
        """Remember the chords of these keys as certified."""
        self._known.update(keys)


def _arms_why(status: tuple[str, str]) -> str:
    """The category of an IK refusal from both arms' statuses, e.g. "left arm joint_limits"."""
    return " / ".join(f"{s} arm {st}" for s, st in zip(("left", "right"), status) if st != "ok")


def _refused(P: FloatArray, reason: str, why: str, ratio: float = 0.0) -> Run:
    """The run of an edge (fine poses P) with no valid step."""
    return Run(0, P[:0], np.empty((0, 6)), np.empty((0, 6)), np.empty(0), np.zeros(0, dtype=np.int64), reason, why,
               ratio)


def _runs(idx: list[int]) -> list[tuple[int, int]]:
    """Maximal runs [a, b) of consecutive integers in the sorted list idx."""
    out: list[tuple[int, int]] = []
    for c in idx:
        if out and out[-1][1] == c:
            out[-1] = (out[-1][0], c + 1)
        else:
            out.append((c, c + 1))
    return out


class EdgeChecker:
    """One fallback search's edge validation: World, parameters, start pose and times, and a tally
    of why edges were refused (reported when the search fails)."""

    def __init__(
        self, world: World, p: FallbackParams, A: FloatArray, t0: float, step_time: float,
        certified: ChordMemo | None = None,
    ) -> None:
        self.world, self.p, self.A, self.t0, self.dt = world, p, A, t0, step_time
        self.sub = checked_substeps(p.substeps, p.step, p.rot_step)
        self.margin = world.covered(world.cell.safety_margin if p.margin is None else p.margin)
        self.timed = bool(world.moving) and step_time > 0.0
        self.stats: Counter[str] = Counter()
        self.reach, self.v_max = motion_bounds(world)
        self.held = held_screen(world)
        self.certified = ChordMemo() if certified is None else certified
        self.certified.bind(world, self.margin)

    def clear(
        self, qL: FloatArray, qR: FloatArray, times: FloatArray
    ) -> tuple[FloatArray, npt.NDArray[np.int64]]:
        """Batched clearance; the bar rides on the left hand (its pose from the joints, which hold
        the object pose to IK precision), times only matter with moving obstacles."""
        return min_clearance(self.world, np.hstack([qL, qR]), times)

    def n_out(self, A: FloatArray, B: FloatArray) -> int:
        """Output steps of the edge A -> B."""
        return n_steps(float(np.linalg.norm(B[:3, 3] - A[:3, 3])), angle(A[:3, :3], B[:3, :3]), self.p.step,
                       self.p.rot_step)

    def metric(self, A: FloatArray, B: FloatArray) -> float:
        """The search's SE(3) distance |dp| + rot_weight * angle [m]."""
        return float(np.linalg.norm(B[:3, 3] - A[:3, 3])) + self.p.rot_weight * angle(A[:3, :3], B[:3, :3])

    def t_lb(self, P: FloatArray) -> FloatArray:
        """Earliest possible time of poses P (K, 4, 4): straight output steps from the start pose."""
        if not self.timed:
            return np.full(P.shape[0], self.t0)
        d = np.linalg.norm(P[:, :3, 3] - self.A[:3, 3], axis=1)
        c = np.clip((np.einsum("ij,kij->k", self.A[:3, :3], P[:, :3, :3]) - 1.0) / 2.0, -1.0, 1.0)
        n = np.maximum(
            np.ceil(d / self.p.step - 1e-9), np.ceil(np.arccos(c) / self.p.rot_step - 1e-9)
        )
        return self.t0 + n * self.dt

    def validate(self, P: FloatArray, q0: tuple[FloatArray, FloatArray], times: FloatArray,
                 start: tuple[float, float] | None = None, certify: bool = True, whole: bool = False,
                 finer: bool = False, screen: bool = False) -> Run:
        """Leading valid output steps of fine poses P (n*sub, 4, 4) at times (n*sub,) [s] continuing
        joints q0. Clearance is exact at the output steps; the sub-poses between them are queried
        only where their lower bound from the neighbouring steps does not keep the margin
        (:func:`~.certify.between_clearance`; ``run.d`` holds that bound there). With ``start`` =
        (clearance at q0 [m], its time [s]) the first step's sub-poses are bounded from q0 too and,
        with ``certify``, the motions along the bar's path between consecutive output steps (from
        q0) are certified (:func:`~.certify.certify_chords`, ``closed_chain``). With ``whole`` (a
        caller that takes the whole run or nothing) it stops at the first failure it finds, in the
        order IK and joint steps,
        clearance at the output steps, between them, certificate: the leading valid steps are then
        not worked out further (their clearance may be NaN) and the reason is that failure's. With
        ``whole`` and ``finer`` (the caller cuts an edge refused for a joint step finer, as
        :meth:`edge` does) a joint step is reported only when every output pose after it with IK
        keeps the margin; else that pose's clearance is, and the edge is not cut finer in vain.

        With ``screen`` the bar's clearance to the fixed geometry is first bounded from above at the
        output poses, from the object poses alone (no IK:
        :class:`~dualpuma.collision.held.HeldScreen`): where that bound is below the margin, the
        exact clearance there is too, so no step from there on is valid. With ``whole`` the edge is
        then refused without solving the arms (``m`` = 0, the reason naming the output step);
        otherwise only the steps up to that pose are validated: the same run as the whole edge's
        (its steps after that pose cannot change it), for less IK and no queries beyond it."""
        w, sub, p = self.world, self.sub, self.p
        n = P.shape[0] // sub
        if screen:
            k, bound, pk = self.held.first_below(P[sub - 1 :: sub], self.margin - _SCREEN_TOL)
            if k >= 0 and whole:
                reason, why = self._clear_reason(bound, pk, at_most=True)
                return _refused(P, f"output step {k + 1}: {reason}", why)
            if k == 0:
                return self._refused_first(P[:sub], q0, bound, pk)
            if 0 < k < n - 1:
                return self.validate(P[: (k + 1) * sub], q0, times[: (k + 1) * sub], start, certify)
        sol = solve_path_unchecked(w, P, q0, p.max_joint_step)
        m, reason, why, ratio = sol.n_ok // sub, sol.reason, "", 0.0
        if m < n:
            why = _arms_why(sol.status)
        qL, qR = sol.q_left, sol.q_right
        if m:
            bad, step_reason, step_ratio = self._joint_step(qL, qR, q0, m)
            if bad < m:
                m, reason, why, ratio = bad, step_reason, "joint step", step_ratio
        k, unfollowed = first_unfollowed(w, P, qL, qR, np.concatenate(q0), None, sub, m)
        if k < m:  # not cut finer: finer steps follow the same path (the wrist swings, a joint leaves its limit)
            m, reason, ratio = k, f"output step {k + 1}: {unfollowed}", 0.0
            why = "wrist swing" if unfollowed == WRIST_SWING else "between poses"
        d = np.full(m * sub, np.nan)
        pair = np.zeros(m * sub, dtype=np.int64)
        if whole and m < n:
            if finer and why == "joint step":  # a pose further on below the margin: finer steps would not pass it either
                bad_k, d_bad, p_bad = self._first_too_close(qL, qR, times, m, sol.n_ok // sub)
                if bad_k >= 0:
                    reason, why = self._clear_reason(d_bad, p_bad)
                    reason, ratio = f"output step {bad_k + 1}: {reason}", 0.0
            return Run(m, P[: m * sub], qL[: m * sub], qR[: m * sub], d, pair, reason, why, ratio)
        bad_k, d_bad, p_bad = self._first_too_close(qL, qR, times, 0, m, d, pair)  # pass 1: the output-step poses
        if bad_k >= 0:
            m = bad_k
            reason, why = self._clear_reason(d_bad, p_bad)
        if m and sub > 1 and not (whole and m < n):  # pass 2: the sub-poses between steps (before the certificate)
            fine = np.flatnonzero(np.arange(m * sub) % sub != sub - 1)
            out = np.arange(1, m + 1) * sub - 1
            Qe = np.vstack([np.concatenate(q0), np.hstack([qL[out], qR[out]])])
            de = np.concatenate([[-np.inf if start is None else start[0]], d[out]])
            te = np.concatenate([[times[0] if start is None else start[1]], times[out]])
            d[fine], pair[fine] = between_clearance(w, Qe, de, te, np.hstack([qL[fine], qR[fine]]), times[fine],
                                                    fine // sub, self.margin, self.reach, self.v_max)
            bad = np.flatnonzero(d[: m * sub] < self.margin)
            if bad.size:
                j = int(bad[0])
                m = j // sub
                reason, why = self._clear_reason(d[j], int(pair[j]))
        f = m * sub
        run = Run(m, P[:f], qL[:f], qR[:f], d[:f], pair[:f], reason if m < n else "", why if m < n else "", ratio)
        if start is None or not certify or (whole and m < n):
            return run
        return self.certify_run(run, q0, times, start)

    def _refused_first(self, P: FloatArray, q0: tuple[FloatArray, FloatArray], bound: float, pk: int) -> Run:
        """The run of an edge whose first output pose (the last of the fine poses P (sub, 4, 4)) the
        screen found too close (its bar's clearance at most ``bound`` [m], pair ``pk``): no step is
        valid. What :meth:`validate` says of that step, solved: its IK's failure, or a joint step
        (the edge is then cut finer), or else the screen's clearance (the exact clearance there, and
        the check between the poses, could only refuse it too)."""
        sol = solve_path_unchecked(self.world, P, q0, self.p.max_joint_step)
        reason, why, ratio = sol.reason, "", 0.0
        if sol.n_ok < P.shape[0]:
            why = _arms_why(sol.status)
        else:
            bad, reason, ratio = self._joint_step(sol.q_left, sol.q_right, q0, 1)
            if bad == 0:
                why = "joint step"
            else:
                reason, why = self._clear_reason(bound, pk, at_most=True)
                reason = f"output step 1: {reason}"
        return _refused(P, reason, why, ratio)

    def _joint_step(self, qL: FloatArray, qR: FloatArray, q0: tuple[FloatArray, FloatArray], m: int
                    ) -> tuple[int, str, float]:
        """The first of output steps 0..m-1 (joints qL, qR at the fine poses, from q0) in which a joint
        moves more than ``max_joint_step``: ``(its index, why, that move / max_joint_step)``, or
        ``(m, "", 0.0)`` when none does."""
        sub, limit = self.sub, self.p.max_joint_step
        idx = np.arange(1, m + 1) * sub - 1
        prevL, prevR = np.vstack([q0[0], qL[idx[:-1]]]), np.vstack([q0[1], qR[idx[:-1]]])
        jump = np.maximum(np.abs(qL[idx] - prevL).max(axis=1), np.abs(qR[idx] - prevR).max(axis=1))
        bad = np.flatnonzero(jump > limit + 1e-12)
        if not bad.size:
            return m, "", 0.0
        k = int(bad[0])
        return k, f"a joint would move {jump[k]:.4f} rad in output step {k + 1}", float(jump[k] / limit)

    def _first_too_close(self, qL: FloatArray, qR: FloatArray, times: FloatArray, a: int, b: int,
                         d: FloatArray | None = None, pair: npt.NDArray[np.int64] | None = None
                         ) -> tuple[int, float, int]:
        """The first of output steps a..b-1 (joints qL, qR at the fine poses, times [s]) whose pose is
        closer than the margin, 8 at a time (a refusal is found ``substeps`` times faster than with
        every pose): ``(its index, its clearance [m], its pair)``, or ``(-1, nan, -1)`` when all keep
        the margin. With ``d`` and ``pair`` (per fine pose) the clearances and pairs of the poses
        asked are written there."""
        sub = self.sub
        for k in range(a, b, 8):
            idx = np.arange(k, min(b, k + 8)) * sub + sub - 1
            dk, pk = self.clear(qL[idx], qR[idx], times[idx])
            if d is not None and pair is not None:
                d[idx], pair[idx] = dk, pk
            bad = np.flatnonzero(dk < self.margin)
            if bad.size:
                return k + int(bad[0]), float(dk[bad[0]]), int(pk[bad[0]])
        return -1, float("nan"), -1

    def certify_run(self, run: Run, q0: tuple[FloatArray, FloatArray], times: FloatArray,
                    start: tuple[float, float]) -> Run:
        """``run`` cut to its leading output steps whose motion from the previous one (from q0, with
        clearance and time ``start``) is certified; ``times`` of the fine poses [s]."""
        sub, m = self.sub, run.m
        if not m:
            return run
        out = np.arange(1, m + 1) * sub - 1
        V = np.vstack([np.concatenate(q0), np.hstack([run.qL[out], run.qR[out]])])
        ok, why = self.certify(V, np.concatenate([[start[0]], run.d[out]]), np.concatenate([[start[1]], times[out]]))
        if ok == m:
            return run
        f = ok * sub
        return Run(ok, run.P[:f], run.qL[:f], run.qR[:f], run.d[:f], run.pair[:f],
                   f"the motion into output step {ok + 1} is not certified: {why}", "uncertified")

    def certify(self, V: FloatArray, d: FloatArray, times: FloatArray) -> tuple[int, str]:
        """(leading chords of V (n + 1, 12) certified, why the next one is not): chords this plan
        certified before (:class:`ChordMemo`) are not certified again."""
        memo = self.certified
        keys = memo.keys(V, d, times)
        for a, b in _runs([c for c, key in enumerate(keys) if key not in memo]):  # runs of unknown chords, in order
            cert = certify_chords(self.world, V[a : b + 1], d[a : b + 1], times[a : b + 1], self.margin, self.reach,
                                  self.v_max, closed_chain=True)
            memo.add(keys[a : a + cert.n_ok])
            if cert.n_ok < b - a:
                return a + cert.n_ok, cert.reason
        return V.shape[0] - 1, ""

    def _clear_reason(self, d: float, k: int, at_most: bool = False) -> tuple[str, str]:
        a, b = self.world.pair_names[k]
        return (
            (f"clearance {'at most ' if at_most else ''}{below_text(d, self.margin)} m below the margin "
             f"{self.margin:.3f} m ({a} – {b})"),
            f"clearance {a} – {b}",
        )

    def edge(
        self,
        A: FloatArray,
        q0: tuple[FloatArray, FloatArray],
        B: FloatArray,
        t_a: float | None,
        n: int | None = None,
        d_a: float | None = None,
        whole: bool = False,
        certify: bool = True,
    ) -> tuple[Run, int]:
        """Validate the geodesic A -> B from joints q0; ``t_a``: time at A (None: goal-tree lower bounds);
        ``d_a``: clearance at A [m] to certify the motion between output steps (None, or
        ``certify`` False: not certified;
        with ``t_a`` None it is certified at the lower-bound times, which the found path's
        verification at its real times has the last word on).

        ``n`` output steps (default: by ``step``/``rot_step``); where a joint would move more than
        ``max_joint_step`` in one output step (near the wrist singularity), the edge is cut into more
        steps, up to 8 times as many. (A motion between output steps that cannot be certified is
        not: the certificate is of the bar's path, which finer steps follow too.) ``whole``: the
        caller takes the whole edge or nothing
        (a shortcut, a connection, a path verified as one): validation stops at the first failure it
        finds (:meth:`validate`) and a prefix is not certified. Returns (run, output steps used).
        """
        n = self.n_out(A, B) if n is None else n
        n_max = 8 * n
        start = None if d_a is None else (d_a, float(self.t_lb(A[None])[0]) if t_a is None else t_a)
        while True:
            F = n * self.sub
            P = slerp(A, B, np.arange(1, F + 1) / F)
            times = self.t_lb(P) if t_a is None else t_a + np.arange(1, F + 1) / self.sub * self.dt
            # certified below, once the resolution is settled
            run = self.validate(P, q0, times, start, certify=False, whole=whole, finer=n < n_max,
                                screen=True)
            if run.why != "joint step" or n >= n_max:
                break
            n = min(n_max, math.ceil(n * min(4.0, 1.25 * run.ratio)))
        if certify and start is not None and not (whole and run.m < n):
            run = self.certify_run(run, q0, times, start)
        if run.why:
            self.stats[run.why] += 1
        return run, n
