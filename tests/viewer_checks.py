"""Checks shared by the viewer tests: waiting for the server to reach a state, and an independent
hand pose (a fresh Pinocchio model of the PUMA 560, not the viewer's World) to check grasps with."""

from __future__ import annotations

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
