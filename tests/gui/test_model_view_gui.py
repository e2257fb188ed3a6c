"""The model in the real FreeCAD GUI: import, screenshots, toggles, save and reload, bad files.

Pictures go to build/artifacts (conftest.artifact_path). Colour checks count
pixels by hue: shading under white light keeps a colour's hue, so every patch shows up
as pixels of its palette hue whatever the lighting (testsupport.colour_pixel_counts).
"""
import os
import shutil
import tempfile
import unittest

import numpy as np

import FreeCAD
import FreeCADGui

from tsplcam.layout.layout import Layout
from tsplcam.model.samples import sample_path
from conftest import artifact_path
from tsplcam.workbench import display, importer, messages
from tsplcam.workbench.modelobject import model_objects, model_of, patch_of_element
from tsplcam.workbench.testsupport import (colour_pixel_counts, errors_since, image_rgb,
                                           report_view_mark, view_from)

W, H = 800, 600
MIN_PIXELS = 400           # a patch "is in the picture" with at least this many of its pixels


def grid_points(model, n=7):
    g = np.linspace(0.0, 1.0, n)
    U, V = np.meshgrid(g, g)
    return np.concatenate([p.evaluate(U.ravel(), V.ravel()).P for p in model.patches])


def dark_pixels(path):
    return int((image_rgb(path).max(axis=2) < 0.25).sum())


def render(name, azimuth=None, elevation=None, view="Isometric"):
    v = FreeCADGui.ActiveDocument.ActiveView
    if azimuth is None:
        getattr(v, "view" + view)()
        v.fitAll()
    else:
        view_from(azimuth, elevation)
    FreeCADGui.updateGui()
    path = artifact_path(name)
    v.saveImage(path, W, H, "White")
    return path


class _GuiCase(unittest.TestCase):
    def setUp(self):
        self._dialogs = messages.show_dialogs
        messages.show_dialogs = False
        self.docs_before = set(FreeCAD.listDocuments())
        self.tmp = tempfile.mkdtemp(prefix="tsplcam-guitest-")

    def tearDown(self):
        for name in set(FreeCAD.listDocuments()) - self.docs_before:
            FreeCAD.closeDocument(name)
        messages.show_dialogs = self._dialogs
        shutil.rmtree(self.tmp, ignore_errors=True)
        FreeCADGui.updateGui()


