"""The surface kernel on Catmull-Clark cages, checked against independent references:
OpenSubdiv's Hbr refinement baselines, closed-form limit masks, published eigenvalues."""
import functools
import os
import tempfile
import unittest

import numpy as np
from scipy.spatial import cKDTree

import tsplcam
from tsplcam.errors import InputError
from tsplcam.layout.layout import CORNER_UV, Layout
from tsplcam.model.cage import Cage, cage_model
from tsplcam.model.eigen import scheme_for
from tsplcam.model.formats.obj import read_obj
from tsplcam.model.quadmesh import QuadMesh
from tsplcam.model.samples import sample_path
from conftest import assert_finite_everywhere, curvature_gap, edge_pair, external, ngon_prism




def closed_form_limit(mesh: QuadMesh, P: np.ndarray, v: int):
    """Catmull-Clark limit position and normal of interior vertex v from the closed-form
    masks (position: (n^2 v + 4 sum e + sum f) / (n (n + 5)); tangents: Halstead, Kass and
    DeRose 1993)."""
    fan, boundary = mesh.fan(v)
    assert not boundary
    n = len(fan)
    e = np.array([P[mesh.faces[f][(k + 1) % 4]] for f, k in fan])
    fv = np.array([P[mesh.faces[f][(k + 2) % 4]] for f, k in fan])
    pos = (n * n * P[v] + 4 * e.sum(0) + fv.sum(0)) / (n * (n + 5))
    An = 1 + np.cos(2 * np.pi / n) + np.cos(np.pi / n) * np.sqrt(2 * (9 + np.cos(2 * np.pi / n)))
    j = np.arange(n)
    c0, c1 = np.cos(2 * np.pi * j / n), np.cos(2 * np.pi * (j + 1) / n)
    s0, s1 = np.sin(2 * np.pi * j / n), np.sin(2 * np.pi * (j + 1) / n)
    t1 = (An * c0[:, None] * e + (c0 + c1)[:, None] * fv).sum(0)
    t2 = (An * s0[:, None] * e + (s0 + s1)[:, None] * fv).sum(0)
    nrm = np.cross(t1, t2)
    return pos, nrm / np.linalg.norm(nrm)


def angle_between(a, b) -> np.ndarray:
    """Angles between rows of a and b, up to orientation, precise near zero (atan2, not arccos)."""
    a, b = np.atleast_2d(a), np.atleast_2d(b)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.abs(np.einsum("ij,ij->i", a, b)))


def refine_points(cage: Cage, times: int) -> np.ndarray:
    mesh, H = cage.mesh, cage.homogeneous()
    for _ in range(times):
        mesh, R, _ = mesh.refine()
        H = R @ H
    return H[:, :3] / H[:, 3:]


def limit_positions(cage: Cage, levels: int) -> np.ndarray:
    """Exact limit positions of every vertex of the cage refined ``levels`` times: interior
    vertices by the closed-form mask, boundary vertices by the crease mask (a + 4 v + b)/6,
    sharp corners stay. Independent of the evaluator (refinement is checked against Hbr)."""
    mesh, H = cage.mesh, cage.homogeneous()
    for _ in range(levels):
        mesh, R, _ = mesh.refine()
        H = R @ H
    P = H[:, :3] / H[:, 3:]
    out = np.empty_like(P)
    for v in range(mesh.n_vertices):
        fan, boundary = mesh.fan(v)
        if not boundary:
            out[v] = closed_form_limit(mesh, P, v)[0]
        elif len(fan) == 1 and mesh.boundary_rule == "edge-and-corner":
            out[v] = P[v]
        else:
            (f0, k0), (f1, k1) = fan[0], fan[-1]
            out[v] = (P[mesh.faces[f0][(k0 + 1) % 4]] + 4 * P[v] + P[mesh.faces[f1][(k1 + 3) % 4]]) / 6
    return out


def read_obj_points(path: str) -> np.ndarray:
    with open(path) as fh:
        return np.array([[float(x) for x in ln.split()[1:4]] for ln in fh if ln.startswith("v ")])


def corner_of(model, node):
    for p in model.patches:
        for k in range(4):
            if p.corner_nodes[k] == node:
                return p, k
    raise KeyError(node)


