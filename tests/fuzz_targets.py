"""The public API as fuzz targets: for every callable in the subpackages' ``__all__``, a valid call
(positional arguments and keywords) that the fuzz tests then break one argument at a time.

Each target is ``Target(name, function, args, kwargs)``; ``args``/``kwargs`` are zero-argument
factories (so that a fresh valid value is built for each call). Names in a subpackage's ``__all__``
that are not functions to fuzz are listed in :data:`NOT_FUZZED` with the reason.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import os
from collections.abc import Callable
from concurrent.futures import Executor, Future
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np

import dualpuma
from dualpuma import collision, envelope, kinematics, model, planning, scenarios


@dataclass(frozen=True)
class Target:
    name: str
    fn: Callable
    args: tuple = ()
    kwargs: dict = field(default_factory=dict)


class InlineExecutor(Executor):
    """Runs submitted work at once in the calling thread (a fast executor for plan_many)."""

    def submit(self, fn, /, *args, **kwargs):
        f: Future = Future()
        try:
            f.set_result(fn(*args, **kwargs))
        except BaseException as e:  # noqa: BLE001
            f.set_exception(e)
        return f


@cache
def cell() -> model.Cell:
    return model.Cell.default()


@cache
def world() -> model.World:
    return model.World(cell())


@cache
def arm() -> kinematics.Arm:
    return kinematics.Arm.puma560()


@cache
def kernel() -> collision.ClearanceKernel:
    return collision.ClearanceKernel(world())


ARM6 = str(Path(__file__).parent / "data" / "arm6.urdf")


@cache
def ur5() -> kinematics.Arm:
    return kinematics.Arm.load("ur5")


@cache
def z1() -> kinematics.Arm:
    return kinematics.Arm.load("z1")


def q_ur5():
    return np.array([0.3, -1.2, 1.4, -0.8, 1.1, 0.2])


def T_ur5():
    return ur5().fk(q_ur5())


def q_z1():
    return np.array([0.2, 1.0, -1.0, 0.1, 0.6, 0.0])


def T_z1():
    return z1().fk(q_z1())


@cache
def reached_plan() -> planning.Plan:
    """A short reached plan of the default cell (3 steps)."""
    B = T_start()
    B[:3, 3] += (-0.03, -0.02, 0.02)
    p = planning.plan(cell(), T_start(), B, planning.StrivingParams(step=0.015), world=world())
    assert p.reached
    return p


@cache
def timed() -> planning.Trajectory:
    return planning.time_plan(reached_plan(), world(), dt=0.05)


@cache
def timed_plan() -> planning.Plan:
    return planning.with_trajectory(reached_plan(), world(), dt=0.05)


def T_start():
    return cell().T_world_object_start.copy()


def q_home():
    return cell().left.q_home.copy(), cell().right.q_home.copy()


def T_wrist():
    return kinematics.fk(cell().left.q_home)


def _targets() -> list[Target]:
    c, w = cell, world
    qL, qR = (lambda: cell().left.q_home.copy()), (lambda: cell().right.q_home.copy())
    Tb = lambda: cell().left.T_world_base.copy()
    field2 = lambda: np.outer(np.linspace(0, 1, 5), np.linspace(0, 1, 4))
    xs, ys = (lambda: np.linspace(0, 1, 5)), (lambda: np.linspace(0, 1, 4))
    half = lambda v: (lambda: v)
    R0 = lambda: T_start()[:3, :3]
    pts = lambda: T_start()[:3, 3][None, :]
    k = kinematics
    return [
        # ---------------------------------------------------------------- kinematics
        Target("kinematics.fk", k.fk, (qL,)),
        Target("kinematics.ik", k.ik, (T_wrist,), {"config": half(None), "q_near": qL, "limits": half(None)}),
        Target("kinematics.ik_all", k.ik_all, (T_wrist,), {"q_near": qL, "limits": half(None)}),
        Target("kinematics.Arm.fk", lambda *a, **kw: arm().fk(*a, **kw), (qL,), {"frame": half(None)}),
        Target("kinematics.Arm.jacobian", lambda *a, **kw: arm().jacobian(*a, **kw), (qL,),
               {"frame": half(None), "reference": half("world_aligned")}),
        Target("kinematics.Arm.manipulability", lambda *a, **kw: arm().manipulability(*a, **kw), (qL,),
               {"frame": half(None)}),
        Target("kinematics.Arm.within_limits", lambda *a, **kw: arm().within_limits(*a, **kw), (qL,), {"tol": half(1e-9)}),
        Target("kinematics.Arm.ik", lambda *a, **kw: arm().ik(*a, **kw), (T_wrist,), {"config": half(None), "q_near": qL}),
        Target("kinematics.Arm.ik_all", lambda *a, **kw: arm().ik_all(*a, **kw), (T_wrist,), {"q_near": qL}),
        Target("kinematics.Arm.frame_id", lambda *a: arm().frame_id(*a), (half("wrist"),)),
        Target("kinematics.Arm.load", k.Arm.load, (half("puma560"),)),
        Target("kinematics.hands_from_object", k.hands_from_object, (c, T_start)),
        Target("kinematics.solve_dual", k.solve_dual, (w, T_start, q_home),
               {"max_step": half(0.3), "check_clearance": half(True), "t": half(0.0)}),
        Target("kinematics.solve_path", k.solve_path, (w, lambda: T_start()[None], q_home), {"max_step": half(0.3)}),
        Target("kinematics.continue_branch", k.continue_branch, (arm, T_wrist, qL)),
        Target("kinematics.puma.branch_of", k.puma.branch_of, (qL,)),
        Target("kinematics.puma.config_to_branch", k.puma.config_to_branch, (half(1), half(1), half(1))),
        # other arms (issue 16): a UR5 (closed form) and the Z1 (numeric), a URDF arm, capsule fits
        Target("kinematics.Arm.ik[ur5]", lambda *a, **kw: ur5().ik(*a, **kw), (T_ur5,), {"config": half(None), "q_near": q_ur5}),
        Target("kinematics.Arm.ik_all[ur5]", lambda *a, **kw: ur5().ik_all(*a, **kw), (T_ur5,), {"q_near": q_ur5}),
        Target("kinematics.Arm.branch_of[ur5]", lambda *a: ur5().branch_of(*a), (q_ur5,)),
        Target("kinematics.Arm.ik[z1]", lambda *a, **kw: z1().ik(*a, **kw), (T_z1,), {"q_near": q_z1}),
        Target("kinematics.Arm.from_urdf", k.Arm.from_urdf, (half(ARM6), half("tool"))),
        Target("kinematics.RobotSpec", k.RobotSpec, (half(ARM6), half("tool"))),
        Target("kinematics.fit_capsule", k.fit_capsule, (lambda: np.random.default_rng(0).normal(size=(20, 3)),),
               {"pad": half(0.001)}),
        # ---------------------------------------------------------------- model
        Target("model.World", model.World, (c,)),
        Target("model.World.clearance", lambda *a, **kw: w().clearance(*a, **kw), (qL, qR),
               {"T_world_object": half(None), "t": half(0.0), "per_pair": half(False)}),
        Target("model.World.min_distance", lambda *a, **kw: w().min_distance(*a, **kw), (qL, qR, half(None), half(0.0))),
        Target("model.World.permitted", lambda *a, **kw: w().permitted(*a, **kw), (qL, qR),
               {"T_world_object": half(None), "t": half(0.0), "margin": half(None)}),
        Target("model.World.hand_poses", lambda *a: w().hand_poses(*a), (qL, qR)),
        Target("model.World.q_full", lambda *a: w().q_full(*a), (qL, qR)),
        Target("model.World.object_from_left", lambda *a: w().object_from_left(*a), (qL,)),
        Target("model.World.segments", lambda *a: w().segments(*a), (qL, qR)),
        Target("model.World.geometry", lambda *a: w().geometry(*a), (half("bar"),)),
        Target("model.ArmMount", model.ArmMount, (half("left"), half("puma560"), Tb, qL)),
        Target("model.Bar", model.Bar, (half("box"), lambda: np.array([0.5, 0.05, 0.05]), lambda: np.eye(4))),
        Target("model.Grasp", model.Grasp, (lambda: np.eye(4),)),
        Target("model.Obstacle", model.Obstacle, (half("o"), half("box"), lambda: [0.1, 0.1, 0.1], lambda: np.eye(4)),
               {"velocity": lambda: np.zeros(3), "t_start": half(0.0), "t_end": half(math.inf)}),
        Target("model.Cell", model.Cell,
               (lambda: c().left, lambda: c().right, lambda: c().bar, lambda: c().grasp_left, lambda: c().grasp_right,
                T_start), {"obstacles": half(()), "floor_z": half(0.0), "safety_margin": half(0.02),
                           "name": half("x")}),
        Target("model.seed_units_to_world", model.seed_units_to_world, (half([1.0, 2.0, 3.0]),)),
        Target("model.cell_to_toml", model.cell_to_toml, (c,)),
        Target("model.cell_from_toml", model.cell_from_toml, (lambda: model.cell_to_toml(cell()),),
               {"source": half("x.toml")}),
        Target("model.example_cell", model.example_cell, (half("default"),)),
        Target("model.cell_from_spec", model.cell_from_spec, (half("default"),)),
        # ---------------------------------------------------------------- collision
        Target("collision.clearance_batch", collision.clearance_batch, (w, qL, qR),
               {"T_world_object": half(None), "t": half(None), "method": half("auto")}),
        Target("collision.pair_distances_batch", collision.pair_distances_batch, (w, qL, qR),
               {"T_world_object": half(None), "t": half(None)}),
        Target("collision.batch_kernel", collision.batch_kernel, (w,)),
        Target("collision.self_contact", collision.self_contact, (w, qL, qR)),
        Target("collision.unmapped_sides", collision.unmapped_sides, (w,)),
        Target("collision.ClearanceKernel", collision.ClearanceKernel, (w,), {"block": half(16)}),
        Target("collision.ClearanceKernel.__call__", lambda *a, **kw: kernel()(*a, **kw),
               (lambda: np.concatenate(q_home())[None],), {"T_world_object": half(None), "t": half(None)}),
        Target("collision.ClearanceKernel.pair_distances", lambda *a, **kw: kernel().pair_distances(*a, **kw),
               (lambda: np.concatenate(q_home())[None],), {"T_world_object": lambda: T_start()[None], "t": half(0.0)}),
        Target("collision.ClearanceKernel.geometry_placements",
               lambda *a, **kw: kernel().geometry_placements(*a, **kw),
               (lambda: np.concatenate(q_home())[None],), {"T_world_object": half(None), "t": half(None)}),
        Target("collision.node_positions", collision.node_positions, (Tb, qL)),
        Target("collision.node_search", collision.node_search, (Tb, qL, lambda: cell().right.T_world_base.copy(), qR),
               {"threshold": half(0.175)}),
        Target("collision.bar_major_dimension", collision.bar_major_dimension, (c,)),
        Target("collision.grown_obstacles", collision.grown_obstacles, (lambda: model.example_cell("routine7_box"),),
               {"t": half(0.0)}),
        Target("collision.object_point_clear", collision.object_point_clear,
               (lambda: model.example_cell("routine7_box"), T_start), {"t": half(0.0)}),
        Target("collision.arm_arm_distance", collision.arm_arm_distance, (w, qL, qR), {"T_world_object": half(None)}),
        Target("collision.twisting", collision.twisting, (half(0.1), half(0.05), half(0.1))),
        # ---------------------------------------------------------------- planning
        Target("planning.plan", planning.plan, (c, T_start, T_start),
               {"params": half(None), "rng": half(None), "q_start": half(None), "start_rpy": half(None),
                "goal_rpy": half(None), "world": half(None)}),
        Target("planning.plan_many", planning.plan_many, (lambda: [(cell(), T_start(), T_start())],),
               {"params": half(None), "executor": lambda: InlineExecutor(), "progress": half(False),
                "chunksize": half(None)}),
        Target("planning.Problem", planning.Problem, (c, T_start, T_start)),
        Target("planning.StrivingParams", planning.StrivingParams, (),
               {"step": half(0.05), "substeps": half(5), "margin": half(None), "orientation": half("slerp"),
                "alternates": half(()), "max_steps": half(10), "fallback": half(False),
                "fallback_params": half(None), "mapping": half(False), "step_time": half(0.1)}),
        Target("planning.FallbackParams", planning.FallbackParams, (),
               {"max_iterations": half(10), "step": half(0.05), "substeps": half(2), "bounds": half(None),
                "goal_bias": half(0.1), "margin": half(None), "rot_weight": half(0.15),
                "restart_iterations": half(1000), "time_limit": half(None)}),
        Target("planning.rrt_connect", planning.rrt_connect, (w, T_start, q_home, T_start),
               {"params": half(planning.FallbackParams(max_iterations=5)), "rng": half(None), "t0": half(0.0),
                "step_time": half(0.0), "striving": half(None)}),
        Target("planning.interpolate_object", planning.interpolate_object, (T_start, T_start, half(3)),
               {"method": half("slerp"), "rpy_start": half(None), "rpy_goal": half(None), "puma_branch": half(0)}),
        Target("planning.orientation_joints", planning.orientation_joints, (R0, half(0))),
        Target("planning.robmov", planning.robmov, (qL, qR), {"max_step": half(0.3)}),
        Target("planning.time_plan", planning.time_plan, (reached_plan, w),
               {"v_max": half(None), "a_max": half(None), "closure_tol": half(0.5e-3), "dt": half(0.05),
                "period": half(None), "limit_scale": half(0.98), "margin": half(None), "max_wait": half(10.0),
                "max_slowdown": half(4.0)}),
        Target("planning.time_plan[period]", planning.time_plan, (reached_plan, w),
               {"dt": half(None), "period": half(0.05), "closure_tol": half(0.5e-3), "max_wait": half(10.0)}),
        Target("planning.with_trajectory", planning.with_trajectory, (reached_plan, w), {"dt": half(0.05)}),
        Target("planning.Trajectory.from_dict", planning.Trajectory.from_dict, (lambda: timed().to_dict(),)),
        Target("planning.Plan.from_json[timed]", planning.Plan.from_json, (lambda: timed_plan().to_json(),)),
        Target("planning.chain", planning.chain,
               (lambda: planning.Plan.failed("frozen", "x"), lambda: planning.Plan.failed("frozen", "y"))),
        Target("planning.Plan", planning.Plan,
               (half("reached"), half(""), lambda: T_start()[None], lambda: cell().left.q_home[None],
                lambda: cell().right.q_home[None], half(np.zeros(1)), half((("a", "b"),)), half(np.zeros(1))),
               {"events": half(()), "path_length": half(0.0), "planning_time": half(0.0), "planner": half("x"),
                "meta": half({})}),
        Target("planning.Plan.failed", planning.Plan.failed, (half("frozen"), half("why")),
               {"planning_time": half(0.0), "planner": half("striving")}),
        Target("planning.Plan.from_json", planning.Plan.from_json,
               (lambda: planning.Plan.failed("frozen", "x").to_json(),)),
        Target("planning.Plan.from_dict", planning.Plan.from_dict, (lambda: planning.Plan.failed("frozen", "x").to_dict(),)),
        Target("planning.Plan.to_json", lambda *a, **kw: planning.Plan.failed("frozen", "x").to_json(*a, **kw), (),
               {"indent": half(None)}),
        # ---------------------------------------------------------------- envelope
        Target("envelope.ideal_envelope", envelope.ideal_envelope, (half(1.0), half(2.5), half(1.0)),
               {"resolution": half(8), "base_left": half(None), "base_right": half(None), "rtol": half(1e-6)}),
        Target("envelope.contains_ideal", envelope.contains_ideal,
               (half(np.zeros((2, 3))), half(np.array([-1.25, 0, 0])), half(np.array([1.25, 0, 0])), half(1.0), half(1.0))),
        Target("envelope.membership_slacks", envelope.membership_slacks,
               (half(np.zeros((2, 3))), half(np.array([-1.25, 0, 0])), half(np.array([1.25, 0, 0])), half(1.0), half(1.0))),
        Target("envelope.closed_form_volume", envelope.closed_form_volume, (half(1.0), half(2.5), half(1.0))),
        Target("envelope.solve_real", envelope.solve_real, (c, pts), {"R_world_object": half(None), "world": half(None)}),
        Target("envelope.contains_real", envelope.contains_real, (c, pts), {"R_world_object": R0, "world": half(None)}),
        Target("envelope.real_envelope", envelope.real_envelope, (c, half(0.2)),
               {"orientations": half(None), "world": half(None), "bounds": half(((1.2, 1.8), (-0.5, 0.0), (0.0, 0.5))),
                "floor": half(True)}),
        Target("envelope.marching_squares", envelope.marching_squares, (field2, xs, ys), {"level": half(0.5)}),
        Target("envelope.contour_polylines", envelope.contour_polylines, (field2, xs, ys), {"level": half(0.5)}),
        # ---------------------------------------------------------------- scenarios
        Target("scenarios.routine", scenarios.routine, (half(2),)),
        Target("scenarios.routine_cell", scenarios.routine_cell, (half(1),)),
        Target("scenarios.run_routine", scenarios.run_routine, (half(2),), {"params": half(None), "world": half(None)}),
        Target("scenarios.random_problem", scenarios.random_problem, (half(0),), {"max_obstacles": half(1), "base": half(None)}),
        Target("scenarios.random_problems", scenarios.random_problems, (half(1),), {"seed": half(0), "max_obstacles": half(1)}),
        Target("scenarios.slot_field_cell", scenarios.slot_field_cell, ()),
        Target("scenarios.rising_ball_cell", scenarios.rising_ball_cell, (), {"t_start": half(0.5), "t_end": half(1.0)}),
        Target("scenarios.run_legs", scenarios.run_legs, (c, T_start, lambda: [(T_start(), None)]),
               {"params": half(None), "world": half(None), "q_start": half(None), "start_rpy": half(None),
                "t_start": half(0.0)}),
        # ---------------------------------------------------------------- top level
        Target("dualpuma.load_cell", dualpuma.load_cell, (half("/nonexistent/cell.toml"),)),
        Target("dualpuma.save_cell", dualpuma.save_cell, (c, half("/nonexistent/dir/cell.toml")),
               {"overwrite": half(False)}),
    ]


def _with_defaults(t: Target) -> Target:
    """The target with every parameter it does not list yet added at its default value, so that a
    parameter is fuzzed as soon as the function has it (one that takes ``*args, **kwargs`` is left
    as it is)."""
    try:
        sig = inspect.signature(t.fn)
    except (TypeError, ValueError):
        return t
    params = [p for p in sig.parameters.values() if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
    named = {p.name for p in params[: len(t.args)]} | set(t.kwargs)
    extra = {p.name: (lambda v=p.default: v) for p in params if p.name not in named and p.default is not p.empty}
    return dataclasses.replace(t, kwargs={**t.kwargs, **extra}) if extra else t


TARGETS: list[Target] = [_with_defaults(t) for t in _targets()]

#: public names of the subpackages that are not called by the fuzz, with the reason
#: The fuzz tests run a fixed, reproducible set of inputs (the CI's run); DUALPUMA_FUZZ_RANDOM=1
#: draws new ones each run (with DUALPUMA_FUZZ_EXAMPLES=600, the deep runs reported in notes).
FUZZ_RANDOM = os.environ.get("DUALPUMA_FUZZ_RANDOM") == "1"

NOT_FUZZED = {
    # data classes / constants / results (constructed by the library, not by users with raw input)
    "Capsule": "data record built from a URDF",
    "IKResult": "result record",
    "IKStatus": "constants",
    "DualSolution": "result record",
    "PathSolution": "result record",
    "Clearance": "result record",
    "GeometryInfo": "result record",
    "WorldCache": "internal cache keyed by the library's own constants (no user input)",
    "GrownObstacle": "result record",
    "KernelUnsupported": "an error class",
    "FallbackResult": "result record",
    "IdealEnvelope": "result record",
    "RealEnvelope": "result record",
    "RealMembership": "result record",
    "Routine": "result record",
    "puma": "module (fuzzed through its functions)",
    "example_robot_data_dir": "takes no arguments",
    "load_cell": "fuzzed as dualpuma.load_cell",
    "save_cell": "fuzzed as dualpuma.save_cell",
    "Arm": "fuzzed through its methods",
    "PumaIK": "IK provider, trusted input (fuzzed through Arm.ik/ik_all/branch_of on a PUMA, a UR5, a Z1)",
    "URIK": "IK provider, trusted input (fuzzed through Arm.ik/ik_all/branch_of on a UR5)",
    "NumericIK": "IK provider, trusted input (fuzzed through Arm.ik on a Z1)",
    "ur": "module of trusted-input kernels (fuzzed through Arm on a UR5)",
    # documented trusted-input kernels of the hot paths (their public callers validate)
    "Trajectory": "fuzzed through Trajectory.from_dict and Plan.from_json of a timed plan",
    "continue_paths": "trusted-input kernel (solve_path and the planners validate)",
    "min_clearance": "trusted-input kernel (clearance_batch is the validated form)",
    "below_margin": "trusted-input kernel (clearance_batch is the validated form)",
    "first_contact_chord": "trusted-input certificate step (self_contact is the validated form)",
    "point_distance": "trusted-input kernel (object_point_clear is the validated form)",
    "segment_segment": "trusted-input closed form of the clearance kernel",
    "point_box": "trusted-input closed form of the clearance kernel",
    "segment_box": "trusted-input closed form of the clearance kernel",
}


def public_callables() -> set[str]:
    """Every callable public name of the subpackages (``subpackage.name``)."""
    out = set()
    for pkg in (kinematics, model, collision, planning, envelope, scenarios):
        short = pkg.__name__.split(".")[-1]
        for name in pkg.__all__:
            obj = getattr(pkg, name)
            if callable(obj) or isinstance(obj, type(kinematics)):
                out.add(f"{short}.{name}")
    return out