class KeycapView(_GuiCase):
    def test_keycap_shows_five_patch_colours_and_its_extraordinary_points(self):
        obj = importer.open(sample_path("keycap"))
        self.assertIsNotNone(obj, messages.recorded[-1:])
        FreeCADGui.updateGui()
        # from above every patch is in sight: the sides slope outwards to the rim
        path = render("keycap_patches_top.png", view="Top")
        counts = colour_pixel_counts(path, display.PALETTE[:5])
        for k, n in enumerate(counts):
            self.assertGreaterEqual(n, MIN_PIXELS, f"patch {k} colour: {counts}")
        # the four extraordinary points: red markers
        red = colour_pixel_counts(path, [display.EP_COLOUR], min_saturation=0.7)[0]
        self.assertGreater(red, 4 * 20, red)
        # the people's view: isometric, three patches in sight
        iso = render("keycap_patches_iso.png")
        self.assertEqual(sum(n >= MIN_PIXELS for n in colour_pixel_counts(iso, display.PALETTE[:5])), 3)

    def test_picking_names_the_patch(self):
        obj = importer.open(sample_path("keycap"))
        v = FreeCADGui.ActiveDocument.ActiveView
        v.viewTop()
        v.fitAll()
        FreeCADGui.updateGui()
        model = model_of(obj)
        for k, patch in enumerate(model.patches):
            for u, w in ((0.5, 0.5), (0.3, 0.6)):
                p = patch.evaluate(u, w).P[0]
                x, y = v.getPointOnScreen(FreeCAD.Vector(*p))
                info = v.getObjectInfo((int(round(x)), int(round(y))))
                self.assertIsNotNone(info, (k, u, w))
                self.assertEqual(info["Object"], obj.Name)
                self.assertEqual(patch_of_element(info["Component"]), k, (k, u, w, info))

    def test_patch_numbers_readable_at_the_patch_centres(self):
        """A white disc with dark text at every patch centre; off with ShowPatchNumbers."""
        obj = importer.open(sample_path("keycap"))
        v = FreeCADGui.ActiveDocument.ActiveView
        v.viewTop()
        v.fitAll()
        FreeCADGui.updateGui()
        w, h = v.getSize()
        model = model_of(obj)

        def discs(name):
            path = artifact_path(name)
            v.saveImage(path, w, h, "White")
            img = image_rgb(path)
            out = []
            for patch in model.patches:
                x, y = v.getPointOnScreen(FreeCAD.Vector(*patch.evaluate(0.5, 0.5).P[0]))
                r, c = int(round(h - 1 - y)), int(round(x))
                win = img[max(r - 7, 0):r + 8, max(c - 7, 0):c + 8]
                white = (win.min(axis=2) > 0.93).sum()
                dark = (win.max(axis=2) < 0.3).sum()
                out.append(bool(white >= 20 and dark >= 5))
            return out
        self.assertEqual(discs("keycap_numbers_on.png"), [True] * 5)
        obj.ViewObject.ShowPatchNumbers = False
        self.assertEqual(discs("keycap_numbers_off.png"), [False] * 5)

    def test_control_mesh_on_demand(self):
        obj = importer.open(sample_path("keycap"))
        off = render("keycap_no_cage.png")
        obj.ViewObject.ShowControlMesh = True
        on = render("keycap_control_mesh.png")
        obj.ViewObject.ShowControlMesh = False
        again = render("keycap_no_cage.png")
        self.assertGreater(dark_pixels(on), dark_pixels(off) + 2000)
        self.assertEqual(dark_pixels(again), dark_pixels(off))

    def test_save_and_reload_keeps_model_and_view(self):
        obj = importer.open(sample_path("keycap"))
        obj.ViewObject.ShowControlMesh = True
        before = grid_points(model_of(obj))
        path = os.path.join(self.tmp, "keycap.FCStd")
        obj.Document.saveAs(path)
        FreeCAD.closeDocument(obj.Document.Name)
        FreeCADGui.updateGui()
        doc = FreeCAD.openDocument(path)
        FreeCADGui.updateGui()
        objs = model_objects(doc)
        self.assertEqual(len(objs), 1)
        o = objs[0]
        self.assertTrue(o.ViewObject.ShowControlMesh)
        self.assertEqual(o.Patches, 5)
        # re-read and re-evaluated: the same surface to 1e-9 mm
        np.testing.assert_allclose(grid_points(model_of(o)), before, rtol=0, atol=1e-9)
        shot = render("keycap_reloaded_top.png", view="Top")
        counts = colour_pixel_counts(shot, display.PALETTE[:5])
        self.assertTrue(all(n >= MIN_PIXELS for n in counts), counts)


class Figure4Adjacency(_GuiCase):
    def test_adjacency_graph_of_figure4(self):
        obj = importer.open(sample_path("figure4"))
        plain = render("figure4_patches.png", view="Top")
        obj.ViewObject.ShowAdjacency = True
        top = render("figure4_adjacency_top.png", view="Top")
        render("figure4_adjacency_iso.png", azimuth=-60, elevation=40)
        self.assertGreater(dark_pixels(top), dark_pixels(plain) + 3000)
        # the graph in the scene: boundary links solid, corner links dashed
        from pivy import coin
        layer = obj.ViewObject.Proxy.layers["adjacency"]
        sets = []
        sa = coin.SoSearchAction()
        sa.setType(coin.SoLineSet.getClassTypeId())
        sa.setInterest(coin.SoSearchAction.ALL)
        sa.apply(layer)
        for i in range(sa.getPaths().getLength()):
            path = sa.getPaths()[i]
            style = None
            for k in range(path.getLength()):
                node = path.getNode(k)
                if isinstance(node, coin.SoSeparator):
                    for c in range(node.getNumChildren()):
                        if isinstance(node.getChild(c), coin.SoDrawStyle):
                            style = node.getChild(c)
            sets.append((path.getTail().numVertices.getNum(), style.linePattern.getValue()))
        layout = Layout.from_model(model_of(obj))
        d = display.adjacency(model_of(obj), layout)
        self.assertIn((len(layout.edge_links), 0xFFFF), sets)
        self.assertIn((len(d.corner), 0x0F0F), sets)
        self.assertEqual(len(layout.edge_links), 17)


