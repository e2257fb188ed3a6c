"""The verification module against closed forms and brute force, on paths built by hand
(not by the generator): parallel lines on a plane and on a cylinder, chords across a
convex curve, a point pushed into the surface, and the KD-tree search against all capsules."""
import unittest

import numpy as np

from tsplcam.model.bspline import bspline_patch
from conftest import cylinder_patch, one_patch_model
from tsplcam.toolpath.path import Move, ToolPath
from tsplcam.verify.metrics import compare_table, path_metrics
from tsplcam.verify.scallop import Swept, measure, surface_grid




def plane(W=10.0, H=6.0):
    poles = np.array([[[0, 0, 0], [0, H, 0]], [[W, 0, 0], [W, H, 0]]], float)
    return one_patch_model(bspline_patch(poles, None, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1))




def zigzag_by_hand(contacts_per_line, normals_per_line, r, patch=0):
    """A ToolPath from lists of (m, 3) contact arrays, alternating direction, LINK between."""
    P, N, M, L = [], [], [], []
    for k, (c, n) in enumerate(zip(contacts_per_line, normals_per_line)):
        if k % 2:
            c, n = c[::-1], n[::-1]
        mv = np.full(len(c), Move.CUT)
        mv[0] = Move.LINK if k else Move.CUT
        P.append(c), N.append(n), M.append(mv), L.append(np.full(len(c), k))
    P, N = np.concatenate(P), np.concatenate(N)
    n = len(P)
    return ToolPath(P, N, N, np.concatenate(M), np.full(n, patch), np.zeros((n, 2)), np.concatenate(L), r,
                    info={"settings": {}})


