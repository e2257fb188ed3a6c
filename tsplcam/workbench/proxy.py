"""Base classes for tsplcam's document objects and view providers.

Every pipeline stage that gets a document object (model, processing list, tool path,
post) follows the same pattern:

* a ``FeatureProxy`` subclass for ``App::FeaturePython`` that keeps its inputs in
  properties (files inside the .FCStd via ``App::PropertyFileIncluded``), rebuilds engine
  objects on demand and caches them in plain attributes that are never saved;
* a ``ViewProxy`` subclass that draws with Coin from the engine objects (never from OCCT
  shapes) and keeps its switches in view properties;
* a maker function ``make_...(doc, ...)`` that reads/computes with the engine *first*
  and only then creates the object, so bad input never leaves a half-built object.

State: FreeCAD 0.20 saves a proxy with ``__getstate__``/``__setstate__``, FreeCAD 1.0
with ``dumps``/``loads``; both are defined and save only a small JSON-able dict.
"""
from __future__ import annotations


def add_property(obj, kind: str, name: str, group: str, doc: str, value=None,
                 read_only: bool = False, hidden: bool = False) -> bool:
    """Add property ``name`` unless present (so restored old files gain new properties);
    returns True when it was added (and ``value`` set)."""
    if name in obj.PropertiesList:
        return False
    obj.addProperty(kind, name, group, doc)
    if value is not None:
        setattr(obj, name, value)
    modes = []
    if read_only:
        modes.append("ReadOnly")
    if hidden:
        modes.append("Hidden")
    if modes:
        obj.setEditorMode(name, modes)
    return True


def set_read_only(obj, name: str, value) -> None:
    """Assign a property the user cannot edit (read-only only in the editor)."""
    if getattr(obj, name) != value:
        setattr(obj, name, value)


class FeatureProxy:
    """Proxy of an ``App::FeaturePython``; subclasses set TYPE and VERSION and add their
    properties in ``ensure_properties`` (also called on restore, so old files gain new ones).

    Recompute: ``execute`` refuses at once when an input failed (tsplcam.workbench.validity),
    then calls the subclass's ``recompute``; what that raises is reported where the person
    works (a message box naming the place, the Report view; see ``messages``) and raised on,
    so FreeCAD marks the object Invalid with the reason."""
    TYPE = "TsplcamFeature"
    VERSION = 1
    TITLE = "tsplcam"

    def __init__(self, obj):
        obj.Proxy = self
        self.Type = self.TYPE
        self.ensure_properties(obj)

    @staticmethod
    def ensure_properties(obj) -> None:
        """Add the object's properties unless present (see :func:`add_property`)."""

    def recompute(self, obj) -> None:
        """The object's own recompute (subclasses)."""

    def stale(self, obj) -> str | None:
        """Why the stored result is older than the inputs, or None (subclasses)."""
        return None

    def execute(self, obj):
        from ..progress import Cancelled
        from . import messages, validity
        validity.install()
        validity.check_inputs(obj)
        try:
            self.recompute(obj)
        except (validity.StaleInput, Cancelled) as exc:
            messages.info(f"{obj.Label}: {exc}")
            raise
        except Exception as exc:
            messages.exception(self.TITLE, exc, f"recomputing {obj.Label}")
            raise

    # -- persistence (0.20 and 1.0 names) -----------------------------------------------
    def __getstate__(self):
        return {"type": self.TYPE, "version": self.VERSION}

    def __setstate__(self, state):
        self.Type = self.TYPE
        self.restored_version = (state or {}).get("version", self.VERSION) if isinstance(state, dict) else self.VERSION
        return None

    def dumps(self):
        return self.__getstate__()

    def loads(self, state):
        return self.__setstate__(state)


class Stateless:
    """A view proxy nothing of which is saved (0.20 and 1.0 names)."""

    def __getstate__(self):
        return None

    def __setstate__(self, state):
        return None

    def dumps(self):
        return None

    def loads(self, state):
        return None


class EditableMixin:
    """setEdit/doubleClicked of a view provider opening its task panel: ``panel()`` returns the
    panel class (imported late: panels import the GUI)."""

    @staticmethod
    def panel():
        raise NotImplementedError

    def setEdit(self, vobj, mode=0):
        if mode != 0:
            return False
        import FreeCADGui
        FreeCADGui.Control.showDialog(self.panel()(vobj.Object))
        return True

    def unsetEdit(self, vobj, mode=0):
        import FreeCADGui
        FreeCADGui.Control.closeDialog()
        return True

    def doubleClicked(self, vobj):
        import FreeCADGui
        FreeCADGui.ActiveDocument.setEdit(vobj.Object.Name, 0)
        return True


