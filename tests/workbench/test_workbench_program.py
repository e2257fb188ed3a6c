"""The program document object under FreeCAD (no GUI): tool axes and G-code for a tool
path, kept in the .FCStd, recomputed only when an input changes, refused without a
matching tool.

Reference: the command line run as its own process on the same sample and settings
(`python3 -m tsplcam path ... --orientation smooth --machine ... --gcode`): the document's
program must be the same bytes, with the same machining-time estimate."""
import os
import re
import shutil
import subprocess
import tempfile
import unittest

import numpy as np

from tsplcam.model.samples import sample_path
from conftest import REPO_DIR as ROOT, needs_freecad, require_freecad

MACHINE = "mikron_ucp600_heidenhain"


@needs_freecad
class ProgramObject(unittest.TestCase):
    def setUp(self):
        self.FreeCAD = require_freecad()
        from tsplcam.workbench import importer, messages, pathobject, planobject, programobject
        if not pathobject.toolpath_available():
            raise unittest.SkipTest("the path generator (tsplcam.toolpath.zigzag_path) is absent")
        self.importer, self.messages = importer, messages
        self.pathobject, self.planobject, self.programobject = pathobject, planobject, programobject
        self._dialogs = messages.show_dialogs
        messages.show_dialogs = False
        self.tmp = tempfile.mkdtemp(prefix="tsplcam-programtest-")
        self.docs_before = set(self.FreeCAD.listDocuments())
        self.doc = self.FreeCAD.newDocument("TsplcamProgramTest")
        model_obj = self.importer.import_file(sample_path("keycap"), self.doc)
        plan = self.planobject.make_processing_list(model_obj)
        self.path_obj = self.pathobject.make_tool_path(plan, scallop=0.05)
        self.assertIsNotNone(self.path_obj, self.messages.recorded[-1:])

    def tearDown(self):
        for name in set(self.FreeCAD.listDocuments()) - self.docs_before:
            self.FreeCAD.closeDocument(name)
        self.messages.show_dialogs = self._dialogs
        shutil.rmtree(self.tmp, ignore_errors=True)

    def test_program_equals_the_command_line_and_survives_reload(self):
        po = self.programobject
        obj = po.make_program(self.path_obj)
        self.assertIsNotNone(obj, self.messages.recorded[-1:])
        self.assertEqual((obj.Tool, obj.Orientation, obj.Machine), ("ball1_keycap", "smooth", MACHINE))
        self.assertEqual(obj.Collisions, 0)
        self.assertGreater(obj.SmallestClearance.Value, 0.0)
        text = po.program_text(obj)
        self.assertEqual(obj.ProgramName, "keycap.h")

        # the same job through the command line, as its own process
        out = os.path.join(self.tmp, "keycap.h")
        run = subprocess.run(["/usr/bin/python3", "-m", "tsplcam", "path", "keycap", "--tool-radius", "0.5",
                              "--scallop", "0.05", "--tool", "ball1_keycap", "--orientation", "smooth",
                              "--machine", MACHINE, "--gcode", out],
                             cwd=ROOT, capture_output=True, text=True, timeout=600)
        self.assertEqual(run.returncode, 0, run.stderr)
        with open(out, encoding="ascii") as f:
            self.assertEqual(text, f.read())
        self.assertEqual(re.search(r"machining time (\d+:\d\d:\d\d)", run.stdout).group(1), obj.MachiningTime)
        blocks = int(re.search(r"posted (\d+) blocks", run.stdout).group(1))
        self.assertEqual(obj.Blocks, blocks)
        tilt, rot = map(float, re.search(r"rotary travel ([\d.]+) deg \w, ([\d.]+) deg \w", run.stdout).groups())
        self.assertAlmostEqual(obj.RotaryTravel, tilt + rot, delta=0.1)
        self.assertGreater(obj.RotaryTravel, 360.0)               # a float: no angle range clips it

        # the main job with the same settings: the same program, through the same builder
        # (without the measurements and the HTML report, which do not touch the program)
        from tsplcam.job import run_job
        settings = obj.Proxy.settings(obj)
        self.assertEqual((settings.tool, settings.tool_radius, settings.scallop), ("ball1_keycap", 0.5, 0.05))
        settings.model, settings.out = "keycap", os.path.join(self.tmp, "job")
        settings.verify, settings.html_report = False, False
        run_job(settings, log=lambda *a: None, progress=lambda stage, done, total: None)
        with open(os.path.join(self.tmp, "job", obj.ProgramName), encoding="ascii") as f:
            self.assertEqual(text, f.read())

        # the stored axes are unit vectors on the tool side of the surface
        tp = obj.Proxy.oriented_path(obj)
        np.testing.assert_allclose(np.linalg.norm(tp.axis, axis=1), 1.0, atol=1e-12)
        self.assertTrue(np.all(np.einsum("ij,ij->i", tp.axis, tp.normal) > 0))
        steps = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", tp.axis[1:], tp.axis[:-1]), -1, 1)))
        self.assertAlmostEqual(obj.LargestAxisStep.Value, steps.max(), places=9)

        exported = po.export_program(obj, os.path.join(self.tmp, "out.h"))
        with open(exported, "rb") as f:
            self.assertEqual(f.read(), text.encode("ascii"))

        # kept inside the document: reloaded without recomputing, recomputed on a change
        path = os.path.join(self.tmp, "program.FCStd")
        self.doc.saveAs(path)
        self.FreeCAD.closeDocument(self.doc.Name)
        doc = self.FreeCAD.openDocument(path)
        again = [o for o in doc.Objects if po.is_program_object(o)][0]
        self.assertEqual(po.program_text(again), text)
        calls = []
        original = again.Proxy.compute
        again.Proxy.compute = lambda o: calls.append(1) or original(o)
        again.touch()
        doc.recompute()
        self.assertEqual(calls, [])
        again.Machine = "linuxcnc_xyzac_trt"
        doc.recompute()
        self.assertEqual(calls, [1])
        self.assertEqual(again.ProgramName, "keycap.ngc")
        self.assertIn("G93", po.program_text(again))          # LinuxCNC inverse-time feed

    def test_a_tool_of_another_radius_is_refused(self):
        po = self.programobject
        before = len(self.doc.Objects)
        self.assertIsNone(po.make_program(self.path_obj, tool="ball5_impeller"))
        title, text, is_error = self.messages.recorded[-1]
        self.assertTrue(is_error)
        self.assertIn("radius", text)
        self.assertEqual(len(self.doc.Objects), before)
        self.assertEqual(po.tool_for_radius(0.5), "ball1_keycap")
        self.assertIsNone(po.tool_for_radius(0.123))

    def test_stock_is_part_of_the_collision_checks(self):
        """The mold block as a Mesh object gives the same program as the sample's own block;
        a lid over the cavity leaves no collision-free axis: an error naming the point and
        patch, and no object."""
        import Mesh
        import Part
        from tsplcam.model import samples
        po = self.programobject
        model_obj = self.importer.import_file(sample_path("keycap_mold"), self.doc)
        plan = self.planobject.make_processing_list(model_obj)
        path_obj = self.pathobject.make_tool_path(plan, scallop=0.1)
        self.assertIsNotNone(path_obj, self.messages.recorded[-1:])
        own = po.make_program(path_obj)                    # the sample brings its block
        self.assertIsNotNone(own, self.messages.recorded[-1:])
        V, T = samples.keycap_mold_stock()
        block = self.doc.addObject("Mesh::Feature", "Block")
        block.Mesh = Mesh.Mesh([[list(V[i]) for i in tri] for tri in T])
        linked = po.make_program(path_obj, stock=block)
        self.assertIsNotNone(linked, self.messages.recorded[-1:])
        self.assertIs(linked.Stock, block)
        self.assertEqual(po.program_text(linked), po.program_text(own))
        np.testing.assert_array_equal(po.triangles_of(block)[1].shape, T.shape)

        top = V[:, 2].max()
        lid = self.doc.addObject("Part::Feature", "Lid")
        lid.Shape = Part.makeBox(40, 40, 2, self.FreeCAD.Vector(-20, -20, top + 3))
        before = len(self.doc.Objects)
        self.assertIsNone(po.make_program(path_obj, stock=lid))
        title, text, is_error = self.messages.recorded[-1]
        self.assertTrue(is_error)
        self.assertIn("patch", text)
        self.assertIn("collision-free", text)
        self.assertEqual(len(self.doc.Objects), before)
