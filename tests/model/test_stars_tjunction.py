"""Star points next to T-junctions in their second ring of faces (tsplcam/model/stars.py,
``clear_t_junctions``: local knot insertion clears the star's two rings before the T-NURCC
refinement), against independent references:

* at a regular vertex taken as a star (valence 4, ``subdivide_at``) the construction must be
  the T-spline's own B-spline sum: the brute-force rational sum (scipy's basis, rays cast on
  the grid) and the same T-mesh evaluated without the construction;
* at stars of valence 3, 5 and 6 with non-uniform intervals: the blending functions sum to 1
  on every cell, a plane is reproduced, the faces meet watertight and tangent continuous
  across every edge, one normal at the star;
* a uniform cage with a vertex of a star's second ring taken out (two T-junctions, an
  interval 2): its refinement is the uniform cage again, so the surface must be the
  Catmull-Clark limit (the cage path, cage_model) of some points on that cage: found by least
  squares over every face, the fit must be exact (13 points fitted to 1900 samples)."""
import functools
import unittest

import numpy as np

from tsplcam.model.cage import Cage, cage_model
from tsplcam.model.tmesh import TMesh
from tsplcam.model.tspline import tspline_model
from conftest import angle_between, brute_force, split_face, t_junction_mesh
from test_stars import FAR_TOL, G1_DEG, meet, near_vertex, random_intervals, star_disc, uniform_prism

K = 5                                  # faces per sector side in star_disc


def face_at(j: int, p: int, q: int) -> int:
    """star_disc's face (p, q) of sector j (p along spoke j, q along spoke j + 1)."""
    return j * K * K + p * K + q


def turned(mesh: TMesh, f: int) -> TMesh:
    """The same T-mesh with face f's loop starting one corner later (so that split_face cuts
    it the other way)."""
    out = mesh.copy()
    out.faces[f] = np.roll(out.faces[f], -1)
    out.intervals[f] = np.roll(out.intervals[f], -1)
    return out


def cases(n: int):
    """(name, T-mesh) with T-junctions in the second ring of the star (vertex 0) of valence n,
    each a face of the ring cut in two: on spoke 0 beyond its vertex (from either side), off
    the spoke on the row of the diagonal vertex (the star's own knot beyond the spoke is then
    the farther one: part of its function goes to the spoke vertex), off or on spokes 0 and 1
    at once (parts of the star's and both spoke vertices' functions meet at the diagonal
    vertex between them, with different knots beyond it), and all of these around the star."""
    mesh = star_disc(n, random_intervals(n, 20 + n))
    yield "on spoke 0", split_face(mesh, face_at(0, 1, 0))
    yield "on spoke 0 from sector n-1", split_face(turned(mesh, face_at(n - 1, 0, 1)), face_at(n - 1, 0, 1))
    yield "off spoke 0", split_face(mesh, face_at(0, 1, 1))
    yield "off spokes 0 and 1", split_face(split_face(mesh, face_at(0, 1, 1)), face_at(1, 1, 1))
    yield "on spokes 0 and 1", split_face(split_face(mesh, face_at(0, 1, 0)), face_at(1, 1, 0))
    yield "on spoke 0, off spoke 1", split_face(split_face(mesh, face_at(0, 1, 0)), face_at(1, 1, 1))
    for p, where in ((0, "on"), (1, "off")):
        every = mesh
        for j in range(n):
            every = split_face(every, face_at(j, 1, p))
        yield f"{where} every spoke", every


@functools.lru_cache(maxsize=None)
def plain_cases4() -> list:
    """(name, T-mesh, its T-spline model) of every valence-4 case (built once: two classes
    use them; not to be changed)."""
    return [(name, mesh, tspline_model(mesh)) for name, mesh in cases(4)]


def cell_sums(model, rng, per: int = 6) -> float:
    """Largest |sum of the blending functions - 1| (unit weights) over random points of every
    cell of every patch (star cells included)."""
    err = 0.0
    for p in model.patches:
        group, local = p.cell_group.ravel(), p.cell_local.ravel()
        for gi, g in enumerate(p.groups):
            loc = np.unique(local[group == gi])
            if len(loc):
                idx = np.repeat(loc, per)
                H = g.evaluate(idx, rng.random(len(idx)), rng.random(len(idx)))[0]
                err = max(err, float(np.abs(H[0, 3] - 1.0).max()))
    return err


