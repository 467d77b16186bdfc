"""Exact coordinated work envelope of two idealised robots holding one bar (thesis section 2.6).

Each robot reaches the closed ball of radius R about its base, the bases are D apart and the
hands hold the ends of a bar of length L = 2 r in any orientation u; the bar midpoint O is in the
envelope iff some unit u gives |O + r u - B_left| <= R and |O - r u - B_right| <= R.  With
c1 = B_left - O, c2 = O - B_right, d_i = |c_i| the admissible u of hand i form a spherical cap of
angular radius theta_i, cos theta_i = (r^2 + d_i^2 - R^2) / (2 r d_i), non-empty iff
|d_i - r| <= R; two caps meet iff their centres are at most theta_1 + theta_2 apart, so

    O in E  <=>  |d_1 - r| <= R,  |d_2 - r| <= R  and  angle(c1, c2) <= theta_1 + theta_2.

Swapping the hands (u -> -u) gives the same set.  E is a solid of revolution about the base line
whose meridian boundary is made of circles |O - B_i| = R + r (thesis arcs a, b), circles
|O - B_i| = r - R (only if r > R) and pieces of Watt's sextic (curves c, d).  See docs/envelope.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..checks import as_array, real, vector
from ..errors import ParameterError
from ..values import value_class

__all__ = ["IdealEnvelope", "closed_form_volume", "contains_ideal", "ideal_envelope", "membership_slacks"]

_WATT_TOL = 1e-7  # rad: |theta_1 + theta_2 - psi| below this marks an external cap tangency


@value_class
@dataclass(frozen=True, slots=True)
class IdealEnvelope:
    """Coordinated work envelope of the idealised two-robot, one-bar model.

    Attributes:
        reach_m: Reach radius ``R`` of each robot [m].
        base_distance_m: Distance ``D`` between the bases [m].
        bar_length_m: Bar length ``L`` [m].
        base_left: Left base position, shape (3,) [m] (read-only).
        base_right: Right base position, shape (3,) [m] (read-only).
        volume_m3: Volume of the whole envelope [m^3] (quadrature of the exact cross-section).
        volume_upper_half_m3: Volume above the plane through the base line normal to the
            boundary plane (z >= base height for level bases) [m^3]; ``volume_m3 / 2`` exactly.
        volume_error_m3: Estimated absolute quadrature error of ``volume_m3`` [m^3].
        volume_closed_form_m3: Closed-form volume [m^3] when one exists (empty set, ``L = 0``
            lens, ``D = 0`` or ``D = L`` ball), else ``None``.
        boundary: Meridian boundary in the vertical plane through the bases, as polylines of
            shape (M, 3) [m] (read-only); empty when the envelope is empty.
    """

    reach_m: float
    base_distance_m: float
    bar_length_m: float
    base_left: np.ndarray
    base_right: np.ndarray
    volume_m3: float
    volume_upper_half_m3: float
    volume_error_m3: float
    volume_closed_form_m3: float | None
    boundary: tuple[np.ndarray, ...]


_MAX_SIZE = 1000.0  # [m] largest reach, base distance or bar length accepted


def _size(name: str, value: object, *, allow_zero: bool) -> float:
    return real(value, name, lo=0.0, hi=_MAX_SIZE, lo_open=not allow_zero, unit="m")


def membership_slacks(points: np.ndarray, base_left: np.ndarray, base_right: np.ndarray, reach: float,
                      bar_length: float):
    """The three slacks (each >= 0 iff satisfied) of the exact membership test of
    :func:`contains_ideal` (same arguments).

    Returns:
        ``(cap1 [m], cap2 [m], angle [rad])``, each of shape ``points.shape[:-1]``:
        ``R - |d_i - L/2|`` (d_i the distance from base i) and ``theta_1 + theta_2 - psi``.

    Raises:
        ParameterError: as :func:`contains_ideal` (it took anything and raised numpy's errors).
    """
    o, bl, br, reach, r = _ideal_args(points, base_left, base_right, reach, bar_length)
    return _slacks(o, bl, br, reach, r)


def _ideal_args(points, base_left, base_right, reach, bar_length):
    """The checked arguments of :func:`contains_ideal`: (points (..., 3), bases (3,) [m], R, L / 2)."""
    reach = _size("reach", reach, allow_zero=False)
    r = 0.5 * _size("bar_length", bar_length, allow_zero=True)
    bl = vector(base_left, "base_left", 3, unit="m")
    br = vector(base_right, "base_right", 3, unit="m")
    o = as_array(points, "points")
    if o.ndim < 1 or o.shape[-1] != 3:
        raise ParameterError(f"points must have shape (..., 3) [m], got shape {o.shape}")
    return o, bl, br, reach, r


def _slacks(o: np.ndarray, bl: np.ndarray, br: np.ndarray, reach: float, r: float):
    """:func:`membership_slacks` of trusted input: points o (..., 3), bases bl, br (3,), reach R and
    half bar length r [m]."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        c1 = bl - o
        c2 = o - br
        d1 = np.linalg.norm(c1, axis=-1)
        d2 = np.linalg.norm(c2, axis=-1)
        cap1 = reach - np.abs(d1 - r)
        cap2 = reach - np.abs(d2 - r)
        if r == 0.0:  # point "bar": both hands at O
            return cap1, cap2, np.full_like(d1, np.inf)
        cos1 = np.where(d1 > 0.0, (r * r + d1 * d1 - reach * reach) / (2.0 * r * d1), -1.0)
        cos2 = np.where(d2 > 0.0, (r * r + d2 * d2 - reach * reach) / (2.0 * r * d2), -1.0)
        th = np.arccos(np.clip(cos1, -1.0, 1.0)) + np.arccos(np.clip(cos2, -1.0, 1.0))
        psi = np.arctan2(np.linalg.norm(np.cross(c1, c2), axis=-1), np.sum(c1 * c2, axis=-1))
        return cap1, cap2, th - psi


def contains_ideal(
    points: np.ndarray,
    base_left: np.ndarray,
    base_right: np.ndarray,
    reach: float,
    bar_length: float,
) -> np.ndarray:
    """Exact membership of object origins (bar midpoints) in the coordinated work envelope.

    Symmetric in the two bases, so it also answers the variant where the hands may swap ends.

    Args:
        points: Candidate bar midpoints, shape (..., 3) [m]; non-finite points are outside.
        base_left: Left robot base, shape (3,) [m].
        base_right: Right robot base, shape (3,) [m].
        reach: Reach radius R of each robot, > 0 [m].
        bar_length: Bar length L, >= 0 [m].

    Returns:
        Boolean array of shape ``points.shape[:-1]``: True iff some bar orientation lets each
        hand hold its end within reach.

    Raises:
        ParameterError: A parameter is non-finite or out of range, or ``points`` is not (..., 3).
    """
    cap1, cap2, ang = _slacks(*_ideal_args(points, base_left, base_right, reach, bar_length))
    return (cap1 >= 0.0) & (cap2 >= 0.0) & (ang >= 0.0)


def closed_form_volume(reach: float, base_distance: float, bar_length: float) -> float | None:
    """Closed-form envelope volume where one exists, else None.

    Exists for an empty envelope (0), a zero-length bar (lens of two reach balls), coincident
    bases (ball of radius ``sqrt(R^2 - (L/2)^2)``) and ``L = D`` (ball of radius R about the
    midpoint of the bases: the hands can always form a parallelogram with the bases).  In general the meridian boundary
    contains Watt's sextic and the volume is an elliptic-type integral (no closed form here).

    Args:
        reach: Reach radius R, > 0 [m].
        base_distance: Base separation D, >= 0 [m].
        bar_length: Bar length L, >= 0 [m].

    Returns:
        Volume [m^3] or None.

    Raises:
        ParameterError: A parameter is non-finite or out of range.
    """
    big_r = _size("reach", reach, allow_zero=False)
    d = _size("base_distance", base_distance, allow_zero=True)
    r = 0.5 * _size("bar_length", bar_length, allow_zero=True)
    if d >= 2.0 * (big_r + r) or 2.0 * r >= d + 2.0 * big_r:  # hands cannot be L apart
        return 0.0
    if r == 0.0:  # intersection of two balls of radius R, centres D apart
        return math.pi * (4.0 * big_r + d) * (2.0 * big_r - d) ** 2 / 12.0
    if d == 0.0:
        return 4.0 / 3.0 * math.pi * (big_r * big_r - r * r) ** 1.5
    if d == 2.0 * r:  # parallelogram linkage: the ball of radius R about the bases' midpoint
        return 4.0 / 3.0 * math.pi * big_r**3
    return None


def _section_area(x: np.ndarray, reach: float, a: float, r: float) -> np.ndarray:
    """Exact area [m^2] of the envelope's cross-section at axial coordinates ``x`` [m].

    Bases at (-a, 0, 0) and (a, 0, 0).  Along a ray perpendicular to the axis, membership can
    only change on the circles |O - B_i| = R + r or r - R, or where both hands touch their
    reach spheres in the meridian plane; the latter are roots of a cubic in s = rho^2.  Every
    candidate root is a breakpoint; each gap is classified by the exact test at its midpoint.
    """
    x = np.asarray(x, dtype=float)
    outer = (reach + r) ** 2
    s_hi = np.minimum(outer - (x + a) ** 2, outer - (x - a) ** 2)
    cols = [np.zeros_like(x), s_hi]
    if r > reach:
        cols += [(r - reach) ** 2 - (x + a) ** 2, (r - reach) ** 2 - (x - a) ** 2]
    if r > 0.0 and a == 0.0:  # coincident bases: the cubic is 4 (s - k + x^2)^2 (s + x^2)
        cols.append(reach * reach - r * r - x * x)
    elif r > 0.0:  # 4 s^3 + c2 s^2 + c1 s + c0 = 0: both hands on their spheres, planar bar
        k = reach * reach - r * r
        p0, q0, m0 = (x + a) ** 2, (x - a) ** 2, x * x - a * a
        u, v = p0 - k, q0 - k
        c2 = 4.0 * (u + v) + 2.0 * m0 + p0 + q0
        c1 = u * u + 2 * u * q0 + 2 * u * v + 2 * (u + v) * m0 + v * v + 2 * v * p0
        c1 = c1 - 16.0 * a * a * r * r
        c0 = u * u * q0 + 2 * u * v * m0 + v * v * p0
        comp = np.zeros(x.shape + (3, 3))
        comp[..., 0, 0], comp[..., 0, 1], comp[..., 0, 2] = -c2 / 4.0, -c1 / 4.0, -c0 / 4.0
        comp[..., 1, 0] = comp[..., 2, 1] = 1.0
        roots = np.linalg.eigvals(comp).real  # complex pairs just add harmless breakpoints
        for _ in range(2):  # Newton polish (simple roots to full precision)
            g = ((4.0 * roots + c2[..., None]) * roots + c1[..., None]) * roots + c0[..., None]
            dg = (12.0 * roots + 2.0 * c2[..., None]) * roots + c1[..., None]
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(np.abs(dg) > 0.0, g / dg, 0.0)
            roots = np.where(np.abs(step) < 1e-6 * (1.0 + np.abs(roots)), roots - step, roots)
        cols += [roots[..., i] for i in range(3)]
    s = np.sort(np.clip(np.stack(cols, axis=-1), 0.0, np.maximum(s_hi, 0.0)[..., None]), axis=-1)
    mid = 0.5 * (s[..., 1:] + s[..., :-1])
    pts = np.stack([np.broadcast_to(x[..., None], mid.shape), np.sqrt(mid), np.zeros_like(mid)], -1)
    bl, br = np.array([-a, 0.0, 0.0]), np.array([a, 0.0, 0.0])
    cap1, cap2, ang = _slacks(pts, bl, br, reach, r)
    inside = (cap1 >= 0.0) & (cap2 >= 0.0) & (ang >= 0.0)
    return math.pi * np.sum(np.where(inside, np.diff(s, axis=-1), 0.0), axis=-1)


def _adaptive_quad(
    f: Callable[[np.ndarray], np.ndarray], lo: float, hi: float, panels: int, rtol: float
) -> tuple[float, float]:
    """Globally adaptive Gauss-Legendre quadrature (10-point rule vs. two half panels).

    Returns:
        ``(integral, estimated absolute error)``.
    """
    t, w = np.polynomial.legendre.leggauss(10)
    edges = np.linspace(lo, hi, panels + 1)
    left, right = edges[:-1], edges[1:]
    done, err_done = 0.0, 0.0
    while True:
        mid = 0.5 * (left + right)
        est = []
        for p, q in ((left, right), (left, mid), (mid, right)):
            h = 0.5 * (q - p)
            est.append(h * (f((p + h)[:, None] + h[:, None] * t[None, :]) @ w))
        fine = est[1] + est[2]
        err = np.abs(fine - est[0])
        total, err_total = done + float(np.sum(fine)), err_done + float(np.sum(err))
        tol = rtol * abs(total) + 1e-300
        if err_total <= tol or left.size > 4_000 or np.min(right - left) < 1e-14 * (hi - lo):
            return total, err_total  # converged, or best effort with an honest error estimate
        split = err > tol / (4.0 * (left.size + 1))
        done += float(np.sum(fine[~split]))
        err_done += float(np.sum(err[~split]))
        left = np.concatenate([left[split], mid[split]])
        right = np.concatenate([mid[split], right[split]])


def _runs(keep: np.ndarray) -> list[np.ndarray]:
    """Index arrays of maximal runs of True in ``keep`` (length >= 2)."""
    idx = np.flatnonzero(keep)
    if idx.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(idx) > 1) + 1
    return [g for g in np.split(idx, cuts) if g.size >= 2]