class FlatCusps(unittest.TestCase):
    """Straight parallel lines a distance w apart on a plane: the cusp is r - sqrt(r^2 - w^2/4)."""

    @classmethod
    def setUpClass(cls):
        cls.r, cls.w = 1.0, 0.4
        cls.model = plane(10.0, 6.0)
        xs = np.arange(0.0, 10.0 + 1e-9, cls.w)
        y = np.linspace(0.0, 6.0, 13)
        lines = [np.column_stack([np.full_like(y, x), y, np.zeros_like(y)]) for x in xs]
        normals = [np.tile([0.0, 0.0, 1.0], (len(y), 1)) for _ in xs]
        cls.path = zigzag_by_hand(lines, normals, cls.r)
        cls.h = cls.r - np.sqrt(cls.r ** 2 - cls.w ** 2 / 4)
        cls.rep = measure(cls.path, cls.model, scallop=cls.h)

    def test_kept_heights_are_the_measured_ones(self):
        # measure(heights=True) keeps every sample and ridge it measured, and changes nothing
        rep = measure(self.path, self.model, scallop=self.h, heights=True)
        self.assertEqual(rep.as_dict(), self.rep.as_dict())
        hs = rep.heights
        self.assertEqual(int(np.count_nonzero(~hs.ridge)), rep.samples - rep.uncovered)
        self.assertEqual(int(np.count_nonzero(hs.ridge)), rep.ridges)
        self.assertEqual(float(hs.height.max()), rep.max_scallop)
        self.assertTrue(np.all(hs.patch == 0))
        self.assertTrue(np.all((hs.uv >= 0) & (hs.uv <= 1)))
        # the heights at grid samples follow the circle between two lines: h(x) = r - sqrt(r^2 - d^2)
        grid = ~hs.ridge
        P = self.model.patches[0].evaluate(hs.uv[grid, 0], hs.uv[grid, 1]).P
        d = np.abs((P[:, 0] + 0.5 * self.w) % self.w - 0.5 * self.w)
        inside = (P[:, 1] > 0.6) & (P[:, 1] < 5.4) & (P[:, 0] > 0.5) & (P[:, 0] < 9.5)
        expect = self.r - np.sqrt(self.r ** 2 - d ** 2)
        self.assertLess(float(np.abs(hs.height[grid][inside] - expect[inside]).max()), 1e-9)

    def test_one_patch_shared_among_processes(self):
        """A lone patch's samples and ridges measured in two processes (``_measure_patches``'
        split, several pieces of each) give the report of one process: every figure, cusp
        height and kept height the same bytes."""
        from unittest import mock

        from tsplcam.toolpath import parallel
        from tsplcam.verify import scallop
        if parallel.worker_count(2, 2) < 2:
            self.skipTest("no second process here")
        with mock.patch.dict("os.environ", {"TSPLCAM_WORKERS": "1"}):
            one = measure(self.path, self.model, scallop=self.h, spacing=0.02, heights=True)
        with mock.patch.dict("os.environ", {"TSPLCAM_WORKERS": "2"}), \
                mock.patch.object(scallop, "SPLIT_SAMPLES", 1000), mock.patch.object(scallop, "RIDGE_ROWS", 500), \
                mock.patch.object(parallel, "map_pieces", wraps=parallel.map_pieces) as mp:
            two = measure(self.path, self.model, scallop=self.h, spacing=0.02, heights=True)
        shared = [c for c in mp.call_args_list if c.args[0] in (scallop._grid_rows, scallop._ridge_rows)]
        self.assertEqual({c.args[0] for c in shared}, {scallop._grid_rows, scallop._ridge_rows})
        self.assertTrue(all(c.args[3] == 2 and c.args[2] > 2 for c in shared))     # pieces, processes
        self.assertEqual(two.as_dict(), one.as_dict())
        self.assertEqual(two.cusp_heights.tobytes(), one.cusp_heights.tobytes())
        for a, b in zip((one.heights.patch, one.heights.uv, one.heights.height, one.heights.ridge),
                        (two.heights.patch, two.heights.uv, two.heights.height, two.heights.ridge)):
            self.assertEqual(a.tobytes(), b.tobytes())

    def test_cusp_heights_match_closed_form(self):
        rep = self.rep
        self.assertEqual(rep.uncovered, 0)
        self.assertGreater(rep.cusps, 100)
        self.assertAlmostEqual(rep.cusp_max / self.h, 1.0, places=5)
        self.assertAlmostEqual(rep.cusp_mean / self.h, 1.0, places=5)
        self.assertAlmostEqual(rep.max_scallop / self.h, 1.0, places=5)

    def test_mean_material_matches_profile_integral(self):
        # mean of r - sqrt(r^2 - x^2) over x in [0, w/2] (the material profile between lines)
        half = self.w / 2
        x = np.linspace(0, half, 200001)
        ref = np.trapz(self.r - np.sqrt(self.r ** 2 - x ** 2), x) / half
        # a spacing unrelated to w (samples at all phases between the lines), away from the
        # edges where the links between the lines cut the cusps down
        rep = measure(self.path, self.model, scallop=self.h, spacing=0.0371, region=(0, 1, 0.2, 0.8))
        self.assertAlmostEqual(rep.mean_material / ref, 1.0, delta=0.01)
        self.assertAlmostEqual(ref / self.h, 1 / 3, delta=0.01)       # a circular cusp's mean is about h/3

    def test_no_gouge_on_exact_path(self):
        self.assertLess(self.rep.gouge_points, 1e-12)
        self.assertLess(self.rep.gouge_chords, 1e-12)

    def test_pushed_point_is_a_gouge(self):
        p = self.path
        contact = p.contact.copy()
        contact[40, 2] -= 0.01                        # the ball moved 0.01 mm into the plane
        bad = ToolPath(contact, p.normal, p.axis, p.move, p.patch, p.uv, p.line, p.tool_radius, info=p.info)
        rep = measure(bad, self.model, scallop=self.h)
        self.assertAlmostEqual(rep.gouge_points, 0.01, places=9)

    def test_missing_line_shows_as_scallop(self):
        """Leave one line out: the material there is the cusp of a gap 2w."""
        xs = np.delete(np.arange(0.0, 10.0 + 1e-9, self.w), 10)
        y = np.linspace(0.0, 6.0, 13)
        lines = [np.column_stack([np.full_like(y, x), y, np.zeros_like(y)]) for x in xs]
        path = zigzag_by_hand(lines, [np.tile([0.0, 0.0, 1.0], (len(y), 1)) for _ in xs], self.r)
        rep = measure(path, self.model, scallop=self.h)
        wide = self.r - np.sqrt(self.r ** 2 - (2 * self.w) ** 2 / 4)
        self.assertAlmostEqual(rep.max_scallop / wide, 1.0, places=5)
        self.assertAlmostEqual(rep.cusp_max / wide, 1.0, places=5)


