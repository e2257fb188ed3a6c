"""The T-spline kernel against independent references: OCCT's B-spline surfaces, a brute-force
rational sum with scipy's B-spline basis and a ray caster on the grid of knot lines,
Catmull-Clark cages (closed T-meshes without T-junctions are Catmull-Clark surfaces), and
closed-form properties (partition of unity, linear precision)."""
import unittest

import numpy as np

from tsplcam.errors import InputError
from tsplcam.layout.layout import Layout
from tsplcam.model import samples
from tsplcam.model.cage import cage_model
from tsplcam.model.tmesh import TMesh, bspline_tmesh, from_lines, quad_tmesh
from tsplcam.model.knots import knot_vectors
from tsplcam.model.stars import StarsTooClose, find_stars
from tsplcam.model.tspline import homogeneous_parts, tspline_model
from tsplcam.model.twalk import Walker
from conftest import (needs_freecad, angle_between, assert_finite_everywhere, brute_force, clamped_grid,
                      curvature_gap, edge_pair, faces_meet, grid_knots, ngon_prism, require_freecad,
                      split_face, t_junction_mesh)

RNG_SEED = 20240611


# -- reference: rays cast on the grid of knot lines of a from_lines T-mesh -----------------------
def models():
    """Models for the continuity checks: grids with T-junctions, an L-shaped domain, a closed
    surface with extraordinary points and T-junctions."""
    out = [("t-junctions", tspline_model(t_junction_mesh(1, True)[0])),
           ("t-junctions-general", tspline_model(t_junction_mesh(2, False)[0])),
           ("l-shape", tspline_model(l_shape())),
           ("hole", tspline_model(square_with_hole()))]
    head = samples.head(9)
    mesh = quad_tmesh(head.points, head.mesh.faces)
    out.append(("head-split", tspline_model(split_face(mesh, centre_face(mesh)))))
    return out


def centre_face(mesh) -> int:
    """A face as far as possible (in edges) from the extraordinary points."""
    topo = mesh.topology
    dist = np.full(mesh.n_vertices, 10 ** 6)
    front = [v for v in range(mesh.n_vertices) if topo.is_extraordinary(v)]
    dist[front] = 0
    while front:
        nxt = []
        for v in front:
            for w in topo.edge_by_angle[v].values():
                if dist[w] > dist[v] + 1:
                    dist[w] = dist[v] + 1
                    nxt.append(w)
        front = nxt
    return int(np.argmax([dist[f].min() for f in mesh.faces]))


def edge_class(mesh, a, b):
    """The edges parallel to (a, b) across quads (a consistent set for knot intervals):
    (face, loop index) of each."""
    topo = mesh.topology
    out, todo = set(), [topo.edge_at[(a, b)]]
    while todo:
        f, i = todo.pop()
        for g, j in ((f, i), (f, (i + 2) % 4)):
            if (g, j) in out:
                continue
            out.add((g, j))
            x, y = int(mesh.faces[g][j]), int(mesh.faces[g][(j + 1) % 4])
            twin = topo.edge_at.get((y, x))
            if twin is not None and twin not in out:
                todo.append(twin)
    return out


def on_greville_points(mesh: TMesh, X, Y, height) -> TMesh:
    """Control points over the Greville points of their knot vectors (so that a clamped
    boundary's first two rows are distinct), z = height(x, y)."""
    S, T = knot_vectors(mesh)
    x = X[mesh.grid_index[:, 0]] + S[:, 1:4].mean(axis=1)
    y = Y[mesh.grid_index[:, 1]] + T[:, 1:4].mean(axis=1)
    mesh.points = np.column_stack([x, y, height(x, y)])
    return mesh


def square_with_hole() -> TMesh:
    """A clamped square with a clamped square hole: eight patches around it."""
    X = np.array([0, 0, 1, 2, 2, 3, 4, 4, 5, 6, 6.0])
    n = len(X)
    h = [(j, 0, n - 1) for j in range(n)]
    v = [(i, 0, n - 1) for i in range(n)]
    h[4], h[6], v[4], v[6] = (4, 3, 7), (6, 3, 7), (4, 3, 7), (6, 3, 7)
    mesh = from_lines(X, X, h, v, lambda i, j: (0.0, 0.0, 0.0), holes=lambda cx, cy: 4 <= cx <= 6 and 4 <= cy <= 6)
    return on_greville_points(mesh, X, X, lambda x, y: np.sin(x) * np.cos(y))


