"""Checks shared by the viewer tests: waiting for the server to reach a state, an independent
hand pose (a fresh Pinocchio model of the PUMA 560, not the viewer's World) to check grasps with,
and ``dualpuma serve`` started as a terminal starts it."""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pinocchio as pin

from dualpuma.kinematics import Arm


def wait(cond, timeout: float = 20.0, what: str = "condition", step=None, poll: float = 0.02) -> None:
    """Return once ``cond()`` holds (calling ``step()`` before each look, e.g. a viewer loop tick
    driven by the test); AssertionError naming ``what`` after ``timeout`` seconds."""
    t0 = time.time()
    while time.time() - t0 < timeout:
        if step is not None:
            step()
        if cond():
            return
        time.sleep(poll)
    raise AssertionError(f"timed out waiting for {what}")


def hand(cell, side: str, q) -> np.ndarray:
    """World pose (4, 4) of ``side``'s wrist frame at joints q [rad]: independent FK of one hand
    with a fresh Pinocchio model of the arm."""
    arm = Arm.puma560()
    data = arm.model.createData()
    pin.framesForwardKinematics(arm.model, data, np.asarray(q, float))
    return getattr(cell, side).T_world_base @ data.oMf[arm.model.getFrameId("wrist")].homogeneous


def serve_process(*args: str) -> subprocess.Popen:
    """``python -m dualpuma.cli serve *args`` as a terminal starts it in the foreground (stdout and
    stderr piped, text): Ctrl-C (SIGINT) reaches it even when the test runner was itself started
    with SIGINT ignored, as a background job of a shell without job control is, which would pass
    the ignored signal on to the server and leave it running."""
    start = ("import runpy, signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
             "sys.argv[0] = 'dualpuma'; runpy.run_module('dualpuma.cli', run_name='__main__')")
    return subprocess.Popen([sys.executable, "-c", start, "serve", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