class CylinderCusps(unittest.TestCase):
    """Lines along the axis of a cylinder, ball centres on the circle R + r (convex) or R - r
    (concave); the cusp is where the two circles of radius r meet, found here in 2D."""

    def check(self, outward):
        R, r, H = 10.0, 1.0, 5.0
        model = one_patch_model(cylinder_patch(R, H, outward=outward))
        ang = np.radians(np.linspace(-40, 40, 41))
        dth = ang[1] - ang[0]
        z = np.linspace(0, H, 11)
        sgn = 1.0 if outward else -1.0
        lines, normals = [], []
        for a in ang:
            n = sgn * np.array([np.cos(a), np.sin(a), 0.0])
            lines.append(np.column_stack([R * np.cos(a) + 0 * z, R * np.sin(a) + 0 * z, z]))
            normals.append(np.tile(n, (len(z), 1)))
        path = zigzag_by_hand(lines, normals, r)
        Rc = R + sgn * r
        half = Rc * np.sin(dth / 2)
        root = np.sqrt(r * r - half * half)
        if outward:
            h = Rc * np.cos(dth / 2) - root - R
        else:
            h = R - (Rc * np.cos(dth / 2) + root)
        rep = measure(path, model, scallop=h)
        self.assertEqual(rep.uncovered, 0)
        self.assertAlmostEqual(rep.cusp_max / h, 1.0, places=5)
        self.assertAlmostEqual(rep.cusp_mean / h, 1.0, places=4)
        self.assertLess(rep.gouge_points, 1e-9)

    def test_convex(self):
        self.check(True)

    def test_concave(self):
        self.check(False)

    def test_chord_sag_on_convex_circle_is_the_overcut(self):
        """Points every phi around the convex cylinder: the centre chord cuts (R + r)(1 - cos(phi/2))."""
        R, r, H = 10.0, 1.0, 5.0
        model = one_patch_model(cylinder_patch(R, H))
        phi = np.radians(4.0)
        ang = np.arange(-np.radians(40), np.radians(40) + 1e-12, phi)
        lines, normals = [], []
        for zz in np.linspace(0, H, 9):
            n = np.column_stack([np.cos(ang), np.sin(ang), 0 * ang])
            lines.append(np.column_stack([R * np.cos(ang), R * np.sin(ang), np.full_like(ang, zz)]))
            normals.append(n)
        path = zigzag_by_hand(lines, normals, r)
        rep = measure(path, model, scallop=0.01)
        self.assertAlmostEqual(rep.gouge_chords, (R + r) * (1 - np.cos(phi / 2)), places=9)
        self.assertLess(rep.gouge_points, 1e-9)


