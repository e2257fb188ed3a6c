"""The processing-list document object (``TsplcamProcessingList``): the plan of a model.

It links a TsplcamModel and keeps the list as text in the engine's file format
(``tsplcam.plan.listfile``, format tsplcam-processing-list), so the .FCStd holds exactly
what ``tsplcam plan --out`` would write. The ProcessingList is read from that text and
checked against the model's layout on demand (cached, never pickled): a model whose
patches changed makes the object report the layout mismatch instead of machining a stale
plan.
"""
from __future__ import annotations

import hashlib

import FreeCAD

from ..errors import InputError
from ..layout.layout import Layout
from . import messages
from .transaction import in_transaction
from .modelobject import is_model_object, model_of
from .proxy import FeatureProxy, add_property, set_read_only

TITLE = "Processing list"


def plan_model(model, pins=None):
    """A fresh processing list for ``model`` (the planner with the surface's edge lengths)."""
    from ..plan import plan
    from ..plan.graph import model_edge_lengths
    return plan(Layout.from_model(model), pins, edge_lengths=model_edge_lengths(model), model=model.name)


def replan(model, plist):
    """Keep what ``plist`` pins, solve the rest (``tsplcam plan --complete``)."""
    from ..plan import complete
    from ..plan.graph import model_edge_lengths
    out = complete(plist, Layout.from_model(model), edge_lengths=model_edge_lengths(model))
    out.model = plist.model or model.name
    return out


class TsplcamProcessingList(FeatureProxy):
    """Order, start/finish corners and crossfeed of every patch of a model."""
    TYPE = "TsplcamProcessingList"
    VERSION = 1

    _plist = None
    _key = None

    @staticmethod
    def ensure_properties(obj) -> None:
        g = "Processing list"
        add_property(obj, "App::PropertyLink", "Model", g, "The tsplcam model this list machines")
        add_property(obj, "App::PropertyString", "ListText", g,
                     "The list in the tsplcam-processing-list JSON format", hidden=True)
        add_property(obj, "App::PropertyInteger", "Steps", g, "Patches in the list", read_only=True)
        add_property(obj, "App::PropertyString", "Order", g, "Patch order", read_only=True)
        add_property(obj, "App::PropertyInteger", "Retractions", g,
                     "Retractions between patches", read_only=True)
        add_property(obj, "App::PropertyInteger", "CornerLinks", g,
                     "Steps reached through a corner shared without an edge", read_only=True)
        add_property(obj, "App::PropertyInteger", "BoundaryLinks", g,
                     "Steps reached through a corner of a shared edge", read_only=True)
        add_property(obj, "App::PropertyString", "Solver", g, "How the list was made", read_only=True)

    def onDocumentRestored(self, obj):
        self.ensure_properties(obj)

    def onChanged(self, obj, prop):
        if prop in ("ListText", "Model"):
            self._plist = None

    TITLE = TITLE

    def recompute(self, obj):
        self.update_info(obj, self.processing_list(obj))

    def _cache_key(self, obj):
        """The list text's hash and the model itself (held, so that a model read again is
        never mistaken for the old one at the same address)."""
        model = model_of(obj.Model)
        return (hashlib.sha1(obj.ListText.encode()).hexdigest(), model)

    def processing_list(self, obj):
        """The ProcessingList, read from ListText and checked against the model's layout."""
        if obj.Model is None or not is_model_object(obj.Model):
            raise InputError("the processing list has no model", item=obj.Label)
        key = self._cache_key(obj)
        if self._plist is None or self._key is None or self._key[0] != key[0] or self._key[1] is not key[1]:
            from ..plan import loads
            self._plist = loads(obj.ListText, Layout.from_model(model_of(obj.Model)), path=obj.Label)
            self._key = key
        return self._plist

    def set_list(self, obj, plist) -> None:
        """Store ``plist`` (already checked) as the object's list."""
        from ..plan import dumps
        obj.ListText = dumps(plist)
        self._plist = plist
        self._key = self._cache_key(obj)
        self.update_info(obj, plist)

    @staticmethod
    def update_info(obj, plist) -> None:
        set_read_only(obj, "Steps", len(plist.steps))
        set_read_only(obj, "Order", " ".join(str(p) for p in plist.order))
        set_read_only(obj, "Retractions", plist.retractions)
        set_read_only(obj, "CornerLinks", plist.corner_links)
        set_read_only(obj, "BoundaryLinks", plist.boundary_links)
        if "order_method" in plist.info:
            set_read_only(obj, "Solver", str(plist.info["order_method"]))


def is_plan_object(obj) -> bool:
    return getattr(getattr(obj, "Proxy", None), "Type", None) == TsplcamProcessingList.TYPE


def plan_of(obj):
    return obj.Proxy.processing_list(obj)


def make_processing_list(model_obj, plist=None):
    """A TsplcamProcessingList for ``model_obj``: planned now unless ``plist`` is given.
    Plans (and checks) first, adds the object only on success; None after reporting."""
    try:
        model = model_of(model_obj)
        if plist is None:
            plist = plan_model(model)
        else:
            from ..plan.listfile import check
            check(plist, Layout.from_model(model))
    except Exception as exc:
        messages.exception(TITLE, exc, f"planning {model_obj.Label}")
        return None
    doc = model_obj.Document

    def work():
        obj = doc.addObject("App::FeaturePython", "ProcessingList")
        TsplcamProcessingList(obj)
        obj.Label = f"{model_obj.Label} processing list"
        obj.Model = model_obj
        obj.Proxy.set_list(obj, plist)
        if FreeCAD.GuiUp:
            from .viewplan import ViewProviderProcessingList
            ViewProviderProcessingList(obj.ViewObject)
        return obj
    obj = in_transaction(doc, TITLE, f"adding the processing list of {model_obj.Label}", work)
    if obj is None:
        return None
    from .modelobject import plural
    messages.info(f"{obj.Label}: {plural(obj.Steps, 'step')}, {plural(obj.BoundaryLinks, 'boundary link')}, "
                  f"{plural(obj.CornerLinks, 'corner link')}, {plural(obj.Retractions, 'retraction')}")
    return obj
