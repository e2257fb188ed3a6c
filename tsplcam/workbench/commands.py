"""Workbench commands. Each is registered only once it works end to end.

``COMMANDS`` maps command names to classes, in toolbar order; ``available()`` drops the
ones whose engine parts are missing in this checkout (e.g. models from shapes without
``shapes.py``). A later stage adds its commands the same way: a class with
GetResources/IsActive/Activated here (or in its own module, imported here), an entry in
COMMANDS, and its check in ``available()`` if it depends on optional parts.
"""
import os

import FreeCAD
import FreeCADGui

import tsplcam
from tsplcam.workbench.resources import icon

PARAMS = "User parameter:BaseApp/Preferences/Mod/tsplcam"


def _main_window():
    return FreeCADGui.getMainWindow()


def _selected_or_all_models():
    from tsplcam.workbench.modelobject import is_model_object, model_objects
    sel = [o for o in FreeCADGui.Selection.getSelection() if is_model_object(o)]
    return sel or model_objects(FreeCAD.ActiveDocument)


def _selected_or_only(is_kind) -> list:
    """The selected objects of a kind, else the only one of the active document (else none)."""
    sel = [o for o in FreeCADGui.Selection.getSelection() if is_kind(o)]
    if sel:
        return sel
    doc = FreeCAD.ActiveDocument
    found = [o for o in doc.Objects if is_kind(o)] if doc else []
    return found if len(found) == 1 else []


class AboutCommand:
    """Show the version of tsplcam and of the libraries it runs on."""

    def GetResources(self):
        return {"Pixmap": icon("tsplcam"), "MenuText": "About tsplcam",
                "ToolTip": "Version of tsplcam and of numpy, scipy, python-fcl and elkai"}

    def IsActive(self):
        return True

    def Activated(self):
        from tsplcam.cli import dependency_versions
        lines = [f"tsplcam {tsplcam.__version__}"]
        lines += [f"{k}: {v}" for k, v in dependency_versions().items()]
        FreeCAD.Console.PrintMessage("\n".join(lines) + "\n")
        if FreeCAD.GuiUp:
            from PySide import QtGui
            QtGui.QMessageBox.information(_main_window(), "About tsplcam", "\n".join(lines))


class ImportModelCommand:
    """Import T-spline models from files (engine formats; STEP/IGES with shapes support)."""

    def GetResources(self):
        from tsplcam.workbench.modelobject import FORMAT_NAMES, readable_formats
        names = ", ".join(FORMAT_NAMES[f] for f in readable_formats())
        return {"Pixmap": icon("import"), "MenuText": "Import T-spline model...",
                "ToolTip": f"Read a surface model into the active document ({names}); "
                           "it shows its patches, patch numbers and extraordinary points"}

    def IsActive(self):
        return True

    def Activated(self):
        from PySide import QtGui
        from tsplcam.workbench import importer
        from tsplcam.workbench.modelobject import file_filters
        params = FreeCAD.ParamGet(PARAMS)
        start = params.GetString("LastImportDir", os.path.expanduser("~"))
        paths, _ = QtGui.QFileDialog.getOpenFileNames(_main_window(), "Import T-spline model", start,
                                                      ";;".join(file_filters() + ["All files (*)"]))
        for path in paths:
            params.SetString("LastImportDir", os.path.dirname(path))
            obj = importer.import_file(path)
            if obj is not None:
                importer.fit_view(obj.Document)


class OpenSampleCommand:
    """Open one of the sample models shipped with tsplcam."""

    def GetResources(self):
        return {"Pixmap": icon("sample"), "MenuText": "Open sample model...",
                "ToolTip": "Import a sample shipped with tsplcam: the keycap of the paper, its mold, "
                           "a head-like closed model, or the 12-patch layout of the paper's figure 4"}

    def IsActive(self):
        return True

    def Activated(self):
        from PySide import QtGui
        from tsplcam.model.samples import SAMPLES, sample_path
        from tsplcam.workbench import importer
        names = list(SAMPLES)
        name, ok = QtGui.QInputDialog.getItem(_main_window(), "Open sample model", "Sample:", names, 0, False)
        if ok and name:
            obj = importer.import_file(sample_path(name))
            if obj is not None:
                importer.fit_view(obj.Document)


