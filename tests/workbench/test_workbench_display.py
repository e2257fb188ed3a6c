"""What the model view draws, measured on the samples (plain numpy: runs under pytest too).

References are independent of the drawing code: the shared edges of neighbouring patches
(the surface is watertight), Euler's formula for the cage, brute-force neighbour sets from
the corner nodes, and the neighbours of patch 0 that shang2020 figure 4 names.
"""
import colorsys
import itertools
import unittest

import numpy as np

import tsplcam
from tsplcam.layout import examples
from tsplcam.layout.layout import Layout
from tsplcam.model.samples import sample_path
from tsplcam.workbench import display


def hue(rgb) -> float:
    return colorsys.rgb_to_hsv(*rgb)[0] * 360.0


def hue_gap(a: float, b: float) -> float:
    d = abs(a - b) % 360.0
    return min(d, 360.0 - d)


class Tessellation(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.model = tsplcam.load(sample_path("keycap"))
        cls.meshes = display.tessellate(cls.model, 6)

    def test_grid_follows_knot_spans(self):
        for mesh, patch in zip(self.meshes, self.model.patches):
            self.assertEqual((mesh.nu, mesh.nv), (6 * round(patch.knot_size[0]), 6 * round(patch.knot_size[1])))
            self.assertEqual(len(mesh.points), (mesh.nu + 1) * (mesh.nv + 1))
            self.assertTrue(np.isfinite(mesh.points).all())
            np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-12)

    def test_neighbours_share_their_boundary_polylines(self):
        """Patch a's edge and patch b's edge are one curve: the drawn boundaries meet."""
        size = display.model_size(self.model)
        links = Layout.from_model(self.model).edge_links
        self.assertEqual(len(links), 8)
        for link in links:
            ea = self.meshes[link.a].boundary()[link.ea]
            eb = self.meshes[link.b].boundary()[link.eb]
            if link.reversed:
                eb = eb[::-1]
            self.assertEqual(ea.shape, eb.shape)
            self.assertLess(np.abs(ea - eb).max(), 1e-9 * size, link)

    def test_quads_face_the_surface_normal(self):
        """Quad corners run counter-clockwise about the normal (lighting, picking)."""
        for mesh in self.meshes:
            q = mesh.quads()
            p = mesh.points
            geo = np.cross(p[q[:, 2]] - p[q[:, 0]], p[q[:, 3]] - p[q[:, 1]])
            agree = np.einsum("ij,ij->i", geo, mesh.normals[q].mean(axis=1)) > 0
            self.assertGreater(agree.mean(), 0.99, mesh.patch)

    def test_point_budget(self):
        grids = display.samples_per_patch(self.model, 10_000)
        total = sum((a + 1) * (b + 1) for a, b in grids)
        self.assertLessEqual(total, display.MAX_POINTS)
        self.assertGreater(total, display.MAX_POINTS // 4)


class Colours(unittest.TestCase):
    def test_first_five_hues_far_apart_and_away_from_the_marker_red(self):
        hues = [hue(c) for c in display.PALETTE[:5]]
        for a, b in itertools.combinations(hues, 2):
            self.assertGreaterEqual(hue_gap(a, b), 40.0)
        for c in display.PALETTE:
            self.assertGreater(hue_gap(hue(c), hue(display.EP_COLOUR)), 20.0, c)

    def test_each_patch_its_own_colour_while_the_palette_lasts(self):
        layout = examples.keycap()
        self.assertEqual(display.patch_colours(layout), list(range(5)))

    def test_linked_patches_never_share_a_colour(self):
        for layout in (examples.grid(10, 10), examples.figure4(), examples.random_layout(3, 60)):
            colour = display.patch_colours(layout)
            self.assertEqual(len(colour), layout.n_patches)
            cn = layout.corner_nodes
            for a, b in itertools.combinations(range(layout.n_patches), 2):
                if set(cn[a]) & set(cn[b]):                 # boundary or corner linked
                    self.assertNotEqual(colour[a], colour[b], (a, b))


class AdjacencyGraph(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.model = tsplcam.load(sample_path("figure4"))
        cls.layout = Layout.from_model(cls.model)
        cls.drawing = display.adjacency(cls.model, cls.layout)

    def test_links_by_brute_force(self):
        cn = self.layout.corner_nodes
        edge_pairs, corner_pairs = set(), set()
        sides = [{frozenset((q[k], q[(k + 1) % 4])) for k in range(4)} for q in cn]
        for a, b in itertools.combinations(range(len(cn)), 2):
            if sides[a] & sides[b]:                       # two consecutive corner nodes
                edge_pairs.add((a, b))
            elif set(cn[a]) & set(cn[b]):
                corner_pairs.add((a, b))
        drawn_edges = {tuple(sorted(p)) for p in self.drawing.boundary_pairs}
        self.assertEqual(drawn_edges, edge_pairs)
        self.assertEqual(set(self.drawing.corner_pairs), corner_pairs)
        self.assertEqual(len(self.drawing.boundary), len(self.layout.edge_links))
        self.assertEqual(len(self.drawing.corner), len(corner_pairs))

    def test_patch_0_as_in_the_paper(self):
        """shang2020 figure 4: patch 0 is boundary linked with 1, 3, 4, 6 (blue) and corner
        linked with 2, 5, 7, 8, 9 (green); 10 and 11 are not linked (gray)."""
        edge = {b if a == 0 else a for a, b in self.drawing.boundary_pairs if 0 in (a, b)}
        corner = {b if a == 0 else a for a, b in self.drawing.corner_pairs if 0 in (a, b)}
        self.assertEqual(edge, {1, 3, 4, 6})
        self.assertEqual(corner, {2, 5, 7, 8, 9})

    def test_polylines_join_centres_through_the_shared_place(self):
        size = display.model_size(self.model)
        lift = 0.004 * size
        c = self.drawing.centres
        for line, (a, b) in zip(self.drawing.boundary + self.drawing.corner,
                                self.drawing.boundary_pairs + self.drawing.corner_pairs):
            np.testing.assert_allclose(line[0], c[a], atol=1e-9 * size)
            np.testing.assert_allclose(line[-1], c[b], atol=1e-9 * size)
            half = len(line) // 2
            # the two halves meet on the shared edge/corner (both lifted along the normal)
            self.assertLess(np.linalg.norm(line[half - 1] - line[half]), 0.05 * lift + 1e-9 * size)
        # the centres float above the surface by the lift
        P = np.array([self.model.patches[k].evaluate(0.5, 0.5).P[0] for k in range(len(c))])
        np.testing.assert_allclose(np.linalg.norm(c - P, axis=1), lift, rtol=1e-9)


class ControlNetAndPoints(unittest.TestCase):
    def test_keycap_cage_edges_by_euler(self):
        model = tsplcam.load(sample_path("keycap"))
        pts, edges = display.control_net(model)
        faces = model.control.mesh.faces
        # an open box is a disk: V - E + F = 1
        self.assertEqual(len(pts) - len(edges) + len(faces), 1)
        self.assertEqual(len(np.unique(edges, axis=0)), len(edges))

    def test_keycap_extraordinary_points_at_the_top_corners(self):
        model = tsplcam.load(sample_path("keycap"))
        pos, valence, boundary = display.extraordinary_points(model)
        self.assertEqual(valence.tolist(), [3, 3, 3, 3])
        self.assertFalse(boundary.any())
        lo, hi = model.bounding_box(17)
        # the four top corners: symmetric in x and y, near the top of the cap
        np.testing.assert_allclose(np.sort(np.abs(pos[:, 0])), np.abs(pos[0, 0]), atol=1e-9)
        self.assertTrue((pos[:, 2] > lo[2] + 0.8 * (hi[2] - lo[2])).all())

    def test_model_without_extraordinary_points(self):
        class Plain:
            extraordinary = []
        pos, valence, boundary = display.extraordinary_points(Plain())
        self.assertEqual((pos.shape, valence.shape, boundary.dtype), ((0, 3), (0,), np.dtype(bool)))
        self.assertEqual(len(pos[~boundary]), 0)

    def test_model_without_control_mesh(self):
        class Bare:
            control = None
        self.assertIsNone(display.control_net(Bare()))


if __name__ == "__main__":
    unittest.main()


class PlanDrawing(unittest.TestCase):
    def test_curves_run_from_start_to_finish_corner(self):
        from tsplcam.layout.layout import CORNER_UV
        from tsplcam.plan import plan
        model = tsplcam.load(sample_path("figure4"))
        plist = plan(Layout.from_model(model))
        size = display.model_size(model)
        lift = 0.006 * size
        d = display.plan_drawing(model, plist, lift)
        self.assertEqual(len(d.curves), len(plist.steps))
        for curve, s in zip(d.curves, plist.steps):
            patch = model.patches[s.patch]
            for end, corner in ((curve[0], s.start), (curve[-1], s.finish)):
                sp = patch.evaluate(*CORNER_UV[corner])
                self.assertLess(np.linalg.norm(end - sp.P[0]), lift * 1.000001 + 1e-9)
        # a transit point wherever a step hands over without retracting
        self.assertEqual(len(d.transits), len(plist.steps) - 1 - plist.retractions)
        np.testing.assert_allclose(d.start, d.curves[0][0])
        np.testing.assert_allclose(d.finish, d.curves[-1][-1])

    def test_retraction_arcs_rise_above_the_surface(self):
        from tsplcam.plan import plan
        model = tsplcam.load(sample_path("keycap"))
        plist = plan(Layout.from_model(model))
        plist.steps[2].retract_before = True
        d = display.plan_drawing(model, plist)
        self.assertEqual(len(d.retractions), 1)
        arc = d.retractions[0]
        np.testing.assert_allclose(arc[0], d.curves[1][-1])
        np.testing.assert_allclose(arc[-1], d.curves[2][0])
        rise = np.linalg.norm(arc - arc[0], axis=1).max()
        self.assertGreater(rise, 0.03 * display.model_size(model))


class PathSegments(unittest.TestCase):
    def test_runs_of_one_move_cover_every_segment_once(self):
        rng = np.random.default_rng(3)
        pts = rng.normal(size=(200, 3))
        move = rng.integers(0, 4, 200)
        move[:50] = 0
        runs = display.segments_by_move(pts, move)
        seen = []
        for kind, lines in runs.items():
            for line in lines:
                # every segment of the run has this move at its end point
                idx = [int(np.nonzero((pts == p).all(axis=1))[0][0]) for p in line]
                self.assertEqual(idx, list(range(idx[0], idx[-1] + 1)))
                self.assertTrue((move[idx[1:]] == kind).all())
                seen += list(zip(idx[:-1], idx[1:]))
        self.assertEqual(sorted(seen), [(i, i + 1) for i in range(199)])
