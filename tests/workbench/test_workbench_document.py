"""The model document object under FreeCAD (no GUI): import, save and reload, bad files.

Runs under ``freecadcmd -t TestTsplcam``; skips under plain pytest. References: the sample
file's own bytes (inside the .FCStd zip), the engine reading the original file, and line
numbers the test computes from the text it wrote.
"""
import json
import os
import shutil
import tempfile
import unittest
import zipfile

import numpy as np

import tsplcam
from tsplcam.model.samples import KEYCAP_SIZE, sample_path
from conftest import needs_freecad, require_freecad


def grid_points(model, n=7):
    g = np.linspace(0.0, 1.0, n)
    U, V = np.meshgrid(g, g)
    return np.concatenate([p.evaluate(U.ravel(), V.ravel()).P for p in model.patches])


@needs_freecad
class _DocCase(unittest.TestCase):
    def setUp(self):
        self.FreeCAD = require_freecad()
        from tsplcam.workbench import importer, messages
        self.importer = importer
        self.messages = messages
        self._dialogs = messages.show_dialogs
        messages.show_dialogs = False
        self.tmp = tempfile.mkdtemp(prefix="tsplcam-wbtest-")
        self.docs_before = set(self.FreeCAD.listDocuments())
        self.doc = self.FreeCAD.newDocument("TsplcamDocTest")

    def tearDown(self):
        for name in set(self.FreeCAD.listDocuments()) - self.docs_before:
            self.FreeCAD.closeDocument(name)
        self.messages.show_dialogs = self._dialogs
        shutil.rmtree(self.tmp, ignore_errors=True)


class ModelObject(_DocCase):
    def test_import_shows_what_the_model_is(self):
        obj = self.importer.import_file(sample_path("keycap"), self.doc)
        self.assertIsNotNone(obj, self.messages.recorded[-1:])
        self.assertEqual(obj.Patches, 5)
        self.assertEqual(obj.ExtraordinaryPoints, 4)
        self.assertEqual(obj.Valences, "3 3 3 3")
        self.assertEqual((obj.Format, obj.FileName, obj.Units), ("obj", "keycap.obj", "mm"))
        # the keycap's limit surface is 14.4 x 14.4 x 6.8 mm (samples.py fits it so)
        np.testing.assert_allclose([obj.Size.x, obj.Size.y, obj.Size.z], KEYCAP_SIZE, rtol=0.01)
        self.assertEqual(obj.Proxy.__getstate__(), obj.Proxy.dumps())
        json.dumps(obj.Proxy.dumps())                     # state is plain JSON
        self.assertNotIn("Touched", obj.State)

    def test_import_fusion_tsm_through_the_engine_reader(self):
        """A Fusion-dialect .tsm (the shipped sample) comes in through the engine's reader
        registry: the same patches, stars and surface as the engine reads."""
        obj = self.importer.import_file(sample_path("fusion_mold"), self.doc)
        self.assertIsNotNone(obj, self.messages.recorded[-1:])
        self.assertEqual((obj.Format, obj.FileName, obj.Units), ("tsm", "fusion_mold.tsm", "mm"))
        self.assertEqual((obj.Patches, obj.ExtraordinaryPoints), (32, 8))
        self.assertEqual(sorted(obj.Valences.split()), ["3"] * 6 + ["5"] * 2)
        ref = tsplcam.load(sample_path("fusion_mold"))
        np.testing.assert_allclose(grid_points(obj.Proxy.model(obj)), grid_points(ref), rtol=0, atol=1e-12)

    def test_save_and_reload_without_the_original_file(self):
        src = os.path.join(self.tmp, "cap.obj")
        shutil.copyfile(sample_path("keycap"), src)
        obj = self.importer.import_file(src, self.doc)
        before = grid_points(obj.Proxy.model(obj))
        path = os.path.join(self.tmp, "cap.FCStd")
        self.doc.saveAs(path)
        self.FreeCAD.closeDocument(self.doc.Name)
        os.remove(src)                                    # the document must not need it
        with zipfile.ZipFile(path) as z:
            embedded = [n for n in z.namelist() if n.endswith(".obj")]
            self.assertEqual(len(embedded), 1)
            with open(sample_path("keycap"), "rb") as f:
                self.assertEqual(z.read(embedded[0]), f.read())
        doc = self.FreeCAD.openDocument(path)
        from tsplcam.workbench.modelobject import model_objects, model_of
        objs = model_objects(doc)
        self.assertEqual(len(objs), 1)
        o = objs[0]
        self.assertIsNone(o.Proxy._model)                 # lazy: nothing read yet
        model = model_of(o)
        self.assertEqual(len(model.patches), o.Patches)
        self.assertEqual(model.name, "cap.obj")
        # re-read and re-evaluated: the same surface to 1e-9 mm
        np.testing.assert_allclose(grid_points(model), before, rtol=0, atol=1e-9)
        self.assertIs(model_of(o), model)                 # cached
        doc.recompute()
        self.assertFalse([x for x in doc.Objects if "Invalid" in x.State])

    def test_registered_with_freecad_import(self):
        from tsplcam.model.formats import surface_readers
        for ext in (e.lstrip(".") for r in surface_readers() for e in r.extensions):
            self.assertIn("tsplcam.workbench.importer", self.FreeCAD.getImportType(ext), ext)
        # FreeCAD's own dispatch (File > Import without the GUI) reaches insert()
        self.FreeCAD.loadFile(sample_path("keycap"), self.doc.Name, "tsplcam.workbench.importer")
        self.assertEqual(len(self.doc.Objects), 1)
        self.assertEqual((self.doc.Objects[0].FileName, self.doc.Objects[0].Patches), ("keycap.obj", 5))

    def test_figure4_counts(self):
        obj = self.importer.import_file(sample_path("figure4"), self.doc)
        self.assertEqual((obj.Patches, obj.ExtraordinaryPoints), (12, 4))
        # sharp sheet corners (edge-and-corner rule) are regular: only the interior points
        self.assertEqual(sorted(obj.Valences.split()), sorted("3 3 5 5".split()))


