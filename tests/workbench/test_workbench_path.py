"""The tool-path document object under FreeCAD (no GUI): compute, keep in the .FCStd,
recompute only when an input changes, refuse a ball too large. Skips where the engine's
path generator (tsplcam.toolpath.zigzag_path) is absent.

References: the model evaluated at each stored (patch, u, v) (the contact points lie on
the surface, also after reloading), the processing list's order (patches in the path
appear in that order), and segment lengths summed independently."""
import os
import shutil
import tempfile
import unittest

import numpy as np

from tsplcam.model.samples import sample_path
from conftest import needs_freecad, require_freecad


@needs_freecad
class ToolPathObject(unittest.TestCase):
    def setUp(self):
        self.FreeCAD = require_freecad()
        from tsplcam.workbench import importer, messages, pathobject, planobject
        if not pathobject.toolpath_available():
            raise unittest.SkipTest("the path generator (tsplcam.toolpath.zigzag_path) is absent")
        self.importer, self.messages = importer, messages
        self.pathobject, self.planobject = pathobject, planobject
        self._dialogs = messages.show_dialogs
        messages.show_dialogs = False
        self.tmp = tempfile.mkdtemp(prefix="tsplcam-pathtest-")
        self.docs_before = set(self.FreeCAD.listDocuments())
        self.doc = self.FreeCAD.newDocument("TsplcamPathTest")

    def tearDown(self):
        for name in set(self.FreeCAD.listDocuments()) - self.docs_before:
            self.FreeCAD.closeDocument(name)
        self.messages.show_dialogs = self._dialogs
        shutil.rmtree(self.tmp, ignore_errors=True)

    def test_keycap_path_kept_and_recomputed_only_on_change(self):
        from tsplcam.toolpath import Move
        from tsplcam.workbench.modelobject import model_of
        model_obj = self.importer.import_file(sample_path("keycap"), self.doc)
        plan = self.planobject.make_processing_list(model_obj)
        obj = self.pathobject.make_tool_path(plan, scallop=0.05)
        self.assertIsNotNone(obj, self.messages.recorded[-1:])
        tp = self.pathobject.path_of(obj)
        model = model_of(model_obj)
        # contact points are surface points of their (patch, u, v)
        on = tp.patch >= 0
        for p in np.unique(tp.patch[on]):
            sel = on & (tp.patch == p)
            P = model.patches[p].evaluate(tp.uv[sel, 0], tp.uv[sel, 1]).P
            self.assertLess(np.abs(P - tp.contact[sel]).max(), 1e-9)
        # patches come in the order of the processing list, without retractions
        seq = tp.patch[on][np.r_[True, np.diff(tp.patch[on]) != 0]]
        self.assertEqual(seq.tolist(), [int(x) for x in plan.Order.split()])
        self.assertEqual(obj.Retractions, 0)
        seg = np.linalg.norm(np.diff(tp.contact, axis=0), axis=1)
        self.assertAlmostEqual(obj.CutLength.Value, seg[tp.move[1:] == Move.CUT].sum(), places=6)

        path = os.path.join(self.tmp, "path.FCStd")
        self.doc.saveAs(path)
        self.FreeCAD.closeDocument(self.doc.Name)
        doc = self.FreeCAD.openDocument(path)
        again = [o for o in doc.Objects if self.pathobject.is_path_object(o)][0]
        calls = []
        original = again.Proxy.compute
        again.Proxy.compute = lambda o: calls.append(1) or original(o)
        again.touch()
        doc.recompute()
        self.assertEqual(calls, [])                      # unchanged inputs: the stored path
        tp2 = self.pathobject.path_of(again)
        # exact by construction: the stored arrays (np.savez, binary), not a recomputation
        np.testing.assert_array_equal(tp2.contact, tp.contact)
        np.testing.assert_array_equal(tp2.move, tp.move)
        again.Scallop = 0.1
        doc.recompute()
        self.assertEqual(calls, [1])                     # a new scallop: computed again
        self.assertLess(again.Points, len(tp))

    def test_a_ball_too_large_is_refused_with_the_place(self):
        model_obj = self.importer.import_file(sample_path("keycap_mold"), self.doc)
        plan = self.planobject.make_processing_list(model_obj)
        n = len(self.doc.Objects)
        self.assertIsNone(self.pathobject.make_tool_path(plan, tool_radius=5.0, scallop=0.05))
        self.assertEqual(len(self.doc.Objects), n)
        text = self.messages.recorded[-1][1]
        self.assertIn("patch", text)
        self.assertNotIn("internal error", text)


if __name__ == "__main__":
    unittest.main()
