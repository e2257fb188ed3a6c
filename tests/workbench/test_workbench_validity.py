"""Document objects under freecadcmd: a program is valid only while every input recomputed;
feeds in mm/min end to end; the machine's limits refuse a feed; defaults from the preferences;
older documents' speed-typed feeds migrate; a model's boundary extraordinary points are
counted apart; the CAM job's moves read back through FreeCAD's own LinuxCNC post; and
``job --fcstd`` writes a document that reopens with every object valid.

References: FreeCAD's own object State (Invalid / Touched), the program object's stored text
(exported bytes), the posted F words read with the dialect's reader, FreeCAD's linuxcnc_post
output parsed as text against the program's motion blocks, the command line's own program
file for the --fcstd document.
"""
import os
import re
import shutil
import subprocess
import tempfile
import unittest

import numpy as np

from tsplcam.model.samples import sample_path
from conftest import REPO_DIR, needs_freecad, require_freecad

MACHINE = "mikron_ucp600_heidenhain"


@needs_freecad
class _Doc(unittest.TestCase):
    def setUp(self):
        self.FreeCAD = require_freecad()
        from tsplcam.workbench import (camjob, importer, messages, pathobject, planobject, prefs, programobject,
                                       runner, validity)
        self.camjob, self.importer, self.messages = camjob, importer, messages
        self.pathobject, self.planobject, self.programobject = pathobject, planobject, programobject
        self.prefs, self.runner, self.validity = prefs, runner, validity
        self._dialogs = messages.show_dialogs
        messages.show_dialogs = False
        prefs.clear()
        self.tmp = tempfile.mkdtemp(prefix="tsplcam-validity-")
        self.docs_before = set(self.FreeCAD.listDocuments())
        self.doc = self.FreeCAD.newDocument("TsplcamValidity")

    def tearDown(self):
        self.prefs.clear()
        for name in set(self.FreeCAD.listDocuments()) - self.docs_before:
            self.FreeCAD.closeDocument(name)
        self.messages.show_dialogs = self._dialogs
        shutil.rmtree(self.tmp, ignore_errors=True)

    def chain(self, sample="keycap", scallop=0.2, **program):
        model_obj = self.importer.import_file(sample_path(sample), self.doc)
        plan = self.planobject.make_processing_list(model_obj)
        path = self.pathobject.make_tool_path(plan, scallop=scallop)
        self.assertIsNotNone(path, self.messages.recorded[-1:])
        prog = self.programobject.make_program(path, **program)
        self.assertIsNotNone(prog, self.messages.recorded[-1:])
        return model_obj, plan, path, prog


class Validity(_Doc):
    def test_a_failed_input_fails_the_program_and_export_refuses(self):
        po, v = self.programobject, self.validity
        model_obj, plan, path, prog = self.chain(orientation="normal")
        text = po.program_text(prog)
        out = os.path.join(self.tmp, "keycap.h")
        # changed and not recomputed: refused already
        path.ToolRadius = 60.0
        with self.assertRaises(Exception) as ctx:
            po.export_program(prog, out)
        self.assertIn("not recomputed", str(ctx.exception))
        self.doc.recompute()
        self.assertIn("Invalid", path.State)
        self.assertIn("Invalid", prog.State)                  # FreeCAD's own state, not just ours
        self.assertIn(path.Label, prog.getStatusString())
        self.assertIn("concave radius", prog.getStatusString())
        with self.assertRaises(Exception) as ctx:
            po.export_program(prog, out)
        said = str(ctx.exception)
        self.assertIn("not exported", said)
        self.assertRegex(said, r"patch \d+: concave radius .* at \(u, v\) = \(")
        self.assertFalse(os.path.exists(out))
        # the report the person sees names the place too (a box in the GUI)
        self.assertTrue(any("concave radius" in t and err for _, t, err in self.messages.recorded[-4:]))
        path.ToolRadius = 0.5
        self.doc.recompute()
        self.assertFalse(v.failed(prog), prog.State)
        self.assertIsNone(v.problem(prog))
        po.export_program(prog, out)
        with open(out, encoding="ascii") as f:
            self.assertEqual(f.read(), text)

    def test_a_failed_list_fails_path_and_program(self):
        model_obj, plan, path, prog = self.chain(orientation="normal")
        plan.ListText = plan.ListText.replace('"patch": 0', '"patch": 7', 1)
        self.doc.recompute()
        for o in (plan, path, prog):
            self.assertTrue(self.validity.failed(o), (o.Label, o.State))
        self.assertIn("unknown patch 7", self.validity.problem(prog))


