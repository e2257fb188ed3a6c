"""FreeCAD shapes (STEP, IGES, document bodies) as compound-NURBS models.

The engine half (``tsplcam.model.compound``) runs everywhere; the FreeCAD half compares
every patch with OCCT's own evaluation of the face's surface (value, derivatives via
getDN, normals via face.normalAt) and skips under plain pytest.
"""
import os
import shutil
import tempfile
import unittest

import numpy as np

from tsplcam.errors import InputError
from tsplcam.layout.layout import CORNER_UV, Layout
from tsplcam.model.bspline import bspline_patch
from tsplcam.model.compound import compound_model
from conftest import needs_freecad, require_freecad

CUBIC = np.array([0, 0, 0, 0, 1, 1, 1, 1], float)


def height(x, y):
    return 0.3 * np.sin(1.3 * x) * np.cos(0.7 * y) + 0.05 * x * y


def grid_poles(x0, x1, y0, y1, n=5):
    """Poles over a rectangle, lifted by ``height`` (first index along x)."""
    X, Y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n), indexing="ij")
    return np.stack([X, Y, height(X, Y)], -1)


class CompoundEngine(unittest.TestCase):
    """Joining patches by their edges, without FreeCAD."""

    def test_two_by_two(self):
        knots = np.array([0, 0, 0, 0, 0.5, 1, 1, 1, 1])
        # four faces from one 4x4 grid of poles on each quarter: edges coincide where the
        # boundary rows of poles are the same points
        patches = []
        for k, (x0, y0) in enumerate(((0, 0), (1, 0), (1, 1), (0, 1))):
            P = grid_poles(x0, x0 + 1, y0, y0 + 1)
            if k == 2:                              # one face mirrored in u
                P = P[::-1]
            patches.append(bspline_patch(P, None, knots, knots, 3, 3, index=k, name=f"Face{k + 1}"))
        m = compound_model(patches)
        lay = Layout.from_model(m)
        self.assertEqual(len(lay.edge_links), 4)
        self.assertEqual(len(m.node_points), 9)
        self.assertEqual(m.extraordinary, [])        # the centre has four patches
        centre = [n for n in range(9) if np.allclose(m.node_points[n], [1, 1, height(1, 1)])]
        self.assertEqual(len(centre), 1)
        self.assertEqual(int((lay.corner_nodes == centre[0]).sum()), 4)
        mirrored = [l for l in lay.edge_links if 2 in (l.a, l.b)]
        self.assertTrue(all(not l.reversed for l in mirrored))
        self.assertTrue(all(l.reversed for l in lay.edge_links if l not in mirrored))
        for p in m.patches:
            np.testing.assert_allclose(p.evaluate(CORNER_UV[:, 0], CORNER_UV[:, 1]).P,
                                       m.node_points[p.corner_nodes], atol=1e-14)

    def test_partial_edges_are_not_neighbours_and_poles_are_refused(self):
        knots = np.array([0, 0, 0, 0, 0.5, 1, 1, 1, 1])
        a = bspline_patch(grid_poles(0, 2, 0, 1), None, knots, knots, 3, 3, index=0, name="Face1")
        b = bspline_patch(grid_poles(0, 1, 1, 2), None, knots, knots, 3, 3, index=1, name="Face2")
        m = compound_model([a, b])
        self.assertEqual(Layout.from_model(m).edge_links, [])     # b's bottom is half of a's top
        P = np.zeros((4, 4, 3))
        P[..., 0] = np.linspace(0, 1, 4)[:, None] * np.linspace(0, 1, 4)[None, :]   # u=0 collapses
        P[..., 1] = np.linspace(0, 1, 4)[None, :]
        with self.assertRaises(InputError) as cm:
            compound_model([bspline_patch(P, None, CUBIC, CUBIC, 3, 3, name="Face7")])
        self.assertIn("Face7", str(cm.exception))
        self.assertIn("collapsed", str(cm.exception))