def _from(loop: list, first: int) -> list:
    k = loop.index(first)
    return loop[k:] + loop[:k]


def without_second_ring_vertex(cage: Cage, star: int):
    """The cage's T-mesh (every interval 1) with vertex w taken out, w the corner of the
    second ring beyond the first face's diagonal vertex q along spoke 0 (in that face's
    chart, S at (0, 0), q at (1, 1), w at (2, 1)): the edges (2, 0)-w-(2, 2) go, q-w-(3, 1)
    becomes one edge of interval 2, and the four faces at w become two faces with the
    T-junctions (2, 0) and (2, 2). Returns (T-mesh, w, per T-mesh face: the cage face it is,
    or its two halves with their corners 0)."""
    faces = [[int(v) for v in f] for f in cage.mesh.faces]
    edge = {(f[k], f[(k + 1) % 4]): i for i, f in enumerate(faces) for k in range(4)}
    _, s0, q, _ = _from(next(f for f in faces if star in f), star)
    g1 = edge[(q, s0)]
    _, a, w, _ = _from(faces[g1], s0)
    g1b = edge[(w, a)]
    _, c, d, _ = _from(faces[g1b], a)
    g2 = edge[(q, w)]
    _, _, e, f2 = _from(faces[g2], q)
    g2b = edge[(e, w)]
    _, _, g, _ = _from(faces[g2b], w)
    gone = {g1, g1b, g2, g2b}
    origin = [i for i in range(len(faces)) if i not in gone]
    loops = [faces[i] for i in origin] + [[s0, a, c, d, q], [q, d, g, e, f2]]
    corners = [(0, 1, 2, 3)] * len(origin) + [(0, 2, 3, 4), (0, 1, 2, 4)]
    iv = [[1.0] * 4] * len(origin) + [[1.0, 1.0, 1.0, 2.0, 1.0], [2.0, 1.0, 1.0, 1.0, 1.0]]
    origin += [((g1, s0), (g1b, a)), ((g2, q), (g2b, w))]
    keep = [v for v in range(len(cage.points)) if v != w]
    new = {v: k for k, v in enumerate(keep)}
    mesh = TMesh(cage.points[keep], None, [[new[v] for v in f] for f in loops], corners, iv)
    return mesh, w, origin


def on_cage(cage: Cage, origin, rng, per: int = 6):
    """Random points of every T-mesh face as (T-mesh face, s, t) and (cage face, s, t)."""
    fm, sm, tm, fc, sc, tc = [], [], [], [], [], []
    for k, o in enumerate(origin):
        for s, t in rng.random((per, 2)):
            fm.append(k)
            sm.append(s)
            tm.append(t)
            if not isinstance(o, tuple):
                fc.append(o)
                sc.append(s)
                tc.append(t)
                continue
            half, first = o[0] if s < 0.5 else o[1]
            x = 2 * s if s < 0.5 else 2 * s - 1
            r = (4 - [int(v) for v in cage.mesh.faces[half]].index(first)) % 4
            fc.append(half)
            u, v = [(x, t), (t, 1 - x), (1 - x, 1 - t), (1 - t, x)][r]    # the face's own corner 0
            sc.append(u)
            tc.append(v)
    return (fm, sm, tm), (fc, sc, tc)


