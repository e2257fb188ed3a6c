"""The workflow a CAM programmer follows, driven through the real commands and task panels in
the FreeCAD GUI: sample in, processing list edited in its panel (two steps swapped by
dragging, validated, solved, a retraction ticked), tool path and program with progress in the
status bar, one run cancelled, an input broken so that export refuses, fixed, exported, a CAM
job made, the document saved and reopened.

References: the processing-list checker's verdict (the red row is the step it names), the
patch the 3D view outlines against the row's step (projected patch centres), pixel hues of
the palette and of the tool, the exported bytes against the program object's own text, the
CAM operation's moves against the program's motion blocks (feeds in mm/s = mm/min / 60),
and the reloaded document against the saved one. Pictures go to build/artifacts.
"""
import os
import shutil
import tempfile
import time
import unittest

import numpy as np

import FreeCAD
import FreeCADGui
from PySide import QtCore, QtGui

from conftest import artifact_path
from tsplcam.model.samples import sample_path
from tsplcam.workbench import (camjob, display, importer, messages, pathobject, planobject, prefs,
                               programobject, runner, validity, viewprogram)
from tsplcam.workbench.testsupport import colour_pixel_counts, image_rgb, view_from

W, H = 800, 600


def render(name, azimuth=-60, elevation=50, at_view_size=False):
    """The 3D view from azimuth/elevation as a PNG; ``at_view_size``: pixels are the view's
    own, so projected points (getPointOnScreen) fall on them."""
    view_from(azimuth, elevation)
    FreeCADGui.updateGui()
    path = artifact_path(name)
    v = FreeCADGui.ActiveDocument.ActiveView
    w, h = v.getSize() if at_view_size else (W, H)
    v.saveImage(path, w, h, "White")
    return path


def grab_panel(name):
    """The task dock as a picture (what the person sees of the panel)."""
    FreeCADGui.updateGui()
    mw = FreeCADGui.getMainWindow()
    dock = next(d for d in mw.findChildren(QtGui.QDockWidget) if d.objectName() in ("Combo View", "Tasks")
                and d.isVisible())
    path = artifact_path(name)
    dock.grab().save(path)
    return path


def grab_tree(name):
    """The document tree (Model tab of the Combo View), expanded, as a picture."""
    mw = FreeCADGui.getMainWindow()
    tree = next(t for t in mw.findChildren(QtGui.QTreeWidget))
    tree.expandAll()
    tree.resize(max(tree.width(), 480), 520)
    FreeCADGui.updateGui()
    path = artifact_path(name)
    tree.grab().save(path)
    return path


def pixels_of(path, rgb, tol=0.06):
    img = image_rgb(path)
    return int((np.abs(img - np.asarray(rgb, float)).max(axis=2) < tol).sum())


def screen_xy(v, p):
    x, y = v.getPointOnScreen(FreeCAD.Vector(*[float(c) for c in p]))
    w, h = v.getSize()
    return x, h - 1 - y


def later(ms, fn):
    QtCore.QTimer.singleShot(int(ms), fn)


