"""Scene nodes of the viewer. Built when a cell is shown (:meth:`Scene.set_world`), then only moved.

* both arms from their URDF *visual* geometry (:class:`~dualpuma.viewer.arm_visual.ArmVisual`),
  one colour per arm (:data:`ARM_COLORS`); their collision capsules as a toggle (translucent);
* the held bar and the obstacles (moving ones move with the playback's time), the grown obstacles
  of the configuration mapping (toggle), the idealised coordinated work-envelope arcs and the real
  envelope's x–z section (toggles, off by default);
* floor grid, world/base/hand/object frames (toggle), the planned path, and the closest pair with
  its distance (green, red below the margin).

:meth:`Scene.update` only sets poses and properties (call it inside ``server.atomic()``, from the
thread that made the clearance query: it reads that thread's coal placements). :meth:`Scene.points`
gives what a camera must see (:func:`~dualpuma.viewer.camera.frame_points`).
"""

from __future__ import annotations

import numpy as np
import viser

from ..collision import grown_obstacles
from ..envelope import ideal_envelope, real_envelope
from ..errors import DualpumaError
from ..kinematics.puma import A2, A3, D2, D4
from ..lie import quaternion_wxyz as wxyz
from .arm_visual import ArmVisual, load_visual_urdf

__all__ = ["ARM_COLORS", "COLORS", "Scene", "capsule_mesh"]

ARM_COLORS = {"left": (236, 150, 40), "right": (50, 120, 215)}  #: body colour of each arm (RGB)
COLORS = {  #: colours of everything else (RGB); the view tab's legend lists them
    "bar": (70, 70, 80),
    "obstacle": (170, 60, 60),
    "grown": (240, 160, 60),
    "envelope": (120, 60, 200),
    "real_envelope": (20, 150, 110),
    "path": (250, 200, 30),
    "clear": (30, 170, 60),
    "collision": (230, 30, 30),
}
_VISIBLE = {"arms": True, "capsules": False, "frames": True, "grown": False, "envelope": False, "real_envelope": False}