class HbrBaselines(unittest.TestCase):
    """One and two rounds of refinement against OpenSubdiv's reference meshes (point sets)."""

    def check(self, shape, level):
        cage = read_obj(external("opensubdiv", f"{shape}.obj"))
        ref = read_obj_points(external("opensubdiv", "hbr_baseline", f"{shape}_level{level}.obj"))
        mine = refine_points(cage, level + 1)
        self.assertEqual(len(mine), len(ref))
        d, idx = cKDTree(ref).query(mine)
        self.assertEqual(len(set(idx)), len(ref), "not a one-to-one match")
        scale = np.abs(ref).max()
        self.assertLess(d.max(), 1e-6 * max(1.0, scale), f"{shape} level {level}: {d.max():.3g}")

    def test_cube(self):
        for level in (0, 1, 2):
            self.check("catmark_cube", level)

    def test_tent_edge_only_boundary(self):
        for level in (0, 1):
            self.check("catmark_tent", level)

    def test_edgecorner_boundary(self):
        for level in (0, 1):
            self.check("catmark_edgecorner", level)


class ExtraordinaryPoints(unittest.TestCase):
    def test_cube_limit_point_and_normal(self):
        model = tsplcam.load(external("opensubdiv", "catmark_cube.obj"))
        self.assertEqual(len(model.patches), 6)
        self.assertEqual(sum(not e.boundary for e in model.extraordinary), 8)
        # docs/formats.md 3.3: vertex 1 (0, -1.414214, 1) has limit (0, -0.707107, 0.5) and normal
        # (0, -0.816496, 0.577350)
        sp = model.evaluate_faces([0], [0.0], [0.0])
        np.testing.assert_allclose(sp.P[0], [0, -0.707107, 0.5], atol=5e-7)
        np.testing.assert_allclose(sp.normal[0], [0, -0.816496, 0.577350], atol=5e-7)

    def test_limit_masks_valence_3_to_12(self):
        for n in (3, 5, 6, 8, 10, 12):
            cage = ngon_prism(n, seed=n)
            model = cage_model(cage)
            P = cage.points
            pos, nrm = closed_form_limit(cage.mesh, P, 0)
            node = int(np.nonzero(model.node_vertex == 0)[0][0])
            patch, k = corner_of(model, node)
            sp = patch.evaluate(*CORNER_UV[k])
            scale = np.abs(P).max()
            self.assertLess(np.linalg.norm(sp.P[0] - pos), 1e-12 * scale, f"valence {n}")
            angle = angle_between(sp.normal, nrm)[0]
            self.assertLess(angle, 1e-9, f"valence {n}: normal off by {angle:.3g} rad")
            # every patch at this point has the same tangent plane
            for p in model.patches:
                for kk in range(4):
                    if p.corner_nodes[kk] == node:
                        q = p.evaluate(*CORNER_UV[kk])
                        self.assertLess(np.linalg.norm(q.P[0] - pos), 1e-12 * scale)
                        self.assertLess(angle_between(q.normal, nrm)[0], 1e-9)

    def test_eigenvalues_match_published_spectra(self):
        for n in (3, 5, 6):
            path = external("jovobe_tsl", f"AeigensL_{n}.txt")
            with open(path) as fh:
                vals = [float(x) for x in fh.read().split()]
            ref = np.sort(np.array(vals[1:1 + int(vals[0])]))[::-1]
            mesh = ngon_prism(n).mesh.refine()[0]
            f, k = next((f, k) for f in range(len(mesh.faces)) for k in range(4) if mesh.faces[f][k] == 0)
            scheme, _ = scheme_for(mesh, f, k)
            self.assertEqual(scheme.K, 2 * n + 8)
            np.testing.assert_allclose(np.sort(scheme.lam)[::-1], ref, atol=1e-12)

    def test_one_scheme_per_kind_whatever_the_mesh_order(self):
        """Every irregular face of a kind shares one scheme, built from the kind's canonical
        faces: its matrices equal (to rounding) those of a template in the mesh's own face
        order, and its bits do not depend on which face or model came first."""
        from tsplcam.model import eigen
        mesh = ngon_prism(5, seed=1).mesh.refine()[0]
        irregular = [(f, k) for f in range(len(mesh.faces)) for k in range(4)
                     if len(mesh.fan(int(mesh.faces[f][k]))[0]) != 4]
        saved = dict(eigen._SCHEMES)
        try:
            eigen._SCHEMES.clear()
            got = [scheme_for(mesh, f, k)[0] for f, k in irregular]
            kinds = {id(s) for s in got}
            # valence 5 at both poles, valence 3 on the rims: two kinds for 10 + 30 faces
            self.assertEqual(len(kinds), 2, f"{len(irregular)} irregular faces")
            for (f, k), sch in zip(irregular, got):
                config = mesh.config(f, k)
                local = {v: i for i, v in enumerate(config)}
                faces = mesh.neighbourhood_faces(f)
                tfaces = np.array([[local[int(v)] for v in mesh.faces[g]] for g in faces])
                directed = {(int(mesh.faces[h][m]), int(mesh.faces[h][(m + 1) % 4]))
                            for h in faces for m in range(4)}
                cut = {(min(local[a], local[b]), max(local[a], local[b]))
                       for g in faces for a, b in zip(mesh.faces[g], np.roll(mesh.faces[g], -1))
                       if (int(b), int(a)) not in directed}
                own = eigen.SubdivisionScheme(QuadMesh(tfaces, len(config), mesh.boundary_rule),
                                              faces.index(f), k, cut, "mesh order")
                np.testing.assert_allclose(sch.A, own.A, rtol=0, atol=1e-15)
                np.testing.assert_allclose(sch.S, own.S, rtol=0, atol=1e-15)
                np.testing.assert_allclose(sch.limit_mask, own.limit_mask, rtol=0, atol=1e-14)
            # the same bits when another model's faces of these kinds came first
            eigen._SCHEMES.clear()
            other = ngon_prism(5, seed=7).mesh.refine()[0]
            for f in range(len(other.faces)):
                for k in range(4):
                    if len(other.fan(int(other.faces[f][k]))[0]) != 4:
                        scheme_for(other, f, k)
            again = [scheme_for(mesh, f, k)[0] for f, k in reversed(irregular)][::-1]
            for a, b in zip(got, again):
                np.testing.assert_array_equal(a.A, b.A)
                np.testing.assert_array_equal(a.S, b.S)
                for x, y in zip(a.tangent_masks, b.tangent_masks):
                    np.testing.assert_array_equal(x, y)
        finally:
            eigen._SCHEMES.clear()
            eigen._SCHEMES.update(saved)

    def test_convergence_to_the_limit_point(self):
        cage = ngon_prism(5, seed=3)
        model = cage_model(cage)
        node = int(np.nonzero(model.node_vertex == 0)[0][0])
        patch, k = corner_of(model, node)
        limit = patch.evaluate(*CORNER_UV[k]).P[0]
        diag = CORNER_UV[(k + 2) % 4] - CORNER_UV[k]
        dist = []
        for level in range(1, 60):
            u, v = CORNER_UV[k] + diag * 2.0 ** -level
            dist.append(np.linalg.norm(patch.evaluate(u, v).P[0] - limit))
        dist = np.array(dist)
        self.assertTrue(np.all(np.diff(dist[:40]) < 0), "distance to the limit must shrink")
        ratio = dist[21] / dist[20]
        self.assertAlmostEqual(ratio, 0.5505, delta=0.01)     # subdominant eigenvalue, n = 5
        self.assertLess(dist[-1], 1e-14)


