"""The view tab: fit view, what is drawn (toggles), and the legend of colours."""

from __future__ import annotations

from .camera import fit_client
from .intents import Intent, choice, flag
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
                h = c.input(f"view.{key}", g.add_checkbox(label, app.scene.visible[key], hint=HINTS[key]))
                if key == "real_envelope" and app.scene.real_envelope is None:
                    h.disabled = True
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
            app.scene.show(what, flag(it.value, TOGGLES[what]))
            app.redraw = True
        else:
            return False
        return True

    def show(self, seq: int) -> None:
        for key in TOGGLES:
            self.app.controls.show(f"view.{key}", self.app.scene.visible[key], seq)
        self.app.controls.handles["view.real_envelope"].disabled = self.app.scene.real_envelope is None