class ModelFromShapeCommand:
    """Build a model from the selected Part object(s) or faces."""

    def GetResources(self):
        return {"Pixmap": icon("fromshape"), "MenuText": "Model from selected shape",
                "ToolTip": "Build a tsplcam model from the selected shape or faces (STEP/IGES "
                           "imports, Part and PartDesign bodies); the shape is kept in the document"}

    def IsActive(self):
        if FreeCAD.ActiveDocument is None:
            return False
        from tsplcam.workbench.shapeimport import shape_selection
        return bool(shape_selection())

    def Activated(self):
        from tsplcam.workbench.shapeimport import model_from_object, shape_selection
        for obj, subs in shape_selection():
            model_from_object(obj, subs)


class PatchNeighboursCommand:
    """Colour the patches by their link to the selected patch (shang2020 figure 4 (a))."""

    def GetResources(self):
        return {"Pixmap": icon("neighbours"), "MenuText": "Neighbours of selected patch",
                "ToolTip": "Click a patch first: its edge neighbours turn blue, its corner-only "
                           "neighbours green, the rest gray. With a whole model selected: back to "
                           "one colour per patch"}

    def _targets(self):
        from tsplcam.workbench.modelobject import is_model_object, patch_of_element
        out = []
        for sel in FreeCADGui.Selection.getSelectionEx():
            if not is_model_object(sel.Object) or getattr(sel.Object, "ViewObject", None) is None:
                continue
            patches = [patch_of_element(n) for n in sel.SubElementNames]
            patches = [p for p in patches if p is not None]
            out.append((sel.Object, patches[-1] if patches else -1))
        return out

    def IsActive(self):
        return bool(self._targets())

    def Activated(self):
        for obj, patch in self._targets():
            obj.ViewObject.NeighboursOf = patch
        FreeCADGui.updateGui()


class PlanCommand:
    """Plan the processing list of the selected model (or the document's only model)."""

    def GetResources(self):
        return {"Pixmap": icon("plan"), "MenuText": "Processing list",
                "ToolTip": "Plan the order of the patches, their start and finish corners and "
                           "crossfeed (no retractions where the layout allows); double-click the "
                           "list to edit it, pin steps and solve again"}

    def _models(self):
        from tsplcam.workbench.modelobject import is_model_object, model_objects
        sel = [o for o in FreeCADGui.Selection.getSelection() if is_model_object(o)]
        if sel:
            return sel
        models = model_objects(FreeCAD.ActiveDocument)
        return models if len(models) == 1 else []

    def IsActive(self):
        return FreeCAD.ActiveDocument is not None and bool(self._models())

    def Activated(self):
        from tsplcam.workbench.planobject import make_processing_list
        for model in self._models():
            obj = make_processing_list(model)
            if obj is not None and FreeCAD.GuiUp:
                FreeCADGui.Selection.clearSelection()
                FreeCADGui.Selection.addSelection(obj)


class _MakeCommand:
    """Make an object of each selected input (or of the document's only one) and select it.
    Subclasses name the input kind and the maker as (module, function) of tsplcam.workbench."""
    KIND = ("", "")
    MAKER = ("", "")

    def _inputs(self):
        import importlib
        module, name = self.KIND
        return _selected_or_only(getattr(importlib.import_module("tsplcam.workbench." + module), name))

    def IsActive(self):
        return FreeCAD.ActiveDocument is not None and bool(self._inputs())

    def Activated(self):
        import importlib
        module, name = self.MAKER
        make = getattr(importlib.import_module("tsplcam.workbench." + module), name)
        for source in self._inputs():
            obj = make(source)
            if obj is not None:
                FreeCADGui.Selection.clearSelection()
                FreeCADGui.Selection.addSelection(obj)


