"""OMPL's RRTConnect on a hard-set problem with the same validity as the general planner's fallback
(for bench_hard_set.py): the object pose in SE(3) (OMPL's SE3StateSpace, the fallback's sampling
box), a state valid when both arms reach it on the start's IK branches inside the limits and every
pair keeps the margin, a motion valid when the fallback's own edge check accepts it — dual IK
continuing from the state's joints at every sub-pose, joint steps, clearance at every sub-pose and
the motion between output steps certified (EdgeChecker.edge). Then OMPL's simplifier, and the
simplified path re-verified from the start joints as one path (the same verify as ours).

Requires ``pip install 'dualpuma[bench]'`` (ompl >= 2.0.1)."""

from __future__ import annotations

import itertools
import math
import time

import numpy as np
import pinocchio as pin
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou
from path_metrics import lengths

from dualpuma.collision import clearance_batch
from dualpuma.kinematics import puma
from dualpuma.kinematics.continuity import wrapped_gap
from dualpuma.kinematics.dual import hands_from_object
from dualpuma.planning import FallbackParams
from dualpuma.planning.edges import EdgeChecker
from dualpuma.planning.smoothing import verify

ou.setLogLevel(ou.LogLevel.LOG_ERROR)
ou.RNG.setSeed(1)  # once, before any sampler exists: the benchmark's OMPL runs are reproducible in order


def _pose(state) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (state.getX(), state.getY(), state.getZ())
    r = state.rotation()
    T[:3, :3] = pin.Quaternion(r.w, r.x, r.y, r.z).toRotationMatrix()
    return T


def _set(state, T: np.ndarray) -> None:
    state.setXYZ(*map(float, T[:3, 3]))
    q = pin.Quaternion(T[:3, :3])
    r = state.rotation()
    r.x, r.y, r.z, r.w = float(q.x), float(q.y), float(q.z), float(q.w)


class _Validity:
    """The fallback's validity as OMPL callbacks (states: IK on the start's branches)."""

    def __init__(self, world, q0, params: FallbackParams) -> None:
        self.world, self.q0 = world, q0
        self.cfg = [int(puma.branch_of(q)) for q in q0]
        self.lim = [world.arms[s].limits for s in ("left", "right")]
        self.ec = EdgeChecker(world, params, np.eye(4), 0.0, 0.0)
        self.calls = 0

    def joints(self, T: np.ndarray):
        out = []
        for T_bh, q, c, lim in zip(hands_from_object(self.world.cell, T), self.q0, self.cfg, self.lim):
            r = puma.ik(T_bh, config=c, q_near=q, limits=lim)
            if not r.ok:
                return None
            out.append(r.q)
        return out[0], out[1]

    def clearance(self, q) -> float:
        return float(clearance_batch(self.world, q[0][None], q[1][None])[0][0])

    def state_valid(self, state) -> bool:
        self.calls += 1
        q = self.joints(_pose(state))
        return bool(q is not None and self.clearance(q) >= self.ec.margin)

    def motion_valid(self, s1, s2) -> bool:
        T1, T2 = _pose(s1), _pose(s2)
        q1, q2 = self.joints(T1), self.joints(T2)
        if q1 is None or q2 is None:
            return False
        run, n = self.ec.edge(T1, q1, T2, 0.0, d_a=self.clearance(q1))
        if run.m < n:
            return False
        gap = max(wrapped_gap(run.qL[-1], q2[0]).max(), wrapped_gap(run.qR[-1], q2[1]).max())
        return bool(gap <= 1e-6)


class _Motion(ob.MotionValidator):
    def __init__(self, si, validity: _Validity) -> None:
        super().__init__(si)
        self.v = validity

    def checkMotion(self, s1, s2, *args):  # OMPL's name
        return self.v.motion_valid(s1, s2)


def solve(problem, world, time_limit: float = 10.0) -> dict:
    """OMPL RRTConnect + simplifySolution on one problem; its time, success and path length."""
    params = FallbackParams()
    A, B = np.asarray(problem.start, float), np.asarray(problem.goal, float)
    q0 = tuple(np.asarray(q, float) for q in problem.q_start)
    tic = time.perf_counter()
    space = ob.SE3StateSpace()
    lo = np.minimum(A[:3, 3], B[:3, 3]) - params.bounds_padding
    hi = np.maximum(A[:3, 3], B[:3, 3]) + params.bounds_padding
    lo[2] = max(lo[2], float(world.cell.floor_z))
    bounds = ob.RealVectorBounds(3)
    for i in range(3):
        bounds.setLow(i, float(lo[i]))
        bounds.setHigh(i, float(hi[i]))
    space.setBounds(bounds)
    ss = og.SimpleSetup(space)
    validity = _Validity(world, q0, params)
    ss.setStateValidityChecker(validity.state_valid)
    si = ss.getSpaceInformation()
    mv = _Motion(si, validity)
    si.setMotionValidator(mv)
    start, goal = space.allocState(), space.allocState()
    _set(start, A)
    _set(goal, B)
    ss.setStartAndGoalStates(start, goal)
    planner = og.RRTConnect(si)
    planner.setRange(params.max_extend)
    ss.setPlanner(planner)
    ss.solve(time_limit)
    out = {"ok": False, "time_s": time.perf_counter() - tic, "length": math.nan, "metric": math.nan,
           "raw_length": math.nan}
    if not ss.haveExactSolutionPath():
        return out
    raw = ss.getSolutionPath()
    out["raw_length"] = lengths([_pose(raw.getState(i)) for i in range(raw.getStateCount())])[0]
    ss.simplifySolution(max(0.0, time_limit - (time.perf_counter() - tic)))
    path = ss.getSolutionPath()
    poses = [_pose(path.getState(i)) for i in range(path.getStateCount())]
    out["time_s"] = time.perf_counter() - tic
    ec = EdgeChecker(world, params, A, 0.0, 0.0)
    way, q = [(poses[0], 0)], q0
    for a, T in itertools.pairwise(poses):  # each edge cut as the motion validator cut it (certified)
        run, n = ec.edge(a, q, T, 0.0, d_a=validity.clearance(q))
        way.append((T, n))
        q = (run.qL[-1], run.qR[-1]) if run.m == n else q
    checked, _ = verify(ec, way, q0, validity.clearance(q0))
    out["ok"] = checked is not None and out["time_s"] <= time_limit
    out["length"], out["metric"] = lengths(poses)
    return out
