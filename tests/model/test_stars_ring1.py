"""Star points whose first ring of faces has T-junctions (tsplcam/model/stars.py:
``ring1_t_junctions``, ``_ring1_functions``, ``_level1_parts``): a T-junction in the middle of
an outer side of a face around the star, or a spoke or diagonal vertex that is itself a
T-junction. Against independent references:

* at a regular vertex taken as a star (valence 4, ``subdivide_at``) the construction must be
  the T-spline's own surface, the same T-mesh evaluated without it, on every face (its
  Bezier extraction is tested against the brute-force rational sum in test_stars*.py);
* at stars of valence 3, 5 and 6 with random intervals: the blending functions sum to 1 on
  every cell, a plane is reproduced, the faces meet watertight and tangent continuous across
  every edge, one normal at the star (also with rational weights);
* T-junctions off the middle of their sides (``_levelm_parts``: at k/2^m, or anywhere at
  3/2^m of the side from the spoke or further, m <= 10): the same checks, at 1/4, 3/8, 7/8,
  1/3 and 0.1 of the sides, and two on one side (1/4 and 5/8) with one on the other face at
  the same spoke (3/4);
* what the construction cannot take is refused by name: a T-junction too close to the spoke,
  one on a spoke, and at valence 3 a diagonal whose rays meet T-junctions on both sides of
  the star (from valence 4 on it loads: at valence 4 it is the T-spline)."""
import unittest

import numpy as np

from tsplcam.errors import InputError
from tsplcam.model.tmesh import TMesh
from tsplcam.model.tspline import tspline_model
from conftest import angle_between, split_face
from test_stars import G1_DEG, meet, near_vertex, random_intervals, star_disc
from test_stars_tjunction import cell_sums, face_at, turned

SCALE_TOL = 1e-12          # positions, of the model size
DERIV_TOL = 1e-10          # first derivatives, of the model size
POU_TOL = 1e-13            # sum of the blending functions - 1
OFF = "off the middle"     # analysis-suitable layouts with T-junctions off their sides' middles


def split_at(mesh: TMesh, f: int, ratio: float) -> TMesh:
    """Quad face f cut in two along sides 0 and 2 at ``ratio`` of side 0 (from corner 0) and
    the same knot value on side 2: two new vertices, T-junctions on the neighbours across."""
    loop = [int(x) for x in mesh.faces[f]]
    a, b, c, d = loop
    P = list(mesh.points) + [(1 - ratio) * mesh.points[a] + ratio * mesh.points[b],
                             ratio * mesh.points[c] + (1 - ratio) * mesh.points[d]]
    m1, m2 = len(P) - 2, len(P) - 1
    faces = [list(map(int, x)) for x in mesh.faces]
    corners = [list(x) for x in mesh.corners]
    iv = [list(map(float, x)) for x in mesh.intervals]
    da, db = iv[f][0], iv[f][1]

    def insert(u, v_, mid, first):
        for g, lp in enumerate(faces):
            for k in range(len(lp)):
                if lp[k] == u and lp[(k + 1) % len(lp)] == v_:
                    whole = iv[g][k]
                    lp.insert(k + 1, mid)
                    iv[g][k:k + 1] = [first * whole, (1 - first) * whole]
                    corners[g] = [x + 1 if x > k else x for x in corners[g]]
                    return

    insert(b, a, m1, 1 - ratio)
    insert(d, c, m2, ratio)
    faces[f], corners[f], iv[f] = [a, m1, m2, d], [0, 1, 2, 3], [ratio * da, db, ratio * da, db]
    faces.append([m1, b, c, m2])
    corners.append([0, 1, 2, 3])
    iv.append([(1 - ratio) * da, db, (1 - ratio) * da, db])
    return TMesh(np.array(P), np.ones(len(P)), faces, corners, iv)


