"""The ends of the RRT-Connect fallback's search (:mod:`.rrt`): the start checked (both hands at
their grasps, the joints inside the limits, the clearance at least the margin) and the goal solved
on the start's IK branches, which are the goal tree's roots."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ..collision.contact import contact_reason, self_contact
from ..kinematics.dual import hands_from_object
from ..kinematics.providers import wrist_partner
from .edges import EdgeChecker

__all__ = ["root_checks"]

FloatArray = npt.NDArray[np.float64]


def root_checks(
    ctx: EdgeChecker, A: FloatArray, q0: tuple[FloatArray, FloatArray], B: FloatArray
) -> tuple[str, float, list[tuple[FloatArray, FloatArray, float]]]:
    """(reason, start clearance, goal roots): the goal solved on the start's IK branches and their
    wrist partners (up to 4 permitted combinations, the goal tree's roots: joints and clearance);
    reason "" if fine."""
    w = ctx.world
    for s, H, q in zip(("left", "right"), w.hand_poses(*q0), q0):
        if not np.allclose(H, A @ w.T_object_hand[s], rtol=0.0, atol=1e-6):
            return (
                f"invalid start: the {s} hand is not at its grasp of the start pose",
                math.nan,
                [],
            )
        if not np.all(w.arms[s].within_limits(q, tol=1e-12)):
            return f"invalid start: {s} arm joints outside the limits", math.nan, []
    touch = self_contact(w, q0[0], q0[1])[0]  # (the cheaper check first)
    if touch is not None:
        return f"invalid start: {contact_reason(*touch)}", math.nan, []
    c = w.clearance(q0[0], q0[1], A, ctx.t0)
    if c.distance < ctx.margin:
        return (
            f"invalid start: clearance {c.distance:.4f} m below the margin {ctx.margin:.3f} m ({c.pair[0]} – {c.pair[1]})",
            c.distance,
            [],
        )
    options: list[list[FloatArray]] = []
    for k, (s, T_bh) in enumerate(zip(("left", "right"), hands_from_object(w.cell, B))):
        arm = w.arms[s]
        if arm.analytic:  # the start's branch and its wrist partner (reached through q5 = 0)
            b = arm.branch_of(q0[k])
            rs = [arm.ik(T_bh, config=c, q_near=q0[k]) for c in (b, wrist_partner(b))]
        else:
            rs = [arm.ik(T_bh, q_near=q0[k])]
        ok = [np.array(r.q, dtype=float) for r in rs if r.ok]
        if not ok:
            r = rs[0]
            return (
                f"goal unreachable: {s} arm IK on the start's branch: {r.status}: {r.reason}",
                c.distance,
                [],
            )
        options.append(ok)
    tg = float(ctx.t_lb(B[None])[0])
    roots, worst, touching = [], None, None
    for qL in options[0]:
        for qR in options[1]:
            touch = self_contact(w, qL, qR)[0]
            if touch is not None:
                touching = touching or touch
                continue
            cg = w.clearance(qL, qR, B, tg)
            if cg.distance >= ctx.margin:
                roots.append((qL, qR, cg.distance))
            elif worst is None or cg.distance < worst.distance:
                worst = cg
    if not roots and worst is None and touching is not None:
        return f"goal blocked: at the goal pose {contact_reason(*touching)}", c.distance, []
    if not roots and worst is not None:
        return (
            (
                f"goal blocked: clearance at the goal pose itself is {worst.distance:.4f} m, below the "
                f"margin {ctx.margin:.3f} m ({worst.pair[0]} – {worst.pair[1]}, t = {tg:.2f} s)"
            ),
            c.distance,
            [],
        )
    return "", c.distance, roots
