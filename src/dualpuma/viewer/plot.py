"""The clearance-along-the-path plot (uPlot): x is the step (or the time of a timed trajectory),
never a date; a vertical marker stands at the current position.

uPlot takes data only (no JS plugins through viser), and treats NaN as a value, so the marker is
drawn with finite data: four samples inserted at the marker's x, where a "marker" series drawn
under the clearance curve goes from the curve down to the plot's floor, up to its top and back
(:func:`with_marker`); everywhere else it runs under the curve and is hidden by it.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from viser import uplot

__all__ = ["ClearancePlot", "with_marker"]

FloatArray = npt.NDArray[np.float64]


def with_marker(x: npt.ArrayLike, y: npt.ArrayLike, extra: list, at: float, lo: float, hi: float) -> tuple[FloatArray, ...]:
    """Plot data (x, marker, y, *extra) with a vertical marker at ``at`` spanning [lo, hi]."""
    x = np.asarray(x, dtype=np.float64)
    ys = [np.asarray(y, dtype=np.float64)] + [np.asarray(e, dtype=np.float64) for e in extra]
    at = float(np.clip(at, x[0], x[-1]))
    k = int(np.searchsorted(x, at))
    vals = [float(np.interp(at, x, v)) for v in ys]
    xs = np.concatenate([x[:k], np.full(4, at), x[k:]])
    out = [np.concatenate([v[:k], np.full(4, a), v[k:]]) for v, a in zip(ys, vals)]
    marker = out[0].copy()
    marker[k:k + 4] = (vals[0], lo, hi, vals[0])
    return (xs, marker, *out)


class ClearancePlot:
    """The plot handle and its data (millimetres on y)."""

    def __init__(self, gui, margin_mm: float) -> None:
        self.margin_mm = margin_mm
        self.x = np.array([0.0, 1.0])
        self.y = np.zeros(2)
        self.label = "step"
        self.at = 0.0
        self.handle = gui.add_uplot(
            data=self._data(),
            series=self._series(),
            scales=self._scales(),
            axes=(uplot.Axis(label="step"), uplot.Axis(label="clearance [mm]")),
            title="clearance along the path [mm]",
            aspect=1.7,
        )

    def _scales(self):
        """The x range pinned to the curve's (a new object each time: the page rebuilds the chart).
        Left to uPlot, the page kept the last plan's x range when the axis changed between steps
        and seconds (a 2.5 s trajectory squashed into 0..73, or cut off at 1 s)."""
        return {"x": uplot.Scale(time=False, auto=False, range=(float(self.x[0]), float(self.x[-1]))),
                "y": uplot.Scale(auto=True)}

    def _series(self):
        return (uplot.Series(label=self.label),
                uplot.Series(label="now", stroke="rgba(230,30,30,0.9)", width=1.5, points={"show": False}),
                uplot.Series(label="clearance", stroke="rgb(30,90,200)", width=2),
                uplot.Series(label="margin", stroke="rgb(230,30,30)", width=1, dash=(6, 4), points={"show": False}))

    def _data(self) -> tuple[FloatArray, ...]:
        lo = float(min(np.min(self.y), self.margin_mm, 0.0))
        hi = float(max(np.max(self.y), self.margin_mm)) * 1.05 + 1.0
        return with_marker(self.x, self.y, [np.full(len(self.x), self.margin_mm)], self.at, lo, hi)

    def set_curve(self, x: npt.ArrayLike, clearance_m: npt.ArrayLike, label: str, margin_mm: float) -> None:
        """A new curve (a new plan): x values, clearance [m]."""
        x = np.asarray(x, dtype=np.float64)
        if x.size < 2:
            x = np.array([0.0, 1.0])
            clearance_m = np.full(2, np.asarray(clearance_m, float).reshape(-1)[:1].sum() if np.size(clearance_m) else 0.0)
        self.x, self.y, self.margin_mm = x, np.asarray(clearance_m, dtype=np.float64) * 1000.0, margin_mm
        self.at = float(x[0])
        self.handle.data = self._data()
        if label != self.label:
            self.label = label
            self.handle.series = self._series()
            self.handle.axes = (uplot.Axis(label=label), uplot.Axis(label="clearance [mm]"))
        self.handle.scales = self._scales()

    def set_marker(self, at: float) -> None:
        """Move the marker to x = ``at`` (re-sends the data; call when it moved)."""
        if at != self.at:
            self.at = float(at)
            self.handle.data = self._data()

    def value_at(self, at: float) -> float:
        """The plotted clearance [mm] at x = ``at`` (linear between samples)."""
        return float(np.interp(at, self.x, self.y))
