"""The tool-path document object (``TsplcamToolPath``): the finishing path of a processing list.

Inputs are a linked TsplcamProcessingList (which links its model) and the settings
(ball radius, scallop height, chord tolerance, feed) as properties. The path comes from
``tsplcam.toolpath.zigzag_path`` on recompute, and only when an input changed: it takes
seconds. It is kept inside the .FCStd as a .npz of the ToolPath arrays (``PathFile``) so
that a reloaded document shows it at once; ``InputsKey`` records what it was made from.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile

import numpy as np

import FreeCAD

from ..errors import InputError
from . import messages
from .transaction import in_transaction
from .modelobject import model_of
from .planobject import is_plan_object, plan_of
from .proxy import FeatureProxy, add_property, set_read_only

TITLE = "Tool path"
ARRAYS = ("contact", "normal", "axis", "move", "patch", "uv", "line")


def toolpath_available() -> bool:
    """True when the engine's path generator is present in this checkout."""
    try:
        from ..toolpath import zigzag_path  # noqa: F401
    except (ImportError, AttributeError):
        return False
    return True


def save_npz(tp, path: str) -> None:
    np.savez(path, **{k: getattr(tp, k) for k in ARRAYS},
             tool_radius=np.array(tp.tool_radius), feed=np.array(tp.feed))


def load_npz(path: str):
    from ..toolpath.path import ToolPath
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in ARRAYS}
            return ToolPath(tool_radius=float(z["tool_radius"]), feed=float(z["feed"]), **arrays)
    except (OSError, KeyError, ValueError) as exc:
        raise InputError(f"the stored tool path cannot be read ({exc})", path=path) from None


class TsplcamToolPath(FeatureProxy):
    """Finishing path: zigzags patch after patch in the order of the processing list."""
    TYPE = "TsplcamToolPath"
    VERSION = 1

    _path = None
    _path_file = None

    @staticmethod
    def ensure_properties(obj) -> None:
        g = "Tool path"
        add_property(obj, "App::PropertyLink", "ProcessingList", g, "The processing list this path follows")
        add_property(obj, "App::PropertyLength", "ToolRadius", g, "Ball-end radius", 0.5)
        add_property(obj, "App::PropertyLength", "Scallop", g, "Largest scallop height left", 0.01)
        add_property(obj, "App::PropertyLength", "ChordTolerance", g,
                     "Largest distance between the path's chords and the surface", 0.001)
        add_property(obj, "App::PropertySpeed", "Feed", g, "Cutting feed", "1000 mm/min")
        add_property(obj, "App::PropertyFileIncluded", "PathFile", g,
                     "The computed path (numpy .npz), kept inside the document", hidden=True)
        add_property(obj, "App::PropertyString", "InputsKey", g,
                     "What the stored path was computed from", hidden=True)
        add_property(obj, "App::PropertyInteger", "Points", g, "Points of the path", read_only=True)
        add_property(obj, "App::PropertyInteger", "Lines", g, "Isoparametric lines", read_only=True)
        add_property(obj, "App::PropertyInteger", "Retractions", g, "Retractions", read_only=True)
        add_property(obj, "App::PropertyLength", "CutLength", g, "Length of the cutting moves",
                     read_only=True)
        add_property(obj, "App::PropertyLength", "LinkLength", g,
                     "Length of the links between lines and patches", read_only=True)

    def onDocumentRestored(self, obj):
        self.ensure_properties(obj)

    # -- inputs -----------------------------------------------------------------------------------
    def settings(self, obj) -> dict:
        return dict(tool_radius=float(obj.ToolRadius.Value), scallop=float(obj.Scallop.Value),
                    chord_tol=float(obj.ChordTolerance.Value),
                    feed=float(obj.Feed.getValueAs("mm/min")))

    def inputs_key(self, obj) -> str:
        plan = obj.ProcessingList
        model_obj = plan.Model
        h = hashlib.sha1()
        h.update(plan.ListText.encode())
        with open(model_obj.SourceFile, "rb") as f:
            h.update(f.read())
        h.update(json.dumps(self.settings(obj), sort_keys=True).encode())
        return h.hexdigest()

    def _check_inputs(self, obj):
        plan = obj.ProcessingList
        if plan is None or not is_plan_object(plan):
            raise InputError("the tool path needs a processing list", item=obj.Label)
        return model_of(plan.Model), plan_of(plan)

    # -- computing -----------------------------------------------------------------------------------
    def compute(self, obj):
        """Run the path generator; returns the ToolPath (raises InputError/GeometryError)."""
        from ..toolpath import zigzag_path
        model, plist = self._check_inputs(obj)
        return zigzag_path(model, plist, **self.settings(obj))

    def execute(self, obj):
        self._check_inputs(obj)
        key = self.inputs_key(obj)
        if key != obj.InputsKey or not obj.PathFile or not os.path.isfile(obj.PathFile):
            self.store(obj, self.compute(obj), key)
        self.update_info(obj, self.path(obj))

    def store(self, obj, tp, key: str) -> None:
        tmp = tempfile.mkdtemp(prefix="tsplcam-path-")
        try:
            path = os.path.join(tmp, "toolpath.npz")
            save_npz(tp, path)
            obj.PathFile = path                  # FreeCAD copies it into the document
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        obj.InputsKey = key
        self._path, self._path_file = tp, obj.PathFile

    def path(self, obj):
        """The ToolPath, read from the document's copy once."""
        if self._path is None or self._path_file != obj.PathFile:
            if not obj.PathFile or not os.path.isfile(obj.PathFile):
                raise InputError("the tool path has not been computed yet (recompute)", item=obj.Label)
            self._path, self._path_file = load_npz(obj.PathFile), obj.PathFile
        return self._path

    @staticmethod
    def update_info(obj, tp) -> None:
        from ..toolpath.path import Move
        seg = np.linalg.norm(np.diff(tp.contact, axis=0), axis=1)
        kind = tp.move[1:]
        set_read_only(obj, "Points", len(tp))
        set_read_only(obj, "Lines", int(len(np.unique(tp.line[tp.line >= 0]))))
        set_read_only(obj, "Retractions", tp.retractions)
        cut = float(seg[kind == Move.CUT].sum())
        link = float(seg[kind == Move.LINK].sum())
        if abs(obj.CutLength.Value - cut) > 1e-9:
            obj.CutLength = cut
        if abs(obj.LinkLength.Value - link) > 1e-9:
            obj.LinkLength = link


