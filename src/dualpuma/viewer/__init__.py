"""The browser viewer (``dualpuma serve``): a viser server showing a cell, animating plans, and a
teach pendant. Uses the public APIs of the other subpackages only.

May import: every other subpackage (public names).
"""

from .app import ViewerApp, serve

__all__ = ["ViewerApp", "serve"]