@needs_freecad
class FreeCADShapes(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        require_freecad()
        cls.dir = tempfile.mkdtemp()

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.dir, ignore_errors=True)

    def agreement(self, model, faces):
        """Largest distance between patch and face surface (value), and relative errors of
        first and second derivatives; normals must agree with face.normalAt."""
        rng = np.random.default_rng(0)
        worst = [0.0, 0.0, 0.0]
        for p, src, face in zip(model.patches, model.faces, faces):
            self.assertEqual(p.name, src.name)
            u, v = rng.random(25), rng.random(25)
            u[:4], v[:4] = CORNER_UV[:, 0], CORNER_UV[:, 1]
            S = p.evaluate(u, v)
            su, sv = src.surface_params(u, v)
            U0, U1, V0, V1 = src.bounds
            ju = -(U1 - U0) if src.reversed else (U1 - U0)
            jv = V1 - V0
            surf = face.Surface
            ref = np.array([tuple(surf.value(a, b)) for a, b in zip(su, sv)])
            d = lambda i, j: np.array([tuple(surf.getDN(a, b, i, j)) for a, b in zip(su, sv)])  # noqa: E731
            worst[0] = max(worst[0], np.abs(S.P - ref).max())
            D1 = np.concatenate([S.Pu - d(1, 0) * ju, S.Pv - d(0, 1) * jv])
            worst[1] = max(worst[1], np.abs(D1).max() / (np.abs(S.Pu).max() + np.abs(S.Pv).max()))
            D2 = np.concatenate([S.Puu - d(2, 0) * ju * ju, S.Puv - d(1, 1) * ju * jv, S.Pvv - d(0, 2) * jv * jv])
            worst[2] = max(worst[2], np.abs(D2).max() / (1 + np.abs(S.Puu).max() + np.abs(S.Pvv).max()))
            nrm = np.array([tuple(face.normalAt(a, b)) for a, b in zip(su[4:], sv[4:])])
            self.assertGreater(np.einsum("ij,ij->i", S.normal[4:], nrm).min(), 1 - 1e-12)
        return worst

    def test_box_through_step(self):
        import Part
        from tsplcam.workbench.shapes import model_from_step
        box = Part.makeBox(10, 20, 30).toNurbs()
        path = os.path.join(self.dir, "box.step")
        box.exportStep(path)
        m = model_from_step(path)
        shape = Part.read(path)
        self.assertEqual(len(m.patches), 6)
        self.assertEqual(len(Layout.from_model(m).edge_links), 12)
        self.assertEqual(len(m.node_points), 8)
        self.assertEqual(sorted((ep.valence, ep.boundary) for ep in m.extraordinary), [(3, False)] * 8)
        worst = self.agreement(m, shape.Faces)
        self.assertLess(worst[0], 1e-10)
        self.assertLess(max(worst[1:]), 1e-10)
        lo, hi = m.bounding_box()
        np.testing.assert_allclose(hi - lo, [10, 20, 30], atol=1e-10)

    def curved_faces(self):
        """A 2 x 2 arrangement of curved cubic B-spline faces, one reversed, loose (not
        sewn), as Part faces."""
        import FreeCAD
        import Part
        faces = []
        for k, (x0, y0) in enumerate(((0, 0), (1, 0), (1, 1), (0, 1))):
            P = grid_poles(x0, x0 + 1, y0, y0 + 1)
            W = 1.0 + 0.2 * np.sin(np.arange(25)).reshape(5, 5)
            W[0, :] = W[-1, :] = W[:, 0] = W[:, -1] = 1.0     # shared edges stay the same curves
            s = Part.BSplineSurface()
            s.buildFromPolesMultsKnots([[FreeCAD.Vector(*p) for p in row] for row in P.tolist()],
                                       [4, 1, 4], [4, 1, 4], [0.0, 0.4, 1.0], [0.0, 0.6, 1.0],
                                       False, False, 3, 3, W.tolist())
            f = s.toShape()
            if k == 1:
                f.reverse()
            faces.append(f)
        return faces

    def test_curved_compound_through_step_and_iges(self):
        import Part
        from tsplcam.workbench.shapes import model_from_step
        comp = Part.makeCompound(self.curved_faces())
        for ext in ("step", "iges"):
            path = os.path.join(self.dir, "quad." + ext)
            comp.exportStep(path) if ext == "step" else comp.exportIges(path)
            m = model_from_step(path)
            shape = Part.read(path)
            self.assertEqual(len(m.patches), 4, ext)
            self.assertEqual(len(Layout.from_model(m).edge_links), 4, ext)
            self.assertEqual(len(m.node_points), 9, ext)
            self.assertEqual(m.extraordinary, [], ext)
            worst = self.agreement(m, shape.Faces)
            self.assertLess(worst[0], 1e-10, ext)
            self.assertLess(max(worst[1:]), 1e-9, ext)
            # the reversed face keeps its own (face) normal, down; its links are mirrored
            self.assertEqual([p.evaluate([0.5], [0.5]).normal[0, 2] > 0.5 for p in m.patches],
                             [True, False, True, True])
            self.assertEqual(sorted((l.a, l.b, l.reversed) for l in Layout.from_model(m).edge_links),
                             [(0, 1, False), (0, 3, True), (1, 2, False), (2, 3, True)])

    def test_document_body_with_placement(self):
        import FreeCAD
        import Part
        from tsplcam.workbench.shapes import model_from_shape
        doc = FreeCAD.newDocument("tsplcam_shapes_test")
        try:
            obj = doc.addObject("Part::Feature", "Quad")
            obj.Shape = Part.makeShell(self.curved_faces())
            obj.Placement = FreeCAD.Placement(FreeCAD.Vector(5, -3, 2), FreeCAD.Rotation(FreeCAD.Vector(1, 1, 0), 40))
            doc.recompute()
            m = model_from_shape(obj.Shape, obj.Label)
            self.assertEqual(len(Layout.from_model(m).edge_links), 4)
            worst = 0.0
            for p, src, face in zip(m.patches, m.faces, obj.Shape.Faces):
                u = np.linspace(0, 1, 7)
                su, sv = src.surface_params(u, u[::-1])
                ref = np.array([tuple(face.valueAt(a, b)) for a, b in zip(su, sv)])
                worst = max(worst, np.abs(p.evaluate(u, u[::-1]).P - ref).max())
            self.assertLess(worst, 1e-10)
        finally:
            FreeCAD.closeDocument(doc.Name)

    def test_iso_rectangle_of_a_surface_and_a_full_tube(self):
        import Part
        from tsplcam.workbench.shapes import model_from_shape
        surf = self.curved_faces()[0].Surface
        face = surf.toShape(0.2, 0.7, 0.1, 0.9)          # untrimmed: iso-lines of the surface
        m = model_from_shape(face, "part")
        u = np.linspace(0, 1, 9)
        ref = np.array([tuple(surf.value(0.2 + 0.5 * a, 0.1 + 0.8 * b)) for a, b in zip(u, u[::-1])])
        self.assertLess(np.abs(m.patches[0].evaluate(u, u[::-1]).P - ref).max(), 1e-10)
        tube = Part.makeCylinder(2, 5).Faces[0]
        m = model_from_shape(tube, "tube")
        p = m.patches[0]
        self.assertEqual(sum(nb is not None and nb.patch == 0 for nb in p.neighbours), 2)   # seam
        P = p.evaluate(*np.random.default_rng(1).random((2, 200))).P
        self.assertLess(np.abs(np.hypot(P[:, 0], P[:, 1]) - 2).max(), 1e-12)

    def test_trimmed_faces_are_refused_by_name(self):
        import FreeCAD
        import Part
        from tsplcam.workbench.shapes import model_from_shape, model_from_step
        drilled = Part.makeBox(10, 10, 10).cut(Part.makeCylinder(2, 20, FreeCAD.Vector(5, 5, -5)))
        holed = [f"Face{i + 1}" for i, f in enumerate(drilled.Faces) if len(f.Wires) > 1]
        self.assertEqual(len(holed), 2)
        with self.assertRaises(InputError) as cm:
            model_from_shape(drilled, "drilled")
        for name in holed:
            self.assertIn(name + " is trimmed", str(cm.exception))
        plate = Part.makePlane(10, 10)
        disk = plate.common(Part.makeCylinder(3, 1, FreeCAD.Vector(5, 5, -0.5)))
        with self.assertRaises(InputError) as cm:
            model_from_shape(disk, "disk")
        self.assertIn("Face1 is trimmed", str(cm.exception))
        # a STEP file with a trimmed face names the file too
        path = os.path.join(self.dir, "drilled.step")
        drilled.exportStep(path)
        with self.assertRaises(InputError) as cm:
            model_from_step(path)
        self.assertEqual(cm.exception.path, path)
        self.assertIn("trimmed", str(cm.exception))
        with self.assertRaises(InputError) as cm:
            model_from_shape(Part.makeSphere(3), "ball")
        self.assertIn("Face1", str(cm.exception))

    def test_unreadable_files(self):
        from tsplcam.workbench.shapes import model_from_step
        bad = os.path.join(self.dir, "garbage.step")
        with open(bad, "w") as fh:
            fh.write("ISO-10303-21;\nHEADER;\nthis is not step\n")
        import Part
        cut = []
        for ext in ("step", "iges"):
            whole = os.path.join(self.dir, "whole." + ext)
            box = Part.makeBox(1, 2, 3).toNurbs()
            box.exportStep(whole) if ext == "step" else box.exportIges(whole)
            with open(whole) as fh:
                text = fh.read()
            cut.append(os.path.join(self.dir, "cut." + ext))
            with open(cut[-1], "w") as fh:
                fh.write(text[:int(0.95 * len(text))])     # OCCT reads such an IGES file silently
        for path in [bad, os.path.join(self.dir, "missing.step")] + cut:
            with self.assertRaises(InputError) as cm:
                model_from_step(path)
            self.assertEqual(cm.exception.path, path)


if __name__ == "__main__":
    unittest.main()
