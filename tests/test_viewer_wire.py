"""Defects of issue 15 driven the way a browser tab drives the viewer: events over viser's own
protocol (``viser_client.Client``) on the controls a user sees by their labels, and the state read
through the viewer's long-standing accessors (``q``, ``T_object``, ``plan``, ``cell``). The
real-browser test (test_browser.py) drives the page itself."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from viewer_checks import hand as _hand
from viewer_checks import wait as _wait
from viser_client import Client, control

from dualpuma.kinematics import Arm
from dualpuma.lie import pose_from_wxyz, quaternion_wxyz
from dualpuma.model import Cell, example_cell
from dualpuma.viewer import ViewerApp


def _connect(app, n=1):
    clients = [Client(f"ws://127.0.0.1:{app.server.get_port()}") for _ in range(n)]
    _wait(lambda: len(app.server.get_clients()) >= n, 10, "clients")
    return clients


def _grasp_errors(app):
    return [float(np.abs(_hand(app.cell, s, app.q[s]) - app.T_object @ getattr(app.cell, f"grasp_{s}").T_object_hand).max())
            for s in ("left", "right")]


@pytest.fixture()
def app():
    a = ViewerApp(Cell.default(), port=0)
    yield a
    a.close()


def test_a_joint_typed_beyond_its_limit_is_clamped_and_told(app):
    """q5 = -150 deg was accepted while the box showed -100 deg, with no message."""
    app.start()
    (c,) = _connect(app)
    try:
        slider = control(app.server, "right q5")
        c.set(slider, -150.0)
        _wait(lambda: abs(math.degrees(app.q["right"][4]) + 100.0) < 1e-9, 10, "q5 clamped to -100 deg")
        _wait(lambda: slider.value == pytest.approx(-100.0), 5, "the slider to show -100 deg")
        c.wait_notification("clamped to -100.0 deg")
        assert max(_grasp_errors(app)) < 1e-9
    finally:
        c.close()


def test_moving_one_arm_keeps_the_grasp(app):
    """In joint mode the right gripper silently let go of the bar."""
    app.start()
    (c,) = _connect(app)
    try:
        c.set(control(app.server, "left q1"), 62.0)
        _wait(lambda: abs(math.degrees(app.q["left"][0]) - 62.0) < 1e-9, 10, "left q1")
        time.sleep(0.2)
        assert max(_grasp_errors(app)) < 1e-9
    finally:
        c.close()


def test_the_gizmo_sits_on_the_object_and_a_5mm_drag_from_it_is_accepted(app):
    """The gizmo started with no rotation at the start pose: any drag asked for a 180 deg roll."""
    app.start()
    (c,) = _connect(app)
    try:
        g = app.teach.gizmo
        T0 = app.T_object.copy()
        np.testing.assert_allclose(g.position, T0[:3, 3], atol=1e-9)
        assert abs(abs(float(np.dot(g.wxyz, quaternion_wxyz(T0[:3, :3])))) - 1.0) < 1e-9
        target = np.asarray(g.position) + (0.0, 0.005, 0.0)  # a user drags the gizmo they see
        c.drag("/object_gizmo", "start")
        c.drag("/object_gizmo", "update", tuple(g.wxyz), tuple(target))
        c.drag("/object_gizmo", "end")
        _wait(lambda: np.allclose(app.T_object[:3, 3], target, atol=1e-9), 10, "the drag to be accepted")
        np.testing.assert_allclose(app.T_object[:3, :3], pose_from_wxyz(g.wxyz, target)[:3, :3], atol=1e-9)
        c.set(control(app.server, "left q1"), round(math.degrees(app.q["left"][0]) + 1.0, 1))
        _wait(lambda: not np.allclose(app.T_object[:3, 3], target, atol=1e-6), 10, "a joint move")
        time.sleep(0.3)
        np.testing.assert_allclose(g.position, app.T_object[:3, 3], atol=1e-9)  # it follows the object
    finally:
        c.close()


def test_a_routine_with_its_own_cell_does_not_silently_replace_the_users_cell():
    """Running a routine replaced a --cell cell (the AGV box vanished) with no way back."""
    app = ViewerApp(example_cell("agv"), port=0)
    try:
        app.start()
        (c,) = _connect(app)
        routine = control(app.server, "routine")
        c.set(routine, next(o for o in routine.options if o.startswith("8:")))
        time.sleep(0.3)
        c.click(control(app.server, "run routine"))
        time.sleep(3.0)  # routine 8 plans in milliseconds: the old viewer had switched by now
        assert app.cell.name == "agv" and app.plan is None
        c.wait_notification("needs its own cell")
        c.close()
    finally:
        app.close()


def test_playback_moves_smoothly_between_steps(app):
    """Playback jumped from step to step (the shown pose changed only at whole steps). Step by step
    (the 'timed trajectory' box unticked): interpolated between the plan's steps."""
    (c,) = _connect(app)
    try:
        c.set(control(app.server, "timed trajectory (joint limits)"), False)
        _wait(lambda: app.settings["timed"] is False, 10, "the box", step=lambda: app.step(0.0))
        c.click(control(app.server, "run routine"))
        _wait(lambda: app.plan is not None, 60, "routine 2", step=lambda: app.step(0.0))
        p = app.plan
        app.step(0.05)  # routine 2 runs 0.1 s per step at real speed: halfway to step 1
        mid = 0.5 * (p.T_world_object[0, :3, 3] + p.T_world_object[1, :3, 3])
        np.testing.assert_allclose(app.T_object[:3, 3], mid, atol=1e-9)
    finally:
        c.close()


