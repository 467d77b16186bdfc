"""The planner's batched clearance queries on its own finite joints (no input validation).

* :func:`min_clearance` — minimum signed distance and its pair per configuration:
  :func:`dualpuma.clearance.clearance_batch`'s choice (the numpy kernel for large batches, a loop
  of coal calls for small ones) without re-validating.
* :func:`below_margin` — only *whether* each configuration is closer than a margin, which is all
  the between-step poses need: coal's collision test with a security margin (a pair counts as
  colliding when its distance is below the margin) answers that about twice as fast as the
  distance query, because GJK stops as soon as a separating plane proves the margin. The planner
  asks for distances only where it says yes (to report the pair). ``tests/test_queries.py``
  compares it with the distance query, configurations at the margin included.
"""

from __future__ import annotations

import warnings

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .clearance import BATCH_KERNEL_MIN, _coal_loop, batch_kernel
from .world import World, _se3

FloatArray = npt.NDArray[np.float64]

#: from this many configurations up :func:`below_margin` uses the kernel's distances instead
KERNEL_MARGIN_MIN = 2 * BATCH_KERNEL_MIN


def min_clearance(world: World, Q: FloatArray, times: FloatArray):
    """``clearance_batch(world, Q[:, :6], Q[:, 6:], t=times)`` (bar frames implied) for trusted
    joints Q (N, 12) (left then right) at times (N,)."""
    if Q.shape[0] >= BATCH_KERNEL_MIN:
        kernel = batch_kernel(world)
        if kernel is not None:
            return kernel.evaluate(Q, None, times)
    return _coal_loop(world, Q, None, times)


def _margin_data(world: World, margin: float) -> pin.GeometryData:
    """A GeometryData of the World whose collision requests use ``margin`` as security margin
    (kept on the World per margin; coal's warm start off, so answers never depend on history)."""
    cache = world.__dict__.setdefault("_margin_data", {})
    gd = cache.get(margin)
    if gd is None:
        gd = pin.GeometryData(world.geom_model)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            for req in gd.collisionRequests:
                req.security_margin = margin
                if hasattr(req, "enable_cached_gjk_guess"):
                    req.enable_cached_gjk_guess = False
        cache[margin] = gd
    return gd


def below_margin(world: World, Q: FloatArray, times: FloatArray, margin: float) -> npt.NDArray[np.bool_]:
    """Per configuration Q (N, 12) (left then right joints) at times (N,): True where some
    checked pair is closer than ``margin`` [m] (bar frames implied by the left grasp)."""
    n = Q.shape[0]
    if n >= KERNEL_MARGIN_MIN and batch_kernel(world) is not None:
        return min_clearance(world, Q, times)[0] < margin
    model, data, gm = world.model, world.data, world.geom_model
    gd = _margin_data(world, float(margin))
    out = np.empty(n, dtype=bool)
    coll = pin.computeCollisions
    if not world.moving:
        for i in range(n):
            out[i] = coll(model, data, gm, gd, Q[i], True)
        return out
    upd = pin.updateGeometryPlacements
    for i in range(n):
        upd(model, data, gm, gd, Q[i])
        for gid, ob in world.moving:
            gd.oMg[gid] = _se3(np.asarray(ob.pose_at(times[i]), float))
        out[i] = coll(gm, gd, True)
    return out
