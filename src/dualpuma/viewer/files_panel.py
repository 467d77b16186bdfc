"""The cell & files tab: the cell selector (shipped examples and the TOML files of the data
directory) and the taught waypoints' files. Every file name is a short name inside the data
directory (:mod:`.datadir`); nothing else is ever read or written."""

from __future__ import annotations

from ..errors import CellError, DualpumaError
from ..model import EXAMPLE_CELLS, MAX_CELL_BYTES, cell_from_toml, example_cell
from .datadir import DataDir, waypoints_from_bytes, waypoints_to_bytes
from .intents import Intent, Refused, choice, flag, text
from .status import markdown_text

__all__ = ["MAX_TYPED", "FilesPanel", "cell_options"]

MAX_TYPED = 200  #: longest text kept in the file-name box [characters]


def cell_options(data: DataDir, extra: tuple[str, ...] = ()) -> tuple[str, ...]:
    """The cell selector's options: ``extra`` (the startup cell, a routine's cell), the shipped
    examples, the data directory's ``*.toml`` files."""
    opts = list(extra) + [f"example: {n}" for n in EXAMPLE_CELLS] + [f"file: {n}" for n in data.names(".toml")]
    return tuple(dict.fromkeys(opts))


class FilesPanel:
    """The cell & files tab of ``app``."""

    def __init__(self, app, tab) -> None:
        self.app = app
        g, c = app.server.gui, app.controls
        with tab:
            g.add_markdown(f"**data directory**: {markdown_text(app.data.root)}  \nfiles are read and written only "
                           "here, by name (letters, digits, - and \\_)")
            self.cell = c.input("cell_choice", g.add_dropdown("cell", self.options(), initial_value=app.cell_label))
            c.group("cell_action", g.add_button_group("cell", ("load cell", "refresh list")))
            self.cell_info = g.add_markdown("")
            c.input("file_name", g.add_text("waypoint file", app.settings["file_name"], hint="a name, e.g. pick-1"))
            c.input("overwrite", g.add_checkbox("overwrite", app.settings["overwrite"],
                                                hint="for one save (replace the file) or load (replace the "
                                                     "recorded waypoints); unticked after it, done or refused"))
            c.group("file_action", g.add_button_group("waypoints", ("save", "load")))
            self.listing = g.add_markdown("")
        self._kept = app.state.waypoints  # the waypoints last saved or loaded (others are the user's new work)
        self.refresh()

    def options(self) -> tuple[str, ...]:
        extra = tuple(x for x in (self.app.startup_label, self.app.cell_label) if x)
        return cell_options(self.app.data, extra)

    def refresh(self) -> None:
        """Re-read the data directory (cell options, waypoint files)."""
        self.cell.options = self.options()
        data = self.app.data
        names = data.names(".json")
        listing = ("waypoint files: " + ", ".join(markdown_text(n) for n in names[:30])
                   + (" …" if len(names) > 30 else "")) if names else "no waypoint files yet"
        left_out = data.unlisted(".toml") + data.unlisted(".json")
        if left_out:  # say so rather than leave a user's file out silently
            listing += (f"  \nnot listed ({len(left_out)}; a name of letters, digits, - and \\_, a regular file, not a "
                        "link): " + ", ".join(markdown_text(n) for n in left_out[:10]) + (" …" if len(left_out) > 10 else ""))
        self.listing.content = listing

    def load_choice(self, label: str):
        """The Cell an option names (CellError/FileError/ParameterError if it cannot be loaded)."""
        app = self.app
        if label == app.startup_label:
            return app.startup_cell
        kind, _, name = label.partition(": ")
        if kind == "example":
            return example_cell(name)
        if kind == "file":
            raw = app.data.read(name, ".toml", MAX_CELL_BYTES)  # validates the name, refuses links and large files
            where = app.data.path(name, ".toml").name
            try:
                toml_text = raw.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise CellError(f"{where}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
            # a URDF robot of this cell must be in the data directory too: nothing outside is read
            return cell_from_toml(toml_text, source=where, base_dir=app.data.root, urdf_root=app.data.root)
        raise Refused(f"cell: {label!r} cannot be loaded here")

    # ------------------------------------------------------------------ intents (loop thread)
    def apply(self, it: Intent) -> bool:
        app, key, s = self.app, it.key, self.app.settings
        if key == "cell_choice":
            s["cell_choice"] = choice(it.value, tuple(self.cell.options), "cell")
        elif key == "cell_action":
            if choice(it.value, ("load cell", "refresh list"), "cell") == "refresh list":
                self.refresh()
                return True
            label = s["cell_choice"]
            try:
                cell = self.load_choice(label)
            except DualpumaError as exc:
                raise Refused(f"cell {label!r} not loaded: {exc}") from None
            app.switch_cell(cell, label, it)
        elif key == "file_name":
            s["file_name"] = text(it.value, "file name", MAX_TYPED)
        elif key == "overwrite":
            s["overwrite"] = flag(it.value, "overwrite")
        elif key == "file_action":
            if choice(it.value, ("save", "load"), "waypoints") == "save":
                self._save(it)
            else:
                self._load(it)
        else:
            return False
        return True

    def _save(self, it: Intent) -> None:
        app, s = self.app, self.app.settings
        waypoints = app.state.waypoints
        overwrite, s["overwrite"] = s["overwrite"], False  # for this one attempt: a refused one uses it up too
        try:
            existed = app.data.path(s["file_name"], ".json").exists()  # (validates the name first)
            if not waypoints and (overwrite or not existed):  # an empty file, or a blanked one
                raise Refused("waypoints not saved: none recorded ('record' in the teach tab adds one)")
            p = app.data.write(s["file_name"], ".json", waypoints_to_bytes(list(waypoints)), overwrite=overwrite)
        except DualpumaError as exc:
            raise Refused(f"waypoints not saved: {exc}") from None
        self._kept = waypoints
        self.refresh()
        app.status.tell(f"saved {len(waypoints)} waypoint(s) to {p}{', replacing the file that was there' if existed else ''}",
                        "ok", it.client, title="Saved")

    def _load(self, it: Intent) -> None:
        app, s = self.app, self.app.settings
        overwrite, s["overwrite"] = s["overwrite"], False  # for this one attempt, as for a save
        unsaved = app.state.waypoints is not self._kept and len(app.state.waypoints) > 0
        if unsaved and not overwrite:
            raise Refused(f"waypoints not loaded: it would replace the {len(app.state.waypoints)} waypoint(s) recorded "
                          "since the last save or load; save them first, or tick 'overwrite' to replace them")
        try:
            name = s["file_name"]
            poses = waypoints_from_bytes(app.data.read(name, ".json", 1 << 20), app.data.path(name, ".json").name)
        except DualpumaError as exc:
            raise Refused(f"waypoints not loaded: {exc}") from None
        app.state.set_waypoints(poses, it, f"loaded {len(poses)} waypoint(s) from {app.data.path(name, '.json').name}")
        self._kept = app.state.waypoints

    # ------------------------------------------------------------------ write-back (loop thread)
    def show(self, seq: int) -> None:
        c, s = self.app.controls, self.app.settings
        for key in ("file_name", "overwrite"):
            c.show(key, s[key], seq)
        if s["cell_choice"] not in self.cell.options:
            s["cell_choice"] = self.app.cell_label
        c.show("cell_choice", s["cell_choice"], seq)
        cell = self.app.cell
        info = (f"**shown**: {markdown_text(self.app.cell_label)} — {markdown_text(cell.name)}, {len(cell.obstacles)} obstacle(s), "
                f"margin {cell.safety_margin * 1000:.0f} mm")
        if self.cell_info.content != info:
            self.cell_info.content = info

