"""Sample molds: shipped files match their generators and the sizes and layouts promised."""
import os
import unittest

import numpy as np

import tsplcam
from tsplcam.layout.layout import Layout
from tsplcam.layout import examples
from tsplcam.model import samples


def neighbour_signature(layout):
    """Per patch, the sorted kinds of its links: equal for layouts equal up to relabelling."""
    return sorted(sorted(layout.link_kind(a, b) or "-" for b in range(layout.n_patches) if b != a)
                  for a in range(layout.n_patches))


class ShippedSamples(unittest.TestCase):
    def test_files_match_generators(self):
        for name, fn in samples.SAMPLES.items():
            path = samples.sample_path(name)
            self.assertTrue(os.path.isfile(path), path)
            shipped = tsplcam.load(path)
            cage = fn()
            np.testing.assert_allclose(shipped.control.points, cage.points, atol=1e-8, err_msg=name)
            if name in samples.TSPLINE_SAMPLES:
                self.assertTrue(path.endswith(".tspl"))
                for a, b in zip(shipped.control.faces, cage.faces):
                    np.testing.assert_array_equal(a, b)
                for a, b in zip(shipped.control.intervals, cage.intervals):
                    # the generator computes the intervals on this machine, the file was
                    # written on another: equal to 1e-12 of the largest
                    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * max(1.0, np.abs(b).max()))
                self.assertEqual(shipped.control.corners, cage.corners)
                continue
            np.testing.assert_array_equal(shipped.control.mesh.faces, cage.mesh.faces)

    def test_keycap_size_layout(self):
        model = tsplcam.load(samples.sample_path("keycap"))
        lo, hi = samples._limit_box(model.control, 65)
        np.testing.assert_allclose(hi - lo, [14.4, 14.4, 6.8], atol=2e-3)
        self.assertEqual(len(model.patches), 5)
        self.assertEqual(sorted(e.valence for e in model.extraordinary if not e.boundary), [3, 3, 3, 3])
        self.assertEqual(neighbour_signature(Layout.from_model(model)), neighbour_signature(examples.keycap()))
        # dished top: the centre of the top lies below the top's highest points
        top = max(model.patches, key=lambda p: p.evaluate(0.5, 0.5).P[0, 2])
        self.assertLess(top.evaluate(0.5, 0.5).P[0, 2], hi[2] - 0.3)

    def test_keycap_mold_half(self):
        model = tsplcam.load(samples.sample_path("keycap_mold"))
        lo, hi = samples._limit_box(model.control, 65)
        np.testing.assert_allclose(hi - lo, [14.4, 14.4, 6.8], atol=2e-3)
        self.assertAlmostEqual(hi[2], samples.MOLD_BLOCK[2], delta=2e-3)
        V, T = samples.keycap_mold_stock()
        np.testing.assert_allclose(V.max(0) - V.min(0), samples.MOLD_BLOCK)
        self.assertTrue(np.all(np.abs(lo[:2]) < samples.MOLD_BLOCK[0] / 2))
        # normals point into the cavity, toward the tool: the bottom's normal points up
        bottom = min(model.patches, key=lambda p: p.evaluate(0.5, 0.5).P[0, 2])
        self.assertGreater(bottom.evaluate(0.5, 0.5).normal[0, 2], 0.99)

    def test_head_and_figure4_layouts(self):
        head = tsplcam.load(samples.sample_path("head"))
        self.assertEqual((len(head.patches), len(head.extraordinary)), (6, 8))
        self.assertEqual(neighbour_signature(Layout.from_model(head)), neighbour_signature(examples.head()))
        fig4 = tsplcam.load(samples.sample_path("figure4"))
        self.assertEqual(len(fig4.patches), 12)
        layout = Layout.from_model(fig4)
        self.assertEqual(neighbour_signature(layout), neighbour_signature(examples.figure4()))
        kinds = [layout.link_kind(a, b) for a in range(12) for b in range(a + 1, 12)]
        self.assertGreater(kinds.count("corner"), 0)

    def test_tjunction_mold(self):
        """The T-spline sample: T-junctions, non-uniform knot intervals, clamped boundary; a
        60 x 40 mm pocket floor 8 mm deep with a rib, normals toward the tool (+z)."""
        model = tsplcam.load(samples.sample_path("tjunction_mold"))
        mesh = model.control
        self.assertEqual(model.kind, "t-spline")
        self.assertGreaterEqual(sum(len(f) > 4 for f in mesh.faces), 8)
        positive = np.concatenate([d[d > 0] for d in mesh.intervals])
        self.assertGreater(len(np.unique(np.round(positive, 9))), 4)
        self.assertEqual(len(model.patches), 1)
        g = np.linspace(0, 1, 81)
        U, V = np.meshgrid(g, g)
        s = model.patches[0].evaluate(U.ravel(), V.ravel())
        np.testing.assert_allclose(s.P.min(axis=0)[:2], [0.0, 0.0], atol=1e-9)
        np.testing.assert_allclose(s.P.max(axis=0)[:2], samples.TJUNCTION_MOLD_SIZE[:2], atol=1e-9)
        self.assertAlmostEqual(s.P[:, 2].max(), 0.0, delta=1e-9)      # the rim
        self.assertLess(s.P[:, 2].min(), -samples.TJUNCTION_MOLD_SIZE[2] + 0.1)
        self.assertGreater(s.normal[:, 2].min(), 0.0)
        # partition of unity of its blending functions (without the rational division)
        from tsplcam.model.tspline import homogeneous_parts, tspline_model
        unit = mesh.copy()
        unit.weights = np.ones(mesh.n_vertices)
        weight = homogeneous_parts(tspline_model(unit).patches[0])[1]
        self.assertLess(np.abs(weight.evaluate(U.ravel(), V.ravel()).P[:, 0] - 1).max(), 1e-12)
        # the rib: higher at x = 30 than 10 mm beside it, across the middle
        mid = model.patches[0].evaluate([0.5, 20 / 60, 40 / 60], [0.5, 0.5, 0.5]).P
        self.assertGreater(mid[0, 2] - mid[1, 2], 1.5)