def test_the_initial_camera_frames_the_cell_not_the_world_origin(app):
    cam = app.server.initial_camera
    look = np.asarray(cam.look_at)
    bases = np.array([app.cell.left.T_world_base[:3, 3], app.cell.right.T_world_base[:3, 3]])
    assert np.linalg.norm(look[:2] - bases[:, :2].mean(axis=0)) < 0.8
    d = np.linalg.norm(np.asarray(cam.position) - look)
    assert 1.5 < d < 8.0


def test_envelope_overlays_are_off_by_default(app):
    assert not app.scene.envelope.visible


def test_numbers_show_a_tenth_at_most(app):
    """Number boxes showed 7 decimals."""
    for side in ("left", "right"):
        for j in range(6):
            v = control(app.server, f"{side} q{j + 1}").value
            assert v == round(v, 1), (side, j, v)


def test_a_timed_plan_plays_its_trajectory_at_real_speed(app):
    """With the box ticked (the default) a routine is timed under the PUMA's joint limits and the
    shown joints follow its trajectory in time; both hands stay on the bar within 0.5 mm."""
    (c,) = _connect(app)
    try:
        assert app.settings["timed"] is True
        c.click(control(app.server, "run routine"))
        _wait(lambda: app.plan is not None, 60, "routine 2", step=lambda: app.step(0.0))
        tr = app.plan.trajectory
        assert tr is not None and tr.certified and app.playback.timed
        assert app.playback.t_end == pytest.approx(tr.t[-1])
        app.step(0.303)
        k = int(np.searchsorted(tr.t, tr.t[0] + 0.303, side="right") - 1)
        s = (tr.t[0] + 0.303 - tr.t[k]) / (tr.t[k + 1] - tr.t[k])
        np.testing.assert_allclose(app.q["left"], tr.q_left[k] + s * (tr.q_left[k + 1] - tr.q_left[k]), atol=1e-9)
        G = app.T_object @ app.cell.grasp_right.T_object_hand
        H = app.cell.right.T_world_base @ Arm.puma560().fk(app.q["right"])
        assert np.linalg.norm(H[:3, 3] - G[:3, 3]) < 0.5e-3
        assert f"/{app.plan.n_steps}" in app.routines.status.content
    finally:
        c.close()
