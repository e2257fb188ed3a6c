"""The model document object (``TsplcamModel``): a surface model kept inside the .FCStd.

The object keeps the model's *source file* in the document (``SourceFile``,
App::PropertyFileIncluded) with its ``Format``, and rebuilds the engine ``Model`` from it
on demand: lazily, once, cached in the proxy and never pickled. Saving and reloading the
.FCStd therefore gives back the same model, evaluated by the same reader.

Sources: the engine's readers (``tsplcam.load``: every surface reader of the registry
``tsplcam.model.formats.READERS``), and CAD shapes (.step/.iges files, or a Part object's
shape kept as .brep) through ``tsplcam.workbench.shapes.model_from_shape`` when that
module is present.
"""
from __future__ import annotations

import os
import shutil
import tempfile

import FreeCAD

import tsplcam
from ..errors import InputError
from ..model.formats import reader_for, surface_readers
from .proxy import FeatureProxy, add_property, set_read_only

# formats FreeCAD reads as shapes; the engine gets them through shapes.model_from_shape
SHAPE_FORMATS = {"step": (".step", ".stp"), "iges": (".iges", ".igs"), "brep": (".brep", ".brp")}
SHAPE_NAMES = {"step": "STEP", "iges": "IGES", "brep": "OpenCASCADE BRep"}
# formats the engine reads into surface models: the registry of tsplcam.model.formats
ENGINE_FORMATS = {r.name: r.extensions for r in surface_readers()}
FORMAT_NAMES = {**{r.name: r.description for r in surface_readers()}, **SHAPE_NAMES}


def format_of(path: str) -> str:
    """Format name from a file's extension ('obj', 'iga', 'step', ...)."""
    reader = reader_for(path)
    if reader is not None:
        return reader.name
    ext = os.path.splitext(path)[1].lower()
    for name, exts in SHAPE_FORMATS.items():
        if ext in exts:
            return name
    return ext.lstrip(".")


def shapes_module():
    """``tsplcam.workbench.shapes`` when it exists and imports, else None."""
    try:
        from . import shapes
    except ImportError:
        return None
    return shapes if hasattr(shapes, "model_from_shape") else None


def engine_formats() -> tuple[str, ...]:
    """The formats ``tsplcam.load`` reads into surface models."""
    return tuple(ENGINE_FORMATS)


def readable_formats() -> list[str]:
    """Every format a model can be imported from here (engine formats, then CAD shapes)."""
    out = list(engine_formats())
    if shapes_module() is not None:
        out += list(SHAPE_FORMATS)
    return out


def file_filters() -> list[str]:
    """Qt file-dialog filters for ``readable_formats``, all of them first."""
    fmts = readable_formats()
    exts = {**ENGINE_FORMATS, **SHAPE_FORMATS}
    pats = lambda f: " ".join("*" + e for e in exts[f])   # noqa: E731
    out = ["Surface models (" + " ".join(pats(f) for f in fmts) + ")"]
    out += [f"{FORMAT_NAMES[f]} ({pats(f)})" for f in fmts]
    return out


# -- reading -------------------------------------------------------------------------------
def read_model(path: str, fmt: str | None = None, name: str | None = None):
    """The engine Model of a file: engine formats through ``tsplcam.load``, CAD files
    through FreeCAD's Part.read and ``shapes.model_from_shape``. Raises InputError (which
    names the file and line or record) for anything wrong with the file."""
    path = os.fspath(path)
    fmt = fmt or format_of(path)
    name = name or os.path.basename(path)
    if not os.path.isfile(path):
        raise InputError("no such file", path=path)
    if fmt in SHAPE_FORMATS:
        model = _read_shape_file(path, fmt, name)
    else:
        model = _read_engine_file(path, fmt)
    model.name = name
    return model


