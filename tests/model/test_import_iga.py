""".iga T-spline Bezier extraction files: parsing, rational evaluation, recovery of the
Bezier mesh (T-junctions, extraordinary points), patches and their parametrisation.

References are independent of the kernel: the measured values of docs/formats.md 1.4, closed forms
(circles, a global polynomial surface), a direct evaluation of the file's formula
x = sum_k (sum_a C[a,k] w_a x_a) B_k / sum_k (sum_a C[a,k] w_a) B_k with Bernstein
polynomials written out here, and finite differences.
"""
import os
import shutil
import tempfile
import unittest
from math import comb

import numpy as np

import tsplcam
from tsplcam.errors import InputError
from tsplcam.layout.layout import CORNER_UV, Layout
from tsplcam.model.bezier_mesh import bezier_model
from tsplcam.model.formats.iga import model_from_iga, read_iga
from tsplcam.model.cells import SQUARE_MAPS
from conftest import external

GEO = ("geopdes",)
REFERENCE = {   # docs/formats.md 1.4: element 0 at (s, t) = (0, 0), (0.5, 0.5), (1, 1)
    "square_structured": [(0.5, 0, 0), (0.75, 0.25, 0), (1, 0.5, 0)],
    "arch_nurbs": [(1, 0, 0), (1.106218539469, 0.204708433964, 0), (1.162235376328, 0.460118386952, 0)],
    "arch_tsplines": [(0, 1.5, 0), (0.068263498853, 1.529727641518, 0), (0.140397559215, 1.556179544708, 0)],
    "square_unstructured": [(0, 0.253115394271, 0), (0.076747755958, 0.297053951316, 0),
                            (0.148234776667, 0.342325464839, 0)],
}
EPS = {5: (0.61298, 0.38119), 3: (0.28027, 0.73564)}     # docs/formats.md 1.4: valence -> (x, y)
_CACHE = {}


def load(name, folder="geopdes"):
    key = (folder, name)
    if key not in _CACHE:
        _CACHE[key] = tsplcam.load(external(folder, name + ".iga"))
    return _CACHE[key]


def bern(n, x):
    x = np.asarray(x, float)
    return np.stack([comb(n, i) * x ** i * (1 - x) ** (n - i) for i in range(n + 1)], axis=-1)


def direct(iga, e, s, t):
    """The file's own formula, evaluated without the kernel (s fastest)."""
    el = iga.elements[e]
    B = (bern(el.q, t)[:, :, None] * bern(el.p, s)[:, None, :]).reshape(len(s), -1)   # k = j(p+1)+i
    w = iga.weights[el.nodes]
    num = B @ (el.C.T @ (w[:, None] * iga.points[el.nodes]))
    den = B @ (el.C.T @ w)
    return num / den[:, None]


def via_model(model, e, s, t):
    """Points of element e at (s, t) evaluated through the model's patches."""
    out = np.full((len(s), 3), np.nan)
    for pl in model.elements:
        if pl.element != e:
            continue
        sel = pl.contains(s, t)
        if sel.any():
            u, v = pl.uv_of(s[sel], t[sel])
            out[sel] = model.patches[pl.patch].evaluate(u, v).P
    return out


def polynomial_nets(rects, f, degree=3, syms=None):
    """Bezier nets of the surface (x, y, f(x, y)) over axis-aligned rectangles (exact for a
    polynomial f of degree <= degree), optionally re-oriented per element."""
    from tsplcam.model.basis import to_bernstein
    nets = []
    for k, (x0, x1, y0, y1) in enumerate(rects):
        xs = x0 + (x1 - x0) * np.linspace(0, 1, degree + 1)
        ys = y0 + (y1 - y0) * np.linspace(0, 1, degree + 1)
        X, Y = np.meshgrid(xs, ys)
        V = np.stack([X, Y, f(X, Y), np.ones_like(X)], -1)
        Q = to_bernstein(degree, to_bernstein(degree, V.transpose(1, 0, 2)).transpose(1, 0, 2))
        sym = syms[k] if syms else 0
        if sym & 1:
            Q = Q[:, ::-1]
        if sym & 2:
            Q = Q[::-1]
        if sym & 4:
            Q = Q.transpose(1, 0, 2)
        nets.append(Q)
    return nets