def l_shape(seed=5) -> TMesh:
    """An L-shaped clamped T-mesh: its concave corner makes three patches."""
    rng = np.random.default_rng(seed)
    X = np.array([0, 0, 1, 2, 3, 3, 4, 5, 5.0])
    Y = np.array([0, 0, 1, 2, 2.5, 2.5, 3, 4, 4.0])
    h = [(j, 0, 8) for j in range(5)] + [(5, 4, 8)] + [(j, 0, 5) for j in range(6, 9)]
    v = [(i, 0, 8) for i in range(5)] + [(5, 4, 8)] + [(i, 0, 5) for i in range(6, 9)]
    h[2] = (2, 0, 4)
    mesh = from_lines(X, Y, h, v, lambda i, j: (0.0, 0.0, 0.0), holes=lambda cx, cy: cx > 5 and cy > 5)
    mesh = on_greville_points(mesh, X, Y, lambda x, y: np.sin(x) * np.cos(y))
    mesh.points[:, 0] += 0.05 * rng.standard_normal(mesh.n_vertices)
    return mesh


@needs_freecad
class AgainstOCCT(unittest.TestCase):
    """A T-mesh without T-junctions is the B-spline surface FreeCAD builds from the same data."""

    def surfaces(self):
        rng = np.random.default_rng(RNG_SEED)
        out = []
        for rational, mult in ((False, 1), (True, 1), (True, 2), (False, 3)):
            uk = np.array([0.0, 0.7, 1.1, 2.0, 3.2, 4.0])
            vk = np.array([-1.0, 0.0, 0.4, 1.5, 2.0])
            um = [4] + [mult if k == 2 else 1 for k in range(1, len(uk) - 1)] + [4]
            vm = [4] + [1] * (len(vk) - 2) + [4]
            nu, nv = sum(um) - 4, sum(vm) - 4
            poles = rng.standard_normal((nu, nv, 3)) * 2.0
            poles[..., 0] += np.arange(nu)[:, None] * 3
            poles[..., 1] += np.arange(nv)[None, :] * 3
            weights = rng.uniform(0.4, 2.5, (nu, nv)) if rational else np.ones((nu, nv))
            out.append((uk, vk, um, vm, poles, weights, rational))
        return out

    def test_equals_occt_bspline(self):
        require_freecad()
        import FreeCAD
        import Part
        rng = np.random.default_rng(3)
        for uk, vk, um, vm, poles, weights, rational in self.surfaces():
            bs = Part.BSplineSurface()
            bs.buildFromPolesMultsKnots([[FreeCAD.Vector(*p) for p in row] for row in poles], um, vm,
                                        list(uk), list(vk), False, False, 3, 3, weights.tolist())
            U = np.repeat(uk, um)
            V = np.repeat(vk, vm)
            model = tspline_model(bspline_tmesh(poles, weights, U, V))
            self.assertEqual(len(model.patches), 1)
            patch = model.patches[0]
            u = np.concatenate([rng.random(300), [0.0, 1.0, 0.0, 1.0, 0.5]])
            v = np.concatenate([rng.random(300), [0.0, 0.0, 1.0, 1.0, 1.0]])
            got = patch.evaluate(u, v)
            du, dv = uk[-1] - uk[0], vk[-1] - vk[0]
            scale = np.abs(poles).max()
            k1, k2 = got.principal_curvatures
            mean = got.mean_curvature
            for n in range(len(u)):
                U_, V_ = uk[0] + u[n] * du, vk[0] + v[n] * dv
                ref = np.array(bs.value(U_, V_))
                self.assertLess(np.abs(got.P[n] - ref).max(), 1e-10 * scale, (rational, u[n], v[n]))
                for arr, (a, b) in ((got.Pu, (1, 0)), (got.Pv, (0, 1)), (got.Puu, (2, 0)),
                                    (got.Puv, (1, 1)), (got.Pvv, (0, 2))):
                    ref = np.array(bs.getDN(U_, V_, a, b)) * du ** a * dv ** b
                    tol = 1e-8 * max(1.0, np.abs(ref).max())
                    self.assertLess(np.abs(arr[n] - ref).max(), tol, (rational, a, b, u[n], v[n]))
                # OCCT's curvatures follow its normal Su x Sv, as ours do (max = k1, min = k2)
                kmax, kmin = bs.curvature(U_, V_, "Max"), bs.curvature(U_, V_, "Min")
                kscale = 1.0 + abs(kmax) + abs(kmin)
                self.assertLess(abs(k1[n] - kmax) + abs(k2[n] - kmin), 1e-8 * kscale)
                self.assertLess(abs(mean[n] - bs.curvature(U_, V_, "Mean")), 1e-8 * kscale)
                self.assertLess(abs(k1[n] * k2[n] - bs.curvature(U_, V_, "Gauss")), 1e-8 * kscale ** 2)

    def test_bspline_tmesh_matches_kernel_bspline_patch(self):
        """Without FreeCAD: the same check against bspline.py's knot-vector extraction."""
        from tsplcam.model.bspline import bspline_patch
        rng = np.random.default_rng(4)
        for uk, vk, um, vm, poles, weights, rational in self.surfaces():
            U, V = np.repeat(uk, um), np.repeat(vk, vm)
            ref = bspline_patch(poles, weights, U, V, 3, 3)
            got = tspline_model(bspline_tmesh(poles, weights, U, V)).patches[0]
            u, v = rng.random(200), rng.random(200)
            a, b = got.evaluate(u, v), ref.evaluate(u, v)
            for k in ("P", "Pu", "Pv", "Puu", "Puv", "Pvv"):
                x, y = getattr(a, k), getattr(b, k)
                self.assertLess(np.abs(x - y).max(), 1e-9 * (1 + np.abs(y).max()), k)