def _lift(xz: np.ndarray) -> np.ndarray:
    """(..., 2) meridian (x, z) coordinates [m] -> (..., 3) points with y = 0 [m]."""
    return np.stack([xz[..., 0], np.zeros(xz.shape[:-1]), xz[..., 1]], axis=-1)


def _circle_margin(
    phi: np.ndarray, centre: float, rad: float, own: int, reach: float, a: float, r: float
) -> np.ndarray:
    """Slack [m or rad] of the conditions not defining the circle about base ``own``."""
    xz = np.stack([centre + rad * np.cos(phi), rad * np.sin(phi)], axis=-1)
    sl = _slacks(_lift(xz), np.array([-a, 0.0, 0.0]), np.array([a, 0.0, 0.0]), reach, r)
    return np.minimum(sl[1 - own], sl[2])


def _meridian_polylines(reach: float, a: float, r: float, n: int) -> list[np.ndarray]:
    """Meridian boundary as (M, 2) polylines of (x, z) [m], bases at (-a, 0) and (a, 0)."""
    out: list[np.ndarray] = []
    for centre, own in ((-a, 0), (a, 1)) if a > 0.0 else ((0.0, 0),):  # coincident bases: one circle, not two alike
        for rad in [reach + r] + ([r - reach] if r > reach else []):
            args = (centre, rad, own, reach, a, r)
            phi = np.linspace(0.0, 2.0 * np.pi, 4 * n + 1)
            keep = _circle_margin(phi, *args) >= -1e-12
            if keep[0] and keep[-1] and not keep.all():  # rotate: no run may wrap around 2 pi
                shift = int(np.flatnonzero(~keep)[0])
                phi = np.concatenate([phi[shift:-1], phi[: shift + 1] + 2.0 * np.pi])
                keep = np.concatenate([keep[shift:-1], keep[: shift + 1]])
            for g in _runs(keep):
                seg = phi[g]
                if g.size < phi.size:  # bisect the exact ends of the boundary arc
                    inside = np.array([seg[0], seg[-1]])
                    outside = phi[[max(g[0] - 1, 0), min(g[-1] + 1, phi.size - 1)]]
                    for _ in range(60):
                        m = 0.5 * (inside + outside)
                        ok = _circle_margin(m, *args) >= 0.0
                        inside, outside = np.where(ok, m, inside), np.where(ok, outside, m)
                    seg = np.concatenate([inside[:1], seg, inside[1:]])
                out.append(np.stack([centre + rad * np.cos(seg), rad * np.sin(seg)], -1))
    if r > 0.0 and a > 0.0:
        out += _watt_polylines(reach, a, r, n)
    elif r > 0.0:  # coincident bases: the ball of radius sqrt(R^2 - r^2)
        phi = np.linspace(0.0, 2.0 * np.pi, 4 * n + 1)
        out.append(math.sqrt(reach * reach - r * r) * np.stack([np.cos(phi), np.sin(phi)], -1))
    return out


