"""Fallback path quality (issue 13, item 5): the whole returned path is smoothed — Striving's
wandering prefix included — and stays certified (independent reference at 20 joint-linear
sub-poses per step)."""

from __future__ import annotations

import dataclasses

import numpy as np
from motion_reference import MotionReference

from dualpuma import Cell, StrivingParams, World, plan
from dualpuma.model import Obstacle


def _pose(yaw_cos, yaw_sin, p):
    T = np.eye(4)
    T[:2, :2] = [[yaw_cos, -yaw_sin], [yaw_sin, yaw_cos]]
    T[:3, 3] = p
    return T


def _overhang():
    """Routine 8's slab and post, moved and turned (hard set problem overhang-4): Striving's seed
    alternates wander around the slab for 20 steps before the fallback takes over."""
    slab = Obstacle("slab", "box", [0.32, 0.08, 0.22],
                    _pose(0.9922314787103635, -0.1244053562200816, (1.7617009153786085, -0.48271629033668667, 0.4152314682138549)))
    post = Obstacle("post", "box", [0.19, 0.08, 0.33],
                    _pose(0.9959594367111378, 0.0898042338981461, (1.7795472746591963, -0.4924316880673294, 0.165)))
    cell = dataclasses.replace(Cell.default(), obstacles=(slab, post))
    A = cell.T_world_object_start
    B = A.copy()
    B[:3, 3] = (1.5626001333624198, -0.23178530363748473, 0.5129983072254353)
    return cell, A, B


def test_whole_path_is_smoothed_and_certified():
    cell, A, B = _overhang()
    world = World(cell)
    p = plan(cell, A, B, StrivingParams(fallback=True), world=world)
    assert p.reached and p.planner == "striving+rrt"
    assert any("took AP" in e for e in p.events)  # Striving did wander before the fallback
    straight = float(np.linalg.norm(B[:3, 3] - A[:3, 3]))
    assert p.path_length <= 1.15 * straight, (p.path_length, straight)  # the prefix's detour is gone
    ref = MotionReference(cell)
    Q = np.hstack([p.q_left, p.q_right])
    for i in range(p.n_steps):
        for s in np.linspace(0.0, 1.0, 21):
            q = Q[i] + s * (Q[i + 1] - Q[i])
            assert ref.clearance(q[:6], q[6:], float(p.t[i]), 0.02)[0] >= 0.02 - 1e-6
