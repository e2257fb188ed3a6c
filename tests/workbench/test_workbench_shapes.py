"""Models from FreeCAD shapes: a Part object or a STEP file becomes a TsplcamModel that
keeps its shape inside the document (runs under freecadcmd; skips under plain pytest).

Uses ``tsplcam.workbench.shapes.model_from_shape`` when it exists; until then a stand-in
that records the shape it is given, so the document side (which shape is passed, how it
is kept, that it comes back after reloading, bad files) is tested either way. The shape
kept in the .FCStd is checked against the original with OCCT (area, volume, faces).
"""
import os
import shutil
import sys
import tempfile
import types
import unittest
import zipfile

import numpy as np

import tsplcam
from tsplcam.model.samples import sample_path
from conftest import needs_freecad, require_freecad


def grid_points(model, n=5):
    g = np.linspace(0.0, 1.0, n)
    U, V = np.meshgrid(g, g)
    return np.concatenate([p.evaluate(U.ravel(), V.ravel()).P for p in model.patches])


@needs_freecad
class ShapeModels(unittest.TestCase):
    def setUp(self):
        self.FreeCAD = require_freecad()
        import Part
        self.Part = Part
        from tsplcam.workbench import importer, messages, shapeimport
        from tsplcam.workbench.modelobject import shapes_module
        self.importer, self.messages, self.shapeimport = importer, messages, shapeimport
        self._dialogs = messages.show_dialogs
        messages.show_dialogs = False
        self.given = []
        self.stub = None
        if shapes_module() is None:
            self.stub = types.ModuleType("tsplcam.workbench.shapes")

            def model_from_shape(shape, name):
                self.given.append(shape.copy())
                model = tsplcam.load(sample_path("keycap"))
                model.name = name
                return model
            self.stub.model_from_shape = model_from_shape
            sys.modules["tsplcam.workbench.shapes"] = self.stub
            import tsplcam.workbench as wb
            wb.shapes = self.stub
        self.tmp = tempfile.mkdtemp(prefix="tsplcam-shapetest-")
        self.docs_before = set(self.FreeCAD.listDocuments())
        self.doc = self.FreeCAD.newDocument("TsplcamShapeTest")

    def tearDown(self):
        for name in set(self.FreeCAD.listDocuments()) - self.docs_before:
            self.FreeCAD.closeDocument(name)
        if self.stub is not None:
            sys.modules.pop("tsplcam.workbench.shapes", None)
            import tsplcam.workbench as wb
            if getattr(wb, "shapes", None) is self.stub:
                del wb.shapes
        self.messages.show_dialogs = self._dialogs
        shutil.rmtree(self.tmp, ignore_errors=True)

    def _box(self):
        box = self.doc.addObject("Part::Feature", "Box")
        box.Shape = self.Part.makeBox(10, 8, 5, self.FreeCAD.Vector(1, 2, 3))
        self.doc.recompute()
        return box

    def test_part_object_to_model_survives_reload(self):
        box = self._box()
        obj = self.shapeimport.model_from_object(box)
        self.assertIsNotNone(obj, self.messages.recorded[-1:])
        self.assertEqual((obj.Format, obj.SourceObject), ("brep", box))
        self.assertTrue(obj.FileName.endswith(".brep"))
        if self.stub is not None:
            self.assertEqual(len(self.given), 1)
            self.assertAlmostEqual(self.given[0].Volume, 400.0, places=9)
        from tsplcam.workbench.modelobject import model_objects, model_of
        before = grid_points(model_of(obj))
        path = os.path.join(self.tmp, "box.FCStd")
        self.doc.saveAs(path)
        self.FreeCAD.closeDocument(self.doc.Name)
        with zipfile.ZipFile(path) as z:
            brep = [n for n in z.namelist() if n.endswith(".brep")]
            self.assertEqual(len(brep), 1)
            kept = os.path.join(self.tmp, "kept.brep")
            with open(kept, "wb") as f:
                f.write(z.read(brep[0]))
        shape = self.Part.read(kept)                  # the document keeps the very shape
        self.assertAlmostEqual(shape.Volume, 400.0, places=9)
        self.assertAlmostEqual(shape.Area, 2 * (80 + 50 + 40), places=9)
        self.assertEqual(len(shape.Faces), 6)
        bb = shape.BoundBox
        np.testing.assert_allclose([bb.XMin, bb.YMin, bb.ZMin, bb.XMax, bb.YMax, bb.ZMax],
                                   [1, 2, 3, 11, 10, 8], atol=1e-9)
        doc = self.FreeCAD.openDocument(path)
        o = model_objects(doc)[0]
        self.assertEqual(o.SourceObject.Name, "Box")
        # re-read and re-evaluated: the same surface to 1e-9 mm
        np.testing.assert_allclose(grid_points(model_of(o)), before, rtol=0, atol=1e-9)

    def test_selected_faces_only(self):
        box = self._box()
        obj = self.shapeimport.model_from_object(box, ("Face1", "Face6"))
        self.assertIsNotNone(obj, self.messages.recorded[-1:])
        if self.stub is not None:
            given = self.given[0]
            self.assertEqual(len(given.Faces), 2)
            self.assertAlmostEqual(given.Area, box.Shape.Face1.Area + box.Shape.Face6.Area, places=9)

    def test_step_file(self):
        path = os.path.join(self.tmp, "box.step")
        self.Part.makeBox(10, 8, 5).exportStep(path)
        obj = self.importer.import_file(path, self.doc)
        self.assertIsNotNone(obj, self.messages.recorded[-1:])
        self.assertEqual((obj.Format, obj.FileName), ("step", "box.step"))
        if self.stub is not None:
            self.assertAlmostEqual(self.given[0].Volume, 400.0, places=6)

    def test_corrupt_step_file_makes_nothing(self):
        path = os.path.join(self.tmp, "broken.step")
        with open(path, "w") as f:
            f.write("ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION(('x'),'2;1');\nDATA;\n#1=CARTESIAN_POINT(")
        n = len(self.messages.recorded)
        self.assertIsNone(self.importer.import_file(path, self.doc))
        self.assertEqual(self.doc.Objects, [])
        new = self.messages.recorded[n:]
        self.assertEqual(len(new), 1, new)
        self.assertIn(path, new[0][1])
        self.assertNotIn("internal error", new[0][1])

    def test_object_without_faces(self):
        wire = self.doc.addObject("Part::Feature", "Line")
        wire.Shape = self.Part.makeLine((0, 0, 0), (1, 0, 0))
        n = len(self.messages.recorded)
        self.assertIsNone(self.shapeimport.model_from_object(wire))
        self.assertEqual([o.Name for o in self.doc.Objects], ["Line"])
        self.assertIn("Line", self.messages.recorded[n][1])


if __name__ == "__main__":
    unittest.main()