def _watt_polylines(reach: float, a: float, r: float, n: int) -> list[np.ndarray]:
    """Boundary pieces of Watt's curve (both hands on their spheres) as (M, 2) (x, z) [m]."""
    big_l = 2.0 * r
    b1, b2 = np.array([-a, 0.0]), np.array([a, 0.0])

    def circ_circ(c0: np.ndarray, r0: float, c1: np.ndarray, r1: float) -> list[np.ndarray]:
        """Intersection points of two circles (0 or 2 points)."""
        dv = c1 - c0
        dd = float(np.hypot(*dv))
        if dd == 0.0 or dd > r0 + r1 or dd < abs(r0 - r1):
            return []
        al = (r0 * r0 - r1 * r1 + dd * dd) / (2 * dd)
        h = math.sqrt(max(r0 * r0 - al * al, 0.0))
        base, perp = c0 + al * dv / dd, np.array([-dv[1], dv[0]]) / dd
        return [base + h * perp, base - h * perp]

    # Toggle positions (link and bar collinear) are inserted exactly into the parameter grid.
    special = []
    for rad in (reach + big_l, abs(reach - big_l)):
        special += [p - b1 for p in circ_circ(b1, reach, b2, rad)]
        for p2 in circ_circ(b1, rad, b2, reach):
            sign = -1.0 if (rad == abs(reach - big_l) and big_l > reach) else 1.0
            special.append(sign * (p2 - b1))
    phi = np.linspace(0.0, 2.0 * np.pi, 8 * n + 1)
    phi = np.unique(np.concatenate([phi, [math.atan2(v[1], v[0]) % (2 * np.pi) for v in special]]))
    p1 = b1 + reach * np.stack([np.cos(phi), np.sin(phi)], -1)
    dv = b2 - p1
    d = np.hypot(dv[:, 0], dv[:, 1])
    ok = (d <= reach + big_l + 1e-12) & (d >= abs(reach - big_l) - 1e-12) & (d > 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        al = np.clip((big_l * big_l - reach * reach + d * d) / (2 * d * big_l), -1.0, 1.0)
        e = dv / d[:, None]
    perp = np.stack([-e[:, 1], e[:, 0]], -1)
    out = []
    for sg in (1.0, -1.0):
        p2 = p1 + big_l * (al[:, None] * e + sg * np.sqrt(1.0 - al * al)[:, None] * perp)
        o = 0.5 * (p1 + p2)
        ang = _slacks(_lift(o), np.array([-a, 0.0, 0.0]), np.array([a, 0.0, 0.0]), reach, r)[2]
        keep = ok & (np.abs(np.nan_to_num(ang, nan=1.0)) <= _WATT_TOL)
        out += [o[g] for g in _runs(keep)]
    return out


def ideal_envelope(
    reach: float,
    base_distance: float,
    bar_length: float,
    resolution: int = 128,
    *,
    base_left: np.ndarray | None = None,
    base_right: np.ndarray | None = None,
    rtol: float = 1e-11,
) -> IdealEnvelope:
    """Volume and meridian boundary of the idealised coordinated work envelope.

    Args:
        reach: Reach radius R of each robot, finite and > 0 [m].
        base_distance: Distance D between the bases, finite and >= 0 [m].
        bar_length: Bar length L, finite and >= 0 [m].
        resolution: Integer in [8, 100000]: initial quadrature panels on the half axis and
            boundary sampling density (4*resolution points per circle, 8*resolution per Watt
            branch).
        base_left: Optional left base (3,) [m]; default (-D/2, 0, 0).  Must be given together
            with ``base_right`` and lie D apart.
        base_right: Optional right base (3,) [m]; default (D/2, 0, 0).
        rtol: Relative tolerance of the volume quadrature, in [1e-14, 1e-3].

    Returns:
        Frozen IdealEnvelope; boundary polylines lie in the vertical plane through the bases.

    Raises:
        ParameterError: A parameter is non-finite or out of range, or the bases are not D apart.
    """
    big_r = _size("reach", reach, allow_zero=False)
    dist = _size("base_distance", base_distance, allow_zero=True)
    r = 0.5 * _size("bar_length", bar_length, allow_zero=True)
    if (
        isinstance(resolution, bool)
        or not isinstance(resolution, (int, np.integer))
        or not (8 <= resolution <= 100_000)
    ):
        raise ParameterError(f"resolution must be an integer in [8, 100000], got {resolution!r}")
    rtol = real(rtol, "rtol", lo=1e-14, hi=1e-3, unit="")  # any real (a numpy float32 was refused)
    if (base_left is None) != (base_right is None):
        raise ParameterError("base_left and base_right must be given together or not at all")
    if base_left is None:
        bl, br = np.array([-dist / 2, 0.0, 0.0]), np.array([dist / 2, 0.0, 0.0])
    else:
        bl, br = vector(base_left, "base_left", 3, unit="m"), vector(base_right, "base_right", 3, unit="m")
        if abs(float(np.linalg.norm(br - bl)) - dist) > 1e-9 * max(1.0, dist):
            raise ParameterError(
                f"base_distance must equal |base_right - base_left| "
                f"(= {float(np.linalg.norm(br - bl))!r} m), got {dist!r}"
            )
    a = dist / 2.0
    half_width = big_r + r - a  # lens of the two (R + r)-balls along the axis
    closed = closed_form_volume(big_r, dist, 2.0 * r)
    if half_width <= 0.0 or closed == 0.0:
        vol, err, lines = 0.0, 0.0, []
    else:
        half, err = _adaptive_quad(
            lambda x: _section_area(x, big_r, a, r), 0.0, half_width, int(resolution), rtol
        )
        vol, err = 2.0 * half, 2.0 * err  # symmetric under swapping the bases (x -> -x)
        lines = _meridian_polylines(big_r, a, r, int(resolution))
    # local frame: ex along the base line, ez the upward direction orthogonal to it
    ex = (br - bl) / dist if dist > 0.0 else np.array([1.0, 0.0, 0.0])
    ez = np.array([0.0, 0.0, 1.0]) - ex[2] * ex
    if np.linalg.norm(ez) < 1e-9:  # vertical base line: any horizontal direction will do
        ez = np.array([1.0, 0.0, 0.0]) - ex[0] * ex
    ez /= np.linalg.norm(ez)
    centre = 0.5 * (bl + br)
    boundary = []
    for xz in lines:
        pts = centre + xz[:, :1] * ex + xz[:, 1:] * ez
        pts.setflags(write=False)
        boundary.append(pts)
    bl.setflags(write=False)
    br.setflags(write=False)
    return IdealEnvelope(
        reach_m=big_r,
        base_distance_m=dist,
        bar_length_m=2.0 * r,
        base_left=bl,
        base_right=br,
        volume_m3=vol,
        volume_upper_half_m3=0.5 * vol,
        volume_error_m3=err,
        volume_closed_form_m3=closed,
        boundary=tuple(boundary),
    )
