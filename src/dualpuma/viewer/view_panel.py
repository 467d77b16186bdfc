"""The view tab: fit view, what is drawn (toggles), and the legend of colours."""

from __future__ import annotations

from .camera import fit_client
from .intents import Intent, Refused, choice, flag
from .scene import ARM_COLORS, COLORS

__all__ = ["HINTS", "TOGGLES", "ViewPanel", "legend_html"]

#: scene toggle key -> label
TOGGLES = {
    "arms": "arms",
    "capsules": "capsules",
    "frames": "frames",
    "grown": "grown obstacles",
    "envelope": "envelope, ideal",
    "real_envelope": "envelope, real x–z",
}
HINTS = {
    "arms": "the arms' URDF visual geometry",
    "capsules": "the collision capsules the clearance is computed with",
    "frames": "world, base, hand and object frames",
    "grown": "obstacles grown by the bar's size (the seed's configuration mapping)",
    "envelope": "the idealised coordinated work-envelope arcs (seed, section 2.6)",
    "real_envelope": "the real coordinated envelope's x-z section through the start frame",
}


def legend_html() -> str:
    """The legend: a coloured square per kind of thing drawn (static text, no user input)."""
    rows = [("left arm", ARM_COLORS["left"]), ("right arm", ARM_COLORS["right"]), ("bar", COLORS["bar"]),
            ("obstacle", COLORS["obstacle"]), ("grown obstacle (toggle)", COLORS["grown"]),
            ("closest pair: clear", COLORS["clear"]), ("closest pair: below the margin", COLORS["collision"]),
            ("planned path", COLORS["path"]), ("idealised envelope (toggle)", COLORS["envelope"]),
            ("real envelope section (toggle)", COLORS["real_envelope"])]
    items = "".join(
        f'<div style="display:flex;align-items:center;gap:6px;font-size:0.8em">'
        f'<span style="display:inline-block;width:12px;height:12px;background:rgb{c}"></span>{name}</div>'
        for name, c in rows)
    return f'<div style="padding:2px 12px">{items}</div>'


class ViewPanel:
    """The view tab of ``app``."""

    def __init__(self, app, tab) -> None:
        self.app = app
        g, c = app.server.gui, app.controls
        with tab:
            c.group("fit", g.add_button_group("camera", ("fit view",)))
            for key, label in TOGGLES.items():
                c.input(f"view.{key}", g.add_checkbox(label, app.scene.visible[key], hint=HINTS[key]))
            g.add_html(legend_html())

    def apply(self, it: Intent) -> bool:
        app = self.app
        if it.key == "fit":
            choice(it.value, ("fit view",), "camera")
            if it.client is not None:
                fit_client(it.client, app.scene.points())
        elif it.key.startswith("view."):
            what = it.key.split(".", 1)[1]
            if what not in TOGGLES:
                return False
            on = flag(it.value, TOGGLES[what])
            if on and what in ("envelope", "real_envelope") and getattr(app.scene, what) is None:
                raise Refused(f"{TOGGLES[what]}: nothing to draw for this cell"
                              + (" (the idealised arcs are the model of two PUMA 560s)" if what == "envelope" else ""))
            app.scene.show(what, on)
            app.redraw = True
        else:
            return False
        return True

    def show(self, seq: int) -> None:
        for key in TOGGLES:
            self.app.controls.show(f"view.{key}", self.app.scene.visible[key], seq)
        # nothing to draw for this cell (the idealised arcs are the two-PUMA model's): disabled, not silent
        for key in ("envelope", "real_envelope"):
            self.app.controls.handles[f"view.{key}"].disabled = getattr(self.app.scene, key) is None