def cylinder_nets(R=2.0, H=3.0, around=4, along=2):
    """A closed tube of exact rational quadratic x linear elements."""
    nets = []
    for k in range(around):
        a0, a1 = 2 * np.pi * k / around, 2 * np.pi * (k + 1) / around
        h = (a1 - a0) / 2
        ring = [(np.cos(a0), np.sin(a0), 1.0), (np.cos(a0 + h) / np.cos(h), np.sin(a0 + h) / np.cos(h), np.cos(h)),
                (np.cos(a1), np.sin(a1), 1.0)]
        for j in range(along):
            Q = np.zeros((2, 3, 4))
            for jj, z in enumerate((H * j / along, H * (j + 1) / along)):
                for i, (x, y, w) in enumerate(ring):
                    Q[jj, i] = [R * x * w, R * y * w, z * w, w]
            nets.append(Q)
    return nets


def fd_check(testcase, patch, h=1e-6, n=60, seed=0):
    """First derivatives against central differences, second against differences of the
    first, in the interior of the cells of one patch."""
    rng = np.random.default_rng(seed)
    u, v = rng.uniform(0.02, 0.98, n), rng.uniform(0.02, 0.98, n)
    S = patch.evaluate(u, v)
    Su = (patch.evaluate(u + h, v).P - patch.evaluate(u - h, v).P) / (2 * h)
    Sv = (patch.evaluate(u, v + h).P - patch.evaluate(u, v - h).P) / (2 * h)
    Suu = (patch.evaluate(u + h, v).Pu - patch.evaluate(u - h, v).Pu) / (2 * h)
    Suv = (patch.evaluate(u, v + h).Pu - patch.evaluate(u, v - h).Pu) / (2 * h)
    scale1 = np.abs(S.Pu).max() + np.abs(S.Pv).max()
    scale2 = np.abs(S.Puu).max() + np.abs(S.Pvv).max() + 1.0
    # points within h of a cell line see both cells: compare only the rest
    far = np.ones(n, bool)
    for br, x in ((patch.ubreaks, u), (patch.vbreaks, v)):
        far &= np.abs(x[:, None] - br[None, :]).min(axis=1) > 2 * h
    testcase.assertGreater(far.sum(), n // 2)
    for a, b, sc in ((S.Pu, Su, scale1), (S.Pv, Sv, scale1), (S.Puu, Suu, scale2), (S.Puv, Suv, scale2)):
        testcase.assertLess(np.abs(a - b)[far].max() / sc, 1e-6)


class Reading(unittest.TestCase):
    def test_element_zero_reference_values(self):
        for name, ref in REFERENCE.items():
            iga = read_iga(external(*GEO, name + ".iga"))
            st = np.array([0.0, 0.5, 1.0])
            np.testing.assert_allclose(direct(iga, 0, st, st), ref, atol=1e-11, err_msg=name)
            np.testing.assert_allclose(via_model(load(name), 0, st, st), ref, atol=1e-11, err_msg=name)

    def test_crlf_comments_sets_and_domains(self):
        path = external(*GEO, "square_structured.iga")
        with open(path, "rb") as fh:
            self.assertIn(b"\r\n", fh.read())
        iga = read_iga(path)
        self.assertEqual(iga.type, "plane")
        self.assertEqual((len(iga.points), len(iga.elements)), (25, 4))
        self.assertEqual(iga.sets["Left_side"].items, [(2, "LEFT"), (3, "LEFT")])
        self.assertEqual(iga.elements[0].nodes[0], 1)            # 0-based, as written

    def test_mixed_degrees_in_square_unstructured(self):
        iga = read_iga(external(*GEO, "square_unstructured.iga"))
        kinds = sorted({(e.p, e.q, len(e.nodes)) for e in iga.elements})
        self.assertEqual(kinds, [(3, 3, 16), (4, 4, 14), (4, 4, 18)])
        m = load("square_unstructured")
        self.assertEqual(sorted({g.ctrl.shape[1:3] for p in m.patches for g in p.groups}), [(4, 4), (5, 5)])

    def test_both_copies_are_the_same_surface(self):
        a, b = load("square_unstructured"), load("square_unstructured", "msolve")
        self.assertEqual(b.iga.type, "surface")
        g = np.linspace(0, 1, 7)
        U, V = np.meshgrid(g, g)
        for pa, pb in zip(a.patches, b.patches):
            # the same numbers in both files: equal to 1e-12 of the unit square's size (not
            # bit for bit: nothing promises two evaluations round alike on every CPU)
            np.testing.assert_allclose(pa.evaluate(U.ravel(), V.ravel()).P,
                                       pb.evaluate(U.ravel(), V.ravel()).P, rtol=0, atol=1e-12)

    def test_model_evaluates_every_element_as_the_file_says(self):
        rng = np.random.default_rng(3)
        for name in REFERENCE:
            m = load(name)
            worst = 0.0
            for e in range(len(m.iga.elements)):
                s, t = rng.random(12), rng.random(12)
                s[:2], t[:2] = (0.0, 1.0), (1.0, 0.0)
                worst = max(worst, np.abs(via_model(m, e, s, t) - direct(m.iga, e, s, t)).max())
            self.assertLess(worst, 1e-13, name)


class Arch(unittest.TestCase):
    def test_inner_and_outer_sides_are_circles(self):
        g = np.linspace(0, 1, 101)
        for name, sets in (("arch_tsplines", ("Inner_side", "Outer_side")), ("arch_nurbs", None)):
            m = load(name)
            if sets:
                for set_name, r in zip(sets, (1.0, 2.0)):
                    for e, pos in m.iga.sets[set_name].items:
                        s, t = {"LEFT": (0 * g, g), "RIGHT": (1 + 0 * g, g), "BOTTOM": (g, 0 * g),
                                "TOP": (g, 1 + 0 * g)}[pos]
                        P = via_model(m, e, s, t)
                        self.assertLess(np.abs(np.linalg.norm(P[:, :2], axis=1) - r).max(), 1e-12)
            # whatever the file's sets: two of the patch's four edges are the circles
            p = m.patches[0]
            radii = []
            for edge in range(4):
                P = p.evaluate(*p.edge_params(edge, g)).P
                r = np.linalg.norm(P[:, :2], axis=1)
                if r.max() - r.min() < 1e-12:
                    radii.append(float(r.mean()))
            self.assertEqual(len(radii), 2, name)
            np.testing.assert_allclose(sorted(radii), [1.0, 2.0], rtol=0, atol=1e-12, err_msg=name)

    def test_tsplines_and_nurbs_are_the_same_surface(self):
        a, b = load("arch_nurbs"), load("arch_tsplines")
        self.assertEqual((len(a.patches), len(b.patches)), (1, 1))
        self.assertEqual(len(b.mesh_info.t_junctions), 8)
        self.assertEqual(len(a.mesh_info.t_junctions), 0)
        g = np.linspace(0, 1, 33)
        U, V = (x.ravel() for x in np.meshgrid(g, g))
        Pa = a.patches[0].evaluate(U, V).P
        # the recovered knot intervals make even the parametrisations agree, up to a symmetry
        best = min(np.abs(Pa - b.patches[0].evaluate(A[0, 0] * U + A[0, 1] * V + o[0],
                                                      A[1, 0] * U + A[1, 1] * V + o[1]).P).max()
                   for A, o in SQUARE_MAPS)
        self.assertLess(best, 1e-12)
        # and the surface is the quarter annulus r in [1, 2], angle in [0, 90] degrees
        for m in (a, b):
            P = m.patches[0].evaluate(U, V).P
            r, ang = np.hypot(P[:, 0], P[:, 1]), np.arctan2(P[:, 1], P[:, 0])
            self.assertTrue(np.all((r > 1 - 1e-12) & (r < 2 + 1e-12)))
            self.assertTrue(np.all((ang > -1e-12) & (ang < np.pi / 2 + 1e-12)))
            self.assertAlmostEqual(r.min(), 1.0, places=12)
            self.assertAlmostEqual(r.max(), 2.0, places=12)

    def test_parametrisation_is_c1_where_the_surface_is(self):
        for name in ("arch_nurbs", "arch_tsplines", "square_structured"):
            m = load(name)
            self.assertLess(m.mesh_info.ratio_rms, 1e-12, name)
            p = m.patches[0]
            # across every interior cell line: P_u and P_v agree from both sides
            for br, along in ((p.ubreaks[1:-1], "u"), (p.vbreaks[1:-1], "v")):
                for x in br:
                    t = np.linspace(0.01, 0.99, 25)
                    lo = p.evaluate(x - 1e-13 + 0 * t, t) if along == "u" else p.evaluate(t, x - 1e-13 + 0 * t)
                    hi = p.evaluate(x + 1e-13 + 0 * t, t) if along == "u" else p.evaluate(t, x + 1e-13 + 0 * t)
                    for d in ("Pu", "Pv"):
                        a, b = getattr(lo, d), getattr(hi, d)
                        self.assertLess(np.abs(a - b).max() / np.abs(a).max(), 1e-9, (name, along, x, d))


class Unstructured(unittest.TestCase):
    def test_two_extraordinary_points(self):
        for folder in ("geopdes", "msolve"):
            m = load("square_unstructured", folder)
            self.assertEqual(len(m.extraordinary), 2)
            found = {ep.valence: ep.position for ep in m.extraordinary}
            self.assertEqual(sorted(found), [3, 5])
            for val, xy in EPS.items():
                np.testing.assert_allclose(found[val][:2], xy, atol=6e-6)
                # exact by construction: every node of the plane has z = 0, so every sum of
                # products that makes the point's z is 0
                self.assertEqual(found[val][2], 0.0)
                self.assertFalse(next(ep for ep in m.extraordinary if ep.valence == val).boundary)
            self.assertEqual(m.mesh_info.t_junctions, [])

    def test_elements_at_the_extraordinary_points_are_quartic(self):
        m = load("square_unstructured")
        iga = m.iga
        at_ep = set()
        for ep in m.extraordinary:
            for e in range(len(iga.elements)):
                st = np.array([0.0, 1.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0, 1.0])
                if np.linalg.norm(direct(iga, e, *st) - ep.position, axis=1).min() < 1e-9:
                    at_ep.add((e, ep.valence))
        self.assertEqual(len(at_ep), 8)
        for e, val in at_ep:
            el = iga.elements[e]
            self.assertEqual((el.p, el.q, len(el.nodes)), (4, 4, 18 if val == 5 else 14))

    def test_patches_layout_and_continuity(self):
        m = load("square_unstructured")
        self.assertEqual(len(m.patches), 6)
        lay = Layout.from_model(m)
        self.assertEqual(len(lay.edge_links), 7)
        self.assertEqual(len(lay.extraordinary), 2)
        # the two EP nodes are corners of 5 and 3 patches
        for ep in m.extraordinary:
            self.assertEqual(int((lay.corner_nodes == ep.node).sum()), ep.valence)
        self.assertEqual(len(m.node_points), 12)
        # every patch is a square of cells covering the unit square and the model covers [0,1]^2
        lo, hi = m.bounding_box()
        np.testing.assert_allclose(lo[:2], [0, 0], atol=1e-12)
        np.testing.assert_allclose(hi[:2], [1, 1], atol=1e-12)
        area = 0.0
        g = (np.arange(40) + 0.5) / 40
        U, V = (x.ravel() for x in np.meshgrid(g, g))
        for p in m.patches:
            S = p.evaluate(U, V)
            area += np.abs(np.cross(S.Pu, S.Pv)[:, 2]).mean()
        self.assertAlmostEqual(area, 1.0, places=3)
        check_edges(self, m)


def check_edges(testcase, m, tol=1e-12):
    """Patches meet along whole edges with matching points, corners at their nodes;
    across edges the knot-unit transform carries first derivatives over away from EPs."""
    g = np.linspace(0, 1, 17)
    ep_nodes = {ep.node for ep in m.extraordinary}
    for p in m.patches:
        np.testing.assert_allclose(p.evaluate(CORNER_UV[:, 0], CORNER_UV[:, 1]).P,
                                   m.node_points[p.corner_nodes], atol=tol)
        for e, nb in enumerate(p.neighbours):
            if nb is None:
                continue
            q = m.patches[nb.patch]
            back = q.neighbours[nb.edge]
            testcase.assertEqual((back.patch, back.edge, back.reversed), (p.index, e, nb.reversed))
            A = p.evaluate(*p.edge_params(e, g))
            B = q.evaluate(*q.edge_params(nb.edge, g[::-1] if nb.reversed else g))
            testcase.assertLess(np.abs(A.P - B.P).max(), tol)
            if set(p.corner_nodes) & ep_nodes:
                continue
            L = m.edge_transform(p.index, e)[:, :2]
            Pu = B.Pu * L[0, 0] + B.Pv * L[1, 0]
            Pv = B.Pu * L[0, 1] + B.Pv * L[1, 1]
            scale = np.abs(A.Pu).max() + np.abs(A.Pv).max()
            testcase.assertLess((np.abs(A.Pu - Pu).max() + np.abs(A.Pv - Pv).max()) / scale, 1e-9)


class Lifted(unittest.TestCase):
    """square_unstructured's operators with lifted control points (docs/formats.md 1.4): a curved
    rational T-spline with the same two extraordinary points."""

    @classmethod
    def setUpClass(cls):
        iga = read_iga(external(*GEO, "square_unstructured.iga"))
        x, y = iga.points[:, 0], iga.points[:, 1]
        iga.points[:, 2] = 0.2 * np.sin(np.pi * x) * np.sin(np.pi * y)
        cls.iga = iga
        cls.model = model_from_iga(iga)

    def test_extraordinary_points_survive(self):
        m = self.model
        self.assertEqual(sorted(ep.valence for ep in m.extraordinary), [3, 5])
        for ep in m.extraordinary:
            np.testing.assert_allclose(ep.position[:2], EPS[ep.valence], atol=6e-6)
            self.assertGreater(ep.position[2], 0.05)

    def test_evaluation_matches_the_file_formula(self):
        rng = np.random.default_rng(5)
        worst = 0.0
        for e in range(len(self.iga.elements)):
            s, t = rng.random(8), rng.random(8)
            worst = max(worst, np.abs(via_model(self.model, e, s, t) - direct(self.iga, e, s, t)).max())
        self.assertLess(worst, 1e-13)

    def test_derivatives_continuity_no_nan(self):
        m = self.model
        for p in m.patches:
            fd_check(self, p)
            g = np.linspace(0, 1, 21)
            U, V = (x.ravel() for x in np.meshgrid(g, g))
            S = p.evaluate(U, V)
            for arr in (S.P, S.Pu, S.Pv, S.Puu, S.Puv, S.Pvv, S.normal):
                self.assertTrue(np.all(np.isfinite(arr)))
            np.testing.assert_allclose(np.linalg.norm(S.normal, axis=1), 1.0, atol=1e-12)
            self.assertGreater(S.normal[:, 2].min(), 0.5)     # one orientation: up
        check_edges(self, m)


class Recovery(unittest.TestCase):
    """Configurations the shipped files lack, on surfaces with a closed form."""

    @staticmethod
    def f(x, y):
        return 0.1 * x ** 3 - 0.2 * x * y * y + 0.3 * y + 0.05 * x * y

    def test_line_through_a_t_junction_stem_cuts_the_element(self):
        # L-shaped domain: the concave corner (1, 1) is a boundary point of valence 3; its
        # line down x = 1 meets the long bottom element's top side at a T-junction's stem
        rects = [(0, 2, 0, 0.5), (0, 1, 0.5, 1), (1, 2, 0.5, 1), (0, 1, 1, 2)]
        for syms in ([0, 0, 0, 0], [3, 5, 6, 1]):
            m = bezier_model(polynomial_nets(rects, self.f, syms=syms))
            self.assertEqual(m.mesh_info.splits, 1)
            self.assertEqual(len(m.patches), 3)
            self.assertEqual([(ep.valence, ep.boundary) for ep in m.extraordinary], [(3, True)])
            np.testing.assert_allclose(m.extraordinary[0].position, [1, 1, self.f(1, 1)], atol=1e-15)
            rng = np.random.default_rng(0)
            for p in m.patches:
                S = p.evaluate(rng.random(200), rng.random(200))
                self.assertLess(np.abs(S.P[:, 2] - self.f(S.P[:, 0], S.P[:, 1])).max(), 1e-14)
                # the chosen parametrisation is affine in (x, y): exactly the knot lines
                for d in (S.Puu, S.Puv, S.Pvv):
                    self.assertLess(np.abs(d[:, :2]).max(), 1e-12)
                fd_check(self, p)
            pieces = [pl.box for pl in m.elements if pl.element == 0]
            self.assertEqual(len(pieces), 2)                 # cut in half at the stem
            self.assertAlmostEqual(sum((b[1] - b[0]) * (b[3] - b[2]) for b in pieces), 1.0, places=15)
            # cut at the stem, x = 0.5 of the element: 1e-12 of its parameter range (a machine
            # with AVX-512 computed 0.4999999999999999)
            self.assertLess(min(abs(x - 0.5) for b in pieces for x in b), 1e-12)
            self.assertEqual(len(Layout.from_model(m).edge_links), 2)
            check_edges(self, m)

    def test_t_junctions_inside_a_patch(self):
        # a 4 x 4 grid with two elements split in half: T-junctions, one patch, still affine
        rects = []
        for i in range(4):
            for j in range(4):
                x0, x1, y0, y1 = i / 4, (i + 1) / 4, j / 4, (j + 1) / 4
                if (i, j) in ((1, 1), (2, 3)):
                    xm = (x0 + x1) / 2
                    rects += [(x0, xm, y0, y1), (xm, x1, y0, y1)]
                elif (i, j) == (3, 0):
                    ym = y0 + 0.3 * (y1 - y0)
                    rects += [(x0, x1, y0, ym), (x0, x1, ym, y1)]
                else:
                    rects.append((x0, x1, y0, y1))
        m = bezier_model(polynomial_nets(rects, self.f))
        self.assertEqual(len(m.patches), 1)
        self.assertEqual(len(m.mesh_info.t_junctions), 4)   # the others are on the boundary
        self.assertLess(m.mesh_info.ratio_rms, 1e-12)
        p = m.patches[0]
        S = p.evaluate(*np.random.default_rng(1).random((2, 300)))
        for d in (S.Puu, S.Puv, S.Pvv):
            self.assertLess(np.abs(d[:, :2]).max(), 1e-12)
        # the patch is the unit square with u along x (or y): P_u is constant
        self.assertLess(np.ptp(S.Pu[:, :2], axis=0).max(), 1e-12)

    def test_closed_tube_is_cut_at_a_seed(self):
        m = bezier_model(cylinder_nets())
        self.assertEqual(len(m.mesh_info.seeds), 1)
        self.assertEqual(len(m.patches), 2)
        self.assertEqual(m.extraordinary, [])
        rng = np.random.default_rng(2)
        for p in m.patches:
            S = p.evaluate(rng.random(500), rng.random(500))
            self.assertLess(np.abs(np.hypot(S.P[:, 0], S.P[:, 1]) - 2.0).max(), 1e-14)
            self.assertEqual(sum(nb is not None and nb.patch == p.index for nb in p.neighbours), 2)
        check_edges(self, m)

    def test_duplicate_elements_are_dropped(self):
        src = external(*GEO, "square_structured.iga")
        el = read_iga(src).elements[0]
        block = [f"belem {len(el.nodes)} {el.p} {el.q}", " ".join(map(str, el.nodes))]
        block += [" ".join(repr(float(x)) for x in row) for row in el.C]
        with open(src) as fh:
            text = fh.read().replace("elemN 4", "elemN 5")
        text = text.replace("\nset 2 side Left_side", "\n" + "\n".join(block) + "\nset 2 side Left_side", 1)
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "dup.iga")
            with open(path, "w") as fh:
                fh.write(text)
            m = tsplcam.load(path)
        self.assertEqual(len(m.iga.elements), 5)
        self.assertEqual(m.mesh_info.duplicates, [(4, 0)])
        ref = load("square_structured")
        g = np.linspace(0, 1, 9)
        np.testing.assert_allclose(m.patches[0].evaluate(g, g[::-1]).P, ref.patches[0].evaluate(g, g[::-1]).P,
                                   atol=1e-15)