class TJunctions(unittest.TestCase):
    def test_partition_of_unity_and_linear_precision(self):
        """Analysis-suitable T-mesh: the blending functions sum to 1 and reproduce linear
        functions (control points at the Greville points of their local knot vectors)."""
        mesh, X, Y, hsegs, vsegs = t_junction_mesh(1, True)
        self.assertGreaterEqual(sum(len(f) > 4 for f in mesh.faces), 3)
        G = np.array([[k[1:4].mean() for k in grid_knots(X, Y, hsegs, vsegs, i, j)] for i, j in mesh.grid_index])
        mesh.points = np.column_stack([G, np.zeros(len(G))])
        mesh.weights = np.ones(len(G))
        model = tspline_model(mesh)
        # without the rational division (which would hide a failure): sum B_i and sum B_i G_i
        numerator, weight = homogeneous_parts(model.patches[0])
        rng = np.random.default_rng(6)
        u, v = rng.random(3000), rng.random(3000)
        total = weight.evaluate(u, v)
        self.assertLess(np.abs(total.P[:, 0] - 1).max(), 1e-12)
        self.assertLess(np.abs(total.Pu).max() + np.abs(total.Puv).max(), 1e-10)
        s = numerator.evaluate(u, v)
        W, H = numerator.knot_size
        self.assertLess(np.abs(s.P[:, 0] - u * W).max(), 1e-12 * W)
        self.assertLess(np.abs(s.P[:, 1] - v * H).max(), 1e-12 * H)
        self.assertLess(np.abs(s.Pu - [W, 0, 0]).max(), 1e-11 * W)
        self.assertLess(np.abs(s.Puu).max(), 1e-9 * W)

    def test_equals_brute_force_rational_sum(self):
        """General (not analysis-suitable) T-meshes: the surface is the rational sum with
        blending functions from rays cast on the knot-line grid."""
        rng = np.random.default_rng(7)
        for seed, suitable in ((1, True), (2, False), (3, False)):
            mesh, X, Y, hsegs, vsegs = t_junction_mesh(seed, suitable)
            patch = tspline_model(mesh).patches[0]
            W, H = patch.knot_size
            u, v = rng.random(400), rng.random(400)
            got = patch.evaluate(u, v)
            S, Ss, St = brute_force(mesh, X, Y, hsegs, vsegs, u * W, v * H)
            scale = np.abs(mesh.points).max()
            self.assertLess(np.abs(got.P - S).max(), 1e-12 * scale, seed)
            self.assertLess(np.abs(got.Pu - Ss * W).max(), 1e-10 * scale * W, seed)
            self.assertLess(np.abs(got.Pv - St * H).max(), 1e-10 * scale * H, seed)

    def test_random_t_meshes_equal_brute_force(self):
        """Random clamped T-meshes (T-junctions anywhere, zero intervals inside) against the
        brute-force sum; meshes whose lines dangle or whose faces are not rectangles must be
        refused with an InputError, never anything else."""
        rng = np.random.default_rng(12)
        valid = 0
        for _ in range(60):
            nx, ny = rng.integers(6, 11, 2)
            steps = lambda n: np.cumsum(rng.choice([0.0, 0.5, 1.0, 2.0], n, p=[0.1, 0.3, 0.3, 0.3]))  # noqa
            gx, gy = np.concatenate([[0.0], steps(nx - 3)]), np.concatenate([[0.0], steps(ny - 3)])
            X, Y = np.concatenate([[0.0], gx, gx[-1:]]), np.concatenate([[0.0], gy, gy[-1:]])
            nx, ny = len(X), len(Y)
            h, v = [], []
            for j in range(ny):
                full = j in (0, 1, ny - 2, ny - 1) or rng.random() < 0.5
                a = 0 if full else int(rng.integers(0, nx - 2))
                h.append((j, a, nx - 1 if full else int(rng.integers(a + 2, nx))))
            for i in range(nx):
                full = i in (0, 1, nx - 2, nx - 1) or rng.random() < 0.5
                a = 0 if full else int(rng.integers(0, ny - 2))
                v.append((i, a, ny - 1 if full else int(rng.integers(a + 2, ny))))
            try:
                mesh = from_lines(X, Y, h, v, rng.standard_normal((nx, ny, 3)), rng.uniform(0.5, 2, (nx, ny)))
                patch = tspline_model(mesh).patches[0]
            except InputError:
                continue
            valid += 1
            W, H = patch.knot_size
            u, w = rng.random(50), rng.random(50)
            S, _, _ = brute_force(mesh, X, Y, h, v, u * W, w * H)
            self.assertLess(np.abs(patch.evaluate(u, w).P - S).max(), 1e-12 * np.abs(mesh.points).max())
        self.assertGreater(valid, 15)

    def test_surface_inside_convex_hull_of_control_points(self):
        from scipy.spatial import Delaunay
        mesh = t_junction_mesh(2, False)[0]
        mesh.points[:, 2] *= 3
        hull = Delaunay(mesh.points)
        g = np.linspace(0, 1, 25)
        U, V = np.meshgrid(g, g)
        P = tspline_model(mesh).patches[0].evaluate(U.ravel(), V.ravel()).P
        # a point is inside when it lies in a simplex, allowing rounding on hull faces
        inside = (hull.find_simplex(P, tol=1e-10) >= 0)
        self.assertTrue(inside.all())


