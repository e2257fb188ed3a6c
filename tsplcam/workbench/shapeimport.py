"""Models from FreeCAD shapes: a selected Part object (or some of its faces) becomes a
TsplcamModel through ``tsplcam.workbench.shapes.model_from_shape``.

The shape is kept inside the document as a .brep file (``Format`` 'brep'), so the model
rebuilds the same way after reloading even if the original object changes or goes away;
``SourceObject`` records where it came from.
"""
from __future__ import annotations

import os
import shutil
import tempfile

import FreeCAD

from ..errors import InputError
from . import messages
from .transaction import in_transaction
from .modelobject import make_model_object, shapes_module

TITLE = "Model from selected shape"


def selection_shape(obj, subnames=()) -> "Part.Shape":   # noqa: F821
    """The faces of ``obj`` named in ``subnames`` ('Face3', ...) or all its faces, placed."""
    import Part
    shape = getattr(obj, "Shape", None)
    if shape is None or shape.isNull():
        raise InputError("has no shape", item=obj.Label)
    if subnames:
        faces = [shape.getElement(s) for s in subnames if s.startswith("Face")]
        if not faces:
            raise InputError(f"no faces among {', '.join(subnames)}", item=obj.Label)
        return faces[0].copy() if len(faces) == 1 else Part.makeCompound(faces)
    if not shape.Faces:
        raise InputError("has no faces", item=obj.Label)
    return shape.copy()


def model_from_object(obj, subnames=(), doc=None):
    """A TsplcamModel built from ``obj``'s shape (or the faces ``subnames``); None after
    reporting why not."""
    shapes = shapes_module()
    if shapes is None:
        messages.error(TITLE, "building models from shapes needs tsplcam.workbench.shapes")
        return None
    doc = doc or obj.Document
    label = obj.Label if not subnames else f"{obj.Label} {' '.join(subnames)}"
    try:
        shape = selection_shape(obj, subnames)
        model = shapes.model_from_shape(shape, label)
    except Exception as exc:
        messages.exception(TITLE, exc, f"building a model from {label}")
        return None
    tmp = tempfile.mkdtemp(prefix="tsplcam-shape-")
    def work():
        path = os.path.join(tmp, _file_stem(label) + ".brep")
        shape.exportBrep(path)
        return make_model_object(doc, model, path, "brep", file_name=os.path.basename(path),
                                 source_object=obj, label=f"{obj.Label} model")
    try:
        made = in_transaction(doc, TITLE, f"adding the model of {label} to the document", work)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if made is None:
        return None
    if FreeCAD.GuiUp and hasattr(obj, "ViewObject") and obj.ViewObject is not None:
        obj.ViewObject.Visibility = False
    from .modelobject import describe
    messages.info(f"model from {label}: {describe(made)}")
    return made


def _file_stem(label: str) -> str:
    keep = "".join(c if c.isalnum() or c in "-_" else "_" for c in label)
    return keep.strip("_") or "shape"


def shape_selection():
    """[(object, subnames)] of the selected objects that carry faces."""
    import FreeCADGui
    out = []
    for sel in FreeCADGui.Selection.getSelectionEx():
        obj = sel.Object
        shape = getattr(obj, "Shape", None)
        if shape is None or shape.isNull() or not shape.Faces:
            continue
        out.append((obj, tuple(n for n in sel.SubElementNames if n.startswith("Face"))))
    return out