def merge(mesh: TMesh, f: int, g: int) -> TMesh:
    """Quad faces f and g, which share one edge, as one face: the shared edge's ends become
    T-junctions on its sides."""
    F, G = [int(x) for x in mesh.faces[f]], [int(x) for x in mesh.faces[g]]
    fi, gi = list(mesh.intervals[f]), list(mesh.intervals[g])
    for k in range(4):
        for m in range(4):
            if F[k] == G[(m + 1) % 4] and F[(k + 1) % 4] == G[m]:
                loop = [F[(k + 1) % 4], F[(k + 2) % 4], F[(k + 3) % 4], F[k], G[(m + 2) % 4], G[(m + 3) % 4]]
                ivs = [fi[(k + 1) % 4], fi[(k + 2) % 4], fi[(k + 3) % 4], gi[(m + 1) % 4], gi[(m + 2) % 4],
                       gi[(m + 3) % 4]]
                keep = [i for i in range(len(mesh.faces)) if i not in (f, g)]
                return TMesh(mesh.points, mesh.weights, [list(map(int, mesh.faces[i])) for i in keep] + [loop],
                             [list(mesh.corners[i]) for i in keep] + [[1, 2, 4, 5]],
                             [list(mesh.intervals[i]) for i in keep] + [ivs])
    raise ValueError("the faces share no edge")


def right(mesh: TMesh, j: int) -> TMesh:
    """A T-junction in the middle of the outer side of sector j's first face along spoke j
    (its face beyond that side cut in two)."""
    return split_face(turned(mesh, face_at(j, 1, 0)), face_at(j, 1, 0))


def top(mesh: TMesh, j: int) -> TMesh:
    """A T-junction in the middle of the outer side of sector j's first face along spoke j+1."""
    return split_face(mesh, face_at(j, 0, 1))


def cases(n: int):
    """(name, T-mesh, analysis-suitable) with T-junctions in the first ring of the star (vertex 0)
    of valence n. The T-spline of the valence-4 disc is a partition of unity in the suitable
    ones only (measured: 0; the others, where the T-junctions' lines cross near the star,
    0.19 and 0.21, and 8.5e-3 at valence 4 where diagonal 3 is between two T-junctions)."""
    mesh = star_disc(n, random_intervals(n, 40 + n))
    yield "outer side along spoke 0", right(mesh, 0), True
    yield "outer side along spoke 1", top(mesh, 0), True
    yield "along spoke 1 in sector 1 and spoke 1 in sector 0", top(right(mesh, 1), 0), True
    # (at valence 4 diagonal 3's rays meet both: not analysis-suitable, the T-spline's sums
    # miss 1 by 8.5e-3 as much as the construction's; it is checked against the T-spline only)
    yield "along spoke 0 in sector 0 and spoke 3 in sector 2", top(right(mesh, 0), 2), n != 4
    yield "diagonal 0 a T-junction (no line upwards)", merge(mesh, face_at(0, 0, 1), face_at(0, 1, 1)), True
    yield "diagonal 0 a T-junction (no line outwards)", merge(mesh, face_at(0, 1, 0), face_at(0, 1, 1)), True
    yield "spoke vertex 0 a T-junction", merge(mesh, face_at(0, 1, 0), face_at(n - 1, 0, 1)), True
    yield "spoke vertex 0 a T-junction, a T-junction in sector 1", top(merge(
        mesh, face_at(0, 1, 0), face_at(n - 1, 0, 1)), 1), True
    # with T-junctions in the second ring too (test_stars_tjunction.py)
    yield "along spoke 0, the second ring cut off spoke 1", split_face(right(mesh, 0), face_at(1, 1, 1)), True
    yield "along spoke 1, the second ring cut on spoke 0", split_face(top(mesh, 0), face_at(0, 1, 0)), True
    yield "along spoke 0, diagonal 1 a T-junction", merge(right(mesh, 0), face_at(1, 0, 1), face_at(1, 1, 1)), True
    if n >= 4:
        yield "along spokes 0 and 1 in sectors 0 and 1", top(right(mesh, 0), 1), True
        yield "along spoke 0 in sectors 0 and 2", right(right(mesh, 0), 2), True
    yield "both outer sides of sector 0", top(right(mesh, 0), 0), False
    every = mesh
    for j in range(n):
        every = top(right(every, j), j)
    yield "both outer sides of every sector", every, False


def off_right(mesh: TMesh, j: int, ratio: float) -> TMesh:
    """A T-junction on the outer side of sector j's first face along spoke j, at ``ratio`` of
    the side from the spoke (the face beyond cut there)."""
    return split_at(turned(mesh, face_at(j, 1, 0)), face_at(j, 1, 0), ratio)