class ZeroIntervals(unittest.TestCase):
    """Zero knot intervals in any consistent arrangement: the order of points at equal knot
    values is a feasibility problem (a linear program), not a least-squares guess."""

    # found by a random search: the minimum-norm least-squares arrangement of its zero
    # intervals leaves an edge of zero order, though an arrangement exists (grid indices)
    X = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]
    Y = [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 2.0, 2.0, 2.0]
    H = [(0, 0, 5), (1, 0, 5), (2, 0, 3), (3, 3, 5), (4, 3, 5), (5, 3, 5), (6, 0, 5), (7, 1, 4),
         (8, 0, 5), (9, 0, 5)]
    V = [(i, 0, 9) for i in range(6)]

    def test_arrangement_least_squares_missed(self):
        from scipy.sparse.linalg import lsqr
        rng = np.random.default_rng(3)
        nx, ny = len(self.X), len(self.Y)
        mesh = from_lines(self.X, self.Y, self.H, self.V, rng.standard_normal((nx, ny, 3)),
                          rng.uniform(0.5, 2, (nx, ny)))
        topo = mesh.topology
        # the least-squares arrangement (start 1 on every zero interval) fails here
        und = {}
        for (a, b), (f, i) in topo.edge_at.items():
            und.setdefault((min(a, b), max(a, b)), mesh.intervals[f][i])
        eid = {k: n for n, k in enumerate(und)}
        zero = np.array([und[k] <= 0 for k in und])
        A = topo._order_matrix(eid)
        xi = zero + lsqr(A, -(A @ zero.astype(float)), atol=1e-14, btol=1e-14)[0]
        self.assertTrue((zero & (xi < 1e-3)).any())
        # the linear program's: every zero interval positive, every face a rectangle
        order = np.array([topo.edge_len[k].imag for k in und])
        self.assertGreaterEqual(order[zero].min(), 1.0 - 1e-9)
        self.assertLess(np.abs(A @ order).max(), 1e-9)
        patch = tspline_model(mesh).patches[0]
        W, Hk = patch.knot_size
        u, v = rng.random(400), rng.random(400)
        S, _, _ = brute_force(mesh, np.array(self.X), np.array(self.Y), self.H, self.V, u * W, v * Hk)
        self.assertLess(np.abs(patch.evaluate(u, v).P - S).max(), 1e-14 * np.abs(mesh.points).max())

    def test_inconsistent_zero_intervals_name_the_edge_and_line(self):
        """Two faces of zero height glued so that face A's bottom (z1) equals its top (z2 + z3)
        and face B's bottom (z2) equals its top (z1): z3 can only be a point."""
        mesh = TMesh(np.random.default_rng(0).random((5, 3)), None, [[0, 1, 2, 3, 4], [3, 2, 1, 0]],
                     [(0, 1, 2, 4), (0, 1, 2, 3)], [[0, 1, 0, 0, 1], [0, 1, 0, 1]], source="z.tsm",
                     edge_labels={(3, 4): ("edge 7", 42)})
        with self.assertRaises(InputError) as cm:
            mesh.topology          # noqa: B018
        self.assertIn("edge 7", str(cm.exception))
        self.assertIn("zero knot interval", str(cm.exception))
        self.assertEqual(cm.exception.line, 42)