class NearSearch(unittest.TestCase):
    """The KD-tree search over capsule pieces against all capsules (brute force)."""

    @classmethod
    def setUpClass(cls):
        r = 0.5
        cls.model = one_patch_model(cylinder_patch(8.0, 4.0, outward=False))
        rng = np.random.default_rng(1)
        ang = np.sort(rng.uniform(-0.69, 0.69, 60))
        ang[0], ang[-1] = -np.radians(40), np.radians(40)
        z = np.linspace(0, 4.0, 9)
        lines = [np.column_stack([8 * np.cos(a) + 0 * z, 8 * np.sin(a) + 0 * z, z]) for a in ang]
        normals = [np.tile([-np.cos(a), -np.sin(a), 0.0], (len(z), 1)) for a in ang]
        cls.sw = Swept(zigzag_by_hand(lines, normals, r), piece=0.1)
        cls.grid = surface_grid(cls.model, 0.2)

    def test_kdtree_never_hides_material(self):
        sw, grid = self.sw, self.grid
        rng = np.random.default_rng(1)
        sel = rng.choice(len(grid), 400, replace=False)
        p, n = grid.P[sel], grid.n[sel]
        h_kd, _ = sw.height(p, n)
        brute = np.full(len(p), np.inf)
        allidx = np.arange(len(sw.a))
        for s in range(0, len(p), 20):
            e = slice(s, s + 20)
            lam = sw.entry(p[e], n[e], np.tile(allidx, (len(p[e]), 1)))
            brute[e] = lam.min(axis=1)
        self.assertTrue(np.all(h_kd >= brute - 1e-12))
        np.testing.assert_allclose(h_kd, brute, atol=1e-12)

    def test_ridge_candidates_hide_no_material(self):
        # a ridge's candidates, asked at the ends and middle of its parameter segment, give
        # every point of the segment each owner's height as all that owner's capsules do
        sw, grid, patch = self.sw, self.grid, self.model.patches[0]
        _, own = sw.height(grid.P, grid.n)
        pid, off, nu, nv = grid.shapes[0]
        ids = np.arange(nu * nv).reshape(nu, nv)
        pairs = np.concatenate([np.column_stack([ids[:-1].ravel(), ids[1:].ravel()]),
                                np.column_stack([ids[:, :-1].ravel(), ids[:, 1:].ravel()])])
        pairs = pairs[own[pairs[:, 0]] != own[pairs[:, 1]]]
        A, B = own[pairs[:, 0]], own[pairs[:, 1]]
        ends = [grid.uv[pairs[:, 0]], grid.uv[pairs[:, 1]]]

        def at(t):
            uv = ends[0] + t * (ends[1] - ends[0])
            sp = patch.evaluate(uv[:, 0], uv[:, 1])
            return sp.P, sp.normal

        near = sw.ridge_candidates((at(0.0), at(1.0), at(0.5)), A, B)
        self.assertGreater(len(pairs), 100)
        lam_all = None
        for t in (0.0, 0.3, 0.5, 0.85, 1.0):
            p, n = at(t)
            la, lb = sw.heights_among(p, n, near)
            lam_all = np.concatenate([sw.entry(p[s:s + 20], n[s:s + 20], np.tile(np.arange(len(sw.a)), (len(p[s:s + 20]), 1)))
                                      for s in range(0, len(p), 20)])
            for got, owner in ((la, A), (lb, B)):
                brute = np.where(sw.owner[None, :] == owner[:, None], lam_all, np.inf).min(axis=1)
                np.testing.assert_allclose(got, brute, atol=1e-12)


    def test_compiled_entries_are_numpys(self):
        """The compiled capsule entries (``compiled.capsule_entries``) give numpy's bits, at grid
        points near the path (hits from outside and inside, misses) and at points pushed
        along the normals and across them (inside the swept volume, far from it)."""
        from unittest import mock

        from tsplcam import compiled
        from tsplcam.verify import scallop
        if compiled.kernels() is None:
            self.skipTest("no compiled kernels (numba is not installed)")
        sw, grid = self.sw, self.grid
        rng = np.random.default_rng(3)
        sel = rng.choice(len(grid), 3000)
        p = grid.P[sel] + rng.normal(size=(len(sel), 3)) * rng.choice([0.0, 0.05, 0.6], (len(sel), 1))
        n = grid.n[sel]
        idx = sw.candidates(p, n)
        idx[::7, -3:] = rng.integers(0, len(sw.a), (len(idx[::7]), 3))       # far capsules too
        got = sw.entry(p, n, idx)
        with mock.patch.object(scallop, "compiled", mock.Mock(kernels=lambda work=None: None)):
            want = sw.entry(p, n, idx)
        self.assertTrue(np.isfinite(got).any() and np.isinf(got).any() and (got < 0).any())
        self.assertEqual(got.tobytes(), want.tobytes())
        # each owner's least entry among marked candidates (a ridge's bisection), against
        # numpy's on the gathered candidates
        of_a, of_b = rng.random(idx.shape) < 0.4, rng.random(idx.shape) < 0.4
        got = sw.heights_among(p, n, (idx, of_a, of_b))
        want = sw.heights_among(p, n, (sw.gather(idx), of_a, of_b))
        self.assertTrue(np.isinf(got[0]).any() and np.isfinite(got[1]).any())
        for g, w in zip(got, want):
            self.assertEqual(g.tobytes(), w.tobytes())