class Errors(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp()
        with open(external(*GEO, "arch_tsplines.iga")) as fh:
            self.lines = fh.read().split("\n")

    def tearDown(self):
        shutil.rmtree(self.dir, ignore_errors=True)

    def write(self, lines, name="bad.iga"):
        path = os.path.join(self.dir, name)
        with open(path, "w") as fh:
            fh.write("\n".join(lines))
        return path

    def expect(self, lines, line, *words):
        path = self.write(lines)
        with self.assertRaises(InputError) as cm:
            tsplcam.load(path)
        err = cm.exception
        self.assertEqual(err.path, path)
        self.assertEqual(err.line, line, str(err))
        for w in words:
            self.assertIn(w, str(err))
        return err

    def test_truncated_inside_an_element(self):
        cut = 130                                 # inside element 0 (belem on line 123)
        self.expect(self.lines[:cut], 123, "element 0", "ends early")

    def test_truncated_between_elements(self):
        starts = [i for i, s in enumerate(self.lines) if s.startswith("belem")]
        self.expect(self.lines[:starts[9]], 3, "elemN says 80", "has 9", "truncated")

    def test_bad_number_names_its_line(self):
        lines = list(self.lines)
        lines[124] = lines[124].replace("0", "0x", 1)
        self.expect(lines, 125, "not a number")

    def test_node_index_out_of_range(self):
        lines = list(self.lines)
        lines[123] = "16 17 38 39 42 43 76 77 78 79 80 81 115 116 117 119"
        self.expect(lines, 124, "outside 0..118")

    def test_row_length(self):
        lines = list(self.lines)
        lines[130] = " ".join(lines[130].split()[:-1])
        self.expect(lines, 131, "row 7", "needs 16")

    def test_header(self):
        self.expect(self.lines[1:], 3, "no 'type' line")       # at the first node
        lines = list(self.lines)
        lines[0] = "type volume"
        self.expect(lines, 1, "not supported")
        lines = list(self.lines)
        lines[3] = "node 1 2 3"
        self.expect(lines, 4, "x y z w")
        lines = list(self.lines)
        lines[3] = "node 1 2 3 0"
        self.expect(lines, 4, "weight")
        lines = list(self.lines)
        lines[5] = "vertex 1 2 3 1"
        self.expect(lines, 6, "unknown record")

    def test_geometry_errors_name_the_element(self):
        lines = list(self.lines)
        # one extraction coefficient of element 0 changed: it no longer meets its neighbours
        row = lines[124].split()
        row[1] = "0.5"
        lines[124] = " ".join(row)
        path = self.write(lines)
        with self.assertRaises(InputError) as cm:
            tsplcam.load(path)
        self.assertEqual(cm.exception.path, path)
        self.assertIsNotNone(cm.exception.line)
        self.assertIn("element", str(cm.exception))

    def test_no_crash_on_truncation_or_corruption(self):
        rng = np.random.default_rng(7)
        text = "\n".join(self.lines)
        cases = [text[:int(n)] for n in rng.integers(0, len(text), 25)]
        for _ in range(25):
            lines = list(self.lines)
            i = int(rng.integers(len(lines)))
            tok = lines[i].split(" ")
            tok[int(rng.integers(len(tok)))] = str(rng.choice(["-1", "1e9", "0", "nan", "1e400", "x"]))
            lines[i] = " ".join(tok)
            cases.append("\n".join(lines))
        for k, t in enumerate(cases):
            path = os.path.join(self.dir, f"c{k}.iga")
            with open(path, "w") as fh:
                fh.write(t)
            try:
                m = tsplcam.load(path)
            except InputError as err:
                self.assertEqual(err.path, path)
                continue
            for p in m.patches:                 # what loads must evaluate
                self.assertTrue(np.all(np.isfinite(p.evaluate([0.5], [0.5]).P)))

    def test_empty_and_binary(self):
        self.expect([""], 1, "no 'type' line")          # an empty file: its first line
        path = os.path.join(self.dir, "bin.iga")
        with open(path, "wb") as fh:
            fh.write(b"\x00\x01\x02type plane")
        with self.assertRaises(InputError):
            tsplcam.load(path)


if __name__ == "__main__":
    unittest.main()