def all_models():
    """(name, model) of the cages the continuity checks run on: a fresh list of models built
    once per run (seven tests read them; none changes them)."""
    return list(_all_models())


@functools.lru_cache(maxsize=None)
def _all_models():
    names = ["catmark_cube", "catmark_tent", "catmark_edgecorner", "catmark_xord_boundary", "catmark_torus"]
    out = [(n, tsplcam.load(external("opensubdiv", n + ".obj"))) for n in names]
    out += [(f"prism{n}", cage_model(ngon_prism(n, seed=10 + n))) for n in (3, 5, 8)]
    return tuple(out)


class LimitSurface(unittest.TestCase):
    def test_dyadic_points_are_limit_points_of_the_refined_cage(self):
        """At parameters k / 2^L every patch passes exactly through the limit position of a
        vertex of the cage refined L times: interior, boundary, corners, irregular vertices."""
        L = 3
        cages = [(n, read_obj(external("opensubdiv", n + ".obj"))) for n in
                 ("catmark_cube", "catmark_tent", "catmark_edgecorner", "catmark_xord_boundary", "catmark_torus")]
        cages += [(f"prism{n}", ngon_prism(n, seed=20 + n)) for n in (3, 5, 7)]
        for name, cage in cages:
            model = cage_model(cage)
            tree = cKDTree(limit_positions(cage, L))
            scale = np.abs(cage.points).max()
            for p in model.patches:
                nu, nv = (int(x) * 2 ** L + 1 for x in p.knot_size)
                U, V = np.meshgrid(np.linspace(0, 1, nu), np.linspace(0, 1, nv))
                d, _ = tree.query(p.evaluate(U.ravel(), V.ravel()).P)
                self.assertLess(d.max(), 1e-12 * scale, f"{name} {p.name}: {d.max():.3g}")


