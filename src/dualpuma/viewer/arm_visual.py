"""One arm drawn from its URDF's *visual* geometry (yourdfpy + ``viser.extras.ViserUrdf``).

The URDF is the one the arm's Pinocchio model was read from (:attr:`Arm.urdf_path`), so any robot
dualpuma can load is drawn as its URDF describes it (the PUMA 560's shaped primitives, a UR5's
meshes). Joint values are mapped by *name* from Pinocchio's order to yourdfpy's (they need not
agree). The URDF's light "body" colour is tinted with the arm's own colour so that the two arms
are told apart at a glance; darker parts (wrist, gripper) keep their colour.
"""

from __future__ import annotations

from functools import partial

import numpy as np
import numpy.typing as npt
import trimesh
import viser
import yourdfpy
from viser.extras import ViserUrdf

from ..errors import RobotError
from ..lie import quaternion_wxyz

__all__ = ["ArmVisual", "load_visual_urdf"]

FloatArray = npt.NDArray[np.float64]


def load_visual_urdf(arm) -> tuple[yourdfpy.URDF, str]:
    """The arm's URDF loaded by yourdfpy with what it has to show (``package://`` resolved next to
    the file, as ROS packages are laid out): ``(urdf, "visual")``, or ``(urdf, "collision")`` for a
    URDF with collision but no visual geometry, or ``(urdf, "none")`` (frames only: the arm is seen
    through its capsules).

    Raises:
        RobotError: the file or a mesh it names cannot be read.
    """
    path = arm.urdf_path
    handler = partial(yourdfpy.filename_handler_magic, dir=path.parent)
    try:
        urdf = yourdfpy.URDF.load(path, build_scene_graph=True, load_meshes=True, build_collision_scene_graph=False,
                                  load_collision_meshes=False, filename_handler=handler)
        if urdf.scene is not None and urdf.scene.geometry:
            return urdf, "visual"
        urdf = yourdfpy.URDF.load(path, build_scene_graph=True, load_meshes=True, build_collision_scene_graph=True,
                                  load_collision_meshes=True, filename_handler=handler)
    except Exception as exc:  # noqa: BLE001 - yourdfpy/lxml/trimesh raise many kinds
        raise RobotError(f"{path}: cannot load the URDF's geometry: {type(exc).__name__}: {exc}") from None
    if urdf.collision_scene is not None and urdf.collision_scene.geometry:
        return urdf, "collision"
    return urdf, "none"


def _tint(scene, color: tuple[int, int, int]) -> None:
    """Give each mesh of our own loaded URDF scene one colour: ``color`` where its colour is light
    (luminance above 0.7: the body), its own colour otherwise (wrist, gripper, textures' mean)."""
    for mesh in ([] if scene is None else scene.geometry.values()):
        try:
            v = mesh.visual.to_color() if mesh.visual.kind == "texture" else mesh.visual
            base = np.asarray(v.main_color, dtype=float).reshape(-1)
        except Exception:  # noqa: BLE001 - a visual trimesh cannot summarise: draw it in the arm's colour
            base = np.zeros(0)
        if base.size < 4 or not np.all(np.isfinite(base)):
            base = np.array([255.0, 255.0, 255.0, 255.0])
        rgba = np.array([*color, 255], dtype=np.uint8) if base[:3].astype(float).mean() > 0.7 * 255 else base.astype(np.uint8)
        mesh.visual = trimesh.visual.ColorVisuals(mesh=mesh, face_colors=np.tile(rgba, (len(mesh.faces), 1)))


class ArmVisual:
    """The visual geometry of one arm under the scene node ``root`` placed at the arm's base.

    Args:
        server: the viser server.
        arm: a :class:`~dualpuma.kinematics.Arm`.
        T_world_base: (4, 4) the arm's base in the world [m].
        root: scene node name, e.g. ``"/arms/left"``.
        color: RGB 0-255 of the arm's body.
        loaded: the arm's :func:`load_visual_urdf` if already loaded.

    Raises:
        RobotError: the URDF cannot be drawn, or its joints are not the model's.
    """

    def __init__(self, server: viser.ViserServer, arm, T_world_base: npt.ArrayLike, root: str,
                 color: tuple[int, int, int], loaded: tuple[yourdfpy.URDF, str] | None = None) -> None:
        self.arm = arm
        self.T_world_base = np.array(T_world_base, dtype=np.float64)
        self.urdf, self.geometry = loaded if loaded is not None else load_visual_urdf(arm)
        _tint(self.urdf.collision_scene if self.geometry == "collision" else self.urdf.scene, color)
        self.root = server.scene.add_frame(root, show_axes=False, position=tuple(self.T_world_base[:3, 3]),
                                           wxyz=quaternion_wxyz(self.T_world_base[:3, :3]))
        self.viser_urdf = ViserUrdf(server, self.urdf, root_node_name=root,
                                    load_meshes=self.geometry != "collision",
                                    load_collision_meshes=self.geometry == "collision")
        model = arm.model
        names = self.viser_urdf.get_actuated_joint_names()
        # the URDF's configuration: the arm's six joints by name, the locked ones (a gripper) fixed
        self.index: list[int] = []  # model index of each moving URDF joint
        self.slot: list[int] = []  # its position in the URDF's configuration
        self.cfg = np.zeros(len(names))
        for k, name in enumerate(names):
            jid = model.getJointId(name)
            if jid < model.njoints and model.joints[jid].nq == 1:
                self.index.append(model.joints[jid].idx_q)
                self.slot.append(k)
            elif name in arm.locked_joints:
                self.cfg[k] = arm.locked_joints[name]
            else:
                raise RobotError(f"{arm.urdf_path}: joint {name!r} is not a one-DOF joint of the arm's model")
        if sorted(self.index) != list(range(model.nq)):
            raise RobotError(f"{arm.urdf_path}: the URDF's actuated joints do not cover the model's {model.nq}")
        self.q: FloatArray | None = None

    def update(self, q: npt.ArrayLike) -> None:
        """Pose the arm at joints ``q`` (6,) [rad] in Pinocchio's order (call inside ``server.atomic()``)."""
        q = np.asarray(q, dtype=np.float64)
        if self.q is not None and np.array_equal(q, self.q):
            return
        self.q = q.copy()
        self.cfg[self.slot] = q[self.index]
        self.viser_urdf.update_cfg(self.cfg.copy())

    def link_pose(self, link: str) -> FloatArray:
        """World pose (4, 4) of URDF link ``link`` as drawn (after :meth:`update`) [m]."""
        return self.T_world_base @ self.urdf.get_transform(link, self.urdf.base_link)

    @property
    def visible(self) -> bool:
        return bool(self.root.visible)

    @visible.setter
    def visible(self, on: bool) -> None:
        self.root.visible = bool(on)

    def remove(self) -> None:
        """Remove every node of this arm (its children go with the root node)."""
        self.root.remove()
