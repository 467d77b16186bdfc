"""The held bar's clearance to the fixed geometry, bounded from above by object poses alone.

The bar's pose is the object pose times ``T_object_bar``: unlike every other pair, the bar's pairs
with geometry that never moves (static obstacles, the floor, the pedestals: geometries on the
universe joint that are not moving obstacles) need no joints, hence no IK. :class:`HeldScreen`
bounds their signed distances *from above* for many object poses at once, so that a planner can
refuse an edge whose bar is certainly closer than its margin somewhere before solving the arms
for it (:meth:`dualpuma.planning.edges.EdgeChecker.validate`).

Why it is an upper bound. Signed distance is monotone in both sets: a subset is never closer
than its superset (apart, the distance can only shrink; meeting, the penetration depth can only
grow). So sd(bar, G) <= sd(B, G') for any ball B inside the bar and any G' inside G, and for a
ball and a box, sd(B(x, r), G') = sd(x, G') - r exactly (apart: the distance to a convex set less
the radius; meeting: the ball leaves the box once its centre is r outside it). The bound is the
least of those values over a set of balls and one box per geometry:

* **Balls in the bar** (:func:`_inner_balls`): a box bar holds the capsule along its longest
  axis whose radius r is its smallest other half extent (ends inset by r); balls of radius r about
  points of that segment at most 2 r apart, and points (radius 0) along the bar's four longest
  edges at most 4 r apart, where a face or an edge of the bar meets the obstacle (capsule
  and sphere bars: their own balls).
* **A box in each geometry** (:func:`_inner_box`): a box is itself; the floor (a halfspace)
  holds a 200 m cube against its plane, whose distance is the plane's wherever the bar can be; a
  capsule holds the box of half sides r / sqrt 2 along its segment, a sphere its inscribed cube
  (looser bounds, fine for the pedestals, which the bar seldom nears). Other shapes, and a bar
  of another shape, are not bounded: the screen never refuses them.

Point–box distances are exact up to rounding (a few 1e-14 m here, with the 100 m floor cube);
callers compare with a level below their margin by more than that. Checked against coal in
tests/test_held_screen.py.
"""

from __future__ import annotations

import math

import coal
import numpy as np
import numpy.typing as npt

__all__ = ["HeldScreen", "held_screen"]

FloatArray = npt.NDArray[np.float64]

_KEY = "collision.held"  # WorldCache key
_FLOOR_HALF = 100.0  #: half side of the cube standing in for a halfspace [m]


class HeldScreen:
    """Upper bounds of the bar's signed distance to each fixed geometry it is paired with, for
    object poses (see the module docstring). Immutable after construction (shared by threads).

    Args:
        world: the :class:`~dualpuma.model.world.World` (read, never modified).

    Attributes:
        pairs: indices into ``world.pair_names`` of the bounded pairs, (G,).
    """

    def __init__(self, world) -> None:
        gm, bar = world.geom_model, int(world.bar_id)
        moving = {int(gid) for gid, _ in world.moving}
        shape = gm.geometryObjects[bar].geometry
        balls = _inner_balls(shape)
        # the bar's balls in the object frame: centres (3, S), radii (S,)
        M = np.array(world.T_object_bar, dtype=np.float64)  # the bar geometry's pose in the object frame
        boxes = []
        if balls is not None:
            self._local = (M[:3, :3] @ balls[0].T + M[:3, 3:]).copy()
            self._radii = balls[1]
            for k, (a, b) in enumerate(world.pair_ids):
                a, b = int(a), int(b)
                if bar not in (a, b):
                    continue
                g = b if a == bar else a
                go = gm.geometryObjects[g]
                if go.parentJoint != 0 or g in moving:
                    continue
                box = _inner_box(go.geometry, np.array(go.placement.rotation), np.array(go.placement.translation))
                if box is not None:
                    boxes.append((k, *box))
        else:
            self._local, self._radii = np.zeros((3, 0)), np.zeros(0)
        self.pairs = np.array([b[0] for b in boxes], dtype=np.int64)
        Rb = np.array([b[1] for b in boxes]).reshape(-1, 3, 3)
        self._Rt = Rb.transpose(0, 2, 1).copy()  # (G, 3, 3): world to box frame
        self._o = self._Rt @ np.array([b[2] for b in boxes]).reshape(-1, 3, 1)  # (G, 3, 1): R^T t
        self._h = np.array([b[3] for b in boxes]).reshape(-1, 3, 1)  # half extents
        for a in (self.pairs, self._local, self._radii):
            a.setflags(write=False)

    def bounds(self, P: FloatArray) -> FloatArray:
        """Upper bounds of the bar's signed distance to each bounded geometry at object poses P
        (K, 4, 4) [m] (trusted): (G, K) [m], rows in :attr:`pairs` order."""
        K, S = P.shape[0], self._local.shape[1]
        G = self.pairs.size
        if not G or not K:
            return np.full((G, K), np.inf)
        X = P[:, :3, :3] @ self._local + P[:, :3, 3:]  # (K, 3, S) points, component first
        X = X.transpose(1, 0, 2).reshape(3, -1)  # (3, K S)
        q = self._Rt @ X  # (G, 3, K S) in each box's frame
        q -= self._o
        np.abs(q, out=q)
        q -= self._h
        out = np.maximum(q, 0.0)
        out *= out
        sd = np.sqrt(out.sum(axis=1))
        sd += np.minimum(q.max(axis=1), 0.0)
        sd = sd.reshape(G, K, S)
        sd -= self._radii
        return sd.min(axis=2)

    def first_below(self, P: FloatArray, level: float) -> tuple[int, float, int]:
        """The first object pose of P (K, 4, 4) whose bar is certainly closer than ``level`` [m] to
        a fixed geometry: ``(its index, the bound [m], the pair's index into world.pair_names)``,
        or ``(-1, nan, -1)``."""
        if not self.pairs.size:
            return -1, float("nan"), -1
        ub = self.bounds(P)
        low = ub.min(axis=0)
        hit = np.flatnonzero(low < level)
        if not hit.size:
            return -1, float("nan"), -1
        k = int(hit[0])
        g = int(np.argmin(ub[:, k]))
        return k, float(ub[g, k]), int(self.pairs[g])