class Feeds(_Doc):
    def test_feed_in_mm_per_min_from_property_to_program(self):
        from tsplcam.post.dialects import heidenhain
        model_obj, plan, path, prog = self.chain(orientation="normal")
        self.assertEqual(path.getTypeIdOfProperty("Feed"), "App::PropertyFloat")
        self.assertEqual(path.Feed, 1000.0)
        path.Feed = 1200.0                                     # typed as mm/min, taken as mm/min
        self.doc.recompute()
        self.assertFalse(self.validity.failed(prog))
        feeds = {round(m.feed, 3) for m in heidenhain.read(self.programobject.program_text(prog))
                 if m.feed is not None and not m.rapid}
        self.assertIn(1200.0, feeds)
        self.assertLessEqual(max(feeds), 1200.0)
        # above the machine's largest feed: the program refuses, naming the property and the limit
        path.Feed = 72000.0
        self.doc.recompute()
        self.assertFalse(self.validity.failed(path))
        self.assertTrue(self.validity.failed(prog))
        self.assertIn("Feed: 72000 mm/min is above the largest feed of machine", prog.getStatusString())
        self.assertIn("20000 mm/min", prog.getStatusString())
        prog.SpindleSpeed = 42000.0
        path.Feed = 1000.0
        self.doc.recompute()
        self.assertIn("SpindleSpeed: 42000 rpm is outside the spindle range", prog.getStatusString())

    def test_an_older_document_feed_becomes_mm_per_min(self):
        from tsplcam.workbench.pathobject import TsplcamToolPath
        obj = self.doc.addObject("App::FeaturePython", "Old")
        obj.addProperty("App::PropertySpeed", "Feed", "Tool path", "")
        obj.Feed = "1000 mm/min"                               # what older documents kept (16.67 mm/s)
        TsplcamToolPath.ensure_properties(obj)
        self.assertEqual(obj.getTypeIdOfProperty("Feed"), "App::PropertyFloat")
        self.assertAlmostEqual(obj.Feed, 1000.0, places=6)


class Defaults(_Doc):
    def test_new_objects_take_the_preferences_defaults(self):
        self.prefs.store({"scallop": 0.2, "feed": 1500.0, "holder_clearance": 0.4, "orientation": "normal"})
        self.assertEqual(self.prefs.stored()["scallop"], 0.2)
        model_obj = self.importer.import_file(sample_path("keycap"), self.doc)
        plan = self.planobject.make_processing_list(model_obj)
        path = self.pathobject.make_tool_path(plan)
        self.assertAlmostEqual(path.Scallop.Value, 0.2)
        self.assertEqual(path.Feed, 1500.0)
        prog = self.programobject.make_program(path)
        self.assertEqual(prog.Orientation, "normal")
        self.assertAlmostEqual(prog.HolderClearance.Value, 0.4)
        # a stored value the engine refuses is reported and left out
        self.prefs.store({"scallop": 0.2})
        self.FreeCAD.ParamGet(self.prefs.PARAMS).SetString("feed", "-5")
        self.assertEqual(self.prefs.defaults()["feed"], 1000.0)
        self.assertIn("feed", self.messages.recorded[-1][1])
        with self.assertRaises(Exception):
            self.prefs.store({"scallop": -1.0})

    def test_progress_reaches_the_end_of_every_stage(self):
        model_obj, plan, path, prog = self.chain(orientation="normal")
        stages = {}
        for stage, done, total in self.runner.last["progress"]:
            stages[stage] = (done, total)
        self.assertEqual(stages["program"][0], stages["program"][1])
        self.assertEqual(stages["collisions"][0], stages["collisions"][1])