def is_path_object(obj) -> bool:
    return getattr(getattr(obj, "Proxy", None), "Type", None) == TsplcamToolPath.TYPE


def path_of(obj):
    return obj.Proxy.path(obj)


def make_tool_path(plan_obj, **settings):
    """A TsplcamToolPath for ``plan_obj``: computed first (seconds), added only on success;
    None after reporting why not (e.g. a ball too large for a concave region, named by
    patch and (u, v))."""
    doc = plan_obj.Document
    defaults = dict(tool_radius=0.5, scallop=0.01, chord_tol=0.001, feed=1000.0)
    defaults.update(settings)
    busy = _busy()
    try:
        from ..toolpath import zigzag_path
        tp = zigzag_path(model_of(plan_obj.Model), plan_of(plan_obj), **defaults)
    except Exception as exc:
        messages.exception(TITLE, exc, f"computing the tool path of {plan_obj.Label}")
        return None
    finally:
        busy()

    def work():
        obj = doc.addObject("App::FeaturePython", "ToolPath")
        TsplcamToolPath(obj)
        obj.Label = f"{plan_obj.Model.Label} tool path"
        obj.ProcessingList = plan_obj
        obj.ToolRadius = defaults["tool_radius"]
        obj.Scallop = defaults["scallop"]
        obj.ChordTolerance = defaults["chord_tol"]
        obj.Feed = f"{defaults['feed']} mm/min"
        obj.Proxy.store(obj, tp, obj.Proxy.inputs_key(obj))
        TsplcamToolPath.update_info(obj, tp)
        if FreeCAD.GuiUp:
            from .viewpath import ViewProviderToolPath
            ViewProviderToolPath(obj.ViewObject)
        return obj
    obj = in_transaction(doc, TITLE, f"adding the tool path of {plan_obj.Label}", work)
    if obj is None:
        return None
    messages.info(f"{obj.Label}: {obj.Points} points, {obj.Lines} lines, {obj.Retractions} retractions, "
                  f"cut {obj.CutLength.Value:.1f} mm, links {obj.LinkLength.Value:.1f} mm")
    return obj


def _busy():
    """A wait cursor while the generator runs (GUI only); returns the function that ends it."""
    if not FreeCAD.GuiUp:
        return lambda: None
    from PySide import QtCore, QtGui
    QtGui.QApplication.setOverrideCursor(QtCore.Qt.WaitCursor)
    return QtGui.QApplication.restoreOverrideCursor