class ExtraordinaryPoints(unittest.TestCase):
    def test_closed_quad_tmesh_equals_catmull_clark(self):
        """Uniform knot intervals, no T-junctions: the T-NURCC is Catmull-Clark, everywhere,
        the extraordinary points included (valence 3, head-like cube of 3 x 3 faces a side)."""
        rng = np.random.default_rng(8)
        for n in (3, 4):
            cage = samples.head(n)
            model = tspline_model(quad_tmesh(cage.points, cage.mesh.faces, interval=2.5))
            ref = cage_model(cage)
            self.assertEqual(len(model.patches), 6)
            self.assertEqual(sorted(e.valence for e in model.extraordinary), [3] * 8)
            F = len(cage.mesh.faces)
            f = np.concatenate([rng.integers(0, F, 2000), np.repeat(np.arange(F), 4)])
            s = np.concatenate([rng.random(2000), np.tile([0, 1, 1, 0.0], F)])
            t = np.concatenate([rng.random(2000), np.tile([0, 0, 1, 1.0], F)])
            a, b = model.evaluate_faces(f, s, t), ref.evaluate_faces(f, s, t)
            scale = np.abs(cage.points).max()
            # at an extraordinary point itself the parametrisation is singular (derivatives
            # depend on the way in; both kernels report the limit point and tangent plane):
            # derivatives everywhere else
            mesh = cage.mesh
            corner = np.zeros(len(f), bool)
            corner[2000:] = True
            k_of = np.tile(np.arange(4), F)
            at_ep = corner & np.array([False] * 2000 + [not mesh.is_regular_vertex(int(mesh.faces[g][k]))
                                                        for g, k in zip(f[2000:], k_of)])
            self.assertGreater(at_ep.sum(), 20)
            self.assertLess(np.abs(a.P - b.P).max(), 1e-12 * scale, (n, "P"))
            for k in ("Pu", "Pv", "Puu", "Puv", "Pvv"):
                self.assertLess(np.abs(getattr(a, k) - getattr(b, k))[~at_ep].max(), 1e-12 * scale, (n, k))
            self.assertLess(angle_between(a.normal, b.normal).max(), 1e-9)

    def test_t_junctions_away_from_extraordinary_points(self):
        """A face split in the middle of a cube side: faces whose blending functions do not
        see the new lines keep the Catmull-Clark surface; the T-junctions' faces do not."""
        cage = samples.head(9)
        mesh = quad_tmesh(cage.points, cage.mesh.faces)
        f = centre_face(mesh)
        split = split_face(mesh, f)
        model = tspline_model(split)
        ref = cage_model(cage)
        self.assertEqual(len(model.patches), 6)
        near = np.linalg.norm(mesh.points[mesh.faces].mean(1) - mesh.points[mesh.faces[f]].mean(0), axis=1)
        spacing = np.linalg.norm(mesh.points[mesh.faces[f][0]] - mesh.points[mesh.faces[f][1]])
        far = np.nonzero(near > 6 * spacing)[0]
        self.assertGreater(len(far), 100)
        rng = np.random.default_rng(9)
        s, t = rng.random(len(far)), rng.random(len(far))
        a, b = model.evaluate_faces(far, s, t), ref.evaluate_faces(far, s, t)
        self.assertLess(np.abs(a.P - b.P).max(), 1e-12 * np.abs(cage.points).max())
        c = model.evaluate_faces([f], [0.25], [0.5])
        d = ref.evaluate_faces([f], [0.5], [0.5])
        self.assertGreater(np.abs(c.P - d.P).max(), 1e-6)

    def test_refusals_name_the_vertex_or_face(self):
        cage = samples.head(5)
        mesh = quad_tmesh(cage.points, cage.mesh.faces)
        topo = mesh.topology
        ep = next(v for v in range(mesh.n_vertices) if topo.is_extraordinary(v))
        # a face with a T-junction next to an extraordinary point
        f = topo.fan[ep][0][0]
        with self.assertRaises(InputError) as cm:
            tspline_model(split_face(mesh, f))
        self.assertIn("extraordinary", str(cm.exception))
        # non-uniform knot intervals at it, and two rings away
        for distance in (0, 2):
            bad = mesh.copy()
            v = ep
            w = None
            for _ in range(distance + 1):          # walk along a spoke
                w = next(iter(topo.edge_by_angle[v].values())) if w is None else w
                prev, v = v, w
                ang = topo.edge_angle[(v, prev)]
                w = topo.edge_by_angle[v].get((ang + 2) % 4)
            a, b = (ep, next(iter(topo.edge_by_angle[ep].values()))) if distance == 0 else (prev, v)
            for g, k in edge_class(mesh, a, b):
                bad.intervals[g][k] = 2.0
            # non-uniform intervals at or near a star point: the NURCC rules (StarPoints)
            model = tspline_model(bad)
            self.assertEqual(len(model.extraordinary), 8)
        # adjacent extraordinary points (two on one face): too close for the star construction
        # (a closed T-mesh with one interval everywhere, a Catmull-Clark cage, then takes the
        # subdivision path)
        prism = ngon_prism(5, noise=0.0)
        two = quad_tmesh(prism.points, prism.mesh.faces)
        with self.assertRaises(StarsTooClose) as cm:
            find_stars(Walker(two))
        self.assertIn("two extraordinary corners", str(cm.exception))
        self.assertEqual(len(tspline_model(two).extraordinary), 2 + 10)