def tiled_figure4(tx, ty):
    """A cage with the figure-4 edge rotation repeated on a tx x ty grid of 4 x 3 tiles:
    4 extraordinary points per tile, a few hundred patches."""
    from tsplcam.model.samples import layout_cage
    nx, ny = 4 * tx, 3 * ty
    nid = lambda i, j: j * (nx + 1) + i    # noqa: E731
    quads, rotated = [], set()
    for a in range(tx):
        for b in range(ty):
            i, j = 4 * a + 1, 3 * b + 1
            rotated |= {(i, j), (i + 1, j)}
            A, B, C = nid(i, j), nid(i + 1, j), nid(i + 2, j)
            D, E, F = nid(i + 2, j + 1), nid(i + 1, j + 1), nid(i, j + 1)
            quads += [(A, B, C, F), (F, C, D, E)]
    quads += [(nid(i, j), nid(i + 1, j), nid(i + 1, j + 1), nid(i, j + 1))
              for j in range(ny) for i in range(nx) if (i, j) not in rotated]
    pts = np.array([(10.0 * i, 10.0 * j, 0.0) for j in range(ny + 1) for i in range(nx + 1)])
    return layout_cage(Layout.from_quads(quads, pts), 2, height=lambda x, y: 0.01 * (x - 120.0) ** 2)


class LargeModel(_GuiCase):
    def test_hundreds_of_patches_with_progress(self):
        from tsplcam.model.formats.obj import write_obj
        from tsplcam.workbench import viewmodel
        path = os.path.join(self.tmp, "tiles.obj")
        write_obj(tiled_figure4(6, 6), path, "figure-4 tiles")
        calls = []

        class Recorder:
            def start(self, text, steps):
                calls.append(("start", steps))

            def next(self, *a):
                calls.append(("next",))

            def stop(self):
                calls.append(("stop",))
        original = FreeCAD.Base.ProgressIndicator
        FreeCAD.Base.ProgressIndicator = Recorder
        try:
            obj = importer.open(path)
        finally:
            FreeCAD.Base.ProgressIndicator = original
        self.assertIsNotNone(obj, messages.recorded[-1:])
        n = obj.Patches
        self.assertGreater(n, viewmodel.PROGRESS_PATCHES)
        self.assertEqual(calls[0], ("start", n))
        self.assertEqual(calls.count(("next",)), n)
        self.assertEqual(calls[-1], ("stop",))
        shot = render("tiles_patches_top.png", view="Top")
        # every palette colour is used, each on many patches
        counts = colour_pixel_counts(shot, display.PALETTE)
        self.assertTrue(all(c >= MIN_PIXELS for c in counts[:8]), counts)


