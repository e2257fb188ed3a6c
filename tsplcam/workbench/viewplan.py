"""View provider of the processing list: the machining order drawn on the model.

As in shang2020 figure 8: per step a curve across its patch from the start corner to the
finish corner (navy on a white halo, with an arrow head), the step number near its start
(white on navy, unlike the patch numbers), the transit points where one patch hands over
to the next, retractions as dashed red arcs above the surface, the start of the whole
list green and its end black. ``CurrentStep`` highlights one step of the stored list. While
the task panel edits a working copy, the view draws that copy (``show_list``) and highlights
the selected row's step (``show_step``): its patch outlined in yellow, its start corner green,
its finish corner red, so the 3D view always matches the row. Double-click opens the task
panel.
"""
from __future__ import annotations

from pivy import coin

from . import coinutil, display, messages
from .modelobject import model_of
from .planobject import plan_of
from .proxy import EditableMixin, ViewProxy, add_property

CURVE = (0.05, 0.12, 0.50)
CURRENT = (1.0, 0.85, 0.0)
RETRACT = (0.85, 0.08, 0.08)
START = (0.10, 0.75, 0.20)
FINISH = (0.0, 0.0, 0.0)
STEP_FINISH = (0.90, 0.10, 0.10)
LAYERS = ("curves", "numbers", "retractions", "markers", "current")


def ensure_view_properties(vobj) -> None:
    g = "Processing list"
    add_property(vobj, "App::PropertyBool", "ShowStepNumbers", g, "Number the steps", True)
    add_property(vobj, "App::PropertyInteger", "CurrentStep", g,
                 "Highlight this step (1-based; 0: none)", 0)


class ViewProviderProcessingList(EditableMixin, ViewProxy):
    ensure_view_properties = staticmethod(ensure_view_properties)
    DISPLAY_MODE = "Order"
    ICON = "plan"
    CHILD = "Model"
    root = None
    layers = None
    _drawn = None
    override = None          # the task panel's working list, drawn instead of the stored one
    step = None              # the task panel's selected step

    def attach(self, vobj):
        super().attach(vobj)
        self.root = coin.SoSeparator()
        self.layers = {}
        for name in LAYERS:
            visible = name != "numbers" or bool(getattr(vobj, "ShowStepNumbers", True))
            sw = coinutil.switch(visible, "tsplcam_plan_" + name)
            self.layers[name] = sw
            self.root.addChild(sw)
        vobj.addDisplayMode(self.root, "Order")
        self.rebuild()

    def updateData(self, obj, prop):
        if prop in ("ListText", "Model"):
            self.rebuild()

    def onChanged(self, vobj, prop):
        if self.layers is None:
            return
        if prop == "ShowStepNumbers":
            coinutil.set_visible(self.layers["numbers"], bool(vobj.ShowStepNumbers))
        elif prop == "CurrentStep":
            self._draw_current()

    def finishRestoring(self):
        self.rebuild(after_restore=True)

    @staticmethod
    def panel():
        from .planpanel import ProcessingListPanel
        return ProcessingListPanel

    # -- drawing -------------------------------------------------------------------------------
    def rebuild(self, after_restore: bool = False) -> bool:
        if self.layers is None:
            return False
        obj = self.Object
        if not after_restore and self.restoring():
            self.later(lambda: self.rebuild(after_restore=True))
            return False
        for sw in self.layers.values():
            sw.removeAllChildren()
        self._drawn = None
        if obj.Model is None or not obj.ListText:
            return False
        try:
            model = model_of(obj.Model)
            plist = self.override if self.override is not None else plan_of(obj)
            drawing = display.plan_drawing(model, plist)
        except Exception as exc:
            messages.exception("Processing list", exc, f"drawing {obj.Label}")
            return False
        self._drawn = (model, plist, drawing)
        size = display.model_size(model)
        pull = 0.002 * size
        self.layers["curves"].addChild(coinutil.haloed_polylines(drawing.curves, CURVE, 3.5, pull=pull))
        self.layers["curves"].addChild(coinutil.cones(drawing.arrows, drawing.arrow_dirs, 0.012 * size,
                                                      0.04 * size, CURVE))
        self.layers["numbers"].addChild(coinutil.labels(
            [str(i + 1) for i in range(len(plist.steps))], drawing.label_points, 14,
            text_colour=(1.0, 1.0, 1.0), background=CURVE, pull=0.04 * size))
        if drawing.retractions:
            self.layers["retractions"].addChild(coinutil.polylines(drawing.retractions, RETRACT, 3.0,
                                                                   coinutil.DASHED))
        markers = self.layers["markers"]
        if len(drawing.transits):
            markers.addChild(coinutil.spheres(drawing.transits, 0.008 * size, CURVE))
        if drawing.start is not None:
            markers.addChild(coinutil.spheres(drawing.start, 0.018 * size, START))
            markers.addChild(coinutil.spheres(drawing.finish, 0.018 * size, FINISH))
        self._draw_current()
        return True

    def show_list(self, plist) -> None:
        """Draw ``plist`` (the task panel's working copy) instead of the stored list; None: back
        to the stored one."""
        self.override = plist
        self.rebuild(after_restore=True)

    def show_step(self, step) -> None:
        """Highlight ``step`` (a plan Step: its patch, start and finish corners); None: none."""
        self.step = step
        if self.layers is not None:
            self._draw_current()

    def _draw_current(self) -> None:
        sw = self.layers["current"]
        sw.removeAllChildren()
        if self._drawn is None:
            return
        model, plist, drawing = self._drawn
        size = display.model_size(model)
        step = self.step
        if step is None:
            k = int(getattr(self.ViewObject, "CurrentStep", 0)) - 1
            step = plist.steps[k] if 0 <= k < len(plist.steps) else None
        if step is None:
            return
        outline, start, finish, curve = display.step_highlight(model, step)
        sw.addChild(coinutil.haloed_polylines(outline, CURRENT, 5.0, halo=(0.0, 0.0, 0.0), halo_width=8.0,
                                              pull=0.004 * size))
        if curve is not None:
            sw.addChild(coinutil.haloed_polylines([curve], CURRENT, 6.0, halo=(0.0, 0.0, 0.0),
                                                  halo_width=9.0, pull=0.004 * size))
        if start is not None:
            sw.addChild(coinutil.spheres(start, 0.022 * size, START))
        if finish is not None:
            sw.addChild(coinutil.spheres(finish, 0.022 * size, STEP_FINISH))