def _read_engine_file(path: str, fmt: str):
    exts = ENGINE_FORMATS.get(fmt)
    if exts is None:
        raise InputError(f"unknown model format {fmt!r}", path=path)
    if os.path.splitext(path)[1].lower() in exts:
        return tsplcam.load(path)
    # the document's copy lost its extension: read it under the right one
    tmp = tempfile.mkdtemp(prefix="tsplcam-")
    try:
        alias = os.path.join(tmp, os.path.splitext(os.path.basename(path))[0] + exts[0])
        shutil.copyfile(path, alias)
        return tsplcam.load(alias)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _read_shape_file(path: str, fmt: str, name: str):
    shapes = shapes_module()
    if shapes is None:
        raise InputError(f"{FORMAT_NAMES[fmt]} models need FreeCAD shapes support "
                         f"(tsplcam.workbench.shapes), which this installation lacks", path=path)
    stem = os.path.splitext(name)[0]
    if hasattr(shapes, "model_from_step"):          # reads STEP, IGES and BRep alike
        return shapes.model_from_step(path, stem)
    import Part
    try:
        shape = Part.read(path)
    except Exception as exc:           # OCCT's reader says little more than "failed"
        raise InputError(f"FreeCAD cannot read this {FORMAT_NAMES[fmt]} file ({exc})", path=path)
    if shape.isNull() or not shape.Faces:
        raise InputError(f"the {FORMAT_NAMES[fmt]} file holds no faces", path=path)
    return shapes.model_from_shape(shape, stem)


# -- the document object ---------------------------------------------------------------------
class TsplcamModel(FeatureProxy):
    """A surface model: its source file inside the document and what the engine reads."""
    TYPE = "TsplcamModel"
    VERSION = 1

    # transient cache, never saved (class defaults: __init__ does not run on restore)
    _model = None
    _model_key = None

    @staticmethod
    def ensure_properties(obj) -> None:
        g = "Model"
        add_property(obj, "App::PropertyFileIncluded", "SourceFile", g,
                     "The model's source file, kept inside the document", read_only=True)
        add_property(obj, "App::PropertyString", "Format", g,
                     "Format of the source file (obj, iga, tsm, tspl, step, iges, brep)", read_only=True)
        add_property(obj, "App::PropertyString", "FileName", g,
                     "Name of the file the model was imported from", read_only=True)
        add_property(obj, "App::PropertyString", "ImportedFrom", g,
                     "Full path the model was imported from (for information only)", read_only=True)
        add_property(obj, "App::PropertyLink", "SourceObject", g,
                     "The shape object the model was built from, if any", read_only=True)
        add_property(obj, "App::PropertyString", "Kind", g,
                     "How the surface is defined (catmull-clark cage, T-spline, NURBS, ...)", read_only=True)
        add_property(obj, "App::PropertyInteger", "Patches", g, "Number of patches", read_only=True)
        add_property(obj, "App::PropertyInteger", "ExtraordinaryPoints", g,
                     "Extraordinary points inside the surface (valence other than 4)", read_only=True)
        add_property(obj, "App::PropertyInteger", "BoundaryExtraordinary", g,
                     "Extraordinary points on the boundary (valence other than 3, marked b in Valences)",
                     read_only=True)
        add_property(obj, "App::PropertyString", "Valences", g,
                     "Valences of the extraordinary points, inside first, then those on the boundary "
                     "(marked b)", read_only=True)
        add_property(obj, "App::PropertyVector", "Size", g,
                     "Extent of the model along x, y, z (mm)", read_only=True)
        add_property(obj, "App::PropertyString", "Units", g, "Length unit of the model", "mm",
                     read_only=True)

    def onDocumentRestored(self, obj):
        self.ensure_properties(obj)

    def onChanged(self, obj, prop):
        if prop in ("SourceFile", "Format"):
            self._model = None
            self._model_key = None

    TITLE = "tsplcam model"

    def recompute(self, obj):
        """Recompute: (re)read the model if its file changed, refresh the information."""
        self.update_info(obj, self.model(obj))

    # -- the engine model ---------------------------------------------------------------------
    def _key(self, obj):
        path = obj.SourceFile
        try:
            st = os.stat(path)
            return (path, st.st_size, st.st_mtime_ns, obj.Format)
        except OSError:
            return (path, None, None, obj.Format)

    def model(self, obj):
        """The engine Model, read from the document's copy of the source file once."""
        key = self._key(obj)
        if self._model is None or self._model_key != key:
            if not obj.SourceFile or not os.path.isfile(obj.SourceFile):
                raise InputError(f"the document holds no model file for {obj.Label}", item=obj.Name)
            self._model = read_model(obj.SourceFile, obj.Format, obj.FileName or None)
            self._model_key = key
        return self._model

    def set_model(self, obj, model) -> None:
        """Adopt a model just read from ``obj.SourceFile`` (saves reading it twice)."""
        self._model = model
        self._model_key = self._key(obj)

    @staticmethod
    def update_info(obj, model) -> None:
        interior = [e for e in model.extraordinary if not e.boundary]
        boundary = [e for e in model.extraordinary if e.boundary]
        set_read_only(obj, "Kind", str(model.kind))
        set_read_only(obj, "Patches", len(model.patches))
        set_read_only(obj, "ExtraordinaryPoints", len(interior))
        set_read_only(obj, "BoundaryExtraordinary", len(boundary))
        set_read_only(obj, "Valences", valences_text(model))
        lo, hi = model.bounding_box(9)
        size = FreeCAD.Vector(*[float(x) for x in (hi - lo)])
        if obj.Size != size:
            obj.Size = size