class Neighbours(_GuiCase):
    def test_neighbours_of_patch_0_as_in_figure4(self):
        """Select patch 0 (a pick names it Patch0), run the command: figure 4 (a) colours."""
        FreeCADGui.activateWorkbench("TsplcamWorkbench")
        obj = importer.open(sample_path("figure4"))
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(obj, "Patch0")
        FreeCADGui.runCommand("Tsplcam_PatchNeighbours")
        self.assertEqual(obj.ViewObject.NeighboursOf, 0)
        render("figure4_neighbours_of_0.png", view="Top")
        # at the view's own size, screen points map to pixels one to one
        v = FreeCADGui.ActiveDocument.ActiveView
        w, h = v.getSize()
        shot = artifact_path("figure4_neighbours_of_0_screen.png")
        v.saveImage(shot, w, h, "White")
        img = image_rgb(shot)
        model = model_of(obj)
        from tsplcam.workbench.testsupport import hsv
        # each patch sampled away from its lines and label: its colour is its relation
        kinds = {}
        for k, patch in enumerate(model.patches):
            x, y = v.getPointOnScreen(FreeCAD.Vector(*patch.evaluate(0.3, 0.7).P[0]))
            hue_, sat, val = hsv(img[int(round(h - 1 - y)), int(round(x))][None, :])
            kinds[k] = ("gray" if sat[0] < 0.15 else "blue" if 200 < hue_[0] < 240
                        else "green" if 100 < hue_[0] < 150 else "yellow" if 35 < hue_[0] < 65 else "?")
        self.assertEqual(kinds, {0: "yellow", 1: "blue", 3: "blue", 4: "blue", 6: "blue",
                                 2: "green", 5: "green", 7: "green", 8: "green", 9: "green",
                                 10: "gray", 11: "gray"})
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(obj)
        FreeCADGui.runCommand("Tsplcam_PatchNeighbours")
        self.assertEqual(obj.ViewObject.NeighboursOf, -1)
        FreeCADGui.Selection.clearSelection()


class BadFileInGui(_GuiCase):
    def test_truncated_file_gives_one_message_and_no_object(self):
        from PySide import QtGui
        with open(sample_path("keycap")) as f:
            lines = f.read().splitlines()
        bad = os.path.join(self.tmp, "truncated.obj")
        with open(bad, "w") as f:
            f.write("\n".join(lines[:30] + ["v 1.5 2"]))
        doc = FreeCAD.newDocument("TsplcamBadFile")
        shown = []
        original = QtGui.QMessageBox.critical
        QtGui.QMessageBox.critical = staticmethod(lambda parent, title, text, *a: shown.append((title, text)))
        messages.show_dialogs = True
        mark = report_view_mark()
        try:
            obj = importer.import_file(bad, doc)
        finally:
            QtGui.QMessageBox.critical = original
            messages.show_dialogs = False
        self.assertIsNone(obj)
        self.assertEqual(doc.Objects, [])
        self.assertEqual(len(shown), 1, shown)
        self.assertIn(bad, shown[0][1])
        self.assertIn("line 31", shown[0][1])
        errors = errors_since(mark)
        self.assertTrue(any(bad in e and "line 31" in e for e in errors), errors)
        self.assertIsNone(QtGui.QApplication.activeModalWidget())


class Commands(unittest.TestCase):
    def test_commands_registered(self):
        FreeCADGui.activateWorkbench("TsplcamWorkbench")
        from tsplcam.workbench import commands
        from tsplcam.workbench.modelobject import shapes_module
        names = set(FreeCADGui.listCommands())
        for name in ("Tsplcam_Import", "Tsplcam_OpenSample", "Tsplcam_ShowControlMesh",
                     "Tsplcam_ShowPatchNumbers", "Tsplcam_ShowAdjacency", "Tsplcam_Program",
                     "Tsplcam_SaveProgram"):
            self.assertIn(name, names)
        self.assertEqual("Tsplcam_ModelFromShape" in commands.available(), shapes_module() is not None)
        from PySide import QtGui
        for name, cls in commands.available().items():
            pix = cls().GetResources()["Pixmap"]
            self.assertTrue(os.path.isfile(pix), pix)
            self.assertFalse(QtGui.QIcon(pix).pixmap(32, 32).isNull(), name)