def off_top(mesh: TMesh, j: int, ratio: float) -> TMesh:
    """A T-junction on the outer side of sector j's first face along spoke j + 1, at ``ratio``
    of the side from the spoke."""
    return split_at(mesh, face_at(j, 0, 1), ratio)


def off_cases(n: int):
    """(name, T-mesh) with first-face T-junctions off their sides' middles (all analysis
    suitable): dyadic and not, alone, with a middle one on another spoke, on two spokes, two on
    one side and one on the other face at that spoke."""
    mesh = star_disc(n, random_intervals(n, 60 + n))
    yield "1/4 along spoke 0", off_right(mesh, 0, 0.25)
    yield "3/8 along spoke 1", off_top(mesh, 0, 0.375)
    yield "1/3 along spoke 0, diagonal 1 a T-junction", merge(off_right(mesh, 0, 1 / 3), face_at(1, 0, 1),
                                                                face_at(1, 1, 1))
    if n != 3:                 # at valence 3 diagonal 2's rays meet both (refused)
        yield "7/8 along spoke 0, 0.1 along spoke 2 in sector 1", off_top(off_right(mesh, 0, 0.875), 1, 0.1)
    two = off_right(mesh, 1, 0.25)            # the face beyond cut again, halfway along its part
    yield "1/4 and 5/8 along spoke 1 in sector 1, 3/4 along spoke 1 in sector 0", off_top(
        split_at(two, len(two.faces) - 1, 0.5), 0, 0.75)


class RegularVertexWithTJunctionsAround(unittest.TestCase):
    """Valence 4: the refinement and the NURCC rules are knot insertion, so the construction
    is the T-spline itself, suitable or not."""

    def test_equals_the_t_spline(self):
        rng = np.random.default_rng(11)
        off = list(off_cases(4))[2:]            # (1/4 and 3/8: at valences 3 and 5; time budget)
        for name, mesh, _ in list(cases(4)) + [(name, mesh, True) for name, mesh in off]:
            plain, star = tspline_model(mesh), tspline_model(mesh, subdivide_at=[0])
            faces = [f for f in range(len(mesh.faces)) if min(plain.face_size[f]) > 0]
            f = np.concatenate([rng.choice(faces, 3000), near_vertex(plain, mesh, 0, 1e-3, 50, rng)[0]])
            s, t = rng.random(len(f)), rng.random(len(f))
            a, b = plain.evaluate_faces(f, s, t), star.evaluate_faces(f, s, t)
            scale = np.abs(mesh.points).max()
            self.assertLess(np.abs(a.P - b.P).max(), SCALE_TOL * scale, name)        # measured <= 7.3e-16
            self.assertLess(np.abs(a.Pu - b.Pu).max(), DERIV_TOL * scale, name)      # measured <= 1.1e-13
            self.assertLess(np.abs(a.Pv - b.Pv).max(), DERIV_TOL * scale, name)      # measured <= 6e-13


