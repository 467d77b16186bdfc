"""Marching squares on a sampled 2-D field or a boolean grid, with segments chained into polylines.

Used by :mod:`.real` to draw the x-z section of the real work envelope (there the
crossings are bisected on the exact membership instead of interpolated). Vectorised: one table
lookup per case over all cells; each crossing edge gets exactly one point, so the chaining is by
edge id, never by floating-point coincidence.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from ..checks import as_array, real
from ..errors import ParameterError

__all__ = ["contour", "contour_polylines", "marching_squares"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]

# corners c0 (i, j), c1 (i+1, j), c2 (i+1, j+1), c3 (i, j+1); edges e0 c0-c1, e1 c1-c2, e2 c2-c3, e3 c3-c0.
# Case = sum of 2**corner over inside corners; 16 / 17: cases 5 / 10 with the cell centre inside.
_CASES: dict[int, tuple[tuple[int, int], ...]] = {
    1: ((3, 0),), 2: ((0, 1),), 3: ((3, 1),), 4: ((1, 2),), 5: ((3, 0), (1, 2)), 6: ((0, 2),),
    7: ((3, 2),), 8: ((2, 3),), 9: ((0, 2),), 10: ((0, 1), (2, 3)), 11: ((1, 2),), 12: ((1, 3),),
    13: ((0, 1),), 14: ((3, 0),), 16: ((0, 1), (2, 3)), 17: ((3, 0), (1, 2)),
}


def contour(
    up: BoolArray,
    xs: FloatArray,
    ys: FloatArray,
    centre_up: Callable[[IntArray, IntArray], BoolArray],
    edge_points: Callable[[IntArray, IntArray, FloatArray, FloatArray], FloatArray],
) -> tuple[FloatArray, tuple[FloatArray, ...]]:
    """Marching squares on a boolean grid: (K, 2, 2) segments and the chained polylines.

    Args:
        up: (nx, ny) inside flags at ``(xs[i], ys[j])``.
        xs, ys: sample coordinates.
        centre_up: ``(ci, cj) -> inside`` at the centres of saddle cells (ci, cj are cell indices).
        edge_points: ``(ia, ib, a, b) -> (n, 2)`` crossing points of the edges from sample ``ia``
            (index pairs (n, 2), coordinates ``a``) to ``ib`` (``b``).

    Edge ids: horizontal edge (i, j)-(i+1, j) is ``i*ny + j``, vertical (i, j)-(i, j+1) is
    ``nx*ny + i*ny + j``; each crossing edge gets one point, so chaining by id is exact."""
    nx, ny = up.shape
    u = up.astype(np.int64)
    case = u[:-1, :-1] + 2 * u[1:, :-1] + 4 * u[1:, 1:] + 8 * u[:-1, 1:]
    ci, cj = np.nonzero((case != 0) & (case != 15))
    cs = case[ci, cj]
    amb = np.nonzero((cs == 5) | (cs == 10))[0]
    if len(amb):
        cs[amb[centre_up(ci[amb], cj[amb])]] += 11  # 5 -> 16, 10 -> 21 (mapped below)
    cs[cs == 21] = 17
    local = np.stack([ci * ny + cj, nx * ny + (ci + 1) * ny + cj, ci * ny + cj + 1, nx * ny + ci * ny + cj], axis=1)
    pairs = [np.stack([local[cs == c, a], local[cs == c, b]], axis=1) for c, segs in _CASES.items() for a, b in segs]
    E = np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=np.int64)
    ids, inv = np.unique(E, return_inverse=True)
    inv = inv.reshape(E.shape)
    vert = ids >= nx * ny
    e = np.where(vert, ids - nx * ny, ids)
    i, j = e // ny, e % ny
    a = np.stack([xs[i], ys[j]], axis=1)
    b = np.stack([xs[np.where(vert, i, i + 1)], ys[np.where(vert, j + 1, j)]], axis=1)
    ia = np.stack([i, j], axis=1)
    ib = np.stack([np.where(vert, i, i + 1), np.where(vert, j + 1, j)], axis=1)
    pts = edge_points(ia, ib, a, b) if len(ids) else np.zeros((0, 2))
    return pts[inv].reshape(-1, 2, 2), tuple(pts[c] for c in _chain(inv))


def _chain(pairs: npt.NDArray[np.int64]) -> list[list[int]]:
    """Chain undirected segments (node pairs, every node of degree <= 2) into node sequences; a
    closed chain repeats its first node."""
    adj: dict[int, list[int]] = {}
    for k, (a, b) in enumerate(pairs.tolist()):
        adj.setdefault(a, []).append(k)
        adj.setdefault(b, []).append(k)
    used = [False] * len(pairs)
    P = pairs.tolist()
    chains = []

    def walk(node: int) -> list[int]:
        out = [node]
        while True:
            nxt = next((k for k in adj[node] if not used[k]), None)
            if nxt is None:
                return out
            used[nxt] = True
            a, b = P[nxt]
            node = b if a == node else a
            out.append(node)

    for node, ks in adj.items():  # open chains first (they end on the grid's border)
        if len(ks) == 1 and not used[ks[0]]:
            chains.append(walk(node))
    for k in range(len(P)):
        if not used[k]:
            chains.append(walk(P[k][0]))
    return chains


def _check_field(field: npt.ArrayLike, xs: npt.ArrayLike, ys: npt.ArrayLike, level: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    F, X, Y = (as_array(v, name) for v, name in ((field, "field"), (xs, "xs"), (ys, "ys")))
    level = real(level, "level")
    if X.ndim != 1 or Y.ndim != 1 or len(X) < 2 or len(Y) < 2 or F.shape != (len(X), len(Y)):
        raise ParameterError(f"field: expected shape (len(xs), len(ys)) with >= 2 samples per axis, got {F.shape}, {X.shape}, {Y.shape}")
    if not (np.all(np.isfinite(F)) and np.all(np.diff(X) > 0) and np.all(np.diff(Y) > 0) and np.isfinite(level)):
        raise ParameterError("field: values must be finite, xs and ys strictly increasing, level finite")
    return F, X, Y


def _field_contour(field, xs, ys, level) -> tuple[FloatArray, tuple[FloatArray, ...]]:
    F, X, Y = _check_field(field, xs, ys, level)
    up = F > level

    def centre_up(ci, cj):
        return 0.25 * (F[ci, cj] + F[ci + 1, cj] + F[ci + 1, cj + 1] + F[ci, cj + 1]) > level

    def edge_points(ia, ib, a, b):  # linear interpolation of the field along the edge
        fa, fb = F[ia[:, 0], ia[:, 1]], F[ib[:, 0], ib[:, 1]]
        t = np.clip((level - fa) / np.where(fb != fa, fb - fa, 1.0), 0.0, 1.0)
        return a + t[:, None] * (b - a)

    return contour(up, X, Y, centre_up, edge_points)


def marching_squares(field: npt.ArrayLike, xs: npt.ArrayLike, ys: npt.ArrayLike, level: float = 0.5) -> FloatArray:
    """Iso-line segments of a 2-D field (vectorised marching squares, linear interpolation).

    Args:
        field: (nx, ny) samples, ``field[i, j]`` at ``(xs[i], ys[j])``; "inside" is ``> level``.
        xs, ys: strictly increasing sample coordinates, nx, ny >= 2.
        level: iso value. Saddle cells are split by the mean of their corners.

    Returns:
        (K, 2, 2) segment end points.

    Raises:
        ParameterError: shapes, non-finite values or non-increasing axes.
    """
    return _field_contour(field, xs, ys, level)[0]


def contour_polylines(field: npt.ArrayLike, xs: npt.ArrayLike, ys: npt.ArrayLike, level: float = 0.5) -> tuple[FloatArray, ...]:
    """The :func:`marching_squares` segments chained into polylines, each (n, 2); a closed contour
    repeats its first point at the end, an open one ends on the grid's border.

    Raises:
        ParameterError: as :func:`marching_squares`.
    """
    return _field_contour(field, xs, ys, level)[1]
