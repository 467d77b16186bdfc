"""Scene nodes of the viewer, built once: capsules of both arms, the bar, obstacles (solid), grown
obstacles (translucent, toggled), the coordinated work-envelope arcs (idealised) and the real
envelope's x–z section (toggled), floor grid, frames, the planned path trace, the goal gizmo and
the closest-pair segment. :meth:`Scene.update` only moves nodes and
changes their properties; it never creates nodes (call it inside ``server.atomic()``)."""

from __future__ import annotations

import numpy as np
import viser

from ..collision.seed import grown_obstacles
from ..envelope.ideal import ideal_envelope
from ..envelope.real import real_envelope
from ..errors import DualpumaError
from ..kinematics.puma import A2, A3, D2, D4
from ..lie import quaternion_wxyz as wxyz

__all__ = ["Scene", "capsule_mesh"]

_ARM = (205, 205, 195)
_BAR = (40, 110, 200)
_OBST = (170, 60, 60)
_RED = (230, 30, 30)
_GREEN = (30, 170, 60)


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
        self.server, self.world, self.cell = server, world, world.cell
        s = server.scene
        s.set_up_direction("+z")
        s.add_grid("/floor", width=4.0, height=3.0, cell_size=0.1, position=(1.5, -0.3, float(self.cell.floor_z)))
        self.geom_nodes: dict[int, object] = {}
        self._add_geoms(world, kinds=("arm", "bar", "obstacle"))
        self.grown: list = []
        self._add_grown()
        self.envelope = self._envelope_arcs()
        self.real_envelope = self._real_envelope_section()
        self.frames = {"world": s.add_frame("/frames/world", axes_length=0.25, axes_radius=0.006)}
        for side in ("left", "right"):
            Tb = world.T_world_base[side]
            self.frames[f"{side}_base"] = s.add_frame(f"/frames/{side}_base", axes_length=0.15, axes_radius=0.005,
                                                      position=tuple(Tb[:3, 3]), wxyz=wxyz(Tb[:3, :3]))
            self.frames[f"{side}_hand"] = s.add_frame(f"/frames/{side}_hand", axes_length=0.1, axes_radius=0.004)
        self.frames["object"] = s.add_frame("/frames/object", axes_length=0.12, axes_radius=0.005)
        self.closest = s.add_line_segments("/closest", np.zeros((1, 2, 3)), colors=_GREEN, thickness=4.0, thickness_units="screen")
        self.closest_label = s.add_label("/closest/label", "")
        self.path = s.add_line_segments("/path", np.zeros((1, 2, 3)), colors=(250, 200, 30), thickness=3.0, thickness_units="screen")
        self.path.visible = False

    def set_world(self, world) -> None:
        """Switch to another cell's World with the same arms (a routine's obstacles): obstacle and
        grown-obstacle nodes are replaced; everything else is kept. Rare (not per frame)."""
        grown_visible = any(node.visible for _, node in self.grown)
        for gid in [g for g, info in enumerate(self.world.geoms) if info.kind == "obstacle"]:
            self.geom_nodes.pop(gid).remove()
        for _, node in self.grown:
            node.remove()
        self.world, self.cell = world, world.cell
        self._add_geoms(world, kinds=("obstacle",))
        self.grown = []
        self._add_grown()
        self.show_grown(grown_visible)

    def _add_geoms(self, world, kinds: tuple[str, ...]) -> None:
        s = self.server.scene
        for gid, info in enumerate(world.geoms):
            if info.kind not in kinds:
                continue
            name = f"/geom/{info.name}"
            color = _ARM if info.kind == "arm" else _BAR if info.kind == "bar" else _OBST
            if info.shape == "capsule":
                v, f = capsule_mesh(info.size[0], info.size[1])
                self.geom_nodes[gid] = s.add_mesh_simple(name, v, f, color=color)
            elif info.shape == "box":
                self.geom_nodes[gid] = s.add_box(name, dimensions=info.size, color=color)
            elif info.shape == "sphere":
                self.geom_nodes[gid] = s.add_icosphere(name, radius=info.size[0], color=color)

    def _add_grown(self) -> None:
        s = self.server.scene
        for g in grown_obstacles(self.cell):
            name = f"/grown/{g.name}"
            if g.shape == "box":
                node = s.add_box(name, dimensions=g.box_size, color=(240, 160, 60), opacity=0.25)
            elif g.shape == "sphere":
                node = s.add_icosphere(name, radius=g.size[0] + g.grow, color=(240, 160, 60), opacity=0.25)
            else:
                v, f = capsule_mesh(g.size[0] + g.grow, g.size[1])
                node = s.add_mesh_simple(name, v, f, color=(240, 160, 60), opacity=0.25)
            node.position = tuple(g.T_world_obstacle[:3, 3])
            node.wxyz = wxyz(g.T_world_obstacle[:3, :3])
            node.visible = False
            self.grown.append((g, node))

    def _envelope_arcs(self):
        """The seed's coordinated work-envelope arcs (idealised model, §2.6) in the bases' plane."""
        bl, br = self.world.T_world_base["left"][:3, 3], self.world.T_world_base["right"][:3, 3]
        reach = float(np.hypot(D2, A2 + np.hypot(A3, D4)))  # shoulder to wrist centre, stretched [m]
        grip = self.world.T_object_hand["right"][:3, 3] - self.world.T_object_hand["left"][:3, 3]
        env = ideal_envelope(reach, float(np.linalg.norm(br - bl)), float(np.linalg.norm(grip)), resolution=64,
                             base_left=bl, base_right=br)
        segs = np.concatenate([np.stack([b[:-1], b[1:]], axis=1) for b in env.boundary if len(b) > 1])
        self.envelope_model = env
        return self.server.scene.add_line_segments("/envelope", segs, colors=(120, 60, 200), thickness=2.0, thickness_units="screen")

    def _real_envelope_section(self):
        """The real coordinated envelope's x–z section through the start frame (reach, joint limits
        and floor of this cell's arms; :func:`dualpuma.envelope.real_envelope`, 25 mm grid, about
        0.15 s), hidden until toggled; None if the cell's arms are not both PUMAs."""
        try:
            env = real_envelope(self.cell)
        except DualpumaError:
            return None
        if len(env.xz_segments) == 0:
            return None
        self.real_envelope_model = env
        node = self.server.scene.add_line_segments("/real_envelope", env.xz_segments, colors=(20, 150, 110),
                                                   thickness=2.0, thickness_units="screen")
        node.visible = False
        return node

    def set_path(self, T_world_object: np.ndarray | None) -> None:
        """Show the object origin's path (or hide it with None)."""
        if T_world_object is None or len(T_world_object) < 2:
            self.path.visible = False
            return
        p = np.asarray(T_world_object)[:, :3, 3]
        self.path.points = np.stack([p[:-1], p[1:]], axis=1).astype(np.float32)
        self.path.visible = True

    def update(self, clearance, T_world_object: np.ndarray, hands: tuple[np.ndarray, np.ndarray], margin: float) -> None:
        """Move every node to the World's current placements (after a clearance query)."""
        gd = self.world.geom_data
        for gid, node in self.geom_nodes.items():
            M = gd.oMg[gid]
            node.position = tuple(M.translation)
            node.wxyz = wxyz(M.rotation)
        for side, H in zip(("left", "right"), hands):
            f = self.frames[f"{side}_hand"]
            f.position, f.wxyz = tuple(H[:3, 3]), wxyz(H[:3, :3])
        fo = self.frames["object"]
        fo.position, fo.wxyz = tuple(T_world_object[:3, 3]), wxyz(T_world_object[:3, :3])
        w = np.asarray(clearance.witness, float)
        self.closest.points = w[None].astype(np.float32)
        self.closest.colors = np.array(_RED if clearance.distance < margin else _GREEN, np.uint8)
        self.closest_label.position = tuple(0.5 * (w[0] + w[1]))
        self.closest_label.text = f"{clearance.distance * 1000:.0f} mm"

    def show_envelope(self, on: bool) -> None:
        self.envelope.visible = bool(on)

    def show_grown(self, on: bool) -> None:
        for _, node in self.grown:
            node.visible = bool(on)

    def show_real_envelope(self, on: bool) -> None:
        if self.real_envelope is not None:
            self.real_envelope.visible = bool(on)

    def show_frames(self, on: bool) -> None:
        for f in self.frames.values():
            f.visible = bool(on)