class BadFiles(_DocCase):
    """A truncated or corrupt file: one message naming the file and line, no object."""

    def _write(self, name, text, mode="w"):
        path = os.path.join(self.tmp, name)
        with open(path, mode) as f:
            f.write(text)
        return path

    def assertRefused(self, path, line=None):
        n_objects = len(self.doc.Objects)
        n_msgs = len(self.messages.recorded)
        obj = self.importer.import_file(path, self.doc)
        self.assertIsNone(obj)
        self.assertEqual(len(self.doc.Objects), n_objects)
        new = self.messages.recorded[n_msgs:]
        self.assertEqual(len(new), 1, new)
        title, text, is_error = new[0]
        self.assertTrue(is_error)
        self.assertIn(path, text)
        if line is not None:
            self.assertIn(f"line {line}", text)
        self.assertNotIn("internal error", text)
        self.assertTrue(text.isprintable(), text)
        return text

    def test_truncated_in_a_vertex(self):
        with open(sample_path("keycap")) as f:
            lines = f.read().splitlines()
        k = next(i for i, l in enumerate(lines) if l.startswith("v ") and i > 20)
        cut = "\n".join(lines[:k] + [lines[k].rsplit(" ", 2)[0]])
        self.assertRefused(self._write("cut.obj", cut), line=k + 1)

    def test_truncated_in_a_face(self):
        with open(sample_path("keycap")) as f:
            lines = f.read().splitlines()
        k = max(i for i, l in enumerate(lines) if l.startswith("f "))
        cut = "\n".join(lines[:k] + [" ".join(lines[k].split()[:3])])
        self.assertRefused(self._write("cut.obj", cut), line=k + 1)

    def test_binary_garbage(self):
        rng = np.random.default_rng(7)
        self.assertRefused(self._write("junk.obj", rng.integers(0, 256, 4000, dtype=np.uint8).tobytes(),
                                       "wb"), line=1)

    def test_face_with_a_missing_vertex(self):
        text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 9\n"
        self.assertRefused(self._write("hole.obj", text), line=5)

    def test_missing_file_and_unknown_type(self):
        self.assertRefused(os.path.join(self.tmp, "absent.obj"))
        self.assertRefused(self._write("model.xyz", "1 2 3\n"))

    def test_truncated_iga(self):
        from conftest import external
        with open(external("geopdes", "square_unstructured.iga")) as f:
            text = f.read()
        cut = text[: len(text) // 2]
        line = cut.count("\n") + 1                 # the line the cut falls on, or the next
        text = self.assertRefused(self._write("cut.iga", cut))
        import re
        found = re.search(r"line (\d+)", text)
        self.assertIsNotNone(found, text)
        self.assertLessEqual(abs(int(found.group(1)) - line), 1, text)

    def test_file_dialog_offers_what_can_be_read(self):
        from tsplcam.workbench.modelobject import file_filters, readable_formats, shapes_module
        fmts = readable_formats()
        self.assertIn("obj", fmts)
        self.assertEqual("step" in fmts, shapes_module() is not None)
        first = file_filters()[0]
        self.assertIn("*.obj", first)
        for f in fmts:
            self.assertTrue(any(f in x.lower() for x in file_filters()[1:]), f)

    def test_open_makes_no_document_for_a_bad_file(self):
        before = set(self.FreeCAD.listDocuments())
        path = self._write("cut.obj", "v 0 0\n")
        self.assertIsNone(self.importer.open(path))
        self.assertIsNone(self.importer.insert(path, "TsplcamNotMade"))
        self.assertEqual(set(self.FreeCAD.listDocuments()), before)
        self.assertIn(path, self.messages.recorded[-1][1])

    def test_insert_into_a_named_document(self):
        obj = self.importer.insert(sample_path("keycap"), "TsplcamInserted")
        self.assertIsNotNone(obj)
        self.assertEqual(obj.Document.Name, "TsplcamInserted")
        obj2 = self.importer.insert(sample_path("figure4"), "TsplcamInserted")
        self.assertEqual(len(obj2.Document.Objects), 2)


if __name__ == "__main__":
    unittest.main()
