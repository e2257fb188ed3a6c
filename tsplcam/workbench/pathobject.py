"""The tool-path document object (``TsplcamToolPath``): the finishing path of a processing list.

Inputs are a linked TsplcamProcessingList (which links its model) and the path options of
:class:`tsplcam.settings.JobSettings` as properties (``fields.PATH_FIELDS``: ball radius,
scallop height, chord tolerance, longest move, feed in mm/min, retract clearance and mode,
balance). The path comes from the engine's ``tsplcam.program.make_path`` on recompute, and
only when an input changed: it takes seconds (in the GUI in a child process, with progress
and cancel: ``runner``). It is kept inside the .FCStd as a .npz of the ToolPath arrays (``PathFile``) so
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
from .fields import PATH_FIELDS, add_properties, set_values, values_of
from .proxy import FeatureProxy, add_property, set_read_only

TITLE = "Tool path"
DEFAULT_RADIUS = 0.5        # mm: the default tool's ball (ball1_keycap)
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
    VERSION = 2
    TITLE = TITLE

    _path = None
    _path_file = None

    @staticmethod
    def ensure_properties(obj, values: dict | None = None) -> None:
        g = "Tool path"
        add_property(obj, "App::PropertyLink", "ProcessingList", g, "The processing list this path follows")
        add_properties(obj, PATH_FIELDS, g, {"tool_radius": DEFAULT_RADIUS, **(values or {})})
        add_property(obj, "App::PropertyFileIncluded", "PathFile", g,
                     "The computed path (numpy .npz), kept inside the document", hidden=True)
        add_property(obj, "App::PropertyString", "InputsKey", g,
                     "What the stored path was computed from", hidden=True)
        r = "Result"
        add_property(obj, "App::PropertyInteger", "Points", r, "Points of the path", read_only=True)
        add_property(obj, "App::PropertyInteger", "Lines", r, "Isoparametric lines (passes)", read_only=True)
        add_property(obj, "App::PropertyInteger", "Retractions", r, "Retractions", read_only=True)
        add_property(obj, "App::PropertyLength", "CutLength", r, "Length of the cutting moves",
                     read_only=True)
        add_property(obj, "App::PropertyLength", "LinkLength", r,
                     "Length of the links between lines and patches", read_only=True)
        add_property(obj, "App::PropertyLength", "LargestStepover", r,
                     "Largest distance between neighbouring passes on the surface", read_only=True)

    def onDocumentRestored(self, obj):
        self.ensure_properties(obj)

    # -- inputs -----------------------------------------------------------------------------------
    def settings(self, obj) -> dict:
        """The path's options (JobSettings field names, lengths in mm, feed in mm/min)."""
        return values_of(obj, PATH_FIELDS)

    def inputs_key(self, obj) -> str:
        plan = obj.ProcessingList
        model_obj = plan.Model
        h = hashlib.sha1()
        h.update(plan.ListText.encode())
        with open(model_obj.SourceFile, "rb") as f:
            h.update(f.read())
        h.update(json.dumps(self.settings(obj), sort_keys=True).encode())
        return h.hexdigest()

    def stale(self, obj) -> str | None:
        if not obj.PathFile or not os.path.isfile(obj.PathFile):
            return "the tool path has not been computed (recompute)"
        try:
            if self.inputs_key(obj) != obj.InputsKey:
                return "the stored tool path is older than its inputs (recompute)"
        except Exception as exc:
            return str(exc)
        return None

    def _check_inputs(self, obj):
        plan = obj.ProcessingList
        if plan is None or not is_plan_object(plan):
            raise InputError("the tool path needs a processing list", item=obj.Label)
        return model_of(plan.Model), plan_of(plan)

    # -- computing -----------------------------------------------------------------------------------
    def compute(self, obj):
        """Run the path generator (in the GUI with progress and cancel); returns the ToolPath
        (raises InputError/GeometryError naming the place, Cancelled on request)."""
        model, plist = self._check_inputs(obj)
        return compute_path(model, plist, self.settings(obj), obj.Label)

    def recompute(self, obj):
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
        stepover = largest_stepover(tp)
        for name, value in (("CutLength", cut), ("LinkLength", link), ("LargestStepover", stepover)):
            if abs(getattr(obj, name).Value - value) > 1e-9:
                setattr(obj, name, value)


