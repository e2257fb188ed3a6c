"""fcl's questions about a few poses answered from a BVH of the triangles near them
(tsplcam.orientation.nearby) give the answers of the whole workpiece's BVH, bit for bit:
collisions of the grown tool parts, of the fcl primitives and of the gouge check's ball,
distances of the clearance parts and the smallest clearance; and the triangles taken are a
superset of those that reach into the frustums asked about."""
import unittest

import numpy as np

from conftest import keycap_mold_checker
from tsplcam.model import samples
from tsplcam.model.cage import cage_model
from tsplcam.orientation import CollisionChecker, load_tool
from tsplcam.orientation.nearby import NearWorkpiece
from tsplcam.verify.orientation import min_clearance

try:
    import fcl
except ImportError:                                       # pragma: no cover
    fcl = None


@unittest.skipIf(fcl is None, "python-fcl is not installed")
class NearAnswersAsWhole(unittest.TestCase):
    """The keycap mold and its stock (the holder near the block), poses over the cavity with
    axes up to 35 deg from the vertical, asked in batches of a few poses (each a near BVH) of
    a checker that never builds the whole BVH, and of one that has it built."""

    @classmethod
    def setUpClass(cls):
        _, cls.near = keycap_mold_checker(clearance=0.3)
        _, cls.whole = keycap_mold_checker(clearance=0.3)
        cls.whole.build_bvh()
        rng = np.random.default_rng(11)
        n = 240
        cls.C = np.column_stack([rng.uniform(-7, 7, n), rng.uniform(-7, 7, n), rng.uniform(1.0, 8.0, n)])
        tilt = np.radians(rng.uniform(0.0, 35.0, n))[:, None]
        side = np.cross([0.0, 0.0, 1.0], rng.normal(size=(n, 3)))
        side /= np.linalg.norm(side, axis=1, keepdims=True)
        cls.A = np.cos(tilt) * np.array([0.0, 0.0, 1.0]) + np.sin(tilt) * side

    def batches(self, n, size=12):
        return [np.arange(n)[s:s + size] for s in range(0, n, size)]

    def test_collisions(self):
        only, _ = self.near.clearance_parts()
        asked = 0
        for g in (0.0, 0.3, 1.0):
            for b in self.batches(len(self.C)):
                a = self.near.collides_parts(self.C[b], self.A[b], g, only=only)
                w = self.whole.collides_parts(self.C[b], self.A[b], g, only=only)
                np.testing.assert_array_equal(a[0], w[0])
                np.testing.assert_array_equal(a[1], w[1])
                asked += int((a[1] != 0).sum())
        for b in self.batches(len(self.C)):
            np.testing.assert_array_equal(self.near.collides_exact(self.C[b], self.A[b]),
                                          self.whole.collides_exact(self.C[b], self.A[b]))
        self.assertGreater(asked, 0)                    # (fcl was asked: the near BVHs answered)
        self.assertIsNone(self.near._wp_object)
        self.assertGreater(self.near._nearby.builds, 0)

    def test_ball_gouges(self):
        # ball centres 0.2-0.8 mm above the mesh's vertices: a ball of 0.49 mm gouges below
        # about 0.5 mm
        model = self.near.mesh
        rng = np.random.default_rng(2)
        k = rng.choice(len(model.vertices), 200, replace=False)
        C = model.vertices[k] + np.array([0.0, 0.0, 1.0]) * rng.uniform(0.2, 0.8, (200, 1))
        got = np.concatenate([self.near.ball_gouges(C[b]) for b in self.batches(len(C), 6)])
        want = self.whole.ball_gouges(C)
        np.testing.assert_array_equal(got, want)
        self.assertTrue(want.any() and (~want).any())
        self.assertIsNone(self.near._wp_object)

    def test_distances_and_smallest_clearance(self):
        """On the mold, some batches' holders reach much of the block: those build the whole
        BVH; on the keycap (convex, as the main job) none does."""
        self.assert_same_distances(self.near, self.whole, self.C, self.A)
        keycap = cage_model(samples.keycap())
        tool = load_tool("ball1_keycap")
        near = CollisionChecker(keycap, tool, clearance=0.3)
        whole = CollisionChecker(keycap, tool, clearance=0.3)
        whole.build_bvh()
        rng = np.random.default_rng(5)
        u, v = rng.uniform(0.05, 0.95, (2, 200))
        sp = keycap.patches[4].evaluate(u, v)
        side = np.cross(sp.normal, rng.normal(size=(200, 3)))
        side /= np.linalg.norm(side, axis=1, keepdims=True)
        tilt = np.radians(rng.uniform(20.0, 60.0, 200))[:, None]
        A = np.cos(tilt) * sp.normal + np.sin(tilt) * side
        self.assert_same_distances(near, whole, sp.P + 0.5 * sp.normal, A)
        self.assertIsNone(near._wp_object)
        self.assertGreater(near._nearby.builds, 0)

    def assert_same_distances(self, near, whole, C, A):
        only, margin = near.clearance_parts()
        free = ~whole.collides(C, A)
        C, A = C[free], A[free]
        below = whole.touching_bound(0.5)
        measured = 0
        for b in self.batches(len(C), 10):
            a = near.clearance_of(C[b], A[b], only, smallest=True, below=below)
            w = whole.clearance_of(C[b], A[b], only, smallest=True, below=below)
            if np.isfinite(w).any():
                self.assertEqual(float(a.min()), float(w.min()))
                self.assertEqual(int(np.argmin(a)), int(np.argmin(w)))
                measured += 1
            else:
                self.assertFalse(np.isfinite(a).any())
        self.assertGreater(measured, 0)
        self.assertEqual(min_clearance(near, C, A), min_clearance(whole, C, A))


