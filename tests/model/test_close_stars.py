"""Star points closer than three edges apart in T-meshes that are not plain Catmull-Clark cages
(tsplcam/model/close_stars.py): the faces around them from a local cage's limit, the kernel
beyond. References: the subdivision path (cage_model) on the same control points where the
knots are uniform; closed-form properties everywhere (the faces on both sides of every edge
meet, translating the control points translates the surface: partition of unity, one
normal at each star point)."""
import unittest

import numpy as np

from tsplcam.errors import InputError
from tsplcam.model import close_stars
from tsplcam.model.cage import Cage, cage_model
from tsplcam.model.quadmesh import QuadMesh
from tsplcam.model.tmesh import TMesh, quad_tmesh
from tsplcam.model.tspline import tspline_model
from tsplcam.model.twalk import Walker
from conftest import angle_between, faces_meet, split_face

EXACT = 1e-12          # of the model size: the same limit surface, to rounding
GAP = 1e-9             # of the model size: faces meet (watertight)
G1_DEG = 0.01          # normal jump at a star point


def rotate_edge(faces: list, f1: int, f2: int):
    """Faces f1 = (a, b, c, d) and f2 = (b, a, e, f) across edge a-b become (c, d, a, e) and
    (e, f, b, c): a and b lose a face, c and e gain one. On a regular grid that makes star
    points of valence 3, 3, 5, 5, each one or two edges from the others."""
    F1, F2 = [int(x) for x in faces[f1]], [int(x) for x in faces[f2]]
    k = next(k for k in range(4) if F1[(k + 1) % 4] in F2 and F2[(F2.index(F1[(k + 1) % 4]) + 1) % 4] == F1[k])
    a, b, c, d = F1[k:] + F1[:k]
    j = F2.index(b)
    _, _, e, f = F2[j:] + F2[:j]
    out = [[int(x) for x in lp] for lp in faces]
    out[f1], out[f2] = [c, d, a, e], [e, f, b, c]
    return out, [a, b, c, e]


def torus(N: int = 16, M: int = 12, seed: int = 0):
    """A closed N x M quad torus with two edges rotated (seven close star points: valences 3,
    3, 3, 3, 5, 5, 6), perturbed, with random weights: (points, faces, weights, stars)."""
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(N), np.arange(M), indexing="ij")
    a, b = 2 * np.pi * i.ravel() / N, 2 * np.pi * j.ravel() / M
    P = np.column_stack([(3 + np.cos(b)) * np.cos(a), (3 + np.cos(b)) * np.sin(a), np.sin(b)])
    P += 0.03 * rng.standard_normal(P.shape)
    idx = lambda p, q: (p % N) * M + q % M                                  # noqa: E731
    faces = [[idx(p, q), idx(p + 1, q), idx(p + 1, q + 1), idx(p, q + 1)] for p in range(N) for q in range(M)]
    faces, first = rotate_edge(faces, 5 * M + 5, 6 * M + 5)
    faces, second = rotate_edge(faces, 5 * M + 6, 5 * M + 7)          # first[2] gets a sixth face
    return P, faces, rng.uniform(0.7, 1.4, len(P)), sorted(set(first) | set(second))


