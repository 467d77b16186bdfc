"""Viewer: node poses follow Pinocchio FK when a joint slider moves."""

import socket

import numpy as np
import pytest

from dualpuma.cell import Cell
from dualpuma.viewer.app import ViewerApp, capsule_mesh


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def app():
    a = ViewerApp(Cell.default(), port=free_port())
    yield a
    a.close()


def test_capsule_mesh_surface():
    v, f = capsule_mesh(0.05, 0.3)
    d = np.hypot(v[:, 0], v[:, 1])
    ends = np.abs(v[:, 2]) > 0.15
    core = np.maximum(np.abs(v[:, 2]) - 0.15, 0)
    np.testing.assert_allclose(np.hypot(d, core), 0.05, atol=1e-6)
    assert f.max() < len(v) and ends.any()


def test_slider_moves_forearm_node_to_pinocchio_pose(app):
    arm = app.world.arms["left"]
    app.sliders[("left", 0)].value = 10.0  # runs on_update synchronously
    app.step()
    q = np.array(app.cell.left.q_home, float)
    q[0] = np.deg2rad(10.0)
    data = arm.model.createData()
    import pinocchio as pin

    pin.forwardKinematics(arm.model, data, q)
    cap = next(c for c in arm.capsules if c.name == "forearm")
    M = app.cell.left.T_world_base @ data.oMi[cap.joint].homogeneous @ cap.placement
    gid = [g.name for g in app.world.geoms].index("left/forearm")
    np.testing.assert_allclose(app.nodes[gid].position, M[:3, 3], atol=1e-9)
    assert "min clearance" in app.readout.content
