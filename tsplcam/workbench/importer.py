"""FreeCAD importer for tsplcam models (File > Open / File > Import, and the workbench).

FreeCAD's importer protocol: module functions ``open(filename)`` (new document) and
``insert(filename, docname)`` (into a document), registered in Init.py for every surface
reader of the engine's registry (``tsplcam.model.formats.READERS``). Both read the file with the engine first and create a ``TsplcamModel`` only when
that succeeded; a bad file gives one message naming the file and line (Report view, and a
message box in the GUI), never a traceback dialog, never a half-built object.
"""
from __future__ import annotations

import os
import re

import FreeCAD

from . import messages
from .transaction import in_transaction
from .modelobject import format_of, make_model_object, read_model

TITLE = "Import T-spline model"


def import_file(filename: str, doc=None, fmt: str | None = None, new_document: str | None = None):
    """Read ``filename`` and add a model object to ``doc``; without ``doc``, to a new
    document named ``new_document``, or to the active one when that is None (a new one if
    there is none). Returns the object, or None after reporting why not."""
    filename = os.fspath(filename)
    try:
        model = read_model(filename, fmt)
    except Exception as exc:
        messages.exception(TITLE, exc, f"reading {filename}")
        return None
    created = False
    if doc is None and new_document is None:
        doc = FreeCAD.ActiveDocument
    if doc is None:
        doc = FreeCAD.newDocument(new_document or _doc_name(filename))
        created = True
    obj = in_transaction(doc, TITLE, f"adding {filename} to the document",
                         lambda: make_model_object(doc, model, filename, fmt or format_of(filename)),
                         on_failure=(lambda: FreeCAD.closeDocument(doc.Name)) if created else None)
    if obj is None:
        return None
    from .modelobject import describe
    messages.info(f"imported {os.path.basename(filename)}: {describe(obj)}")
    return obj


def _doc_name(filename: str) -> str:
    base = os.path.splitext(os.path.basename(filename))[0]
    name = re.sub(r"\W", "_", base) or "Model"
    return name if not name[0].isdigit() else "_" + name


def fit_view(doc) -> None:
    """Fit the document's 3D view to what it shows (GUI only)."""
    if not FreeCAD.GuiUp or doc is None:
        return
    import FreeCADGui
    gdoc = FreeCADGui.getDocument(doc.Name)
    view = getattr(gdoc, "ActiveView", None) if gdoc is not None else None
    if view is not None and hasattr(view, "fitAll"):
        view.fitAll()


def open(filename):  # noqa: A001  (FreeCAD's importer protocol)
    """File > Open: a new document holding the model (no document if the file is bad)."""
    obj = import_file(filename, new_document=_doc_name(filename))
    if obj is not None:
        fit_view(obj.Document)
    return obj


def insert(filename, docname):
    """File > Import: the model into document ``docname`` (created when missing)."""
    try:
        doc = FreeCAD.getDocument(docname)
    except NameError:
        doc = None
    obj = import_file(filename, doc, new_document=None if doc is not None else docname)
    if obj is not None:
        fit_view(obj.Document)
    return obj
