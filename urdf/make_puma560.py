"""Generate urdf/puma560.urdf (the seed's PUMA 560 convention) from its DH table.

Run: python urdf/make_puma560.py > urdf/puma560.urdf   (tests check the committed file is current)

Kinematics: standard DH rows (theta, d, a, alpha) of src/dualpuma/puma.py. Link i's frame is DH
frame i (so joint i+1 rotates about link i's z axis); joint i+1's <origin> is
Tz(d_i) Tx(a_i) Rx(alpha_i).

Collision convention: every <collision> whose <geometry> is a <cylinder> is read by dualpuma as a
CAPSULE (coal.Capsule(radius, length)): the cylinder's axis (local z, centred on its origin) is the
capsule's segment and hemispherical caps of the same radius extend beyond both ends. The collision
element's name tells the capsule's role (e.g. "forearm"). Radii and lengths are listed in CAPSULES
below and in docs/kinematics.md.
"""

from __future__ import annotations

import math
import sys

A2, A3, D2, D4 = 0.4318, -0.02032, 0.14909, 0.43307
D_FLANGE = 0.05625
TCP = 0.12  # gripper frame (tool centre point between the fingers) along the approach axis [m]
SHOULDER_HEIGHT = 0.6604
LIMITS_DEG = [(-160, 160), (-225, 45), (-225, 45), (-266, 266), (-100, 100), (-266, 266)]
# DH rows (d, a, alpha) for joints 1..6
DH = [(0.0, 0.0, -math.pi / 2), (D2, A2, 0.0), (0.0, A3, -math.pi / 2), (D4, 0.0, math.pi / 2),
      (0.0, 0.0, -math.pi / 2), (0.0, 0.0, 0.0)]
# Unimation PUMA 560 rated joint speeds are not modelled; values are nominal placeholders for parsers.
VEL = [2.0] * 6
EFFORT = [97.6, 186.4, 89.4, 24.2, 20.1, 21.3]  # peak motor-side torques are not used by dualpuma

H = math.pi / 2


def f(x: float) -> str:
    x = float(x)
    return "0.0" if abs(x) < 1e-15 else repr(x)


def origin(xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)) -> str:
    return f'<origin xyz="{" ".join(f(v) for v in xyz)}" rpy="{" ".join(f(v) for v in rpy)}"/>'


# (link, name, radius, p0, p1) capsules in link coordinates: the segment p0 -> p1
CAPSULES = {
    "base": [("pedestal", 0.12, (0.0, 0.0, -SHOULDER_HEIGHT + 0.12), (0.0, 0.0, -0.30))],
    "link1": [("column", 0.11, (0.0, 0.0, -0.24), (0.0, 0.0, 0.0))],
    # link1 frame after Rx(-90) -> link2: z along the shoulder axis, x along the upper arm
    "link2": [("shoulder", 0.10, (0.0, 0.0, -0.08), (0.0, 0.0, D2 - 0.04)),
              ("upper_arm", 0.075, (0.0, 0.0, D2), (A2, 0.0, D2))],
    "link3": [("elbow", 0.07, (A3, 0.0, -0.06), (A3, 0.0, 0.06)),
              ("forearm", 0.05, (A3, 0.0, 0.0), (A3, D4 - 0.07, 0.0))],
    "link5": [("wrist", 0.045, (0.0, 0.0, -0.03), (0.0, 0.0, 0.03))],
    "link6": [("gripper", 0.035, (0.0, 0.0, 0.03), (0.0, 0.0, TCP + 0.02))],
}
BODY, DARK, GREY = "0.86 0.86 0.82 1", "0.22 0.22 0.24 1", "0.55 0.55 0.58 1"  # body parts are tinted per arm
UA = 0.08  # upper-arm thickness along the shoulder axis [m]
PED_LOW = -SHOULDER_HEIGHT + 0.12  # the pedestal capsule's lower end (its cap touches the floor) [m]
# Every drawn primitive lies inside the arm's collision capsules (tests/test_puma.py samples them over
# random joint values): what the viewer draws is never closer to anything than what the planner checks.
VISUALS = {  # (kind, size, xyz, rpy, rgba): shaped primitives that read as a PUMA 560
    # the pedestal (a rounded foot on the floor, a flange under the trunk)
    "base": [("sphere", (0.118,), (0, 0, PED_LOW), (0, 0, 0), GREY),
             ("cylinder", (0.118, -0.30 - PED_LOW), (0, 0, (PED_LOW - 0.30) / 2), (0, 0, 0), GREY),
             ("cylinder", (0.112, 0.03), (0, 0, -0.285), (0, 0, 0), DARK)],
    # trunk (turns with q1) and the shoulder housing across it (axis = joint 2 = link1's +y)
    "link1": [("cylinder", (0.105, 0.25), (0, 0, -0.125), (0, 0, 0), BODY),
              ("cylinder", (0.095, 0.2), (0, 0.0, 0), (H, 0, 0), BODY)],
    # upper arm: a flat member offset by d2 along the shoulder axis, wide at the shoulder, rounded ends
    "link2": [("cylinder", (0.095, 0.13), (0, 0, 0.055), (0, 0, 0), BODY),
              ("box", (A2 / 2, 0.125, UA), (A2 / 4, 0, D2), (0, 0, 0), BODY),
              ("box", (A2 / 2, 0.11, UA), (3 * A2 / 4, 0, D2), (0, 0, 0), BODY),
              ("cylinder", (0.06, UA), (0, 0, D2), (0, 0, 0), BODY),
              ("cylinder", (0.06, UA), (A2, 0, D2), (0, 0, 0), BODY),
              ("cylinder", (0.045, 0.015), (0, 0, D2 + UA / 2 + 0.0075), (0, 0, 0), DARK),
              ("cylinder", (0.045, 0.015), (A2, 0, D2 + UA / 2 + 0.0075), (0, 0, 0), DARK)],
    # forearm: elbow housing, then tapering towards the wrist (along link3's +y)
    "link3": [("cylinder", (0.065, 0.11), (A3, 0, 0), (0, 0, 0), BODY),
              ("cylinder", (0.048, 0.2), (A3, 0.1, 0), (H, 0, 0), BODY),
              ("cylinder", (0.042, D4 - 0.26), (A3, 0.2 + (D4 - 0.26) / 2, 0), (H, 0, 0), BODY)],
    # wrist: the q4 drum at the forearm's end and the bearings of joint 5 (axis = link4's y)
    "link4": [("cylinder", (0.045, 0.05), (0, 0, D4 - 0.085), (0, 0, 0), DARK),
              ("cylinder", (0.018, 0.01), (0, 0.035, D4), (H, 0, 0), DARK),
              ("cylinder", (0.018, 0.01), (0, -0.035, D4), (H, 0, 0), DARK)],
    "link5": [("sphere", (0.04,), (0, 0, 0), (0, 0, 0), GREY),
              ("cylinder", (0.03, 0.08), (0, 0, 0), (0, 0, 0), DARK)],
    # flange and a parallel gripper (fingers reach the TCP)
    "link6": [("cylinder", (0.032, D_FLANGE), (0, 0, D_FLANGE / 2), (0, 0, 0), GREY),
              ("box", (0.056, 0.03, 0.02), (0, 0, D_FLANGE + 0.01), (0, 0, 0), DARK),
              ("box", (0.01, 0.02, 0.075), (0.02, 0, D_FLANGE + 0.0575), (0, 0, 0), DARK),
              ("box", (0.01, 0.02, 0.075), (-0.02, 0, D_FLANGE + 0.0575), (0, 0, 0), DARK)],
}