def capsule_mesh(radius: float, length: float, n: int = 16, rings: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """Triangle mesh of a capsule along local z, centred at the origin: (vertices, faces)."""
    verts = []
    for k in range(rings + 1):  # top hemisphere, pole to equator
        phi = np.pi / 2 * (1 - k / rings)
        for j in range(n):
            th = 2 * np.pi * j / n
            verts.append((radius * np.cos(phi) * np.cos(th), radius * np.cos(phi) * np.sin(th), length / 2 + radius * np.sin(phi)))
    for k in range(rings + 1):  # bottom hemisphere, equator to pole
        phi = -np.pi / 2 * k / rings
        for j in range(n):
            th = 2 * np.pi * j / n
            verts.append((radius * np.cos(phi) * np.cos(th), radius * np.cos(phi) * np.sin(th), -length / 2 + radius * np.sin(phi)))
    faces = []
    rows = 2 * (rings + 1)
    for r in range(rows - 1):
        for j in range(n):
            a, b = r * n + j, r * n + (j + 1) % n
            c, d = a + n, b + n
            faces += [(a, c, b), (b, c, d)]
    return np.array(verts, np.float32), np.array(faces, np.uint32)


class Scene:
    """All nodes of one viewer; see the module docstring."""

    def __init__(self, server: viser.ViserServer, world) -> None:
        self.server = server
        self.visible = dict(_VISIBLE)
        s = server.scene
        s.set_up_direction("+z")
        self.cell_root = None  # the frame every cell-dependent node hangs under (not the arms)
        self.generation = 0  # cells shown so far: a part of every cell-dependent node's name
        self.arms: dict[str, ArmVisual] = {}
        self.geom_nodes: dict[int, object] = {}
        self.capsules: dict[int, object] = {}
        self.grown: list = []
        self.frames = {"world": s.add_frame("/frames/world", axes_length=0.25, axes_radius=0.006)}
        for side in ("left", "right"):
            self.frames[f"{side}_hand"] = s.add_frame(f"/frames/{side}_hand", axes_length=0.1, axes_radius=0.004)
        self.frames["object"] = s.add_frame("/frames/object", axes_length=0.12, axes_radius=0.005)
        self.closest = s.add_line_segments("/closest", np.zeros((1, 2, 3)), colors=COLORS["clear"], thickness=4.0,
                                           thickness_units="screen")
        self.closest_label = s.add_label("/closest/label", "")
        self.path = s.add_line_segments("/path", np.zeros((1, 2, 3)), colors=COLORS["path"], thickness=3.0,
                                        thickness_units="screen")
        self.path.visible = False
        self.world = None
        self.set_world(world)

    # ------------------------------------------------------------------ building (rare)
    def set_world(self, world) -> None:
        """Show another cell's World: every cell-dependent node is rebuilt (toggles are kept).

        The new nodes get names no earlier cell used (``/cell<n>/...``, ``/arms/<side><n>``): a
        browser keeps a removed node's pose for a new node of the same name unless the new pose
        is sent, and viser sends none that equals its default (a UR5 base with no turn was drawn
        turned like the PUMA base before it, until the page was reloaded).

        Raises:
            RobotError: an arm's URDF geometry cannot be loaded (the scene is left as it was).
        """
        keep, loaded = {}, {}
        for side in ("left", "right"):  # an arm of the same robot on the same base is kept
            arm = self.arms.get(side)
            if (arm is not None and arm.arm.urdf_path == world.arms[side].urdf_path
                    and np.array_equal(arm.T_world_base, world.T_world_base[side])):
                keep[side] = arm
            else:
                loaded[side] = load_visual_urdf(world.arms[side])  # may raise: nothing removed yet
        if self.cell_root is not None:
            self.cell_root.remove()  # every cell-dependent node goes with it
        for side, arm in self.arms.items():
            if side not in keep:
                arm.remove()
        self.geom_nodes, self.capsules, self.grown = {}, {}, []
        self.world, self.cell = world, world.cell
        self.generation += 1
        s, root = self.server.scene, f"/cell{self.generation}"
        self.cell_root = s.add_frame(root, show_axes=False)
        lo, hi = self._extent()
        s.add_grid(f"{root}/floor", width=float(hi[0] - lo[0]), height=float(hi[1] - lo[1]), cell_size=0.1,
                   position=(float(lo[0] + hi[0]) / 2, float(lo[1] + hi[1]) / 2, float(self.cell.floor_z)))
        self.arms = {side: keep.get(side) or ArmVisual(self.server, world.arms[side], world.T_world_base[side],
                                                       f"/arms/{side}{self.generation}", ARM_COLORS[side], loaded[side])
                     for side in ("left", "right")}
        for side in ("left", "right"):
            Tb = world.T_world_base[side]
            self.frames[f"{side}_base"] = s.add_frame(f"{root}/frames/{side}_base", axes_length=0.15, axes_radius=0.005,
                                                      position=tuple(Tb[:3, 3]), wxyz=wxyz(Tb[:3, :3]))
        for gid, info in enumerate(world.geoms):
            name = f"{root}/geom/{info.name}"
            if info.kind == "arm":
                v, f = capsule_mesh(info.size[0], info.size[1])
                self.capsules[gid] = s.add_mesh_simple(name, v, f, color=ARM_COLORS[info.side], opacity=0.45)
                continue
            color = COLORS["bar"] if info.kind == "bar" else COLORS["obstacle"]
            node = self._shape(name, info.shape, info.size, color)
            if node is not None:
                self.geom_nodes[gid] = node
        for g in grown_obstacles(self.cell):
            node = self._shape(f"{root}/grown/{g.name}", g.shape, g.box_size if g.shape == "box" else
                               (g.size[0] + g.grow, *g.size[1:]), COLORS["grown"], opacity=0.25)
            node.position, node.wxyz = tuple(g.T_world_obstacle[:3, 3]), wxyz(g.T_world_obstacle[:3, :3])
            self.grown.append((g, node))
        self.envelope = self._envelope_arcs(f"{root}/envelope")
        self.real_envelope = self._real_envelope_section(f"{root}/real_envelope")
        for key, on in self.visible.items():
            self.show(key, on)

    def _extent(self) -> tuple[np.ndarray, np.ndarray]:
        """Floor-grid extent: bases, start pose and obstacles, plus a metre around."""
        pts = [self.world.T_world_base[s][:3, 3] for s in ("left", "right")] + [self.cell.T_world_object_start[:3, 3]]
        pts += [np.asarray(ob.pose_at(0.0))[:3, 3] for ob in self.cell.obstacles]
        p = np.array(pts)
        return np.floor(p.min(axis=0) - 1.0), np.ceil(p.max(axis=0) + 1.0)

    def _shape(self, name: str, shape: str, size, color, opacity: float | None = None):
        s = self.server.scene
        kw = {} if opacity is None else {"opacity": opacity}
        if shape == "capsule":
            v, f = capsule_mesh(size[0], size[1])
            return s.add_mesh_simple(name, v, f, color=color, **kw)
        if shape == "box":
            return s.add_box(name, dimensions=tuple(size), color=color, **kw)
        if shape == "sphere":
            return s.add_icosphere(name, radius=size[0], color=color, **kw)
        return None

    def _envelope_arcs(self, name: str):
        """The seed's coordinated work-envelope arcs (idealised model, §2.6) in the bases' plane;
        None if the cell's arms are not PUMAs."""
        if any(self.world.arms[s].robot != "puma560" for s in ("left", "right")):
            return None
        bl, br = self.world.T_world_base["left"][:3, 3], self.world.T_world_base["right"][:3, 3]
        reach = float(np.hypot(D2, A2 + np.hypot(A3, D4)))  # shoulder to wrist centre, stretched [m]
        grip = self.world.T_object_hand["right"][:3, 3] - self.world.T_object_hand["left"][:3, 3]
        try:
            env = ideal_envelope(reach, float(np.linalg.norm(br - bl)), float(np.linalg.norm(grip)), resolution=64,
                                 base_left=bl, base_right=br)
        except DualpumaError:
            return None
        segs = [np.stack([b[:-1], b[1:]], axis=1) for b in env.boundary if len(b) > 1]
        if not segs:
            return None
        self.envelope_model = env
        return self.server.scene.add_line_segments(name, np.concatenate(segs), colors=COLORS["envelope"],
                                                   thickness=2.0, thickness_units="screen")

    def _real_envelope_section(self, name: str):
        """The real coordinated envelope's x–z section through the start frame (reach, joint limits
        and floor of this cell's arms), or None if it cannot be computed for these arms."""
        try:
            env = real_envelope(self.cell)
        except DualpumaError:
            return None
        if len(env.xz_segments) == 0:
            return None
        self.real_envelope_model = env
        return self.server.scene.add_line_segments(name, env.xz_segments, colors=COLORS["real_envelope"],
                                                   thickness=2.0, thickness_units="screen")

    # ------------------------------------------------------------------ per frame
    def set_path(self, T_world_object: np.ndarray | None) -> None:
        """Show the object origin's path (or hide it with None)."""
        if T_world_object is None or len(T_world_object) < 2:
            self.path.visible = False
            return
        p = np.asarray(T_world_object)[:, :3, 3]
        self.path.points = np.stack([p[:-1], p[1:]], axis=1).astype(np.float32)
        self.path.visible = True

    def update(self, q_left, q_right, clearance, T_world_object: np.ndarray, hands, margin: float, t: float = 0.0) -> None:
        """Move every node to the configuration of the last clearance query (same thread)."""
        for side, q in (("left", q_left), ("right", q_right)):
            self.arms[side].update(q)
        gd = self.world.geom_data
        for gid, node in self.geom_nodes.items():
            M = gd.oMg[gid]
            node.position, node.wxyz = tuple(M.translation), wxyz(M.rotation)
        if self.visible["capsules"]:
            for gid, node in self.capsules.items():
                M = gd.oMg[gid]
                node.position, node.wxyz = tuple(M.translation), wxyz(M.rotation)
        if self.visible["grown"] and self.world.moving:
            for g, node in zip(grown_obstacles(self.cell, t), (n for _, n in self.grown)):
                node.position = tuple(g.T_world_obstacle[:3, 3])
        for side, H in zip(("left", "right"), hands):
            f = self.frames[f"{side}_hand"]
            f.position, f.wxyz = tuple(H[:3, 3]), wxyz(H[:3, :3])
        fo = self.frames["object"]
        fo.position, fo.wxyz = tuple(T_world_object[:3, 3]), wxyz(T_world_object[:3, :3])
        w = np.asarray(clearance.witness, float)
        self.closest.points = w[None].astype(np.float32)
        self.closest.colors = np.array(COLORS["collision"] if clearance.distance < margin else COLORS["clear"], np.uint8)
        self.closest_label.position = tuple(0.5 * (w[0] + w[1]))
        self.closest_label.text = f"{clearance.distance * 1000:.1f} mm"

    def show(self, what: str, on: bool) -> None:
        """Toggle ``arms``, ``capsules``, ``frames``, ``grown``, ``envelope`` or ``real_envelope``."""
        self.visible[what] = on = bool(on)
        nodes = {"arms": [a.root for a in self.arms.values()], "capsules": list(self.capsules.values()),
                 "frames": list(self.frames.values()), "grown": [n for _, n in self.grown],
                 "envelope": [self.envelope] if self.envelope is not None else [],
                 "real_envelope": [self.real_envelope] if self.real_envelope is not None else []}[what]
        for node in nodes:
            node.visible = on

    def points(self) -> np.ndarray:
        """Points (N, 3) the camera should see: every arm link, the bar's ends, the obstacles' extents
        (their centres alone left a large one half off-screen), bases on the floor, and the envelope
        drawings that are shown."""
        pts = []
        for side, arm in self.arms.items():
            for link in arm.urdf.link_map:
                pts.append(arm.link_pose(link)[:3, 3])
            b = self.world.T_world_base[side][:3, 3]
            pts += [b + (0.0, 0.0, float(self.cell.floor_z) - b[2]) + d for d in ((0.25, 0, 0), (-0.25, 0, 0), (0, 0.25, 0), (0, -0.25, 0))]
        for node in self.geom_nodes.values():
            pts.append(np.asarray(node.position, float))
        for ob in self.cell.obstacles:  # a sphere around each: centre +- its radius along each axis
            size = np.atleast_1d(np.asarray(ob.size, float))
            r = {"box": 0.5 * float(np.linalg.norm(size)), "sphere": float(size[0])}.get(ob.shape, float(size[0]) + 0.5 * float(size[-1]))
            c = np.asarray(ob.pose_at(0.0), float)[:3, 3]
            pts += [c + r * d for d in np.vstack([np.eye(3), -np.eye(3)])]
        if self.visible["envelope"] and self.envelope is not None:
            pts += [p for b in self.envelope_model.boundary for p in np.asarray(b, float)]
        if self.visible["real_envelope"] and self.real_envelope is not None:
            pts += list(np.asarray(self.real_envelope_model.xz_segments, float).reshape(-1, 3))
        half = 0.5 * float(np.max(np.atleast_1d(self.cell.bar.size)))
        T = self.cell.T_world_object_start
        pts += [T[:3, 3] + half * T[:3, 0], T[:3, 3] - half * T[:3, 0]]
        return np.array(pts, dtype=float)