def disc(n: int = 3, k: int = 14, spoke0=(), m: int | None = None, seed: int = 1):
    """An open clamped T-mesh around a star point (vertex 0) of valence n: sector j a k x k
    grid of faces between spokes j and j + 1, interval 1 along the spokes but for the first
    ones along spoke 0 (``spoke0``: a non-uniform star), 0 at the boundary; the edge between
    faces (m, m) and (m + 1, m) of sector 0 rotated (four close star points; by default in
    the middle, five rings from the boundary and from the star)."""
    rng = np.random.default_rng(seed)
    a = [np.ones(k) for _ in range(n)]
    a[0][:len(spoke0)] = spoke0
    for x in a:
        x[-1] = 0.0
    ids, pts = {}, []

    def node(j, p, q):
        key = ("c",) if p == q == 0 else ("s", j % n, p) if q == 0 else ("s", (j + 1) % n, q) if p == 0 \
            else ("i", j % n, p, q)
        if key not in ids:
            ids[key] = len(pts)
            ang = 2 * np.pi / n
            xy = (np.sum(a[j % n][:p]) * np.array([np.cos(ang * j), np.sin(ang * j)])
                  + np.sum(a[(j + 1) % n][:q]) * np.array([np.cos(ang * (j + 1)), np.sin(ang * (j + 1))]))
            pts.append([xy[0], xy[1], 0.3 * np.sin(0.3 * xy[0]) * np.cos(0.2 * xy[1])])
        return ids[key]

    faces, iv = [], []
    for j in range(n):
        for p in range(k):
            for q in range(k):
                faces.append([node(j, p, q), node(j, p + 1, q), node(j, p + 1, q + 1), node(j, p, q + 1)])
                iv.append([a[j][p], a[(j + 1) % n][q]] * 2)
    m = k // 2 - 1 if m is None else m
    faces, stars = rotate_edge(faces, m * k + m, (m + 1) * k + m)
    P = np.array(pts) + 0.03 * rng.standard_normal((len(pts), 3))
    return TMesh(P, None, faces, [(0, 1, 2, 3)] * len(faces), iv), stars


def corner_st(model, mesh, f, v):
    """(s, t) of vertex v as a corner of face f."""
    k = [int(x) for x in mesh.faces[f]].index(v)
    W, H = model.face_size[f]
    p = mesh.topology.pos[f][k]
    return p[0].real / W, p[1].real / H


def star_normal_jump(model, mesh, stars, rng, eps=2.0 ** -30):
    """The largest angle (degrees) between the normal at a star point (from its first face)
    and the normals on every face around it, at the star and within ``eps`` of a face."""
    worst = 0.0
    for v in stars:
        fan = [f for f, _ in mesh.topology.fan[v]]
        st = np.array([corner_st(model, mesh, f, v) for f in fan])
        ref = model.evaluate_faces([fan[0]], *st[0]).normal
        f = np.repeat(fan, 9)
        r = np.vstack([np.zeros((len(fan), 2)), rng.random((8 * len(fan), 2)) * eps])
        s = np.abs(np.repeat(st[:, 0], 9) - r[:, 0])
        t = np.abs(np.repeat(st[:, 1], 9) - r[:, 1])
        n = model.evaluate_faces(f, s, t).normal
        worst = max(worst, np.degrees(angle_between(n, np.repeat(ref, len(f), 0))).max())
    return worst


def watertight(model, mesh):
    A, B = faces_meet(model, mesh, np.linspace(0.0, 1.0, 9))
    gap = np.abs(A.P - B.P).max() / np.ptp(mesh.points, axis=0).max()
    return gap, np.degrees(angle_between(A.normal, B.normal)).max()


def sample(faces, rng, per=12):
    f = np.repeat(faces, per)
    return f, rng.random(len(f)), rng.random(len(f))


