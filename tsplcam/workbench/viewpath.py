"""View provider of the tool path: the path as polylines coloured by move type.

CUT moves dark blue, LINK moves (between lines and between patches, on the surface)
orange and thicker, RETRACT and RAPID moves red and dashed; the first point green, the
last black. Drawn along the ball centres or the contact points (``Show``), from the
stored ToolPath, never recomputed here.
"""
from __future__ import annotations

import numpy as np

from . import coinutil, display
from .pathobject import path_of
from .proxy import DrawnViewProxy, add_property

MOVE_STYLE = {      # Move value: (colour, width, pattern)
    0: ((0.05, 0.10, 0.45), 1.2, None),          # CUT
    1: ((1.00, 0.50, 0.00), 3.0, None),          # LINK
    2: ((0.85, 0.05, 0.05), 2.5, coinutil.DASHED),   # RETRACT
    3: ((0.85, 0.05, 0.05), 2.0, coinutil.DOTTED),   # RAPID
}


def ensure_view_properties(vobj) -> None:
    g = "Tool path"
    if add_property(vobj, "App::PropertyEnumeration", "Show", g,
                    "Draw the ball centres (what the tool follows) or the contact points"):
        vobj.Show = ["Ball centre", "Contact"]
        vobj.Show = "Ball centre"


class ViewProviderToolPath(DrawnViewProxy):
    ensure_view_properties = staticmethod(ensure_view_properties)
    DISPLAY_MODE = "Path"
    ICON = "toolpath"
    CHILD = "ProcessingList"
    DATA_PROPS = ("PathFile",)
    VIEW_PROPS = ("Show",)
    TITLE = "Tool path"

    def draw(self, obj, group) -> bool:
        if not obj.PathFile:
            return False
        tp = path_of(obj)
        pts = tp.center if getattr(self.ViewObject, "Show", "Ball centre") == "Ball centre" else tp.contact
        for move, lines in sorted(display.segments_by_move(pts, tp.move).items()):
            colour, width, pattern = MOVE_STYLE.get(move, MOVE_STYLE[0])
            group.addChild(coinutil.polylines(lines, colour, width, pattern))
        if len(pts):
            size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) or 1.0
            group.addChild(coinutil.spheres(pts[:1], 0.012 * size, (0.10, 0.75, 0.20)))
            group.addChild(coinutil.spheres(pts[-1:], 0.012 * size, (0.0, 0.0, 0.0)))
        return True