class ToolPathCommand(_MakeCommand):
    """Compute the finishing path of the selected processing list (or the only one)."""
    KIND = ("planobject", "is_plan_object")
    MAKER = ("pathobject", "make_tool_path")

    def GetResources(self):
        return {"Pixmap": icon("toolpath"), "MenuText": "Tool path",
                "ToolTip": "Isoparametric zigzags patch after patch in the order of the processing "
                           "list, stepover under the scallop height; double-click the path for its "
                           "settings (mm, feed in mm/min), Generate with progress and Cancel"}


class ProgramCommand(_MakeCommand):
    """Orient the tool and post the program of the selected tool path (or the only one)."""
    KIND = ("pathobject", "is_path_object")
    MAKER = ("programobject", "make_program")

    def GetResources(self):
        return {"Pixmap": icon("program"), "MenuText": "Post program",
                "ToolTip": "Collision-free tool axes (smooth by default) and the machine program of the "
                           "tool path; double-click the program for its settings, Generate with progress "
                           "and Cancel"}


class SaveProgramCommand:
    """Write the selected program's G-code to a file."""

    def GetResources(self):
        return {"Pixmap": icon("savegcode"), "MenuText": "Save G-code...",
                "ToolTip": "Write the selected program to a file for the machine"}

    def _programs(self):
        from tsplcam.workbench.programobject import is_program_object
        return _selected_or_only(is_program_object)

    def IsActive(self):
        return FreeCAD.ActiveDocument is not None and bool(self._programs())

    def Activated(self):
        from PySide import QtGui
        from tsplcam.workbench import messages
        from tsplcam.workbench.programobject import export_program
        for prog in self._programs():
            name = prog.ProgramName or "program.nc"
            suffix = os.path.splitext(name)[1] or ".nc"
            start = os.path.join(os.path.expanduser("~"), name)
            path, _ = QtGui.QFileDialog.getSaveFileName(
                FreeCADGui.getMainWindow(), f"Save {prog.Label}", start,
                f"Machine program (*{suffix});;All files (*)")
            if not path:
                continue
            try:
                export_program(prog, path)
            except Exception as exc:
                messages.exception("Save G-code", exc, f"writing {path}")
            else:
                messages.info(f"{prog.Label}: wrote {path}")


class CamJobCommand(_MakeCommand):
    """Put the selected program's moves into a FreeCAD CAM Job (tool controller, stock, work
    offset), where the CAM workbench's posts can read them."""
    KIND = ("programobject", "is_program_object")
    MAKER = ("camjob", "make_cam_job")

    def GetResources(self):
        return {"Pixmap": icon("camjob"), "MenuText": "CAM job from program",
                "ToolTip": "A FreeCAD CAM Job holding the selected program's moves (G0/G1 with X Y Z and the "
                           "rotary axes, feeds), with a tool controller (tool number, spindle speed), the stock "
                           "and the work offset: the CAM workbench lists it and its posts read it"}


class EditCommand:
    """Open the task panel of the selected processing list, tool path or program."""

    def GetResources(self):
        return {"Pixmap": icon("settings"), "MenuText": "Edit settings...",
                "ToolTip": "Task panel of the selected processing list, tool path or program: every option "
                           "with its unit, Generate with progress and Cancel (also by double-click)"}

    def _objects(self):
        from tsplcam.workbench import pathobject, planobject, programobject
        kinds = (planobject.is_plan_object, pathobject.is_path_object, programobject.is_program_object)
        return [o for o in FreeCADGui.Selection.getSelection() if any(k(o) for k in kinds)]

    def IsActive(self):
        return FreeCAD.ActiveDocument is not None and len(self._objects()) == 1 and \
            not FreeCADGui.Control.activeDialog()

    def Activated(self):
        obj = self._objects()[0]
        FreeCADGui.ActiveDocument.setEdit(obj.Name, 0)


