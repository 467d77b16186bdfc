"""Camera framing: the whole cell in view at start (``server.initial_camera``, also viser's "Reset
View" target) and on the "fit view" button (the client's own camera, keeping its direction).

viser has no "fit to box": the distance is computed here from the bounding sphere of the points to
see and the camera's field of view (the narrower of vertical and horizontal).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

__all__ = ["FOV", "PANEL", "VIEW_DIRECTION", "fit_client", "frame_points", "set_initial_camera"]

FloatArray = npt.NDArray[np.float64]

VIEW_DIRECTION = (-0.3, -1.0, 0.55)  #: from the cell towards the camera: in front, a little left, above
FOV = math.radians(50.0)  #: vertical field of view of the initial camera [rad]
PANEL = 0.3  #: fraction of a wide window the control panel covers (right side)


def frame_points(points: npt.ArrayLike, fov: float, aspect: float, direction: npt.ArrayLike = VIEW_DIRECTION,
                 margin: float = 1.35, panel: float = PANEL) -> tuple[FloatArray, FloatArray]:
    """Camera (position, look_at) [m] seeing every point, looking along ``-direction``.

    Args:
        points: (N, 3) points [m].
        fov: vertical field of view [rad]; aspect: width / height.
        direction: from the look-at point towards the camera (normalised here).
        margin: >= 1, room around the points.
        panel: fraction of the width covered by the control panel on the right: the points are
            framed in the rest (the camera looks a little to the right of their centre).
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    centre = 0.5 * (p.min(axis=0) + p.max(axis=0))
    radius = max(float(np.max(np.linalg.norm(p - centre, axis=1))), 0.1)
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    free = max(aspect, 1e-3) * (1.0 - panel)
    hfov = 2.0 * math.atan(math.tan(fov / 2.0) * free)
    dist = margin * radius / math.sin(0.5 * min(fov, hfov))
    right = np.cross(-d, (0.0, 0.0, 1.0))
    if np.linalg.norm(right) < 1e-9:
        right = np.array([1.0, 0.0, 0.0])
    right /= np.linalg.norm(right)
    width = 2.0 * dist * math.tan(fov / 2.0) * max(aspect, 1e-3)  # visible width at the look-at distance
    look = centre + 0.5 * panel * width * right
    return look + dist * d, look


def set_initial_camera(server, points: npt.ArrayLike, aspect: float = 1.6) -> None:
    """Where every new client's camera starts (and "Reset View" returns): the whole cell."""
    pos, look = frame_points(points, FOV, aspect)
    cam = server.initial_camera
    cam.fov = FOV
    cam.up = (0.0, 0.0, 1.0)
    cam.position = tuple(float(v) for v in pos)
    cam.look_at = tuple(float(v) for v in look)


def fit_client(client, points: npt.ArrayLike) -> None:
    """Move one client's camera so that every point is in view, keeping its viewing direction."""
    cam = client.camera
    d = np.asarray(cam.position, float) - np.asarray(cam.look_at, float)
    if not np.all(np.isfinite(d)) or np.linalg.norm(d) < 1e-9:
        d = np.asarray(VIEW_DIRECTION, float)
    pos, look = frame_points(points, *_lens(cam), d)
    with client.atomic():
        cam.position = tuple(float(v) for v in pos)  # viser moves look_at with position: set it after
        cam.look_at = tuple(float(v) for v in look)


def _lens(cam) -> tuple[float, float]:
    """The camera's (vertical field of view [rad], aspect), or the initial camera's where a client
    reported ones no browser has (the server screens them: security.screen_message; this is the
    second line: a zero window height made viser's aspect divide by zero, on every frame)."""
    try:
        fov, aspect = float(cam.fov), float(cam.aspect)
    except (ZeroDivisionError, TypeError, ValueError, OverflowError):
        fov, aspect = math.nan, math.nan
    return (fov if 1e-3 < fov < math.pi - 1e-3 else FOV), (aspect if 1e-3 < aspect < 1e3 else 1.6)