def plural(n: int, word: str, many: str | None = None) -> str:
    """'1 patch', '2 patches', '0 extraordinary points'."""
    return f"{n} {word if n == 1 else many or (word + ('es' if word.endswith(('ch', 'sh', 's', 'x')) else 's'))}"


def valences_text(model) -> str:
    """Valences of the extraordinary points, inside first, then the boundary ones marked b."""
    eps = sorted(model.extraordinary, key=lambda e: bool(e.boundary))
    return " ".join(str(e.valence) + ("b" if e.boundary else "") for e in eps)


def describe(obj) -> str:
    """'5 patches, 4 extraordinary points (3 3 3 3)' with boundary ones counted apart, so a
    boundary valence never stands next to an interior count of 0."""
    text = f"{plural(obj.Patches, 'patch')}, {plural(obj.ExtraordinaryPoints, 'extraordinary point')}"
    nb = int(getattr(obj, "BoundaryExtraordinary", 0))
    if nb:
        text += f" inside and {nb} on the boundary"
    return text + (f" ({obj.Valences})" if obj.Valences else "")


def is_model_object(obj) -> bool:
    return getattr(getattr(obj, "Proxy", None), "Type", None) == TsplcamModel.TYPE or \
        isinstance(getattr(obj, "Proxy", None), TsplcamModel)


def model_of(obj):
    """The engine Model of a TsplcamModel object (read on first use, then cached)."""
    if not is_model_object(obj):
        raise InputError(f"{obj.Label} is not a tsplcam model", item=obj.Name)
    return obj.Proxy.model(obj)


PATCH_ELEMENT = "Patch"      # sub-element name of patch k in selections: Patch<k>


def patch_of_element(name: str) -> int | None:
    """Patch index of a selection sub-element name ('Patch3' -> 3), None for others."""
    if name.startswith(PATCH_ELEMENT) and name[len(PATCH_ELEMENT):].isdigit():
        return int(name[len(PATCH_ELEMENT):])
    return None


def model_objects(doc) -> list:
    return [o for o in doc.Objects if is_model_object(o)] if doc is not None else []


def make_model_object(doc, model, source_path: str, fmt: str | None = None,
                      file_name: str | None = None, source_object=None, label: str | None = None):
    """A TsplcamModel in ``doc`` for a model already read from ``source_path``.

    The caller reads first (``read_model``) so that a bad file never creates an object;
    if anything fails here, the half-made object is removed again before re-raising."""
    fmt = fmt or format_of(source_path)
    file_name = file_name or os.path.basename(source_path)
    obj = doc.addObject("App::FeaturePython", "TsplcamModel")
    try:
        TsplcamModel(obj)
        obj.Label = label or os.path.splitext(file_name)[0]
        obj.Format = fmt
        obj.FileName = file_name
        obj.ImportedFrom = os.path.abspath(source_path) if source_object is None else ""
        obj.SourceFile = source_path          # FreeCAD copies it into the document
        if source_object is not None:
            obj.SourceObject = source_object
        obj.Proxy.set_model(obj, model)
        TsplcamModel.update_info(obj, model)
        if FreeCAD.GuiUp:
            from .viewmodel import ViewProviderTsplcamModel
            ViewProviderTsplcamModel(obj.ViewObject)
        obj.purgeTouched()
    except BaseException:
        try:
            doc.removeObject(obj.Name)
        except Exception:
            pass
        raise
    return obj
