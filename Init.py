# tsplcam: FreeCAD start-up, run in both freecadcmd and the GUI.
# Registers the unit-test entry module and the import types. Nothing heavy is imported here.
import FreeCAD

if "TestTsplcam" not in FreeCAD.__unit_test__:
    FreeCAD.__unit_test__ += ["TestTsplcam"]

FreeCAD.addImportType("tsplcam T-spline models (*.tsm *.iga *.tspl)", "tsplcam.workbench.importer")
FreeCAD.addImportType("tsplcam subdivision cage (*.obj)", "tsplcam.workbench.importer")
