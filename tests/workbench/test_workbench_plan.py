"""The processing-list document object under FreeCAD (no GUI): plan, save, reload, pins,
stale models, bad lists. The list is checked against the model by brute force here (every
patch once; each step starts at the node where the one before finished; the crossfeed
can reach the finish), not with the planner's own checker."""
import os
import shutil
import tempfile
import unittest

from tsplcam.layout.layout import CORNER_UV
from tsplcam.model.samples import sample_path
from conftest import needs_freecad, require_freecad


def assert_chained(case, model, plist):
    n = len(model.patches)
    case.assertEqual(sorted(s.patch for s in plist.steps), list(range(n)))
    for i, s in enumerate(plist.steps):
        su, sv = CORNER_UV[s.start]
        fu, fv = CORNER_UV[s.finish]
        case.assertTrue((s.crossfeed == "u" and su != fu) or (s.crossfeed == "v" and sv != fv), s)
        if i and not s.retract_before:
            prev = plist.steps[i - 1]
            case.assertEqual(model.patches[prev.patch].corner_nodes[prev.finish],
                             model.patches[s.patch].corner_nodes[s.start], (i, s))


@needs_freecad
class ProcessingListObject(unittest.TestCase):
    def setUp(self):
        self.FreeCAD = require_freecad()
        from tsplcam.workbench import importer, messages, planobject
        self.importer, self.messages, self.planobject = importer, messages, planobject
        self._dialogs = messages.show_dialogs
        messages.show_dialogs = False
        self.tmp = tempfile.mkdtemp(prefix="tsplcam-plantest-")
        self.docs_before = set(self.FreeCAD.listDocuments())
        self.doc = self.FreeCAD.newDocument("TsplcamPlanTest")

    def tearDown(self):
        for name in set(self.FreeCAD.listDocuments()) - self.docs_before:
            self.FreeCAD.closeDocument(name)
        self.messages.show_dialogs = self._dialogs
        shutil.rmtree(self.tmp, ignore_errors=True)

    def _plan(self, sample):
        model_obj = self.importer.import_file(sample_path(sample), self.doc)
        plan = self.planobject.make_processing_list(model_obj)
        self.assertIsNotNone(plan, self.messages.recorded[-1:])
        return model_obj, plan

    def test_figure4_plan_without_retractions_survives_reload(self):
        from tsplcam.workbench.modelobject import model_of
        model_obj, plan = self._plan("figure4")
        plist = self.planobject.plan_of(plan)
        assert_chained(self, model_of(model_obj), plist)
        self.assertEqual((plan.Steps, plan.Retractions), (12, 0))
        self.assertEqual(plan.Order.split(), [str(p) for p in plist.order])
        path = os.path.join(self.tmp, "plan.FCStd")
        self.doc.saveAs(path)
        self.FreeCAD.closeDocument(self.doc.Name)
        doc = self.FreeCAD.openDocument(path)
        again = [o for o in doc.Objects if self.planobject.is_plan_object(o)][0]
        p2 = self.planobject.plan_of(again)
        self.assertEqual([(s.patch, s.start, s.finish, s.crossfeed) for s in p2.steps],
                         [(s.patch, s.start, s.finish, s.crossfeed) for s in plist.steps])
        assert_chained(self, model_of(again.Model), p2)

    def test_pins_are_kept_when_solving_again(self):
        from tsplcam.workbench.modelobject import model_of
        model_obj, plan = self._plan("keycap")
        model = model_of(model_obj)
        plist = self.planobject.plan_of(plan)
        # put patch 4 (the top) first and pin it there, then let the planner do the rest
        steps = plist.steps
        k = next(i for i, s in enumerate(steps) if s.patch == 4)
        steps.insert(0, steps.pop(k))
        steps[0].pinned = frozenset({"position"})
        out = self.planobject.replan(model, plist)
        self.assertEqual(out.steps[0].patch, 4)
        self.assertIn("position", out.steps[0].pinned)
        assert_chained(self, model, out)
        plan.Proxy.set_list(plan, out)
        self.doc.recompute()
        self.assertEqual(plan.Order.split()[0], "4")
        self.assertNotIn("Invalid", plan.State)

    def test_a_model_with_other_patches_invalidates_the_list(self):
        model_obj, plan = self._plan("keycap")
        model_obj.SourceFile = sample_path("figure4")
        self.doc.recompute()
        self.assertIn("Invalid", plan.State)
        with self.assertRaises(Exception) as ctx:
            self.planobject.plan_of(plan)
        self.assertIn("layout", str(ctx.exception))

    def test_a_broken_list_makes_no_object(self):
        from tsplcam.workbench.modelobject import model_of
        model_obj = self.importer.import_file(sample_path("keycap"), self.doc)
        plist = self.planobject.plan_model(model_of(model_obj))
        plist.steps[1].patch = plist.steps[0].patch            # a patch twice
        n = len(self.doc.Objects)
        self.assertIsNone(self.planobject.make_processing_list(model_obj, plist))
        self.assertEqual(len(self.doc.Objects), n)
        self.assertIn("step 2", self.messages.recorded[-1][1])


if __name__ == "__main__":
    unittest.main()