class Continuity(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.models = models()

    def test_patch_layouts(self):
        counts = {name: len(m.patches) for name, m in self.models}
        self.assertEqual(counts, {"t-junctions": 1, "t-junctions-general": 1, "l-shape": 3, "hole": 8,
                                  "head-split": 6})
        self.assertEqual(len(Layout.from_model(dict(self.models)["hole"]).edge_links), 8)
        head = dict(self.models)["head-split"]
        self.assertEqual(len(Layout.from_model(head).edge_links), 12)
        self.assertEqual(len(head.extraordinary), 8)

    def test_shared_patch_edges_agree(self):
        tau = np.linspace(0, 1, 41)
        for name, model in self.models:
            scale = np.abs(model.node_points).max()
            for link in Layout.from_model(model).edge_links:
                sa, sb = edge_pair(model, link, tau)
                self.assertLess(np.abs(sa.P - sb.P).max(), 1e-12 * scale, name)
                self.assertLess(angle_between(sa.normal, sb.normal).max(), 1e-9, name)

    def test_curvature_continuous_across_patch_edges(self):
        """Where the knots across the patch edge are simple (the clamped L-shape has double
        knot lines at its concave corner: only C1 there)."""
        tau = np.linspace(0.2, 0.8, 13)
        for name, model in self.models:
            if name in ("l-shape", "hole"):
                continue
            for link in Layout.from_model(model).edge_links:
                gap, scale = curvature_gap(*edge_pair(model, link, tau))
                self.assertLess(gap, 1e-7 * scale, f"{name} {link}")

    def test_adjacent_faces_meet(self):
        """Every interior T-mesh edge, sampled from the faces on both sides."""
        tau = np.linspace(0, 1, 9)
        for name, model in self.models:
            scale = np.abs(model.node_points).max()
            A, B = faces_meet(model, model.control, tau)
            self.assertLess(np.abs(A.P - B.P).max(), 1e-12 * scale, name)

    def test_derivatives_match_finite_differences(self):
        rng = np.random.default_rng(5)
        h = 1e-6
        for name, model in self.models:
            for p in model.patches:
                u, v = rng.uniform(0.01, 0.99, 15), rng.uniform(0.01, 0.99, 15)
                s = p.evaluate(u, v)
                fd = ((p.evaluate(u + h, v).P - p.evaluate(u - h, v).P) / (2 * h),
                      (p.evaluate(u, v + h).P - p.evaluate(u, v - h).P) / (2 * h),
                      (p.evaluate(u + h, v).Pu - p.evaluate(u - h, v).Pu) / (2 * h),
                      (p.evaluate(u, v + h).Pu - p.evaluate(u, v - h).Pu) / (2 * h),
                      (p.evaluate(u, v + h).Pv - p.evaluate(u, v - h).Pv) / (2 * h))
                for got, ref in zip((s.Pu, s.Pv, s.Puu, s.Puv, s.Pvv), fd):
                    self.assertLess(np.abs(got - ref).max(), 1e-5 * (1.0 + np.abs(got).max()), f"{name} {p.name}")

    def test_no_nan_anywhere(self):
        assert_finite_everywhere(self, self.models)


class BadInput(unittest.TestCase):
    def base(self):
        X, Y = clamped_grid(6, 6, 3)
        n = len(X)
        return from_lines(X, Y, [(j, 0, n - 1) for j in range(n)], [(i, 0, n - 1) for i in range(n)],
                          lambda i, j: (X[i], Y[j], 0.0))

    def assertRefused(self, mesh, *words):
        with self.assertRaises(InputError) as cm:
            tspline_model(mesh)
        for w in words:
            self.assertIn(w, str(cm.exception))

    def test_weights(self):
        for w in (0.0, -1.0, np.nan):
            m = self.base()
            m.weights[7] = w
            self.assertRefused(m, "vertex 8", "weight")

    def test_nan_coordinate(self):
        m = self.base()
        m.points[3, 1] = np.nan
        self.assertRefused(m, "vertex 4", "not a number")

    def test_unused_vertex(self):
        m = self.base()
        m.points = np.vstack([m.points, [0, 0, 0]])
        m.weights = np.append(m.weights, 1.0)
        self.assertRefused(m, f"vertex {len(m.points)}", "not used")

    def test_inconsistent_intervals(self):
        m = self.base()
        f = next(k for k in range(len(m.faces)) if min(m.intervals[k]) > 0)
        m.intervals[f][0] += 0.5
        self.assertRefused(m, "has knot interval", f"face {f + 1}")
        m2 = self.base()
        m2.intervals[f][0] += 0.5
        for g in range(len(m2.faces)):          # both faces along the edge agree, opposite side not
            for k in range(4):
                a, b = m2.faces[g][k], m2.faces[g][(k + 1) % 4]
                if (a, b) == (m2.faces[f][1], m2.faces[f][0]):
                    m2.intervals[g][k] += 0.5
        self.assertRefused(m2, "opposite sides")

    def test_negative_interval_and_bad_corners(self):
        m = self.base()
        m.intervals[5][1] = -1.0
        self.assertRefused(m, "face 6")
        m = self.base()
        m.corners[4] = (0, 1, 1, 3)
        self.assertRefused(m, "face 5", "corners")

    def test_unclamped_boundary(self):
        X = np.arange(5.0)
        m = from_lines(X, X, [(j, 0, 4) for j in range(5)], [(i, 0, 4) for i in range(5)],
                       lambda i, j: (i, j, 0.0))
        self.assertRefused(m, "not clamped", "face")

    def test_non_manifold_and_orientation(self):
        m = self.base()
        m.faces[3] = m.faces[3][::-1].copy()
        m.corners[3] = (0, 1, 2, 3)
        self.assertRefused(m, "same direction")