class RegularVertexNextToTJunctions(unittest.TestCase):
    """Valence 4: the refinement and the NURCC rules are knot insertion, so the construction
    is the T-spline itself."""

    def test_equals_brute_force_rational_sum(self):
        """Every interior vertex of the T-junction grids whose faces are quads around plain
        neighbours (the construction's other conditions), T-junctions in their two rings or
        not."""
        for seed, suitable, count in ((1, True, 18), (1, False, 10)):
            mesh, X, Y, hsegs, vsegs = t_junction_mesh(seed, suitable)
            topo = mesh.topology
            rng = np.random.default_rng(4)
            scale = np.abs(mesh.points).max()
            # the vertices and their points first, the brute-force sum of all points in one
            # call (its knot vectors and basis functions once, not once per vertex)
            todo = []
            for v in range(mesh.n_vertices):
                i, j = mesh.grid_index[v]
                if topo.boundary[v] or topo.total[v] != 4 or min(X[i] - X[i - 1], X[i + 1] - X[i],
                                                                  Y[j] - Y[j - 1], Y[j + 1] - Y[j]) <= 0:
                    continue
                near = {int(w) for f, _ in topo.fan[v] for w in mesh.faces[f]}
                if any(len(mesh.faces[f]) != 4 for f, _ in topo.fan[v]) or any(
                        topo.total[w] != 4 or any(topo.span(f, k) != 1 for f, k in topo.fan[w])
                        for w in near if not topo.boundary[w]):
                    continue
                W, H = X[-1] - X[0], Y[-1] - Y[0]            # the knot size of the one patch
                x = np.clip(X[i] + rng.uniform(-3, 3, 400) * (X[i + 1] - X[i]), 1e-9 * W, (1 - 1e-9) * W)
                y = np.clip(Y[j] + rng.uniform(-3, 3, 400) * (Y[j + 1] - Y[j]), 1e-9 * H, (1 - 1e-9) * H)
                todo.append((v, x, y))
            S, Ss, St = (r.reshape(len(todo), 400, 3) for r in brute_force(
                mesh, X, Y, hsegs, vsegs, np.concatenate([x for _, x, _ in todo] or [[]]),
                np.concatenate([y for _, _, y in todo] or [[]])))
            for k, (v, x, y) in enumerate(todo):
                patch = tspline_model(mesh, subdivide_at=[v]).patches[0]
                W, H = patch.knot_size
                self.assertAlmostEqual(W, X[-1] - X[0], delta=1e-12 * W)
                self.assertAlmostEqual(H, Y[-1] - Y[0], delta=1e-12 * H)
                sp = patch.evaluate(x / W, y / H)
                self.assertLess(np.abs(sp.P - S[k]).max(), 1e-12 * scale, (seed, v))
                self.assertLess(np.abs(sp.Pu / W - Ss[k]).max(), 1e-11 * scale, (seed, v))
                self.assertLess(np.abs(sp.Pv / H - St[k]).max(), 1e-11 * scale, (seed, v))
            self.assertEqual(len(todo), count, seed)

    def test_star_disc_cases_equal_the_t_spline(self):
        """The valence-4 disc with each second-ring case: the construction at the centre
        against the T-spline evaluated without it, on every face."""
        rng = np.random.default_rng(5)
        for name, mesh, plain in plain_cases4():
            star = tspline_model(mesh, subdivide_at=[0])
            faces = [f for f in range(len(mesh.faces)) if min(plain.face_size[f]) > 0]
            f = rng.choice(faces, 4000)
            s, t = rng.random(4000), rng.random(4000)
            a, b = plain.evaluate_faces(f, s, t), star.evaluate_faces(f, s, t)
            scale = np.abs(mesh.points).max()
            self.assertLess(np.abs(a.P - b.P).max(), 1e-12 * scale, name)
            self.assertLess(np.abs(a.Pu - b.Pu).max(), 1e-10 * scale, name)
            self.assertLess(np.abs(a.Pv - b.Pv).max(), 1e-10 * scale, name)


