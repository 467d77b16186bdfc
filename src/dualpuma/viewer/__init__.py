"""The browser viewer (``dualpuma serve``): a viser server showing a cell, animating plans, and a
teach pendant. Uses the public APIs of the other subpackages only.

May import: every other subpackage (public names).
"""

from .app import ViewerApp, serve
from .datadir import DEFAULT_DATA_DIR, DataDir, load_waypoints, save_waypoints
from .security import AccessPolicy, check_listen, is_loopback

__all__ = [
    "DEFAULT_DATA_DIR",
    "AccessPolicy",
    "DataDir",
    "ViewerApp",
    "check_listen",
    "is_loopback",
    "load_waypoints",
    "save_waypoints",
    "serve",
]