def _inner_box(shape, R: FloatArray, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray] | None:
    """A box inside a geometry placed at (R, t) in the world: (rotation (3, 3), centre (3,), half
    extents (3,)) [m], or None for a shape without one here. A box is itself; a halfspace
    {n.x <= d} holds a cube of half side :data:`_FLOOR_HALF` against its plane (the same bound as
    the plane anywhere closer than that to its foot); a capsule the box of half sides r / sqrt 2
    across its whole segment, a sphere its inscribed cube, both shrunk by a relative 1e-9 so that
    their corners stay inside in floating point."""
    if isinstance(shape, coal.Box):
        return R, t, np.array(shape.halfSide, dtype=np.float64)
    if isinstance(shape, coal.Halfspace):
        n = R @ np.array(shape.n, dtype=np.float64)
        n /= np.linalg.norm(n)
        foot = (float(shape.d) + float(n @ t)) * n  # the plane's point nearest the origin
        a = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])
        a /= np.linalg.norm(a)
        Rf = np.column_stack([a, np.cross(n, a), n])
        return Rf, foot - _FLOOR_HALF * n, np.full(3, _FLOOR_HALF)
    shrink = 1.0 - 1e-9
    if isinstance(shape, coal.Capsule):
        a = float(shape.radius) / math.sqrt(2.0) * shrink
        return R, t, np.array([a, a, float(shape.halfLength)])
    if isinstance(shape, coal.Sphere):
        a = float(shape.radius) / math.sqrt(3.0) * shrink
        return R, t, np.full(3, a)
    return None


def _inner_balls(shape) -> tuple[FloatArray, FloatArray] | None:
    """Balls inside a shape, in its frame: (centres (S, 3) [m], radii (S,) [m]), or None for a
    shape without them here (see the module docstring)."""
    z = np.array([0.0, 0.0, 1.0])
    edges = []
    if isinstance(shape, coal.Box):
        half = np.array(shape.halfSide, dtype=np.float64)
        m = int(np.argmax(half))
        others = [i for i in range(3) if i != m]
        axis, r = np.eye(3)[m], float(half[others].min())
        h = max(float(half[m]) - r, 0.0)
        for sa in (-1.0, 1.0):
            for sb in (-1.0, 1.0):
                c = np.zeros(3)
                c[others[0]], c[others[1]] = sa * half[others[0]], sb * half[others[1]]
                edges.append((c, float(half[m])))
    elif isinstance(shape, coal.Capsule):
        axis, r, h = z, float(shape.radius), float(shape.halfLength)
    elif isinstance(shape, coal.Sphere):
        axis, r, h = z, float(shape.radius), 0.0
    else:
        return None
    if r <= 0.0:  # a flat shape holds no ball
        return None
    centres, radii = [_spaced(np.zeros(3), axis, h, 2.0 * r)], []
    radii.append(np.full(centres[0].shape[0], r))
    for c, he in edges:
        centres.append(_spaced(c, axis, he, 4.0 * r))
        radii.append(np.zeros(centres[-1].shape[0]))
    return np.vstack(centres), np.concatenate(radii)


def _spaced(c: FloatArray, axis: FloatArray, h: float, gap: float) -> FloatArray:
    """Points c + u axis, u from -h to h, at most ``gap`` apart (both ends included): (S, 3)."""
    u = np.linspace(-h, h, max(2, math.ceil(2.0 * h / gap) + 1)) if h > 0.0 else np.zeros(1)
    return c + u[:, None] * axis


def held_screen(world) -> HeldScreen:
    """The World's :class:`HeldScreen` (built on first use, kept in ``world.cache``)."""
    return world.cache.shared(_KEY, lambda: HeldScreen(world))