class StarsWithTJunctionsAround(unittest.TestCase):
    """Valences 3, 5 and 6 with random intervals (ratios up to 4)."""

    @classmethod
    def setUpClass(cls):
        cls.models = [(n, name, mesh, ok, tspline_model(mesh)) for n in (3, 5, 6) for name, mesh, ok in cases(n)]
        cls.models += [(n, name, mesh, OFF, tspline_model(mesh)) for n, pick in ((3, (0, 2, 3)), (5, (1, 3)))
                       for name, mesh in [list(off_cases(n))[i] for i in pick]]          # (time budget)

    def test_partition_of_unity(self):
        rng = np.random.default_rng(8)
        for n, name, mesh, suitable, model in self.models:
            if suitable:
                self.assertLess(cell_sums(model, rng), POU_TOL, (n, name))          # measured <= 1.5e-15

    def test_watertight_and_tangent_continuous_across_edges(self):
        for n, name, mesh, _, model in self.models:
            gap, angle = meet(model, mesh)
            self.assertLess(gap, SCALE_TOL, (n, name))                             # measured <= 5e-16
            self.assertLess(angle, 1e-6, (n, name))                                # measured <= 2.3e-11 deg

    def test_one_normal_at_the_star(self):
        rng = np.random.default_rng(7)
        for n, name, mesh, _, model in self.models:
            f, s, t = near_vertex(model, mesh, 0, 2.0 ** -30, 20, rng)
            near = model.evaluate_faces(f, s, t)
            at = model.evaluate_faces(*near_vertex(model, mesh, 0, 0.0, 1, rng))
            jump = np.degrees(angle_between(near.normal, np.repeat(at.normal[:1], len(f), 0))).max()
            self.assertLess(jump, G1_DEG, (n, name))                              # measured <= 5.3e-5 deg

    def test_plane_is_reproduced(self):
        """Control points on a plane: so is the surface, near the star and on every face."""
        rng = np.random.default_rng(9)
        for n, name, mesh, suitable, _ in self.models:
            if not suitable or n == 6 or (n == 5 and suitable == OFF):    # (the suite's time budget)
                continue
            plane = mesh.points.copy()
            plane[:, 2] = 0.3 * plane[:, 0] - 0.7 * plane[:, 1] + 0.2
            flat = tspline_model(TMesh(plane, None, mesh.faces, mesh.corners, mesh.intervals))
            faces = [f for f in range(len(mesh.faces)) if min(flat.face_size[f]) > 0]
            f = np.concatenate([rng.choice(faces, 1500), near_vertex(flat, mesh, 0, 1e-3, 20, rng)[0]])
            s, t = rng.random(len(f)), rng.random(len(f))
            P = flat.evaluate_faces(f, s, t).P
            self.assertLess(np.abs(P[:, 2] - (0.3 * P[:, 0] - 0.7 * P[:, 1] + 0.2)).max(),
                            SCALE_TOL * np.abs(plane).max(), (n, name))

    def test_rational_weights(self):
        """Weights on the star, its neighbours and the T-junctions: still watertight and
        tangent continuous, one normal at the star."""
        rng = np.random.default_rng(12)
        for n in (3, 5):
            for name, mesh, _ in list(cases(n))[::2]:       # every other layout (time budget)
                mesh.weights = rng.uniform(0.5, 2.0, mesh.n_vertices)
                model = tspline_model(mesh)
                gap, angle = meet(model, mesh)
                self.assertLess(gap, SCALE_TOL, (n, name))
                self.assertLess(angle, 1e-6, (n, name))
                near = model.evaluate_faces(*near_vertex(model, mesh, 0, 2.0 ** -30, 10, rng))
                at = model.evaluate_faces(*near_vertex(model, mesh, 0, 0.0, 1, rng))
                jump = np.degrees(angle_between(near.normal, np.repeat(at.normal[:1], len(near.normal), 0))).max()
                self.assertLess(jump, G1_DEG, (n, name))


class Refused(unittest.TestCase):
    def assertRefused(self, mesh: TMesh, *words):
        with self.assertRaises(InputError) as cm:
            tspline_model(mesh)
        for w in ("extraordinary vertex 1",) + words:
            self.assertIn(w, str(cm.exception))

    def test_t_junction_too_close_to_the_spoke(self):
        """At 1/2000 of its side the T-junction's knot would need 13 levels of refinement."""
        for n in (3, 4, 5):
            mesh = star_disc(n, random_intervals(n, 40 + n))
            cut = off_right(mesh, 0, 1 / 2000)
            t = mesh.n_vertices + 1                       # the T-junction on the first face's side
            if n != 4:
                self.assertRefused(cut, "at 0.0005 of its side from the spoke", cut.vertex_name(t))
                continue
            tspline_model(cut)                            # valence 4: a T-spline without stars
            with self.assertRaises(InputError) as cm:
                tspline_model(cut, subdivide_at=[0])
            self.assertIn("at 0.0005 of its side from the spoke", str(cm.exception))

    def test_t_junction_on_a_spoke(self):
        for n in (3, 5):
            mesh = star_disc(n, random_intervals(n, 40 + n))
            self.assertRefused(split_face(mesh, face_at(0, 0, 0)), "on a side at the star")

    def test_diagonal_between_two_t_junctions(self):
        """Valence 3: a diagonal vertex whose rays through both spoke vertices next to it meet
        a first face's T-junction (sector 2's, T-junctions in sectors 0 and 1: the valence-4
        copy with those sectors next to each other is analysis-suitable, and the construction
        missed the partition of unity by 1.4e-2). From valence 4 on it loads (``cases``)."""
        mesh = star_disc(3, random_intervals(3, 43))
        self.assertRefused(top(right(mesh, 0), 1), "both sides of the star")


if __name__ == "__main__":
    unittest.main()
