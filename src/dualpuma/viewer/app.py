"""`dualpuma serve`: a viser scene of both arms (collision capsules), the bar, obstacles, the floor,
with teach-mode joint sliders (degrees) and a clearance read-out.

Threading: GUI callbacks only record the requested joints under a lock; :meth:`ViewerApp.step`
(run by one loop thread at 30 Hz, or called directly by tests) owns the World, computes FK and
clearance and moves the nodes inside ``server.atomic()``. Meshes are built once.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pinocchio as pin
import viser

from ..world import World

__all__ = ["ViewerApp", "capsule_mesh", "serve"]


def capsule_mesh(radius: float, length: float, n: int = 16, rings: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """Triangle mesh of a capsule along local z, centred at the origin: (vertices, faces)."""
    verts = []
    for k in range(rings + 1):  # top hemisphere then bottom, from pole to pole
        phi = np.pi / 2 * (1 - k / rings)
        for j in range(n):
            th = 2 * np.pi * j / n
            verts.append((radius * np.cos(phi) * np.cos(th), radius * np.cos(phi) * np.sin(th), length / 2 + radius * np.sin(phi)))
    for k in range(rings + 1):
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


def _wxyz(R: np.ndarray) -> tuple[float, float, float, float]:
    q = pin.Quaternion(R)
    return (q.w, q.x, q.y, q.z)


class ViewerApp:
    """One viser server showing a cell; see the module docstring."""

    def __init__(self, cell, host: str = "127.0.0.1", port: int = 8080) -> None:
        self.cell = cell
        self.world = World(cell)
        self.server = viser.ViserServer(host=host, port=port)
        self._lock = threading.Lock()
        self._q = {"left": np.array(cell.left.q_home, float), "right": np.array(cell.right.q_home, float)}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        s = self.server.scene
        s.add_grid("/floor", width=4.0, height=3.0, position=(1.5, 0.0, float(cell.floor_z)))
        self.nodes = {}
        for gid, info in enumerate(self.world.geoms):
            if info.shape == "capsule":
                v, f = capsule_mesh(info.size[0], info.size[1])
                color = (200, 200, 190) if info.kind == "arm" else (180, 120, 60)
                self.nodes[gid] = s.add_mesh_simple(f"/geom/{info.name}", v, f, color=color)
            elif info.shape == "box":
                color = (40, 110, 200) if info.kind == "bar" else (170, 60, 60)
                self.nodes[gid] = s.add_box(f"/geom/{info.name}", dimensions=info.size, color=color)
            elif info.shape == "sphere":
                self.nodes[gid] = s.add_icosphere(f"/geom/{info.name}", radius=info.size[0], color=(170, 60, 60))
        g = self.server.gui
        self.readout = g.add_markdown("")
        self.sliders = {}
        for side in ("left", "right"):
            lim = np.rad2deg(self.world.arms[side].limits)
            with g.add_folder(f"{side} arm (deg)"):
                for j in range(6):
                    sl = g.add_slider(f"{side} q{j + 1}", min=float(lim[j, 0]), max=float(lim[j, 1]), step=0.1,
                                      initial_value=float(np.rad2deg(self._q[side][j])))
                    sl.on_update(lambda ev, side=side, j=j: self._set_joint(side, j, ev.target.value))
                    self.sliders[(side, j)] = sl
        self.step()

    def _set_joint(self, side: str, j: int, deg: float) -> None:
        with self._lock:
            self._q[side][j] = np.deg2rad(float(deg))

    def step(self) -> None:
        """One update: FK + clearance for the requested joints, move every node atomically."""
        with self._lock:
            qL, qR = self._q["left"].copy(), self._q["right"].copy()
        c = self.world.clearance(qL, qR)
        gd = self.world.geom_data
        with self.server.atomic():
            for gid, node in self.nodes.items():
                M = gd.oMg[gid]
                node.position = tuple(M.translation)
                node.wxyz = _wxyz(M.rotation)
        flag = "**below margin**" if c.distance < self.cell.safety_margin else "ok"
        self.readout.content = (
            f"min clearance **{c.distance * 1000:.1f} mm** ({c.pair[0]} – {c.pair[1]}) {flag}\n\n"
            f"left q [deg]: {np.round(np.rad2deg(qL), 1).tolist()}\n\nright q [deg]: {np.round(np.rad2deg(qR), 1).tolist()}"
        )
        self.last_clearance = c

    def run(self) -> None:
        """Loop at 30 Hz until :meth:`close`."""
        while not self._stop.is_set():
            self.step()
            time.sleep(1 / 30)

    def close(self) -> None:
        self._stop.set()
        self.server.stop()


def serve(cell=None, host: str = "127.0.0.1", port: int = 8080) -> None:
    """Start the viewer and block until Ctrl-C."""
    from ..cell import Cell

    app = ViewerApp(cell or Cell.default(), host, port)
    print(f"dualpuma viewer: http://{host}:{port}  (Ctrl-C to stop)", flush=True)
    try:
        app.run()
    except KeyboardInterrupt:
        pass
    finally:
        app.close()