class Continuity(unittest.TestCase):
    def test_shared_edges_agree(self):
        tau = np.linspace(0, 1, 41)
        for name, model in all_models():
            scale = np.abs(model.node_points).max()
            for link in Layout.from_model(model).edge_links:
                sa, sb = edge_pair(model, link, tau)
                self.assertLess(np.abs(sa.P - sb.P).max(), 1e-12 * scale, name)
                angle = angle_between(sa.normal, sb.normal).max()
                self.assertLess(angle, 1e-9, f"{name}: patches {link.a}/{link.b} normals {angle:.3g} rad")

    def test_edge_transform_continues_the_parametrisation(self):
        """Model.edge_transform maps (u, v) across a shared edge in knot units: the first
        derivatives of both patches agree through its linear part (away from the
        extraordinary corners, where no parametrisation is C1)."""
        tau = np.linspace(0.1, 0.9, 9)
        for name, model in all_models():
            for link in Layout.from_model(model).edge_links:
                for a, ea, b, eb in ((link.a, link.ea, link.b, link.eb), (link.b, link.eb, link.a, link.ea)):
                    pa, pb = model.patches[a], model.patches[b]
                    T = model.edge_transform(a, ea)
                    ua, va = pa.edge_params(ea, tau)
                    ub, vb = T[:, :2] @ np.vstack([ua, va]) + T[:, 2:]
                    sa, sb = pa.evaluate(ua, va), pb.evaluate(np.clip(ub, 0, 1), np.clip(vb, 0, 1))
                    np.testing.assert_allclose(ub, np.clip(ub, 0, 1), atol=1e-12)
                    scale = np.abs(sa.P).max()
                    self.assertLess(np.abs(sa.P - sb.P).max(), 1e-12 * scale, name)
                    L = T[:, :2]
                    Pu = sb.Pu * L[0, 0] + sb.Pv * L[1, 0]
                    Pv = sb.Pu * L[0, 1] + sb.Pv * L[1, 1]
                    d = np.abs(sa.Pu - Pu).max() + np.abs(sa.Pv - Pv).max()
                    self.assertLess(d / (np.abs(sa.Pu).max() + np.abs(sa.Pv).max()), 1e-9, f"{name} {a}->{b}")

    def test_corner_neighbours_meet_at_one_point(self):
        """Model.corner_neighbours: every patch corner lists the other patch corners at its
        node (symmetrically); they evaluate to the same point, with one tangent plane where
        the node is inside the surface; a closed fan around an inside node has as many patches
        as edge links, and around an extraordinary point as many as its valence; corner-only
        links (no shared edge) are exactly the layout's corner links."""
        models = all_models() + [(n, tsplcam.load(sample_path(n))) for n in ("keycap", "figure4")]
        for name, model in models:
            layout = Layout.from_model(model)
            valence = {ep.node: ep.valence for ep in model.extraordinary if not ep.boundary}
            scale = np.abs(model.node_points).max()
            corner_only = set()
            for p in model.patches:
                for k in range(4):
                    around = model.corner_neighbours(p.index, k)
                    here = [(p.index, k)] + around
                    for q, kq in around:
                        self.assertIn((p.index, k), model.corner_neighbours(q, kq), name)
                    pts = [model.patches[q].evaluate(*CORNER_UV[kq]) for q, kq in here]
                    P = np.array([s.P[0] for s in pts])
                    self.assertLess(np.abs(P - P[0]).max(), 1e-12 * scale, f"{name} patch {p.index} corner {k}")
                    # a corner pair shares a whole edge or is a corner link
                    edge_pairs = {(q, kq) for q, kq in around for link in layout.edge_links_between(p.index, q)
                                  if (k, kq) in link.corner_pairs()}
                    corner_only |= {tuple(sorted((p.index, q))) for q, kq in set(around) - edge_pairs
                                    if not layout.edge_links_between(p.index, q)}
                    on_boundary = any(model.patches[q].neighbours[e] is None
                                      for q, kq in here for e in (kq, (kq + 3) % 4))
                    if on_boundary:
                        continue
                    links = {tuple(sorted([(q, kq), (r, kr)])) for q, kq in here for r, kr in here
                             if (kq, kr) in [c for lk in layout.edge_links_between(q, r) for c in lk.corner_pairs()]}
                    self.assertEqual(len(links), len(here), f"{name}: fan at patch {p.index} corner {k}")
                    node = p.corner_nodes[k]
                    if node in valence:
                        self.assertEqual(len(here), valence[node], name)
                    normals = np.array([s.normal[0] for s in pts])
                    self.assertLess(angle_between(normals, normals[[0]] * np.ones_like(normals)).max(), 1e-9,
                                    f"{name}: tangent plane at patch {p.index} corner {k}")
            expected = {tuple(sorted((a, b))) for a in range(layout.n_patches) for b in range(a)
                        if layout.link_kind(a, b) == "corner"}
            self.assertEqual(corner_only, expected, name)
            if name == "figure4":
                self.assertGreater(len(corner_only), 0)

    def test_curvature_continuous_across_edges_away_from_extraordinary_points(self):
        tau = np.linspace(0.2, 0.8, 13)
        for name, model in all_models():
            for link in Layout.from_model(model).edge_links:
                gap, scale = curvature_gap(*edge_pair(model, link, tau))
                self.assertLess(gap, 1e-7 * scale, f"{name} {link}")

    def test_derivatives_match_finite_differences(self):
        rng = np.random.default_rng(5)
        h = 1e-6
        for name, model in all_models():
            for p in model.patches:
                u = rng.uniform(0.01, 0.99, 20)
                v = rng.uniform(0.01, 0.99, 20)
                s = p.evaluate(u, v)
                su = (p.evaluate(u + h, v).P - p.evaluate(u - h, v).P) / (2 * h)
                sv = (p.evaluate(u, v + h).P - p.evaluate(u, v - h).P) / (2 * h)
                suu = (p.evaluate(u + h, v).Pu - p.evaluate(u - h, v).Pu) / (2 * h)
                suv = (p.evaluate(u, v + h).Pu - p.evaluate(u, v - h).Pu) / (2 * h)
                svv = (p.evaluate(u, v + h).Pv - p.evaluate(u, v - h).Pv) / (2 * h)
                for got, fd in ((s.Pu, su), (s.Pv, sv), (s.Puu, suu), (s.Puv, suv), (s.Pvv, svv)):
                    scale = 1.0 + np.abs(got).max()
                    self.assertLess(np.abs(got - fd).max(), 1e-5 * scale, f"{name} {p.name}")

    def test_grid_evaluation_equals_scattered_evaluation(self):
        rng = np.random.default_rng(7)
        us = np.sort(np.r_[0.0, 1.0, rng.random(23)])
        vs = rng.random(17)                     # unsorted too
        for name, model in all_models():
            for p in model.patches:
                g = p.evaluate_grid(us, vs)
                U, V = np.meshgrid(us, vs, indexing="ij")
                s = p.evaluate(U.ravel(), V.ravel())
                for a, b in ((g.P, s.P), (g.Pu, s.Pu), (g.Pv, s.Pv), (g.Puu, s.Puu), (g.Puv, s.Puv),
                             (g.Pvv, s.Pvv), (g.normal, s.normal), (g.u, s.u), (g.v, s.v)):
                    self.assertLess(np.abs(a - b).max(), 1e-12 * (1.0 + np.abs(b).max()), f"{name} {p.name}")

    def test_no_nan_anywhere(self):
        assert_finite_everywhere(self, all_models())