def seg_to_cyl(p0, p1):
    """Cylinder origin (centre, rpy) whose local z axis runs p0 -> p1, and its length."""
    d = [b - a for a, b in zip(p0, p1)]
    length = math.sqrt(sum(x * x for x in d))
    c = [(a + b) / 2 for a, b in zip(p0, p1)]
    ux, uy, uz = (x / length for x in d)
    # rotate z onto u: pitch about y then yaw about z (URDF rpy = Rz(yaw) Ry(pitch) Rx(roll))
    pitch = math.acos(max(-1.0, min(1.0, uz)))
    yaw = math.atan2(uy, ux) if abs(ux) + abs(uy) > 1e-12 else 0.0
    return c, (0.0, pitch, yaw), length


def geometry(kind, size):
    if kind == "cylinder":
        return f'<cylinder radius="{f(size[0])}" length="{f(size[1])}"/>'
    if kind == "box":
        return f'<box size="{" ".join(f(v) for v in size)}"/>'
    return f'<sphere radius="{f(size[0])}"/>'


def link(name: str) -> str:
    out = [f'  <link name="{name}">']
    for i, (kind, size, xyz, rpy, rgba) in enumerate(VISUALS.get(name, [])):
        out.append(f'    <visual name="{name}_v{i}">{origin(xyz, rpy)}<geometry>{geometry(kind, size)}</geometry>'
                   f'<material name="{name}_m{i}"><color rgba="{rgba}"/></material></visual>')
    for cname, r, p0, p1 in CAPSULES.get(name, []):
        c, rpy, length = seg_to_cyl(p0, p1)
        out.append(f'    <collision name="{cname}">{origin(c, rpy)}'
                   f'<geometry><cylinder radius="{f(r)}" length="{f(length)}"/></geometry></collision>')
    out.append('    <inertial><mass value="1.0"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>')
    out.append("  </link>")
    return "\n".join(out)


def main() -> None:
    w = sys.stdout.write
    w('<?xml version="1.0"?>\n<!-- Generated by urdf/make_puma560.py: do not edit by hand. -->\n')
    w('<!-- PUMA 560 in the seed (CoordSim) convention: base frame at the shoulder, "wrist" = the seed\'s hand\n'
      '     frame at the wrist centre. Collision cylinders are CAPSULES (see make_puma560.py). -->\n')
    w('<robot name="puma560">\n')
    names = ["base", "link1", "link2", "link3", "link4", "link5", "link6"]
    for n in names:
        w(link(n) + "\n")
    for i in range(6):
        if i == 0:
            xyz, rpy = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        else:
            d, a, alpha = DH[i - 1]
            xyz, rpy = (a, 0.0, d), (alpha, 0.0, 0.0)
        lo, hi = (math.radians(v) for v in LIMITS_DEG[i])
        w(f'  <joint name="joint{i + 1}" type="revolute"><parent link="{names[i]}"/><child link="{names[i + 1]}"/>'
          f'{origin(xyz, rpy)}<axis xyz="0 0 1"/><limit lower="{f(lo)}" upper="{f(hi)}" effort="{EFFORT[i]}" velocity="{VEL[i]}"/></joint>\n')
    for name, z in (("wrist", 0.0), ("flange", D_FLANGE), ("gripper", TCP)):
        w(f'  <link name="{name}"/>\n')
        w(f'  <joint name="{name}_fixed" type="fixed"><parent link="link6"/><child link="{name}"/>{origin((0, 0, z))}</joint>\n')
    w("</robot>\n")


if __name__ == "__main__":
    main()
