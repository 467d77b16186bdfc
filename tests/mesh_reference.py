"""An independent reference for the close link pairs' mesh distance (tests/test_contact.py, the
certified property): the URDF read by Pinocchio itself, its collision meshes placed by Pinocchio's
FK for the whole six-joint vector, and coal's mesh distance (0 where the meshes intersect)."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin

from dualpuma.kinematics import Arm


class MeshReference:
    """coal's distance between two links' collision meshes at whole joint vectors of the URDF."""

    def __init__(self, arm: Arm) -> None:
        self.model = pin.buildModelFromUrdf(str(arm.urdf_path))
        self.geom = pin.buildGeomFromUrdf(self.model, str(arm.urdf_path), pin.COLLISION, package_dirs=list(arm.package_dirs))
        self.data, self.gd = self.model.createData(), pin.GeometryData(self.geom)
        self.names = [g.name.removesuffix("_0") for g in self.geom.geometryObjects]

    def distance(self, q: np.ndarray, a: str, b: str) -> float:
        pin.updateGeometryPlacements(self.model, self.data, self.geom, self.gd, q)
        ia, ib = self.names.index(a), self.names.index(b)
        tf = [coal.Transform3s(self.gd.oMg[i].rotation, self.gd.oMg[i].translation) for i in (ia, ib)]
        return float(coal.distance(self.geom.geometryObjects[ia].geometry, tf[0], self.geom.geometryObjects[ib].geometry,
                                   tf[1], coal.DistanceRequest(), coal.DistanceResult()))

    def least(self, Q: np.ndarray, pairs) -> tuple[float, tuple[str, str], int]:
        """The smallest mesh distance [m] over configurations Q (N, 6) and pairs (a, b): (d, pair, row)."""
        best = (np.inf, ("", ""), -1)
        for i, q in enumerate(Q):
            for a, b in pairs:
                d = self.distance(q, a, b)
                if d < best[0]:
                    best = (d, (a, b), i)
        return best


#: the UR arms' always-close link pairs (two joints apart), by robot name prefix
UR_CLOSE_PAIRS = (("base_link", "upper_arm_link"), ("forearm_link", "wrist_2_link"), ("wrist_1_link", "wrist_3_link"))


def edited_ur5(folder) -> str:
    """A copy of example-robot-data's UR5 file in ``folder`` whose wrist_2 collision mesh sits 1 mm
    further along its link (its meshes found by absolute paths): a geometry no stored contact map
    was derived for. Returns the file's path."""
    from pathlib import Path

    ur5 = Arm.load("ur5")
    share = next(d for d in ur5.package_dirs if (Path(d) / "example-robot-data").is_dir())
    text = ur5.urdf_path.read_text()
    mesh = text.index("collision/wrist2.stl")
    at = text.rindex("<collision>", 0, mesh) + len("<collision>")
    text = text[:at] + '<origin rpy="0 0 0" xyz="0 0 0.001"/>' + text[at:]
    text = text.replace("package://example-robot-data/", f"{share}/example-robot-data/")
    path = Path(folder) / "ur5_edited.urdf"
    path.write_text(text)
    return str(path)
