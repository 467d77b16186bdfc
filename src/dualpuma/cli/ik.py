"""``dualpuma ik``: all eight PUMA IK branches for a wrist pose (mm and degrees), and why a branch
has no solution."""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

import numpy as np

from ..kinematics import puma
from ..kinematics.limits import LIMIT_TOL
from ..lie import rpy_to_rot
from .common import add_command, add_vector, vector

__all__ = ["register"]

# the wrist centre's distance from the shoulder lies in [R_MIN, R_MAX] (the elbow's law of cosines
# with the offsets A3, D2) and its distance from the J1 axis is at least D2 [m]
_RHO3 = math.hypot(puma.A3, puma.D4)
_K0 = puma.A2**2 + puma.A3**2 + puma.D2**2 + puma.D4**2
_R_MAX = math.sqrt(_K0 + 2 * puma.A2 * _RHO3)
_R_MIN = math.sqrt(max(0.0, _K0 - 2 * puma.A2 * _RHO3))


def _why(p: np.ndarray, q: np.ndarray, ok: bool) -> tuple[str, str]:
    """(status, reason) of one branch: ``ok``, ``unreachable`` (and where the wrist centre is) or
    ``joint_limits`` (which joints, by how much)."""
    if ok:
        return "ok", ""
    if np.isnan(q).any():
        axis, dist = math.hypot(p[0], p[1]), float(np.linalg.norm(p))
        if axis < puma.D2:
            where = f"{axis * 1e3:.1f} mm from the J1 axis, closer than the shoulder offset {puma.D2 * 1e3:.1f} mm"
        else:
            where = f"{dist * 1e3:.1f} mm from the shoulder, outside the reachable {_R_MIN * 1e3:.1f}-{_R_MAX * 1e3:.1f} mm"
        return "unreachable", f"unreachable: the wrist centre is {where}"
    lim = puma.JOINT_LIMITS
    bad = [f"q{j + 1} = {math.degrees(q[j]):.1f} deg not in [{math.degrees(lim[j, 0]):.0f}, "
           f"{math.degrees(lim[j, 1]):.0f}]" for j in range(6)
           if not lim[j, 0] - LIMIT_TOL <= q[j] <= lim[j, 1] + LIMIT_TOL]
    return "joint_limits", "outside the joint limits: " + "; ".join(bad)


def _run(args: argparse.Namespace) -> int:
    p = vector(args.xyz, 3, "--xyz [mm]") / 1000.0
    rpy = np.deg2rad(vector(args.rpy, 3, "--rpy [deg]"))
    T = np.eye(4)
    T[:3, :3] = rpy_to_rot(rpy)
    T[:3, 3] = p
    sols, valid = puma.ik_all(T)
    rows = []
    for name, s, v in zip(puma.BRANCH_NAMES, sols, valid):
        status, reason = _why(p, s, bool(v))
        rows.append({"branch": name, "valid": bool(v), "status": status, "reason": reason,
                     "q_deg": None if np.isnan(s).any() else np.rad2deg(s).round(6).tolist()})
    if args.json:
        print(json.dumps({"xyz_mm": (p * 1000).tolist(), "rpy_deg": np.rad2deg(rpy).tolist(),
                          "T_base_wrist": T.tolist(), "solutions": rows}, indent=2))
    else:
        print(f"PUMA 560 wrist centre at {np.round(p * 1000, 3).tolist()} mm, rpy "
              f"{np.round(np.rad2deg(rpy), 3).tolist()} deg (shoulder frame):")
        for r in rows:
            q = " ".join(f"{a:9.3f}" for a in r["q_deg"]) + " deg" if r["valid"] else r["reason"]
            print(f"  {r['branch']:<18} {'ok ' if r['valid'] else 'no '} {q}")
        print(f"  {int(valid.sum())} of 8 branches valid")
    return 0


def register(sub: Any) -> None:
    """Add the ``ik`` command."""
    s = add_command(
        sub, "ik", "all eight PUMA 560 IK branches for a wrist pose (mm, degrees)",
        "All eight closed-form IK branches (shoulder left/right, elbow up/down, wrist noflip/flip) of\n"
        "the PUMA 560 for a wrist-centre pose in the shoulder frame: position [mm] and roll-pitch-yaw\n"
        "[deg] (R = Rz(yaw) Ry(pitch) Rx(roll), as 'dualpuma fk' prints them). A branch without a\n"
        "solution says why: the wrist centre is out of reach, or which joints leave their limits.",
        ("dualpuma ik --xyz 500 150 -200 --rpy 0 90 0", "dualpuma ik --xyz '500,150,-200' --json"),
    )
    add_vector(s, "--xyz", 3, "mm", "wrist centre in the shoulder frame", required=True)
    add_vector(s, "--rpy", 3, "deg", "roll pitch yaw", default=(0, 0, 0))
    s.add_argument("--json", action="store_true", help="print JSON")
    s.set_defaults(func=_run)