class CamWorkflow(unittest.TestCase):
    def setUp(self):
        self._dialogs = messages.show_dialogs
        messages.show_dialogs = False
        self.docs_before = set(FreeCAD.listDocuments())
        self.tmp = tempfile.mkdtemp(prefix="tsplcam-workflow-")
        prefs.clear()
        FreeCADGui.activateWorkbench("TsplcamWorkbench")

    def tearDown(self):
        prefs.clear()
        if FreeCADGui.Control.activeDialog():
            FreeCADGui.Control.closeDialog()
        for name in set(FreeCAD.listDocuments()) - self.docs_before:
            FreeCAD.closeDocument(name)
        messages.show_dialogs = self._dialogs
        shutil.rmtree(self.tmp, ignore_errors=True)
        FreeCADGui.updateGui()

    def run_command(self, name, *selection):
        FreeCADGui.Selection.clearSelection()
        for o in selection:
            FreeCADGui.Selection.addSelection(o)
        FreeCADGui.runCommand(name)
        FreeCADGui.updateGui()

    def test_mold_from_list_to_exported_program_and_cam_job(self):
        t_start = time.perf_counter()
        model_obj = importer.open(sample_path("keycap_mold"))
        doc = model_obj.Document
        self.run_command("Tsplcam_Plan", model_obj)
        plan = next(o for o in doc.Objects if planobject.is_plan_object(o))
        self.assertEqual(plan.Retractions, 0)

        # -- the processing list panel: drag step 3 onto row 2, validate --------------------------------
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.ActiveDocument.setEdit(plan.Name, 0)
        FreeCADGui.updateGui()
        from tsplcam.workbench.planpanel import ProcessingListPanel
        panel = ProcessingListPanel.active
        self.assertIsNotNone(panel)
        self.assertEqual(panel.table.horizontalHeaderItem(3).text(), "Crossfeed")
        before = [s.patch for s in panel.plist.steps]
        panel.table.verticalHeader().moveSection(2, 1)          # a drag of the header
        after = [s.patch for s in panel.plist.steps]
        self.assertEqual(after, [before[0], before[2], before[1]] + before[3:])
        self.assertEqual(panel.table.verticalHeader().visualIndex(1), 1)   # the header back in order
        panel.buttons["validate"].click()
        self.assertFalse(panel.valid)
        self.assertEqual(panel.bad_row, 1, panel.status.text())
        self.assertIn("step 2", panel.status.text())
        self.assertIn("retract", panel.status.text())
        self.assertEqual(panel.table.item(1, 0).toolTip(), panel.bad_text)
        panel.table.clearSelection()
        shot = grab_panel("workflow_list_panel_invalid.png")
        self.assertGreater(pixels_of(shot, (1.0, 200 / 255, 200 / 255)), 300)      # the red row
        # the row's step is the one the 3D view outlines: its patch, start and finish corners
        panel.table.selectRow(1)
        vp = plan.ViewObject.Proxy
        self.assertIs(vp.step, panel.plist.steps[1])
        model_obj.ViewObject.ShowPatchNumbers = False
        top = render("workflow_list_selected_step.png", 0, 90, at_view_size=True)
        v = FreeCADGui.ActiveDocument.ActiveView
        yellow = image_rgb(top)
        ys, xs = np.nonzero((yellow[:, :, 0] > 0.9) & (yellow[:, :, 1] > 0.75) & (yellow[:, :, 2] < 0.2))
        self.assertGreater(len(xs), 200)
        model = planobject.model_of(plan.Model)
        centres = display.patch_centres(model)
        d = [np.hypot(*(np.array(screen_xy(v, c)) - [xs.mean(), ys.mean()])) for c in centres]
        self.assertEqual(int(np.argmin(d)), panel.plist.steps[1].patch, d)
        # solve keeps the dragged position; a retraction ticked before step 4 is allowed
        panel.buttons["solve"].click()
        self.assertTrue(panel.valid, panel.status.text())
        self.assertEqual(panel.plist.steps[1].patch, after[1])          # the dragged step's pinned place
        panel.table.cellWidget(3, 4).setChecked(True)
        self.assertTrue(panel.valid, panel.status.text())
        self.assertEqual(panel.table.item(3, 5).text(), "RETRACT")
        self.assertTrue(panel.accept())
        self.assertEqual(plan.Retractions, 1)
        self.assertEqual(plan.Order.split()[1], str(after[1]))

        # -- tool path and program through the commands, defaults from the preferences ----------------
        prefs.store({"scallop": 0.1, "feed": 1200.0})
        self.run_command("Tsplcam_ToolPath", plan)
        path = next(o for o in doc.Objects if pathobject.is_path_object(o))
        self.assertAlmostEqual(path.Scallop.Value, 0.1)
        self.assertEqual(path.getTypeIdOfProperty("Feed"), "App::PropertyFloat")
        self.assertEqual(path.Feed, 1200.0)                          # mm/min, shown and taken as such
        self.assertEqual(path.Retractions, 1)
        self.assertEqual(runner.last["mode"], "child")
        self.assertEqual(runner.last["progress"][-1], ("path", 5, 5))
        self.run_command("Tsplcam_Program", path)
        prog = next(o for o in doc.Objects if programobject.is_program_object(o))
        stages = {p[0] for p in runner.last["progress"]}
        self.assertTrue({"tool axes", "checking axes", "program"} <= stages, stages)
        self.assertLess(runner.last["max_gap"], 1.0)            # the event loop kept running
        gaps = {"program run": runner.last["seconds"], "longest event-loop pause": runner.last["max_gap"]}
        self.assertIn("F1200", programobject.program_text(prog))
        self.assertFalse(validity.failed(prog))

        # -- the preview: path by patch, links apart, tool axes, stock, tool and holder -----------------
        for o in (plan, path):
            o.ViewObject.Visibility = False
        model_obj.ViewObject.Visibility = False
        prog.ViewObject.ColourBy = "Patch"
        prog.ViewObject.Shafts = 2
        FreeCADGui.Selection.clearSelection()
        shot = render("workflow_program_by_patch.png", -60, 55)
        counts = colour_pixel_counts(shot, display.PALETTE[:5], hue_tolerance=6, min_saturation=0.45)
        self.assertTrue(all(n > 150 for n in counts), counts)
        links = colour_pixel_counts(shot, [viewprogram.LINK_COLOUR], hue_tolerance=5, min_saturation=0.8)[0]
        self.assertGreater(links, 100)
        group = prog.ViewObject.Proxy.group
        names = [group.getChild(i).getName().getString() for i in range(group.getNumChildren())]
        self.assertIn("tsplcam_stock", names)                    # the sample's implicit mold block
        model_obj.ViewObject.Visibility = True
        prog.ViewObject.ColourBy = "Tilt"
        prog.ViewObject.Shafts = 400
        FreeCADGui.ActiveDocument.setEdit(prog.Name, 0)
        FreeCADGui.updateGui()
        from tsplcam.workbench.settingspanel import SettingsPanel
        sp = SettingsPanel.active
        self.assertIsNotNone(sp)
        tp = prog.Proxy.oriented_path(prog)
        k = int(np.argmax(np.degrees(np.arccos(np.clip(tp.axis[:, 2], -1, 1)))))    # the most tilted pose
        sp.show_tool.setChecked(True)
        sp.slider.setValue(k)
        self.assertEqual(prog.ViewObject.ToolAt, k)
        self.assertIn(f"patch {int(tp.patch[k])}", sp.where.text())
        render("workflow_program_tool.png", -60, 55)                   # the camera fitted with the tool
        v = FreeCADGui.ActiveDocument.ActiveView
        w, h = v.getSize()
        with_tool = artifact_path("workflow_program_tool_view.png")
        v.saveImage(with_tool, w, h, "White")
        sp.show_tool.setChecked(False)
        FreeCADGui.updateGui()
        no_tool = artifact_path("workflow_program_no_tool.png")
        v.saveImage(no_tool, w, h, "White")
        changed = np.abs(image_rgb(with_tool) - image_rgb(no_tool)).max(axis=2) > 0.1
        ys, xs = np.nonzero(changed)
        self.assertGreater(len(xs), 2000)                              # the tool and its holder drawn
        tool = prog.Proxy.settings(prog)
        from tsplcam.program import load_tool
        tool = load_tool(tool)
        along = tp.center[k] + np.linspace(0.0, tool.length, 20)[:, None] * tp.axis[k]
        on_screen = np.array([screen_xy(v, p) for p in along])
        # the changed pixels lie along the projected tool axis (within the holder's radius)
        d = np.min(np.hypot(xs[:, None] - on_screen[None, :, 0], ys[:, None] - on_screen[None, :, 1]), axis=1)
        self.assertGreater(float(np.mean(d < 0.5 * (on_screen[:, 1].max() - on_screen[:, 1].min()) + 40)), 0.9)
        sp.show_tool.setChecked(True)
        grab_panel("workflow_program_panel.png")
        model_obj.ViewObject.ShowPatchNumbers = False
        prog.ViewObject.ColourBy = "Patch"
        tilt = np.degrees(np.arccos(np.clip(tp.axis[:, 2], -1, 1)))
        k2 = int(np.argmin(np.abs(tilt - 25.0)))                      # a pose on a wall, seen from its side
        sp.slider.setValue(k2)
        side = np.degrees(np.arctan2(tp.axis[k2, 1], tp.axis[k2, 0])) + 90.0
        render("workflow_program_preview.png", side, 20)            # the picture of the docs
        prog.ViewObject.ColourBy = "Tilt"

        # -- cancel one run: it stops within a second and the program is not valid meanwhile -------------
        sp.controls.controls["smoothing_length"][1].setValue(7.0)
        # cancelled once the child is searching tool axes (a fixed 1.2 s came after the end of
        # the whole run on a fast machine: the child took less)
        seen, tries = [], [0]

        def cancel_mid_run():
            run = runner.active
            tries[0] += 1
            if run is not None:
                seen.append(run)
                if any(p[0] == "tool axes" for p in run.progress):
                    run.cancel()
                    return
            elif seen or tries[0] > 1000:                # (the run is over: nothing to cancel)
                return
            later(10, cancel_mid_run)
        later(10, cancel_mid_run)
        t0 = time.perf_counter()
        self.assertFalse(sp.apply())
        self.assertLess(time.perf_counter() - t0, 8.0)
        self.assertIn("stopped on request", sp.status.text())
        self.assertLess(runner.last["cancel_latency"], 1.0)
        gaps["cancel latency"] = runner.last["cancel_latency"]
        self.assertTrue(validity.failed(prog))
        with self.assertRaises(Exception) as ctx:
            programobject.export_program(prog, os.path.join(self.tmp, "cancelled.h"))
        self.assertIn("stopped on request", str(ctx.exception))
        sp.controls.controls["smoothing_length"][1].setValue(5.0)     # back: the stored program fits again
        self.assertTrue(sp.apply(), sp.status.text())
        self.assertFalse(validity.failed(prog))
        self.assertTrue(sp.accept())

        # -- break an input: the program turns invalid, export refuses naming the place ------------------
        text = programobject.program_text(prog)
        path.ToolRadius = 60.0
        doc.recompute()
        FreeCADGui.updateGui()
        self.assertTrue(validity.failed(path))
        self.assertTrue(validity.failed(prog), prog.State)
        self.assertIn("Invalid", prog.State)
        shown = [t for title, t, err in messages.recorded[-5:] if err]
        self.assertTrue(any("concave radius" in t and "(u, v)" in t and "patch" in t for t in shown), shown)
        self.assertTrue(prog.ViewObject.Proxy.drawn_valid is False)
        bad = render("workflow_program_invalid.png", -60, 55)
        self.assertGreater(pixels_of(bad, (0.75, 0.0, 0.0), 0.08), 200)     # the red NOT VALID label
        out = os.path.join(self.tmp, "keycap_mold.h")
        original = QtGui.QFileDialog.getSaveFileName
        QtGui.QFileDialog.getSaveFileName = staticmethod(lambda *a, **k: (out, ""))
        try:
            self.run_command("Tsplcam_SaveProgram", prog)          # Save G-code...
        finally:
            QtGui.QFileDialog.getSaveFileName = original
        title, said, is_error = messages.recorded[-1]
        self.assertTrue(is_error)
        self.assertIn("not exported", said)
        self.assertIn("concave radius", said)
        with self.assertRaises(Exception) as ctx:
            programobject.export_program(prog, out)
        self.assertIn("not exported", str(ctx.exception))
        self.assertIn("concave radius", str(ctx.exception))
        self.assertFalse(os.path.exists(out))

        # -- fix it: valid again, exported byte for byte ----------------------------------------------------
        path.ToolRadius = 0.5
        doc.recompute()
        self.assertFalse(validity.failed(prog), prog.State)
        self.assertIsNone(validity.problem(prog))
        programobject.export_program(prog, out)
        with open(out, encoding="ascii") as f:
            self.assertEqual(f.read(), text)

        # -- FreeCAD CAM: a job holding the moves, with tool controller and work offset -----------------------
        self.run_command("Tsplcam_CamJob", prog)
        op = next(o for o in doc.Objects if camjob.is_cam_operation(o))
        grab_tree("workflow_cam_job_tree.png")
        job = next(o for o in doc.Objects if hasattr(o, "Operations") and o.Operations is not None
                   and op in o.Operations.Group)
        motion = programobject.motion_of(prog)
        self.assertEqual(len(op.Path.Commands), len(motion["tip"]))
        self.assertEqual(op.ToolController.ToolNumber, prog.ToolNumber)
        self.assertEqual(op.ToolController.SpindleSpeed, prog.SpindleUsed)
        self.assertEqual(list(job.Fixtures), [prog.WorkOffset])
        first_cut = next(c for c in op.Path.Commands if c.Name == "G1" and "F" in c.Parameters)
        self.assertAlmostEqual(first_cut.Parameters["F"] * 60.0, 1200.0, delta=1e-6)

        # -- saved and reopened: the same list, path and program, every object valid --------------------------
        saved = os.path.join(self.tmp, "mold.FCStd")
        list_text, contact = plan.ListText, pathobject.path_of(path).contact.copy()
        doc.saveAs(saved)
        FreeCAD.closeDocument(doc.Name)
        FreeCADGui.updateGui()
        doc = FreeCAD.openDocument(saved)
        doc.recompute()
        FreeCADGui.updateGui()
        objs = {o.Proxy.Type: o for o in doc.Objects if validity.is_tsplcam(o)}
        self.assertEqual(objs["TsplcamProcessingList"].ListText, list_text)
        np.testing.assert_array_equal(pathobject.path_of(objs["TsplcamToolPath"]).contact, contact)
        self.assertEqual(programobject.program_text(objs["TsplcamProgram"]), text)
        for o in doc.Objects:
            self.assertFalse(validity.failed(o), (o.Label, o.State))
        self.assertIsNone(validity.problem(objs["TsplcamCamOperation"]))
        print(f"\n    workflow figures: {', '.join(f'{k} {v:.2f} s' for k, v in gaps.items())}; "
              f"test {time.perf_counter() - t_start:.1f} s", file=__import__('sys').__stdout__)



