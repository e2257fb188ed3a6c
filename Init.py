# tsplcam: FreeCAD start-up, run in both freecadcmd and the GUI.
# Registers the unit-test entry module and the import types (one per surface reader of the
# engine's registry, tsplcam.model.formats.READERS). Nothing heavy is imported here: the
# registry imports a reader's module only when a file is read.
import FreeCAD

from tsplcam.model.formats import surface_readers

if "TestTsplcam" not in FreeCAD.__unit_test__:
    FreeCAD.__unit_test__ += ["TestTsplcam"]

for _reader in surface_readers():
    FreeCAD.addImportType(f"tsplcam {_reader.description} ({_reader.patterns})", "tsplcam.workbench.importer")
del _reader