class _ToggleCommand:
    """Switch a display layer of the selected models (all models when none is selected)."""
    PROPERTY = ""
    ICON = ""
    TEXT = ""
    TIP = ""

    def GetResources(self):
        return {"Pixmap": icon(self.ICON), "MenuText": self.TEXT, "ToolTip": self.TIP}

    def IsActive(self):
        return FreeCAD.ActiveDocument is not None and bool(_selected_or_all_models())

    def Activated(self):
        objs = [o for o in _selected_or_all_models() if getattr(o, "ViewObject", None) is not None]
        if not objs:
            return
        on = not all(bool(getattr(o.ViewObject, self.PROPERTY)) for o in objs)
        for o in objs:
            setattr(o.ViewObject, self.PROPERTY, on)
        FreeCADGui.updateGui()


class ToggleControlMeshCommand(_ToggleCommand):
    PROPERTY = "ShowControlMesh"
    ICON = "controlmesh"
    TEXT = "Control mesh"
    TIP = "Show or hide the control mesh (cage or T-mesh) of the selected models"


class TogglePatchNumbersCommand(_ToggleCommand):
    PROPERTY = "ShowPatchNumbers"
    ICON = "numbers"
    TEXT = "Patch numbers"
    TIP = "Show or hide the patch numbers of the selected models"


class ToggleAdjacencyCommand(_ToggleCommand):
    PROPERTY = "ShowAdjacency"
    ICON = "adjacency"
    TEXT = "Adjacency graph"
    TIP = ("Show or hide the patch adjacency graph: boundary links (shared edge) solid, "
           "corner links (shared corner only) dashed")


COMMANDS = {
    "Tsplcam_Import": ImportModelCommand,
    "Tsplcam_OpenSample": OpenSampleCommand,
    "Tsplcam_ModelFromShape": ModelFromShapeCommand,
    "Tsplcam_ShowControlMesh": ToggleControlMeshCommand,
    "Tsplcam_ShowPatchNumbers": TogglePatchNumbersCommand,
    "Tsplcam_ShowAdjacency": ToggleAdjacencyCommand,
    "Tsplcam_PatchNeighbours": PatchNeighboursCommand,
    "Tsplcam_Plan": PlanCommand,
    "Tsplcam_ToolPath": ToolPathCommand,
    "Tsplcam_Program": ProgramCommand,
    "Tsplcam_SaveProgram": SaveProgramCommand,
    "Tsplcam_CamJob": CamJobCommand,
    "Tsplcam_Edit": EditCommand,
    "Tsplcam_About": AboutCommand,
}


def available() -> dict:
    """COMMANDS without those whose engine parts this checkout lacks."""
    from tsplcam.workbench.modelobject import shapes_module
    out = dict(COMMANDS)
    if shapes_module() is None:
        out.pop("Tsplcam_ModelFromShape")
    try:
        import tsplcam.plan  # noqa: F401
    except ImportError:
        out.pop("Tsplcam_Plan")
    from tsplcam.workbench.pathobject import toolpath_available
    if not toolpath_available():
        out.pop("Tsplcam_ToolPath")
    try:
        import tsplcam.orientation  # noqa: F401
        import tsplcam.post  # noqa: F401,F811
    except ImportError:
        out.pop("Tsplcam_Program")
        out.pop("Tsplcam_SaveProgram")
        out.pop("Tsplcam_CamJob")
    from tsplcam.workbench.camjob import cam_available
    if not cam_available():
        out.pop("Tsplcam_CamJob", None)
    return out


def register():
    """Add the available commands to FreeCAD (once) and return their names in toolbar order."""
    existing = set(FreeCADGui.listCommands())
    cmds = available()
    for name, cls in cmds.items():
        if name not in existing:
            FreeCADGui.addCommand(name, cls())
    return list(cmds)
