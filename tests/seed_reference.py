"""Independent references transcribed from the seed's Pascal listing (not from dualpuma's code).

``seed_calctran`` is procedure CalcTran entry by entry (scale factor dropped, SI metres): the
reference the URDF + Pinocchio and dualpuma.puma.fk are both checked against.
"""

from __future__ import annotations

import numpy as np

A2, A3, D2, D4 = 0.4318, -0.02032, 0.14909, 0.43307  # the seed's param[3][2], [4][2], [3][3], [4][3] / 1000

# Joint values commanded by the seed (radians, as printed in the listing)
ROUTINE1_LEFT = {
    "hover": [-2.618, -0.524, 0.524, 0.0, 0.0, -1.047],
    "vice": [-0.721, 0.284, -0.649, 2.387, 1.300, -2.895],
}
ROUTINE1_RIGHT = {
    "hover": [-2.385, 0.363, -0.023, -2.431, 1.835, -2.877],
    "drill": [-2.752, 0.294, -0.208, -2.826, 1.655, -3.070],
}
FLAG2_LEFT = [-0.5123, 0.1847, -0.8479, 0.0, 0.6632, -0.5123]
FLAG2_RIGHT = [-1.7703, 0.1833, 0.3838, 0.0, -0.5671, -1.7703]


def seed_calctran(q: np.ndarray) -> np.ndarray:
    """CalcTran for one joint vector: 4x4 hand (wrist-centre) pose in the shoulder frame [m]."""
    t1, t2, t3, t4, t5, t6 = q
    C1, S1 = np.cos(t1), np.sin(t1)
    C2, S2 = np.cos(t2), np.sin(t2)
    C23, S23 = np.cos(t2 + t3), np.sin(t2 + t3)
    C4, S4 = np.cos(t4), np.sin(t4)
    C5, S5 = np.cos(t5), np.sin(t5)
    C6, S6 = np.cos(t6), np.sin(t6)
    T = np.eye(4)
    T[0, 3] = C1 * (A2 * C2 - 20.32e-3 * C23 - D4 * S23) - D2 * S1
    T[1, 3] = S1 * (A2 * C2 - 20.32e-3 * C23 - D4 * S23) + D2 * C1
    T[2, 3] = 20.32e-3 * S23 - A2 * S2 - D4 * C23
    T[0, 0] = C1 * (C23 * (C4 * C5 * C6 - S4 * S6) - S23 * S5 * C6) + S1 * (S4 * C5 * C6 + C4 * S6)
    T[1, 0] = S1 * (C23 * (C4 * C5 * C6 - S4 * S6) - S23 * S5 * C6) - C1 * (S4 * C5 * C6 + C4 * S6)
    T[2, 0] = -S23 * (C4 * C5 * C6 - S4 * S6) - C23 * S5 * C6
    T[0, 1] = C1 * (-C23 * (C4 * C5 * S6 + S4 * C6) + S23 * S5 * S6) + S1 * (-S4 * C5 * S6 + C4 * C6)
    T[1, 1] = S1 * (-C23 * (C4 * C5 * S6 + S4 * C6) + S23 * S5 * S6) - C1 * (-S4 * C5 * S6 + C4 * C6)
    T[2, 1] = S23 * (C4 * C5 * S6 + S4 * C6) + C23 * S5 * S6
    T[0, 2] = -C1 * (C23 * C4 * S5 + S23 * C5) - S1 * S4 * S5
    T[1, 2] = -S1 * (C23 * C4 * S5 + S23 * C5) + C1 * S4 * S5
    T[2, 2] = S23 * C4 * S5 - C23 * C5
    return T


def seed_invkin_arm(T: np.ndarray, chars: tuple[int, int, int]) -> np.ndarray:
    """The seed's InvKin (first three joints and the no-flip/flip wrist), transcribed."""
    px, py, pz = T[:3, 3]
    t1 = np.arctan2(py, px) - np.arctan2(D2, chars[0] * np.sqrt(px**2 + py**2 - D2**2))
    inter1 = (px**2 + py**2 + pz**2 - A2**2 - A3**2 - D2**2 - D4**2) / (2 * A2)
    t3 = np.arctan2(A3, D4) - np.arctan2(inter1, chars[1] * np.sqrt(A3**2 + D4**2 - inter1**2))
    c1r = np.cos(t1) * px + np.sin(t1) * py
    inter2 = np.arctan2(
        pz * (-A3 - A2 * np.cos(t3)) - c1r * (D4 - A2 * np.sin(t3)),
        pz * (A2 * np.sin(t3) - D4) + (A3 + A2 * np.cos(t3)) * c1r,
    )
    t2 = inter2 - t3
    ax, ay, az = T[:3, 2]
    c1, s1 = np.cos(t1), np.sin(t1)
    c23, s23 = np.cos(t2 + t3), np.sin(t2 + t3)
    inter3 = -ax * s1 + ay * c1
    inter4 = -ax * c1 * c23 - ay * s1 * c23 + az * s23
    t4 = np.arctan2(inter3, inter4)
    c4, s4 = np.cos(t4), np.sin(t4)
    t5 = np.arctan2(
        az * s23 * c4 - ax * (c1 * c23 * c4 + s1 * s4) - ay * (s1 * c23 * c4 - c1 * s4),
        -ax * c1 * s23 - ay * s1 * s23 - az * c23,
    )
    nx, ny, nz = T[:3, 0]
    c5, s5 = np.cos(t5), np.sin(t5)
    t6 = np.arctan2(
        -nx * (c1 * c23 * s4 - s1 * c4) - ny * (s1 * c23 * s4 + c1 * c4) + nz * s23 * s4,
        nx * ((c1 * c23 * c4 + s1 * s4) * c5 - c1 * s23 * s5)
        + ny * (c5 * (s1 * c23 * c4 - c1 * s4) - s1 * s23 * s5)
        - nz * (s23 * c4 * c5 + c23 * s5),
    )
    if chars[2] == -1:
        t4, t5, t6 = t4 + np.pi, -t5, t6 + np.pi
    return np.array([t1, t2, t3, t4, t5, t6])


def seed_calcrot(rpy) -> np.ndarray:
    """Procedure CalcRot, entry by entry (rpy[1] roll, rpy[2] pitch, rpy[3] yaw)."""
    r1, r2, r3 = rpy
    c, s = np.cos, np.sin
    return np.array(
        [
            [c(r3) * c(r2), c(r3) * s(r2) * s(r1) - s(r3) * c(r1), c(r3) * s(r2) * c(r1) + s(r3) * s(r1)],
            [s(r3) * c(r2), s(r3) * s(r2) * s(r1) + c(r3) * c(r1), s(r3) * s(r2) * c(r1) - c(r3) * s(r1)],
            [-s(r2), c(r2) * s(r1), c(r2) * c(r1)],
        ]
    )