class CellSearch(unittest.TestCase):
    """The kernels' neighbour search on a table of cells (``compiled.k_nearest``, the
    candidates' and the gouge check's) against scipy's kd-tree: the same neighbours in the same
    order and the same distances bit for bit, wherever it does not flag a tie; the callers then
    ask the tree, so their rows are the tree's everywhere."""

    def setUp(self):
        from tsplcam import compiled
        if compiled.kernels() is None:
            self.skipTest("no compiled kernels (numba is not installed)")
        self.compiled = compiled

    @staticmethod
    def point_sets(rng):
        g = np.arange(9) * 0.25                                     # a lattice: exact ties
        yield "lattice", np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
        yield "uniform", rng.uniform(-5, 5, (3000, 3))
        shell = rng.normal(size=(2500, 3))
        yield "shell", 3.0 * shell / np.linalg.norm(shell, axis=1, keepdims=True)
        yield "repeated", np.repeat(rng.uniform(-1, 1, (400, 3)), 3, axis=0)
        yield "flat", np.column_stack([rng.uniform(0, 20, 3000), rng.uniform(0, 2, 3000), np.zeros(3000)])

    def test_same_neighbours_as_the_tree(self):
        from scipy.spatial import cKDTree
        rng = np.random.default_rng(11)
        k_near = self.compiled.kernels()["k_nearest"]
        flagged = {}
        for name, P in self.point_sets(rng):
            tree = cKDTree(P)
            X = np.concatenate([rng.uniform(-9, 9, (400, 3)),                     # far and near
                                P[rng.integers(0, len(P), 300)] + rng.normal(scale=0.05, size=(300, 3)),
                                P[rng.integers(0, len(P), 60)]])                  # on the points
            for edge in (0.05, 0.4, 3.0):
                table = self.compiled.cell_table(P, edge, 4_000_000)
                origin, h, shape, start, items, pts = table
                for k, ub in ((1, np.inf), (16, np.inf), (2, 0.57), (7, 1.5)):
                    j = np.empty((len(X), k), np.int64)
                    d = np.empty((len(X), k))
                    tie = np.empty(len(X), bool)
                    k_near(X, pts, items, start, origin, h, shape, k, ub, j, d, tie)
                    dt, jt = tree.query(X, k=k, distance_upper_bound=ub)
                    dt, jt = dt.reshape(len(X), k), jt.reshape(len(X), k)
                    ok = ~tie
                    what = f"{name}, edge {edge}, k {k}, ub {ub}"
                    np.testing.assert_array_equal(j[ok], jt[ok], what)
                    self.assertEqual(d[ok].tobytes(), dt[ok].tobytes(), what)
                    flagged[name] = flagged.get(name, 0) + int(tie.sum())
        self.assertGreater(flagged["lattice"], 0)                  # the ties are found
        self.assertEqual(flagged["uniform"] + flagged["shell"], 0)

    def test_callers_give_the_trees_rows(self):
        """``Swept.candidates`` and the gouge check's sample search: the tree's rows, ties and
        all (a zigzag of equally spaced lines on a plane, asked at a lattice, where every row
        ties, and at points moved off it, where none does)."""
        from unittest import mock

        from tsplcam.verify import scallop
        rng = np.random.default_rng(2)
        x = np.linspace(0.0, 10.0, 41)
        lines = [np.column_stack([x, np.full(41, y), np.zeros(41)]) for y in np.arange(12) * 0.5]
        up = [np.tile([0.0, 0.0, 1.0], (41, 1))] * len(lines)
        sw = Swept(zigzag_by_hand(lines, up, 0.5), piece=0.1)
        self.assertTrue(sw.near.cells)
        g = np.arange(0.0, 10.0, 0.125)
        P = np.column_stack([np.repeat(g, 45), np.tile(np.arange(45) * 0.125, len(g)), np.zeros(45 * len(g))])
        P = np.concatenate([P, P[::2] + rng.normal(scale=0.02, size=(len(P[::2]), 3)) * [1.0, 1.0, 0.0]])
        n = np.tile([0.0, 0.0, 1.0], (len(P), 1))
        got = sw.candidates(P, n)
        near = scallop._Nearest(P, 0.75)
        X = P[rng.integers(0, len(P), 500)] + [0.0, 0.0, 0.5]
        got_d, got_j = near.query(X, 2)
        off = mock.Mock(kernels=lambda work=None: None, loaded=lambda: None)
        with mock.patch.object(scallop, "compiled", off):
            want = Swept(zigzag_by_hand(lines, up, 0.5), piece=0.1).candidates(P, n)
            want_d, want_j = scallop._Nearest(P, 0.75).query(X, 2)
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(got_j, want_j)
        self.assertEqual(got_d.tobytes(), want_d.tobytes())

    def test_large_part_keeps_the_tree(self):
        """Where the table's cell cap would make cells far larger than asked (a large part),
        the kd-tree answers: the same rows."""
        from unittest import mock

        from tsplcam.verify import scallop
        x = np.linspace(0.0, 10.0, 41)
        lines = [np.column_stack([x, np.full(41, y), np.full(41, 0.5 * y)]) for y in np.arange(12) * 0.5]
        up = [np.tile([0.0, 0.0, 1.0], (41, 1))] * len(lines)
        P = np.random.default_rng(3).uniform(0, 5, (300, 3)) * [2.0, 1.0, 0.5]
        n = np.tile([0.0, 0.0, 1.0], (len(P), 1))
        want = Swept(zigzag_by_hand(lines, up, 0.5), piece=0.1).candidates(P, n)
        with mock.patch.object(scallop, "NEAR_CELLS", 50):
            sw = Swept(zigzag_by_hand(lines, up, 0.5), piece=0.1)
            self.assertIs(sw.near.cells, False)
            np.testing.assert_array_equal(sw.candidates(P, n), want)
            near = scallop._Nearest(P, 0.1)
            near.query(P, 2)
            self.assertIs(near.cells, False)

    def test_cell_table_kernel_is_numpys(self):
        """The table sorted by the kernel (``cell_sort``) and by numpy: the same arrays."""
        rng = np.random.default_rng(4)
        for P in (rng.uniform(0, 7, (20000, 3)) * [1.0, 1.0, 0.01], np.round(rng.normal(size=(3000, 3)), 1),
                  np.zeros((5, 3))):
            for edge in (0.02, 0.3, 4.0):
                got = self.compiled.cell_table(P, edge, 100_000)
                k = self.compiled._STATE.pop("k")
                try:
                    want = self.compiled.cell_table(P, edge, 100_000)
                finally:
                    self.compiled._STATE["k"] = k
                for a, b in zip(got, want):
                    np.testing.assert_array_equal(a, b)
        with self.assertRaises(ValueError):
            self.compiled.cell_table(np.array([[0.0, np.nan, 0.0]]), 1.0, 64)

