"""The workbench in the real FreeCAD GUI: listed with its icon, activates without errors."""
import os
import unittest

import FreeCAD
import FreeCADGui

from conftest import artifact_path
from tsplcam.workbench.testsupport import errors_since, report_view_lines, report_view_mark, save_view


class WorkbenchInGui(unittest.TestCase):
    def test_listed_with_icon(self):
        workbenches = FreeCADGui.listWorkbenches()
        self.assertIn("TsplcamWorkbench", workbenches)
        wb = workbenches["TsplcamWorkbench"]
        self.assertEqual(wb.MenuText, "T-spline CAM")
        self.assertTrue(os.path.isfile(wb.Icon), wb.Icon)
        from PySide import QtGui
        self.assertFalse(QtGui.QIcon(wb.Icon).pixmap(32, 32).isNull())

    def test_activation_prints_no_error(self):
        # the error detector itself must see a printed error
        mark = report_view_mark()
        FreeCAD.Console.PrintError("tsplcam test: this line is an expected error\n")
        self.assertEqual(len(errors_since(mark)), 1, report_view_lines()[-6:])
        mark = report_view_mark()
        FreeCADGui.activateWorkbench("TsplcamWorkbench")
        FreeCADGui.updateGui()
        self.assertEqual(FreeCADGui.activeWorkbench().name(), "TsplcamWorkbench")
        self.assertEqual(errors_since(mark), [])
        self.assertIn("Tsplcam_About", FreeCADGui.listCommands())

    def test_screenshot_of_the_3d_view(self):
        doc = FreeCAD.newDocument("TsplcamGuiSmoke")
        try:
            import Part
            doc.addObject("Part::Feature", "Box").Shape = Part.makeBox(10, 10, 5)
            doc.recompute()
            path = save_view(artifact_path("gui_smoke.png"), 640, 480)
            self.assertGreater(os.path.getsize(path), 1000)
        finally:
            FreeCAD.closeDocument(doc.Name)
