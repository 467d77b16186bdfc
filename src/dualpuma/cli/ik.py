"""``dualpuma ik``: all eight closed-form IK branches of an arm (the PUMA 560 by default, or a UR)
for a hand pose (mm and degrees), and why a branch has no solution; an arm without a closed form
gets its numeric solution."""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

import numpy as np

from ..checks import choice
from ..errors import ParameterError
from ..kinematics import BRANCH_NAMES, KNOWN_ROBOTS, Arm, puma
from ..kinematics.limits import LIMIT_TOL
from ..lie import rpy_to_rot
from ..model.cell import MAX_EXTENT
from .common import add_command, add_vector, angles, vector

__all__ = ["register"]

# the wrist centre's distance from the shoulder lies in [R_MIN, R_MAX] (the elbow's law of cosines
# with the offsets A3, D2) and its distance from the J1 axis is at least D2 [m]
_RHO3 = math.hypot(puma.A3, puma.D4)
_K0 = puma.A2**2 + puma.A3**2 + puma.D2**2 + puma.D4**2
_R_MAX = math.sqrt(_K0 + 2 * puma.A2 * _RHO3)
_R_MIN = math.sqrt(max(0.0, _K0 - 2 * puma.A2 * _RHO3))


def _why(arm: Arm, p: np.ndarray, q: np.ndarray, ok: bool) -> tuple[str, str]:
    """(status, reason) of one branch: ``ok``, ``unreachable`` (and where the hand is) or
    ``joint_limits`` (which joints, by how much)."""
    if ok:
        return "ok", ""
    if np.isnan(q).any():
        axis, dist = math.hypot(p[0], p[1]), float(np.linalg.norm(p))
        if arm.robot != "puma560":
            lo, hi = arm.reach_shell  # bounds: the arm reaches no point outside them, not every point inside
            if not lo <= dist <= hi:
                return "unreachable", (f"unreachable: the hand is {dist * 1e3:.1f} mm from the base, outside the "
                                       f"{lo * 1e3:.1f}-{hi * 1e3:.1f} mm that bound the arm's reach")
            return "unreachable", f"unreachable: no solution on this branch (the hand is {dist * 1e3:.1f} mm from the base)"
        if axis < puma.D2:
            where = f"{axis * 1e3:.1f} mm from the J1 axis, closer than the shoulder offset {puma.D2 * 1e3:.1f} mm"
        else:
            where = f"{dist * 1e3:.1f} mm from the shoulder, outside the reachable {_R_MIN * 1e3:.1f}-{_R_MAX * 1e3:.1f} mm"
        return "unreachable", f"unreachable: the wrist centre is {where}"
    lim = arm.limits
    bad = [f"q{j + 1} = {math.degrees(q[j]):.1f} deg not in [{math.degrees(lim[j, 0]):.0f}, "
           f"{math.degrees(lim[j, 1]):.0f}]" for j in range(6)
           if not lim[j, 0] - LIMIT_TOL <= q[j] <= lim[j, 1] + LIMIT_TOL]
    return "joint_limits", "outside the joint limits: " + "; ".join(bad)


def _rows(arm: Arm, T: np.ndarray) -> list[dict]:
    if not arm.analytic:  # one numeric solution (damped least squares from fixed restarts)
        r = arm.ik(T)
        return [{"branch": "numeric", "valid": r.ok, "status": str(r.status), "reason": r.reason,
                 "q_deg": None if r.q is None else np.rad2deg(r.q).round(6).tolist()}]
    sols, valid = arm.ik_all(T)
    rows = []
    for name, s, v in zip(BRANCH_NAMES, sols, valid):
        status, reason = _why(arm, T[:3, 3], s, bool(v))
        rows.append({"branch": name, "valid": bool(v), "status": status, "reason": reason,
                     "q_deg": None if np.isnan(s).any() else np.rad2deg(s).round(6).tolist()})
    return rows


def _run(args: argparse.Namespace) -> int:
    arm = Arm.load(choice(args.robot, KNOWN_ROBOTS, "--robot"))
    p = vector(args.xyz, 3, "--xyz [mm]") / 1000.0
    if np.abs(p).max() > MAX_EXTENT:  # far beyond any arm; the solvers' arithmetic overflowed there
        raise ParameterError(f"--xyz: expected coordinates within ±{MAX_EXTENT * 1000.0:g} mm, got {(p * 1000.0).tolist()}")
    rpy = np.deg2rad(angles(args.rpy, 3, "--rpy"))
    T = np.eye(4)
    T[:3, :3] = rpy_to_rot(rpy)
    T[:3, 3] = p
    rows = _rows(arm, T)
    if args.json:
        print(json.dumps({"robot": arm.robot, "frame": arm.hand_frame, "xyz_mm": (p * 1000).tolist(),
                          "rpy_deg": np.rad2deg(rpy).tolist(), "T_base_hand": T.tolist(), "solutions": rows}, indent=2))
    else:
        what = "wrist centre" if arm.robot == "puma560" else f"hand frame {arm.hand_frame!r}"
        print(f"{arm.robot} {what} at {np.round(p * 1000, 3).tolist()} mm, rpy "
              f"{np.round(np.rad2deg(rpy), 3).tolist()} deg (base frame):")
        for r in rows:
            q = " ".join(f"{a:9.3f}" for a in r["q_deg"]) + " deg" if r["valid"] else r["reason"]
            print(f"  {r['branch']:<18} {'ok ' if r['valid'] else 'no '} {q}")
        print(f"  {sum(r['valid'] for r in rows)} of {len(rows)} {'branches' if arm.analytic else 'solutions'} valid")
    return 0 if any(r["valid"] for r in rows) else 1  # like plan: 1 = no answer (each row says why)


def register(sub: Any) -> None:
    """Add the ``ik`` command."""
    s = add_command(
        sub, "ik", "all eight IK branches of an arm for a hand pose (mm, degrees)",
        "All eight closed-form IK branches (shoulder left/right, elbow up/down, wrist noflip/flip) of\n"
        "an arm for a pose of its hand frame in its base frame (the PUMA 560's wrist centre in the\n"
        "shoulder frame by default; --robot ur5 etc.): position [mm] and roll-pitch-yaw [deg]\n"
        "(R = Rz(yaw) Ry(pitch) Rx(roll), as 'dualpuma fk' prints them). A branch without a solution\n"
        "says why: out of reach, or which joints leave their limits. An arm without a closed form\n"
        "(z1, kinova) gets one numeric solution. Exit code 0 if some branch is valid, 1 if none, 2 for\n"
        "bad input.",
        ("dualpuma ik --xyz 500 150 -200 --rpy 0 90 0", "dualpuma ik --xyz '500,150,-200' --rpy '0,90,0' --json",
         "dualpuma ik --robot ur5 --xyz 400 100 300 --rpy 180 0 0"),
    )
    s.add_argument("--robot", default="puma560", help=f"the arm: {', '.join(KNOWN_ROBOTS)} (default puma560)")
    add_vector(s, "--xyz", 3, "mm", "the hand frame's position in the base frame (the PUMA 560's wrist centre in its shoulder frame)", required=True)
    add_vector(s, "--rpy", 3, "deg", "roll pitch yaw", default=(0, 0, 0))
    s.add_argument("--json", action="store_true", help="print JSON")
    s.set_defaults(func=_run)
