"""An independent model of an arm's URDF file, built here with Pinocchio from the file itself (not
through dualpuma's Arm): every joint of the file, continuous joints as (cos, sin), the joints
outside the arm's six at neutral (clamped into their limits)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin


def fk_many(model: pin.Model, data: pin.Data, frame_id: int, Q) -> np.ndarray:
    """Pose (N, 4, 4) of one frame at each row of Q, one Pinocchio FK call per row."""
    out = np.empty((len(Q), 4, 4))
    for i, q in enumerate(Q):
        pin.framesForwardKinematics(model, data, q)
        out[i] = data.oMf[frame_id].homogeneous
    return out


class FullUrdf:
    def __init__(self, urdf_path, arm_joint_names, hand_frame: str, package_dirs=()):
        self.model = pin.buildModelFromUrdf(str(urdf_path))
        self.data = self.model.createData()
        self.path, self.package_dirs = str(urdf_path), list(package_dirs)
        self.ids = [self.model.getJointId(n) for n in arm_joint_names]
        assert all(j < self.model.njoints for j in self.ids), arm_joint_names
        hits = [i for i, f in enumerate(self.model.frames) if f.name == hand_frame]
        body = [i for i in hits if self.model.frames[i].type == pin.FrameType.BODY]
        self.hand = (body or hits)[0]

    def q_full(self, q) -> np.ndarray:
        m = self.model
        qf = np.clip(pin.neutral(m), m.lowerPositionLimit, m.upperPositionLimit)
        for j, qi in zip(self.ids, q):
            k = m.idx_qs[j]
            if m.nqs[j] == 2:
                qf[k:k + 2] = np.cos(qi), np.sin(qi)
            else:
                qf[k] = qi
        return qf

    def fk(self, q) -> np.ndarray:
        """The hand frame's pose (4, 4) in the base frame at the arm's six joints ``q``."""
        pin.framesForwardKinematics(self.model, self.data, self.q_full(q))
        return self.data.oMf[self.hand].homogeneous.copy()

    def collision(self):
        """``(geometry model, function q -> list of (geometry object, pose (4, 4)))``."""
        geom = pin.buildGeomFromUrdf(self.model, self.path, pin.COLLISION, package_dirs=self.package_dirs)
        gdata = geom.createData()

        def placements(q):
            pin.forwardKinematics(self.model, self.data, self.q_full(q))
            pin.updateGeometryPlacements(self.model, self.data, geom, gdata)
            return [(go, gdata.oMg[i].homogeneous) for i, go in enumerate(geom.geometryObjects)]

        return geom, placements