@unittest.skipIf(fcl is None, "python-fcl is not installed")
class BvhModel(unittest.TestCase):
    def test_rows_give_the_arrays_bvh(self):
        """nearby.bvh_model hands python-fcl its vertices as rows that are their own float64
        copy: the BVH answers as one made from the plain arrays, bit for bit (distances and
        nearest points to spheres all round the keycap's mesh, collisions)."""
        checker = CollisionChecker(cage_model(samples.keycap()), load_tool("ball1_keycap"))
        V, T = checker.mesh.vertices, checker.mesh.triangles
        from tsplcam.orientation.nearby import bvh_model
        plain = fcl.BVHModel()
        plain.beginModel(len(T), len(V))
        plain.addSubModel(np.ascontiguousarray(V, float), np.ascontiguousarray(T, np.int64))
        plain.endModel()
        ours = fcl.CollisionObject(bvh_model(V, T), fcl.Transform())
        plain = fcl.CollisionObject(plain, fcl.Transform())
        rng = np.random.default_rng(5)
        lo, hi = V.min(axis=0) - 2.0, V.max(axis=0) + 2.0
        hits = 0
        for c in rng.uniform(lo, hi, (60, 3)):
            ball = fcl.CollisionObject(fcl.Sphere(float(rng.uniform(0.2, 2.0))), fcl.Transform(c))
            got = []
            for wp in (ours, plain):
                req, res = fcl.DistanceRequest(enable_nearest_points=True), fcl.DistanceResult()
                d = fcl.distance(ball, wp, req, res)
                hit = fcl.collide(ball, wp, fcl.CollisionRequest(), fcl.CollisionResult())
                got.append((d, tuple(res.nearest_points[1]), hit))
            self.assertEqual(got[0], got[1])
            hits += got[0][2]
        self.assertGreater(hits, 0)


@unittest.skipIf(fcl is None, "python-fcl is not installed")
class NearTriangles(unittest.TestCase):
    def test_every_triangle_reaching_in_is_taken(self):
        """Frustums (cylinders, cones, balls) about random segments over the keycap: every
        triangle with a corner, an edge's midpoint or its centroid inside is taken."""
        checker = CollisionChecker(cage_model(samples.keycap()), load_tool("ball1_keycap"))
        V, T = checker.mesh.vertices, checker.mesh.triangles
        near = NearWorkpiece(V, T, checker.broad)
        rng = np.random.default_rng(4)
        taken = inside_any = 0
        pts = np.concatenate([V[T], 0.5 * (V[T] + V[T][:, [1, 2, 0]]), V[T].mean(axis=1, keepdims=True)], axis=1)
        for trial in range(30):
            P0 = V[rng.integers(len(V))] + rng.normal(scale=1.0, size=3)
            d = rng.normal(size=3)
            L = rng.choice([0.0, 2.0, 8.0])
            P1 = P0 + L * d / np.linalg.norm(d)
            r0, r1 = rng.uniform(0.2, 3.0, 2)
            if L == 0.0:
                r1 = r0
            got = near.triangles(P0[None], P1[None], np.array([r0]), np.array([r1]))
            w = pts - P0
            if L > 0:
                u = (P1 - P0) / L
                t = w @ u
                rho = np.linalg.norm(w - t[..., None] * u, axis=-1)
                inside = (t >= 0) & (t <= L) & (rho <= r0 + (r1 - r0) * np.clip(t / L, 0, 1))
            else:
                inside = np.linalg.norm(w, axis=-1) <= r0
            must = inside.any(axis=1)
            self.assertFalse(np.any(must & ~got), (trial, int((must & ~got).sum())))
            taken += int(got.sum())
            inside_any += int(must.sum())
        self.assertGreater(inside_any, 0)
        self.assertLess(taken, 4 * inside_any + 30 * 200)         # (near ones, not the whole mesh)


if __name__ == "__main__":
    unittest.main()