class ProcessingListView(_GuiCase):
    def test_plan_drawn_and_edited_in_the_task_panel(self):
        from pivy import coin
        from tsplcam.workbench import planobject
        FreeCADGui.activateWorkbench("TsplcamWorkbench")
        model_obj = importer.open(sample_path("figure4"))
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(model_obj)
        FreeCADGui.runCommand("Tsplcam_Plan")
        plans = [o for o in model_obj.Document.Objects if planobject.is_plan_object(o)]
        self.assertEqual(len(plans), 1)
        plan = plans[0]
        FreeCADGui.Selection.clearSelection()          # a selected object is drawn green
        plan.ViewObject.CurrentStep = 1
        render("figure4_processing_list.png", azimuth=-60, elevation=50)
        plan.ViewObject.CurrentStep = 0
        # one curve per step in the scene
        sa = coin.SoSearchAction()
        sa.setType(coin.SoLineSet.getClassTypeId())
        sa.setInterest(coin.SoSearchAction.ALL)
        sa.apply(plan.ViewObject.Proxy.layers["curves"])
        counts = {sa.getPaths()[i].getTail().numVertices.getNum() for i in range(sa.getPaths().getLength())}
        self.assertEqual(counts, {plan.Steps})

        # the task panel: pin patch 9 first by moving it up, solve, accept
        FreeCADGui.ActiveDocument.setEdit(plan.Name, 0)
        FreeCADGui.updateGui()
        panel = FreeCADGui.Control.activeDialog() and _active_panel()
        self.assertIsNotNone(panel)
        self.assertEqual(panel.table.rowCount(), 12)
        row = [s.patch for s in panel.plist.steps].index(9)
        for _ in range(row):
            panel.table.selectRow([s.patch for s in panel.plist.steps].index(9))
            panel.buttons["up"].click()
        self.assertEqual(panel.plist.steps[0].patch, 9)
        self.assertIn("P", panel.table.item(0, 6).text())
        panel.buttons["solve"].click()
        self.assertTrue(panel.valid, panel.status.text())
        self.assertEqual(panel.plist.steps[0].patch, 9)
        # an edit that breaks the chain is reported, not stored
        s1 = panel.plist.steps[1]
        bad = next(c for c in range(4) if c not in (s1.start, s1.finish))
        panel.table.cellWidget(1, 1).setCurrentIndex(bad)
        self.assertFalse(panel.valid)
        self.assertIn("step 2", panel.status.text())
        self.assertFalse(panel.accept())
        panel.buttons["solve"].click()              # keeps the pinned start, fixes the rest
        self.assertEqual(panel.plist.steps[1].start, bad)
        status = panel.status.text()
        self.assertTrue(panel.accept(), status)            # stores the list, closes the panel
        self.assertIsNone(_active_panel())
        FreeCADGui.updateGui()
        self.assertEqual(plan.Order.split()[0], "9")
        self.assertEqual(planobject.plan_of(plan).steps[1].start, bad)


def _active_panel():
    from tsplcam.workbench import planpanel
    return planpanel.ProcessingListPanel.active


class ToolPathView(_GuiCase):
    def test_keycap_path_preview(self):
        from tsplcam.workbench import pathobject, planobject, viewpath
        if not pathobject.toolpath_available():
            self.skipTest("the path generator is absent")
        model_obj = importer.open(sample_path("keycap"))
        plan = planobject.make_processing_list(model_obj)
        obj = pathobject.make_tool_path(plan, scallop=0.05)
        self.assertIsNotNone(obj, messages.recorded[-1:])
        FreeCADGui.Selection.clearSelection()
        plan.ViewObject.Visibility = False
        model_obj.ViewObject.ShowPatchNumbers = False
        shot = render("keycap_tool_path.png", azimuth=-60, elevation=45)
        link = colour_pixel_counts(shot, [viewpath.MOVE_STYLE[1][0]], min_saturation=0.8)[0]
        self.assertGreater(link, 500)                  # orange links between lines and patches
        model_obj.ViewObject.Visibility = False
        alone = render("keycap_tool_path_alone.png", azimuth=-60, elevation=45)
        navy = colour_pixel_counts(alone, [viewpath.MOVE_STYLE[0][0]], hue_tolerance=12,
                                   min_saturation=0.5, min_value=0.1)[0]
        self.assertGreater(navy, 5000)                 # the cutting lines
        obj.ViewObject.ColourBy = "Patch"              # each patch's passes in its model colour
        by_patch = render("keycap_tool_path_by_patch.png", azimuth=-60, elevation=45)
        counts = colour_pixel_counts(by_patch, display.PALETTE[:5], hue_tolerance=6, min_saturation=0.45)
        self.assertEqual(sum(n > 300 for n in counts), 5, counts)
