"""View provider of the program: the tool axes along the path, as a hedgehog of shafts.

At every k-th path point (about ``Shafts`` of them, evenly along the path) a line from the
ball centre along the tool axis, ``ShaftLength`` long, coloured by the angle between the
axis and +Z (near black vertical, to red at the largest tilt of the program): how
the axis leans and turns is what a programmer checks before posting. The ball centres are
drawn as a thin polyline underneath. Drawn from the stored oriented path, never recomputed.
"""
from __future__ import annotations

import numpy as np

from . import coinutil
from .programobject import TsplcamProgram
from .proxy import DrawnViewProxy, add_property

PATH_COLOUR = (0.35, 0.35, 0.40)
TILT_BANDS = 6          # colour bands from vertical to the largest tilt


def ensure_view_properties(vobj) -> None:
    g = "Tool axes"
    add_property(vobj, "App::PropertyInteger", "Shafts", g, "How many tool axes to draw along the path", 400)
    add_property(vobj, "App::PropertyLength", "ShaftLength", g,
                 "Length of the drawn tool axes (0: a tenth of the path's size)", 0.0)


def tilt_colour(t: float) -> tuple:
    """Near black (0, vertical) to pure red (1, the largest tilt): readable over every patch
    colour of the model's palette."""
    t = float(np.clip(t, 0.0, 1.0))
    return (0.08 + 0.87 * t, 0.08 * (1.0 - t), 0.08 * (1.0 - t))


def shaft_sample(n: int, shafts: int) -> np.ndarray:
    """Indices of about ``shafts`` points spread evenly over n path points."""
    if n == 0:
        return np.zeros(0, int)
    return np.unique(np.linspace(0, n - 1, max(2, min(int(shafts), n))).round().astype(int))


class ViewProviderProgram(DrawnViewProxy):
    ensure_view_properties = staticmethod(ensure_view_properties)
    DISPLAY_MODE = "Axes"
    ICON = "program"
    CHILD = "ToolPath"
    DATA_PROPS = ("AxesFile",)
    VIEW_PROPS = ("Shafts", "ShaftLength")
    TITLE = "Program"

    def draw(self, obj, group) -> bool:
        if not obj.AxesFile or not isinstance(obj.Proxy, TsplcamProgram):
            return False
        tp = obj.Proxy.oriented_path(obj)
        if len(tp) == 0:
            return False
        C, A = tp.center, tp.axis
        size = float(np.linalg.norm(C.max(axis=0) - C.min(axis=0))) or 1.0
        length = float(getattr(self.ViewObject, "ShaftLength", 0.0) or 0.0) or 0.1 * size
        group.addChild(coinutil.polylines([C], PATH_COLOUR, 1.0))
        idx = shaft_sample(len(tp), getattr(self.ViewObject, "Shafts", 400))
        tilt = np.degrees(np.arccos(np.clip(A[idx, 2], -1.0, 1.0)))
        top = max(float(tilt.max()), 1e-9)
        band = np.minimum((tilt / top * TILT_BANDS).astype(int), TILT_BANDS - 1)
        for b in np.unique(band):
            sel = idx[band == b]
            pts = np.vstack([C[sel], C[sel] + length * A[sel]])
            edges = np.column_stack([np.arange(len(sel)), np.arange(len(sel)) + len(sel)])
            group.addChild(coinutil.segments(pts, edges, tilt_colour((b + 0.5) / TILT_BANDS), 2.0))
        return True