class ModelInfo(_Doc):
    def test_boundary_extraordinary_points_are_counted_apart(self):
        from tsplcam.workbench.modelobject import describe
        import math
        path = os.path.join(self.tmp, "fan.obj")
        with open(path, "w") as f:
            for k in range(7):
                f.write("v %g %g %g\n" % (2 * math.cos(math.pi * k / 6), 2 * math.sin(math.pi * k / 6), 0.1 * k))
            for k in range(7):
                f.write("v %g %g %g\n" % (4 * math.cos(math.pi * k / 6), 4 * math.sin(math.pi * k / 6), 0.2 * k))
            f.write("v 0 0 0\n")
            for a in (0, 2, 4):
                f.write("f 15 %d %d %d\n" % (1 + a, 2 + a, 3 + a))
            for k in range(6):
                f.write("f %d %d %d %d\n" % (1 + k, 8 + k, 9 + k, 2 + k))
        obj = self.importer.import_file(path, self.doc)
        self.assertIsNotNone(obj, self.messages.recorded[-1:])
        model = obj.Proxy.model(obj)
        inside = sum(not e.boundary for e in model.extraordinary)
        boundary = sum(bool(e.boundary) for e in model.extraordinary)
        self.assertGreater(boundary, 0)
        self.assertEqual((obj.ExtraordinaryPoints, obj.BoundaryExtraordinary), (inside, boundary))
        vals = obj.Valences.split()
        self.assertEqual(sum(v.endswith("b") for v in vals), boundary)
        self.assertTrue(all(v.endswith("b") for v in vals[inside:]))       # inside first
        text = describe(obj)
        self.assertIn(f"{inside} extraordinary points inside and {boundary} on the boundary", text)
        self.assertIn(f"{obj.Patches} patches", text)
        from tsplcam.workbench.modelobject import plural
        self.assertEqual(plural(1, "patch"), "1 patch")
        self.assertEqual(plural(2, "patch"), "2 patches")


class CamJob(_Doc):
    def test_the_cam_job_holds_the_moves_and_freecads_post_reads_them(self):
        if not self.camjob.cam_available():
            self.skipTest("FreeCAD's CAM (Path) workbench is absent")
        model_obj, plan, path, prog = self.chain(orientation="normal")
        path.Feed = 1200.0
        self.doc.recompute()
        job = self.camjob.make_cam_job(prog)
        self.assertIsNotNone(job, self.messages.recorded[-1:])
        op = job.Operations.Group[0]
        self.assertTrue(self.camjob.is_cam_operation(op))
        tc = op.ToolController
        self.assertIn(tc, job.Tools.Group)
        self.assertEqual((tc.ToolNumber, tc.SpindleSpeed, tc.SpindleDir), (prog.ToolNumber, prog.SpindleUsed,
                                                                            "Forward"))
        self.assertAlmostEqual(tc.Tool.Diameter.Value, 1.0)
        self.assertAlmostEqual(tc.HorizFeed.getValueAs("mm/min").Value, 1200.0, places=6)
        self.assertEqual(list(job.Fixtures), ["G54"])
        self.assertEqual(op.CoolantMode, "Flood")
        motion = self.programobject.motion_of(prog)
        self.assertEqual(len(op.Path.Commands), len(motion["tip"]))
        # FreeCAD's LinuxCNC post writes our moves back in mm and mm/min
        from PathScripts.post import linuxcnc_post
        out = os.path.join(self.tmp, "cam.ngc")
        linuxcnc_post.export([tc, op], out, "--no-show-editor")
        with open(out) as f:
            lines = [ln for ln in f.read().splitlines() if ln.startswith(("G0 ", "G1 "))]
        self.assertEqual(len(lines), len(motion["tip"]))
        names = motion["axis_names"]
        rows = []
        for ln in lines:
            w = dict((m.group(1), float(m.group(2))) for m in re.finditer(r"([XYZABCF])(-?[\d.]+)", ln))
            rows.append(w)
        tip = np.array([[r.get(a, np.nan) for a in "XYZ"] for r in rows])
        np.testing.assert_allclose(tip, motion["tip"], atol=1e-3)         # the post writes 3 decimals
        ang = np.array([[r.get(names[3], np.nan), r.get(names[4], np.nan)] for r in rows])
        np.testing.assert_allclose(ang, motion["joints"][:, 3:], atol=1e-3)
        feeds = [r["F"] for r, ln in zip(rows, lines) if "F" in r]
        self.assertIn(1200.0, feeds)                                       # mm/s inside, mm/min out
        # the operation fails with its program
        path.ToolRadius = 60.0
        self.doc.recompute()
        self.assertTrue(self.validity.failed(op), op.State)
        path.ToolRadius = 0.5
        self.doc.recompute()
        self.assertFalse(self.validity.failed(op), op.State)