class Metrics(unittest.TestCase):

    def test_lengths_by_kind(self):
        P = np.array([[0, 0, 0], [3, 0, 0], [3, 1, 0], [0, 1, 0], [0, 1, 10], [5, 5, 10], [5, 5, 0], [9, 5, 0]], float)
        n = np.tile([0.0, 0.0, 1.0], (len(P), 1))
        mv = np.array([Move.CUT, Move.CUT, Move.LINK, Move.CUT, Move.RETRACT, Move.RAPID, Move.LINK, Move.CUT])
        patch = np.array([0, 0, 0, 0, -1, -1, 0, 0])
        tp = ToolPath(P, n, n, mv, patch, np.zeros((8, 2)), np.array([0, 0, 1, 1, -1, -1, 2, 2]), 1.0)
        m = path_metrics(tp)
        self.assertEqual((m.points, m.lines, m.retractions, m.rapid_moves, m.air_moves), (8, 3, 1, 1, 3))
        self.assertAlmostEqual(m.cut_length, 3 + 3 + 4)
        self.assertAlmostEqual(m.link_length, 1)
        self.assertAlmostEqual(m.air_length, 10 + np.sqrt(41) + 10)
        self.assertIn("retractions", compare_table({"a": m, "b": m}))



class GridInRows(unittest.TestCase):
    """``surface_grid`` evaluates a patch whole rows of cells at a time (``GRID_CHUNK``
    samples or so): the same samples, normals and parameters, bit for bit and in the same
    memory layout, as the whole grid's evaluation gave them (its blocks are the same), on a
    T-spline of many cells with an extraordinary point (figure 4) and a one-patch T-spline."""

    @staticmethod
    def whole(model, spacing):
        """The grid as it was made before: each patch's grid evaluated at once, concatenated."""
        from tsplcam.verify import scallop as S
        pp, uvs, Ps, ns = [], [], [], []
        for p in model.patches:
            g = np.linspace(0, 1, 17)
            P = p.evaluate_grid(g, g).P.reshape(17, 17, 3)
            su = float(np.linalg.norm(np.diff(P, axis=0), axis=2).sum(axis=0).max())
            sv = float(np.linalg.norm(np.diff(P, axis=1), axis=2).sum(axis=1).max())
            nu, nv = max(2, int(np.ceil(su / spacing)) + 1), max(2, int(np.ceil(sv / spacing)) + 1)
            gu = np.clip(np.linspace(0, 1, nu), S.GRID_EPS, 1 - S.GRID_EPS)
            gv = np.clip(np.linspace(0, 1, nv), S.GRID_EPS, 1 - S.GRID_EPS)
            sp = p.evaluate_grid(gu, gv, second=False)
            pp.append(np.full(nu * nv, p.index))
            uvs.append(np.column_stack([sp.u, sp.v]))
            Ps.append(sp.P)
            ns.append(sp.normal)
        return [np.concatenate(x) for x in (pp, uvs, Ps, ns)]

    def test_same_as_whole(self):
        from unittest import mock

        from tsplcam import load_model
        from tsplcam.verify import scallop as S
        for name, spacing in (("figure4", 0.4), ("tjunction_mold", 0.2)):
            model = load_model(name)
            want = self.whole(model, spacing)
            with mock.patch.object(S, "GRID_CHUNK", 3000):        # several chunks a patch
                got = surface_grid(model, spacing)
                one = surface_grid(model, spacing, [0])
            for a, b in zip(want, (got.patch, got.uv, got.P, got.n)):
                self.assertEqual((a.shape, a.strides), (b.shape, b.strides), name)
                self.assertEqual(a.tobytes(), b.tobytes(), name)
            first = want[0] == 0
            for a, b in zip(want, (one.patch, one.uv, one.P, one.n)):
                self.assertEqual(a[first].tobytes(), np.ascontiguousarray(b).tobytes(), name)
            rows = list(S._cell_rows(model.patches[0], np.linspace(0, 1, 200), 3000 // 50))
            self.assertGreater(len(rows), 1)
            self.assertEqual([r[0] for r in rows[1:]], [r[1] for r in rows[:-1]])


if __name__ == "__main__":
    unittest.main()
