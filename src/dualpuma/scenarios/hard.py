"""Hard planning problems for the general planner's benchmark: the bar's straight way is blocked.

Three families, each a perturbation of a known scene (:func:`hard_problem`):

* ``boxes`` — the default cell with two to five boxes scattered around the middle of the bar's
  straight way from a random start to a random goal (translation up to 0.35 m, yaw up to 20 deg).
* ``overhang`` — routine 8's overhanging slab on its post, slab and post moved by up to 30 mm and
  turned by up to 10 deg, the goal moved by up to 40 mm.
* ``slot`` — the snaking slot field (:func:`~dualpuma.scenarios.fields.slot_field_cell`) with one or
  two plates, each slot yawed by 35..55 deg (the second the other way) and 0.14..0.16 m wide: the
  bar passes only by turning. (0.15..0.17 m before 2026-11-27: held unrotated the bar passed those
  20.1-20.5 mm from the lips, and the straight run was refused only because the planners then
  certified the joint chords between steps, which dipped below the margin, not the bar's path.)

A problem is kept (:func:`hard_problems`) only when its start and goal are clear on the start's IK
branches, the straight run (Striving without alternates) is refused, and the general planner
(:data:`GENERAL_PARAMS`: the straight run, then the SE(3) fallback) reaches the goal with the
benchmark's own seed within ``budget`` iterations — the set is hard but solvable by construction.
:func:`problems_to_json` / :func:`problems_from_json` keep a generated set as a fixture.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import numpy.typing as npt

from ..checks import integer
from ..errors import ParameterError
from ..kinematics.dual import solve_dual
from ..lie import rot_to_rpy, rpy_to_rot
from ..model.cell import Cell, Obstacle
from ..model.world import World
from ..planning.batch import Problem
from ..planning.params import FallbackParams, StrivingParams
from ..planning.striving import plan
from .fields import slot_field_cell
from .routines import routine

__all__ = ["FAMILIES", "GENERAL_PARAMS", "hard_problem", "hard_problems", "problems_from_json", "problems_to_json"]

FloatArray = npt.NDArray[np.float64]

FAMILIES = ("boxes", "overhang", "slot")
#: the general planner: the straight run, then the SE(3) RRT-Connect fallback
GENERAL_PARAMS = StrivingParams(alternates=(), fallback=True,
                                fallback_params=FallbackParams(max_iterations=20_000, shortcut_iterations=60))
_FORMAT = "dualpuma.problems/1"


def _box(name: str, c, size, yaw: float = 0.0) -> Obstacle:
    T = np.eye(4)
    T[:3, :3] = rpy_to_rot([0.0, 0.0, yaw])
    T[:3, 3] = c
    return Obstacle(name, "box", np.asarray(size, float), T)


def _boxes(rng: np.random.Generator) -> tuple[Cell, FloatArray, FloatArray]:
    base = Cell.default()
    A = base.T_world_object_start.copy()
    A[:3, 3] += rng.uniform([-0.1, -0.15, 0.05], [0.05, -0.05, 0.2])
    B = A.copy()
    B[:3, 3] += rng.uniform([-0.15, -0.35, -0.1], [0.15, -0.15, 0.15])
    B[:3, :3] = rpy_to_rot(rot_to_rpy(A[:3, :3]) + [0.0, 0.0, math.radians(rng.uniform(-20.0, 20.0))])
    mid = 0.5 * ((A @ base.bar.T_object_bar)[:3, 3] + (B @ base.bar.T_object_bar)[:3, 3])
    obs = tuple(_box(f"box{i}", mid + rng.uniform([-0.35, -0.15, -0.2], [0.35, 0.1, 0.15]), rng.uniform(0.05, 0.2, 3),
                     rng.uniform(-math.pi, math.pi)) for i in range(int(rng.integers(2, 6))))
    return dataclasses.replace(base, obstacles=obs, name="hard-boxes"), A, B


def _overhang(rng: np.random.Generator) -> tuple[Cell, FloatArray, FloatArray]:
    r = routine(8)
    obs = []
    for ob in r.cell.obstacles:
        T = np.array(ob.T_world_obstacle)
        T[:3, 3] += rng.uniform(-0.03, 0.03, 3) * (1.0, 1.0, 0.0 if ob.name == "post" else 1.0)
        T[:3, :3] = rpy_to_rot([0.0, 0.0, math.radians(rng.uniform(-10.0, 10.0))])
        obs.append(dataclasses.replace(ob, T_world_obstacle=T))
    A = r.cell.T_world_object_start.copy()
    B = r.legs[0][0].copy()
    B[:3, 3] += rng.uniform(-0.04, 0.04, 3)
    return dataclasses.replace(r.cell, obstacles=tuple(obs), name="hard-overhang"), A, B


def _slot(rng: np.random.Generator) -> tuple[Cell, FloatArray, FloatArray]:
    cell, A, B = slot_field_cell()
    hw, thick, half_len, lip = 0.06, 0.04, 0.5, 0.015
    gap = rng.uniform(0.14, 0.16)
    c0 = (A @ cell.bar.T_object_bar)[:3, 3]
    sense = 1.0 if rng.uniform() < 0.5 else -1.0
    obs = []
    for k in range(1 if rng.uniform() < 0.6 else 2):
        yaw = math.radians(rng.uniform(35.0, 55.0)) * sense * (1.0 if k == 0 else -1.0)
        c = c0 + (0.0, 0.0, -0.11 - 0.26 * k)
        ca, ta = math.cos(yaw), abs(math.tan(yaw))
        yf = (gap / 2 + lip) / ca + hw * ta - 0.005
        for sgn, name in ((1, "back"), (-1, "front")):
            lip_c = c + (0.0, sgn * (gap / 2 + lip / 2) / ca, 0.0)
            obs.append(_box(f"plate{k + 1}_{name}_lip", lip_c, [2 * hw / ca + lip * ta, lip, thick], yaw))
            obs.append(_box(f"plate{k + 1}_{name}", c + (0.0, sgn * 0.5 * (yf + half_len), 0.0),
                            [2 * hw, half_len - yf, thick]))
    return dataclasses.replace(cell, obstacles=tuple(obs), name="hard-slot"), A, B


def hard_problem(rng: np.random.Generator | int, family: str) -> Problem | None:
    """One candidate of ``family`` (:data:`FAMILIES`) with its start joints, or None when its start
    or goal is not clear on the start's IK branches (not checked: that it is hard and solvable)."""
    if family not in FAMILIES:
        raise ParameterError(f"family: expected one of {FAMILIES}, got {family!r}")
    rng = np.random.default_rng(rng)
    cell, A, B = {"boxes": _boxes, "overhang": _overhang, "slot": _slot}[family](rng)
    world = World(cell)
    home = (cell.left.q_home, cell.right.q_home)
    s = solve_dual(world, A, home, max_step=2 * math.pi, check_clearance=False)
    if not s.ok or world.clearance(s.q_left, s.q_right, A).distance < cell.safety_margin:
        return None
    g = solve_dual(world, B, (s.q_left, s.q_right), max_step=2 * math.pi, check_clearance=False)
    if not g.ok or world.clearance(g.q_left, g.q_right, B).distance < cell.safety_margin:
        return None
    return Problem(cell, A, B, q_start=(s.q_left, s.q_right), tag=family)