class PreferencesPage(unittest.TestCase):
    def setUp(self):
        self._dialogs = messages.show_dialogs
        messages.show_dialogs = False

    def tearDown(self):
        prefs.clear()
        messages.show_dialogs = self._dialogs

    def test_the_page_shows_and_stores_every_option_with_its_unit(self):
        from tsplcam.workbench.fields import PREFS_FIELDS as ALL_FIELDS
        from tsplcam.workbench.settingspanel import PreferencesPage as Page
        prefs.clear()
        page = Page()
        page.loadSettings()
        self.assertEqual(set(page.controls.controls), {f.name for f in ALL_FIELDS})
        spin = page.controls.controls["feed"][1]
        self.assertEqual(spin.suffix(), " mm/min")
        self.assertEqual(spin.value(), 1000.0)
        self.assertEqual(page.controls.controls["scallop"][1].suffix(), " mm")
        self.assertEqual(page.controls.controls["lead"][1].suffix(), " °")
        self.assertEqual(page.controls.controls["spindle"][1].suffix(), " rpm")
        spin.setValue(1500.0)
        page.controls.controls["point"][1].setText("1, 2, 3")
        page.saveSettings()
        self.assertEqual(prefs.stored(), {"feed": 1500.0, "point": (1.0, 2.0, 3.0)})
        again = Page()
        again.loadSettings()
        self.assertEqual(again.controls.value("feed"), 1500.0)
        self.assertEqual(again.controls.value("point"), (1.0, 2.0, 3.0))
        # text that is not three numbers is refused, naming the control; nothing is stored
        again.controls.controls["point"][1].setText("1, 2")
        again.saveSettings()
        self.assertIn("Point", messages.recorded[-1][1])
        self.assertEqual(prefs.stored()["point"], (1.0, 2.0, 3.0))


if __name__ == "__main__":
    unittest.main()