class StarsNextToTJunctions(unittest.TestCase):
    """Valences 3, 5 and 6 with random spoke intervals (ratios up to 4)."""

    @classmethod
    def setUpClass(cls):
        cls.models = [(n, name, mesh, tspline_model(mesh)) for n in (3, 5, 6) for name, mesh in cases(n)]
        # where T-junctions on two neighbouring spokes' lines have crossing extensions the
        # T-mesh is not analysis-suitable: its blending functions do not sum to 1 even at a
        # regular vertex (the plain T-spline of the valence-4 disc, 4e-2), nor can they here
        rng = np.random.default_rng(3)
        cls.suitable = {name for name, _, plain in plain_cases4() if cell_sums(plain, rng) < 1e-12}

    def test_partition_of_unity(self):
        rng = np.random.default_rng(8)
        self.assertEqual(len(self.suitable), 6)
        for n, name, mesh, model in self.models:
            if name in self.suitable:
                self.assertLess(cell_sums(model, rng), 1e-12, (n, name))

    def test_watertight_and_tangent_continuous_across_edges(self):
        for n, name, mesh, model in self.models:
            gap, angle = meet(model, mesh)
            self.assertLess(gap, FAR_TOL, (n, name))
            self.assertLess(angle, G1_DEG, (n, name))

    def test_one_normal_at_the_star(self):
        rng = np.random.default_rng(7)
        for n, name, mesh, model in self.models:
            f, s, t = near_vertex(model, mesh, 0, 2.0 ** -30, 20, rng)
            near = model.evaluate_faces(f, s, t)
            at = model.evaluate_faces(*near_vertex(model, mesh, 0, 0.0, 1, rng))
            jump = np.degrees(angle_between(near.normal, np.repeat(at.normal[:1], len(f), 0))).max()
            self.assertLess(jump, G1_DEG, (n, name))

    def test_plane_is_reproduced(self):
        """Control points on a plane: so is the surface, near the star and on every face."""
        rng = np.random.default_rng(9)
        for n, name, mesh, _ in self.models:
            if name not in self.suitable:
                continue
            plane = mesh.points.copy()
            plane[:, 2] = 0.3 * plane[:, 0] - 0.7 * plane[:, 1] + 0.2
            flat = tspline_model(TMesh(plane, None, mesh.faces, mesh.corners, mesh.intervals))
            faces = [f for f in range(len(mesh.faces)) if min(flat.face_size[f]) > 0]
            f = np.concatenate([rng.choice(faces, 2000), near_vertex(flat, mesh, 0, 1e-3, 20, rng)[0]])
            s, t = rng.random(len(f)), rng.random(len(f))
            P = flat.evaluate_faces(f, s, t).P
            self.assertLess(np.abs(P[:, 2] - (0.3 * P[:, 0] - 0.7 * P[:, 1] + 0.2)).max(),
                            1e-12 * np.abs(plane).max(), (n, name))


class UniformCageWithAT(unittest.TestCase):
    def test_is_the_catmull_clark_limit_of_the_refined_cage(self):
        """The refinement inserts w again; the T-spline's surface must be the Catmull-Clark
        limit of the cage with the refined points (those within two edges of w change, 13
        points; the rest are the T-mesh's): found by least squares on random points of every
        face (the limit is linear in the points), the fit must be exact."""
        rng = np.random.default_rng(6)
        for n in (3, 5, 6):
            cage, _, _, cage_limit = uniform_prism(n)            # (built once for test_stars too)
            mesh, w, origin = without_second_ring_vertex(cage, 0)
            on_mesh, on_c = on_cage(cage, origin, rng)
            target = tspline_model(mesh).evaluate_faces(*on_mesh).P
            near = {w}
            for _ in range(2):
                near |= {int(x) for f in cage.mesh.faces if near & set(f.tolist()) for x in f}
            near = sorted(near)
            P = cage.points
            ref = cage_limit.evaluate_faces(*on_c).P
            cols = []
            for i in range(0, len(near), 3):                  # the limit of a unit move of each point
                Q = P.copy()
                for c, v in enumerate(near[i:i + 3]):
                    Q[v, c] += 1.0
                moved = cage_model(Cage(cage.mesh, Q)).evaluate_faces(*on_c).P - ref
                cols += [moved[:, c] for c in range(len(near[i:i + 3]))]
            B = np.array(cols).T
            D = np.linalg.lstsq(B, target - ref, rcond=None)[0]
            self.assertEqual(np.linalg.matrix_rank(B), len(near), n)
            self.assertLess(np.abs(B @ D + ref - target).max(), 1e-9 * np.abs(P).max(), n)


if __name__ == "__main__":
    unittest.main()