class CloseStarsInATMesh(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        P, faces, w, cls.stars = torus()
        cls.cage = Cage(QuadMesh(np.array(faces), len(P)), P, w)
        cls.ref = cage_model(cls.cage)
        cls.mesh = quad_tmesh(P, faces, w)
        cls.rings = close_stars.rings(cls.mesh, cls.stars, 8)
        # a T-junction seven rings out: no longer a cage, the close stars come here
        cls.split = split_face(cls.mesh, cls.rings[6][1])
        cls.model = tspline_model(cls.split)

    def test_found_as_one_cluster(self):
        self.assertEqual(close_stars.clusters(self.split), [self.stars])
        self.assertEqual(sorted(e.valence for e in self.model.extraordinary), [3, 3, 3, 3, 5, 5, 6])

    def test_whole_surface_is_catmull_clark_without_the_t_junction(self):
        """On the cage itself (forced past the cage path) the kernel and the local cage give the
        Catmull-Clark limit everywhere: the zone, its seam and the kernel beyond."""
        rng = np.random.default_rng(3)
        model = close_stars.close_star_model(self.mesh, Walker(self.mesh))
        f, s, t = sample(np.arange(len(self.mesh.faces)), rng, 6)
        a, b = model.evaluate_faces(f, s, t), self.ref.evaluate_faces(f, s, t)
        size = np.ptp(self.cage.points, axis=0).max()
        self.assertLess(np.abs(a.P - b.P).max() / size, EXACT)
        self.assertLess(np.abs(a.Pu - b.Pu).max() / size, 1e3 * EXACT)

    def test_near_the_stars_is_catmull_clark_next_to_a_t_junction(self):
        rng = np.random.default_rng(4)
        f, s, t = sample([f for r in self.rings[:4] for f in r], rng)
        a, b = self.model.evaluate_faces(f, s, t), self.ref.evaluate_faces(f, s, t)
        self.assertLess(np.abs(a.P - b.P).max() / np.ptp(self.cage.points, axis=0).max(), EXACT)

    def test_watertight_and_one_normal_at_the_stars(self):
        gap, angle = watertight(self.model, self.split)
        self.assertLess(gap, GAP)
        self.assertLess(angle, 1e-6)
        self.assertLess(star_normal_jump(self.model, self.split, self.stars, np.random.default_rng(5)), G1_DEG)

    def test_partition_of_unity(self):
        """Translating every control point translates the surface by the same vector."""
        c = np.array([0.3, -1.1, 2.0])
        moved = TMesh(self.split.points + c, self.split.weights, self.split.faces, self.split.corners,
                      self.split.intervals)
        rng = np.random.default_rng(6)
        f, s, t = sample(np.arange(len(self.split.faces)), rng, 4)
        d = tspline_model(moved).evaluate_faces(f, s, t).P - self.model.evaluate_faces(f, s, t).P
        self.assertLess(np.abs(d - c).max() / np.ptp(self.split.points, axis=0).max(), EXACT)


class CloseStarsOnAnOpenDisc(unittest.TestCase):
    def test_next_to_a_non_uniform_star_and_the_boundary(self):
        """A clamped open disc around a valence-3 star with non-uniform spokes (the T-NURCC
        construction), four close stars in one of its sectors: the faces near them are the
        limit of the uniform cage around them; watertight, one normal at every star."""
        mesh, stars = disc(spoke0=(1.5,))
        model = tspline_model(mesh)
        self.assertEqual(sorted(e.valence for e in model.extraordinary), [3, 3, 3, 5, 5])
        rs = close_stars.rings(mesh, stars, 4)
        around = [f for r in rs for f in r]
        loops = np.array([[int(x) for x in mesh.faces[f]] for f in around])
        verts, inv = np.unique(loops, return_inverse=True)
        ref = cage_model(Cage(QuadMesh(inv.reshape(-1, 4), len(verts)), mesh.points[verts]))
        rng = np.random.default_rng(7)
        f, s, t = sample([f for r in rs[:3] for f in r], rng)
        a = model.evaluate_faces(f, s, t)
        b = ref.evaluate_faces([around.index(g) for g in f], s, t)
        self.assertLess(np.abs(a.P - b.P).max() / np.ptp(mesh.points, axis=0).max(), EXACT)
        gap, angle = watertight(model, mesh)
        self.assertLess(gap, GAP)
        self.assertLess(angle, 1e-6)
        self.assertLess(star_normal_jump(model, mesh, stars + [0], rng), G1_DEG)


class Refused(unittest.TestCase):
    def assertRefused(self, mesh, *fragments):
        with self.assertRaises(InputError) as cm:
            tspline_model(mesh)
        for frag in fragments:
            self.assertIn(frag, str(cm.exception))

    def test_t_junction_within_the_rings(self):
        P, faces, w, stars = torus()
        mesh = quad_tmesh(P, faces, w)
        ring3 = close_stars.rings(mesh, stars, 3)[2]
        self.assertRefused(split_face(mesh, ring3[0]), "closer than three edges apart", "has a T-junction")

    def test_other_interval_between_the_stars(self):
        mesh, stars = disc(spoke0=(1, 1, 1, 2))
        self.assertRefused(mesh, "closer than three edges apart", "knot interval 2 where the star points have 1")

    def test_near_the_boundary(self):
        mesh, stars = disc(m=8)
        self.assertRefused(mesh, "closer than three edges apart", "is on the boundary")


if __name__ == "__main__":
    unittest.main()