def hard_problems(n_per_family: int, seed: int = 0, budget: int = 20_000, families=FAMILIES) -> list[Problem]:
    """``n_per_family`` hard, solvable problems of each family (module docstring); deterministic
    for a seed (it plans every candidate: seconds to minutes)."""
    n_per_family = integer(n_per_family, "n_per_family", lo=0, hi=10_000)
    params = dataclasses.replace(GENERAL_PARAMS, fallback_params=FallbackParams(max_iterations=budget))
    out: list[Problem] = []
    for k, family in enumerate(families):
        rng = np.random.default_rng([seed, k])
        got = 0
        while got < n_per_family:
            prob = hard_problem(rng, family)
            if prob is None:
                continue
            world = World(prob.cell)
            straight = plan(prob.cell, prob.start, prob.goal, dataclasses.replace(params, fallback=False),
                            q_start=prob.q_start, world=world)
            if straight.reached or straight.status != "frozen":
                continue
            if plan(prob.cell, prob.start, prob.goal, params, q_start=prob.q_start, world=world).reached:
                out.append(dataclasses.replace(prob, tag=f"{family}-{got}"))
                got += 1
    return out


def problems_to_json(problems: list[Problem]) -> str:
    """A problem set as JSON: per problem its obstacles (on ``Cell.default()``'s or routine 8's
    arms, bar and margin: the default cell), start, goal, start joints and tag."""
    items = []
    for p in problems:
        items.append({
            "tag": p.tag, "cell": p.cell.name,
            "obstacles": [{"name": o.name, "shape": o.shape, "size": np.asarray(o.size).tolist(),
                           "T_world_obstacle": np.asarray(o.T_world_obstacle).tolist()} for o in p.cell.obstacles],
            "start": np.asarray(p.start).tolist(), "goal": np.asarray(p.goal).tolist(),
            "q_start": [np.asarray(q).tolist() for q in p.q_start],
        })
    return json.dumps({"format": _FORMAT, "problems": items}, indent=1)


def problems_from_json(text: str) -> list[Problem]:
    """Inverse of :func:`problems_to_json` (every cell is ``Cell.default()`` with the obstacles)."""
    try:
        d = json.loads(text)
        if d.get("format") != _FORMAT:
            raise ParameterError(f"not a dualpuma problem set (format {d.get('format')!r})")
        base = Cell.default()
        out = []
        for it in d["problems"]:
            obs = tuple(Obstacle(o["name"], o["shape"], np.array(o["size"], float), np.array(o["T_world_obstacle"], float))
                        for o in it["obstacles"])
            cell = dataclasses.replace(base, obstacles=obs, name=str(it["cell"]))
            out.append(Problem(cell, np.array(it["start"], float), np.array(it["goal"], float),
                               q_start=tuple(np.array(q, float) for q in it["q_start"]), tag=it["tag"]))
        return out
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise ParameterError(f"malformed problem set: {type(e).__name__}: {e}") from e