def close_task_panel(obj) -> None:
    """Close the task dialog and leave edit mode of ``obj``'s document."""
    import FreeCADGui
    FreeCADGui.Control.closeDialog()
    gdoc = FreeCADGui.getDocument(obj.Document.Name)
    if gdoc is not None and gdoc.getInEdit() is not None:
        gdoc.resetEdit()


class ViewProxy(Stateless):
    """Proxy of a ``Gui::ViewProviderPythonFeature``: nothing of it is saved but its type.
    Subclasses name their one display mode, their icon (resources/icons) and, in CHILD, the
    link property whose object shows under them in the tree."""
    DISPLAY_MODE = "Default"
    ICON = "tsplcam"
    CHILD = None

    def __init__(self, vobj):
        self.ensure_view_properties(vobj)
        vobj.Proxy = self

    @staticmethod
    def ensure_view_properties(vobj) -> None:
        """Add the view's properties unless present (also on restore, in :meth:`attach`)."""

    def getDisplayModes(self, vobj):
        return [self.DISPLAY_MODE]

    def getDefaultDisplayMode(self):
        return self.DISPLAY_MODE

    def setDisplayMode(self, mode):
        return mode

    def getIcon(self):
        from .resources import icon
        return icon(self.ICON)

    def claimChildren(self):
        child = getattr(getattr(self, "Object", None), self.CHILD, None) if self.CHILD else None
        return [child] if child is not None else []

    def attach(self, vobj):
        self.ensure_view_properties(vobj)
        self.ViewObject = vobj
        self.Object = vobj.Object

    def restoring(self) -> bool:
        """True while the object's document is loading (properties arrive one by one)."""
        obj = getattr(self, "Object", None)
        if obj is None:
            return True
        return bool(getattr(obj.Document, "Restoring", False)) or "Restore" in getattr(obj, "State", [])

    def later(self, fn) -> None:
        """Run ``fn`` once the event loop is free (after a document finished loading on
        FreeCAD versions that do not call finishRestoring on Python view providers)."""
        if getattr(self, "_pending", False):
            return
        self._pending = True
        from PySide import QtCore

        def run():
            self._pending = False
            try:
                fn()
            except Exception:          # the document may have been closed meanwhile
                pass
        QtCore.QTimer.singleShot(0, run)


class DrawnViewProxy(ViewProxy):
    """A view provider that draws one Coin group from its object's stored result.

    Subclasses set DATA_PROPS (object properties whose change redraws), VIEW_PROPS (view
    properties whose change redraws), TITLE (for messages) and implement ``draw(obj,
    group)``; drawing waits until a document has finished loading, and a failure to read
    the stored result is reported, never raised into FreeCAD."""
    DATA_PROPS: tuple = ()
    VIEW_PROPS: tuple = ()
    TITLE = "tsplcam"
    root = None
    group = None

    def attach(self, vobj):
        from pivy import coin
        super().attach(vobj)
        self.root = coin.SoSeparator()
        self.group = coin.SoSeparator()
        self.root.addChild(self.group)
        vobj.addDisplayMode(self.root, self.DISPLAY_MODE)
        self.rebuild()

    def updateData(self, obj, prop):
        if prop in self.DATA_PROPS:
            self.rebuild()

    def onChanged(self, vobj, prop):
        if prop in self.VIEW_PROPS and self.group is not None:
            self.rebuild()

    def finishRestoring(self):
        self.rebuild(after_restore=True)

    def draw(self, obj, group) -> bool:
        """Add the drawing of ``obj`` to ``group`` (empty); True when something was drawn."""
        return False

    def rebuild(self, after_restore: bool = False) -> bool:
        if self.group is None:
            return False
        if not after_restore and self.restoring():
            self.later(lambda: self.rebuild(after_restore=True))
            return False
        self.group.removeAllChildren()
        obj = self.Object
        try:
            return bool(self.draw(obj, self.group))
        except Exception as exc:
            from . import messages
            messages.exception(self.TITLE, exc, f"drawing {obj.Label}")
            return False