class FaceCoordinates(unittest.TestCase):
    def test_opensubdiv_face_convention(self):
        cage = ngon_prism(5, seed=2)
        model = cage_model(cage)
        mesh = cage.mesh
        for f in range(len(mesh.faces)):
            v0, v1, v3 = mesh.faces[f][0], mesh.faces[f][1], mesh.faces[f][3]
            sp = model.evaluate_faces([f, f], [0.0, 0.0], [0.0, 0.0])
            if mesh.is_regular_vertex(int(v0)):
                pos, _ = closed_form_limit(mesh, cage.points, int(v0))
                np.testing.assert_allclose(sp.P[0], pos, atol=1e-12)
            mid = model.evaluate_faces([f], [0.5], [0.5])
            lim = lambda v: refine_points(cage, 6)[v]   # noqa: E731
            # s runs toward the second vertex, t toward the last
            self.assertGreater(mid.Pu[0] @ (cage.points[v1] - cage.points[v0]), 0)
            self.assertGreater(mid.Pv[0] @ (cage.points[v3] - cage.points[v0]), 0)
            del lim
        # normal orientation agrees with Ps x Pt everywhere
        s = model.evaluate_faces(np.arange(len(mesh.faces)), 0.3, 0.6)
        cross = np.cross(s.Pu, s.Pv)
        self.assertTrue(np.all(np.einsum("ij,ij->i", cross, s.normal) > 0))

    def test_patch_counts(self):
        cube = tsplcam.load(external("opensubdiv", "catmark_cube.obj"))
        self.assertEqual((len(cube.patches), len(cube.extraordinary)), (6, 8))
        layout = Layout.from_model(cube)
        self.assertEqual(len(layout.edge_links), 12)
        for p in range(6):
            kinds = layout.neighbours(p)
            self.assertEqual(sorted(kinds.values()).count("boundary"), 4)
        tent = tsplcam.load(external("opensubdiv", "catmark_tent.obj"))
        self.assertEqual(len(tent.patches), 1)


