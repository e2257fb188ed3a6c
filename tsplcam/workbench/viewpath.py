"""View provider of the tool path: the path as polylines coloured by move type or by patch.

``ColourBy`` "Move": CUT moves dark blue; "Patch": each patch's cuts in its colour of the
model's palette. Either way LINK moves (between lines and between patches, on the surface)
are orange and thicker, RETRACT and RAPID moves red and dashed; the first point green, the
last black. Drawn along the ball centres or the contact points (``Show``), from the
stored ToolPath, never recomputed here; gray when the path is not valid.
"""
from __future__ import annotations

import numpy as np

from . import coinutil, display
from .pathobject import path_of
from .proxy import DrawnViewProxy, EditableMixin, add_property

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
    if add_property(vobj, "App::PropertyEnumeration", "ColourBy", g,
                    "Colour of the cutting moves: by move type (navy) or by patch (the model's colours); "
                    "links stay orange, retracts red"):
        vobj.ColourBy = ["Move", "Patch"]
        vobj.ColourBy = "Move"


class ViewProviderToolPath(EditableMixin, DrawnViewProxy):
    ensure_view_properties = staticmethod(ensure_view_properties)
    DISPLAY_MODE = "Path"
    ICON = "toolpath"

    @staticmethod
    def panel():
        from .settingspanel import SettingsPanel
        return SettingsPanel
    CHILD = "ProcessingList"
    DATA_PROPS = ("PathFile",)
    VIEW_PROPS = ("Show", "ColourBy")
    TITLE = "Tool path"
    drawn_valid = True

    def draw(self, obj, group) -> bool:
        from . import validity
        self.drawn_valid = not validity.failed(obj)
        if not obj.PathFile:
            return False
        tp = path_of(obj)
        pts = tp.center if getattr(self.ViewObject, "Show", "Ball centre") == "Ball centre" else tp.contact
        by_patch = getattr(self.ViewObject, "ColourBy", "Move") == "Patch" and self.drawn_valid
        for move, lines in sorted(display.segments_by_move(pts, tp.move).items()):
            colour, width, pattern = MOVE_STYLE.get(move, MOVE_STYLE[0])
            if not self.drawn_valid:
                colour = (0.6, 0.6, 0.6)
            if move == 0 and by_patch:
                self._draw_cuts_by_patch(obj, group, tp, pts)
                continue
            group.addChild(coinutil.polylines(lines, colour, width, pattern))
        if len(pts):
            size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) or 1.0
            group.addChild(coinutil.spheres(pts[:1], 0.012 * size, (0.10, 0.75, 0.20)))
            group.addChild(coinutil.spheres(pts[-1:], 0.012 * size, (0.0, 0.0, 0.0)))
        return True

    def _draw_cuts_by_patch(self, obj, group, tp, pts) -> None:
        from ..layout.layout import Layout
        from .modelobject import model_of
        model = model_of(obj.ProcessingList.Model)
        colours = display.patch_colours(Layout.from_model(model))
        kind = np.asarray(tp.move[1:], int)
        for p in np.unique(tp.patch[tp.patch >= 0]):
            on = np.nonzero((kind == 0) & (tp.patch[1:] == p) & (tp.patch[:-1] == p))[0]
            group.addChild(coinutil.segments(pts, np.column_stack([on, on + 1]),
                                             display.PALETTE[colours[int(p)]], 1.5))