class FcstdFromTheCommandLine(_Doc):
    def test_job_writes_a_document_that_reopens_valid(self):
        out = os.path.join(self.tmp, "job")
        fcstd = os.path.join(self.tmp, "job", "mold.FCStd")
        run = subprocess.run(["/usr/bin/python3", "-m", "tsplcam", "job", "--model", "keycap_mold", "--scallop",
                              "0.2", "--no-verify", "--no-html-report", "--out", out, "--fcstd", fcstd],
                             cwd=REPO_DIR, capture_output=True, text=True, timeout=900)
        self.assertEqual(run.returncode, 0, run.stderr + run.stdout[-2000:])
        self.assertIn("FreeCAD document", run.stdout)
        doc = self.FreeCAD.openDocument(fcstd)
        from tsplcam.workbench.validity import is_tsplcam
        objs = {o.Proxy.Type: o for o in doc.Objects if is_tsplcam(o)}
        self.assertEqual(set(objs), {"TsplcamModel", "TsplcamProcessingList", "TsplcamToolPath", "TsplcamProgram",
                                     "TsplcamCamOperation"})
        calls = []
        for o in (objs["TsplcamToolPath"], objs["TsplcamProgram"]):
            original = o.Proxy.compute
            o.Proxy.compute = lambda obj, original=original: calls.append(obj.Label) or original(obj)
        for o in doc.Objects:
            o.touch()
        doc.recompute()
        self.assertEqual(calls, [])                          # nothing computed again: the stored results fit
        for o in doc.Objects:
            self.assertFalse(self.validity.failed(o), (o.Label, o.State))
        prog = objs["TsplcamProgram"]
        self.assertIsNone(self.validity.problem(prog))
        with open(os.path.join(out, prog.ProgramName), encoding="ascii") as f:
            self.assertEqual(self.programobject.program_text(prog), f.read())
        with open(os.path.join(out, "processing-list.json")) as f:
            from tsplcam.plan.listfile import loads
            from tsplcam.layout.layout import Layout
            model = objs["TsplcamModel"].Proxy.model(objs["TsplcamModel"])
            self.assertEqual(self.planobject.plan_of(objs["TsplcamProcessingList"]).order,
                             loads(f.read(), Layout.from_model(model)).order)
        self.assertEqual(len(objs["TsplcamCamOperation"].Path.Commands), prog.Blocks)

    def test_without_freecadcmd_refused_before_the_work(self):
        env = dict(os.environ, TSPLCAM_FREECADCMD=os.path.join(self.tmp, "no-such-freecadcmd"))
        run = subprocess.run(["/usr/bin/python3", "-m", "tsplcam", "job", "--out", os.path.join(self.tmp, "j"),
                              "--fcstd", os.path.join(self.tmp, "j.FCStd")], cwd=REPO_DIR, env=env,
                             capture_output=True, text=True, timeout=120)
        self.assertEqual(run.returncode, 2, run.stderr)
        self.assertIn("--fcstd: needs FreeCAD's freecadcmd", run.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.tmp, "j")))


if __name__ == "__main__":
    unittest.main()