class BadInput(unittest.TestCase):
    def load_text(self, text):
        with tempfile.NamedTemporaryFile("w", suffix=".obj", delete=False) as fh:
            fh.write(text)
        try:
            return tsplcam.load(fh.name)
        finally:
            os.unlink(fh.name)

    def assertRefused(self, text, *words):
        with self.assertRaises(InputError) as ctx:
            self.load_text(text)
        msg = str(ctx.exception)
        for w in words:
            self.assertIn(w, msg)
        return msg

    GRID = "".join(f"v {i} {j} 0\n" for j in range(3) for i in range(3))

    def test_non_quad(self):
        self.assertRefused(self.GRID + "f 1 2 5\n", "line 10", "3 vertices")

    def test_non_manifold_edge(self):
        text = self.GRID + "v 1 0 1\nv 0 0 1\nf 1 2 5 4\nf 2 3 6 5\nf 1 2 10 11\n"
        self.assertRefused(text, "edge 1-2")

    def test_inconsistent_orientation(self):
        self.assertRefused(self.GRID + "f 1 2 5 4\nf 2 5 6 3\n", "same direction")

    def test_nan_coordinate(self):
        self.assertRefused(self.GRID.replace("v 1 1 0", "v 1 nan 0") + "f 1 2 5 4\nf 2 3 6 5\nf 4 5 8 7\nf 5 6 9 8\n",
                           "vertex 5", "not a number")

    def test_unused_vertex(self):
        self.assertRefused(self.GRID + "v 7 7 7\nf 1 2 5 4\nf 2 3 6 5\nf 4 5 8 7\nf 5 6 9 8\n",
                           "vertex 10", "not used")

    def test_unknown_vertex(self):
        self.assertRefused(self.GRID + "f 1 2 5 40\n", "face 1", "does not exist")

    def test_crease_tags_refused(self):
        # creases are read (tests/model/test_creases.py); one on two vertices that share no
        # edge (a face's diagonal) is refused with its line
        self.assertRefused(self.GRID + "f 1 2 5 4\nt crease 2/1/0 0 4 10\n", "line 11", "crease")

    def test_bowtie_vertex(self):
        text = ("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 0 0\nv -1 -1 0\nv 0 -1 0\n"
                "f 1 2 3 4\nf 1 5 6 7\n")
        self.assertRefused(text, "vertex 1", "non-manifold")

    def test_zero_weight(self):
        cage = ngon_prism(3)
        cage.weights = np.ones(len(cage.points))
        cage.weights[4] = 0.0
        with self.assertRaises(InputError) as ctx:
            cage_model(cage)
        self.assertIn("vertex 5", str(ctx.exception))

    def test_parameter_outside_unit_square(self):
        model = cage_model(ngon_prism(3))
        with self.assertRaises(InputError):
            model.patches[0].evaluate([1.5], [0.2])
        with self.assertRaises(InputError):
            model.patches[0].evaluate([np.nan], [0.2])


if __name__ == "__main__":
    unittest.main()