def largest_stepover(tp) -> float:
    """Largest distance between the first points of neighbouring lines of one patch (mm): the
    side step at the start edge, where the zigzag turns."""
    first = np.nonzero(np.r_[True, np.diff(tp.line) != 0] & (tp.line >= 0))[0]
    if len(first) < 2:
        return 0.0
    same = (tp.patch[first[1:]] == tp.patch[first[:-1]])
    d = np.linalg.norm(tp.contact[first[1:]] - tp.contact[first[:-1]], axis=1)[same]
    return float(d.max()) if len(d) else 0.0


def compute_path(model, plist, settings: dict, label: str):
    """The ToolPath by the path options ``settings`` (JobSettings names), through the
    runner (GUI: child process with progress and cancel; headless: here)."""
    from . import runner
    from .fields import named_properties
    with named_properties():
        return runner.run(f"Tool path of {label}", "path_task", model, plist, dict(settings))


def is_path_object(obj) -> bool:
    return getattr(getattr(obj, "Proxy", None), "Type", None) == TsplcamToolPath.TYPE


def path_of(obj):
    return obj.Proxy.path(obj)


def default_radius() -> float:
    """The ball radius of the default tool (preferences, else JobSettings'), else 0.5 mm."""
    from .fields import PROGRAM_FIELDS
    from .prefs import defaults
    try:
        from ..orientation import load_tool
        return float(load_tool(defaults(PROGRAM_FIELDS)["tool"]).ball_radius)
    except Exception:
        return DEFAULT_RADIUS


def path_defaults(**settings) -> dict:
    """Path options: the preferences page's defaults (JobSettings' where none are set), the
    default tool's ball radius, then ``settings``; checked, errors naming the property."""
    from .fields import checked
    from .prefs import defaults
    values = defaults(PATH_FIELDS)
    if values.get("tool_radius") is None:
        values["tool_radius"] = default_radius()
    values.update(settings)
    checked(values)
    return values


def make_tool_path(plan_obj, computed=None, **settings):
    """A TsplcamToolPath for ``plan_obj``: computed first (seconds; in the GUI with progress and
    cancel), added only on success; None after reporting why not (e.g. a ball too large for
    a concave region, named by patch and (u, v)). ``settings``: path options (JobSettings
    names: tool_radius, scallop, chord_tol, max_step, feed in mm/min, clearance, ...);
    ``computed``: the ToolPath the engine already made with them (headless documents)."""
    doc = plan_obj.Document
    try:
        values = path_defaults(**settings)
        tp = computed if computed is not None else compute_path(model_of(plan_obj.Model), plan_of(plan_obj),
                                                                values, plan_obj.Label)
    except Exception as exc:
        messages.exception(TITLE, exc, f"computing the tool path of {plan_obj.Label}")
        return None

    def work():
        obj = doc.addObject("App::FeaturePython", "ToolPath")
        TsplcamToolPath(obj)
        obj.Label = f"{plan_obj.Model.Label} tool path"
        obj.ProcessingList = plan_obj
        set_values(obj, PATH_FIELDS, values)
        obj.Proxy.store(obj, tp, obj.Proxy.inputs_key(obj))
        TsplcamToolPath.update_info(obj, tp)
        if FreeCAD.GuiUp:
            from .viewpath import ViewProviderToolPath
            ViewProviderToolPath(obj.ViewObject)
        return obj
    obj = in_transaction(doc, TITLE, f"adding the tool path of {plan_obj.Label}", work)
    if obj is None:
        return None
    from .modelobject import plural
    messages.info(f"{obj.Label}: {obj.Points} points, {plural(obj.Lines, 'line')}, "
                  f"{plural(obj.Retractions, 'retraction')}, "
                  f"cut {obj.CutLength.Value:.1f} mm, links {obj.LinkLength.Value:.1f} mm")
    return obj
