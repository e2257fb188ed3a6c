"""Star points on an open boundary in the T-spline kernel (Fusion ``.tsm``,
``boundary_stars.py``): an L-shaped body, whose concave corner is a boundary vertex of
three faces (Catmull-Clark's extraordinary boundary vertex of valence four), and "books" of
four and five quadrants around a boundary vertex. Uniform and without T-junctions, the
kernel gives the cage path's limit (OpenSubdiv's edge-and-corner rule) on every face; with
T-junctions or other knot intervals beyond the star's rings it loads, the star's rings are
still that limit, faces meet without gaps and with one normal, and the functions are a
partition of unity. What it cannot take is refused with the file's line."""
import json
import os
import shutil
import tempfile
import unittest

import numpy as np

from conftest import edge_pair, external, faces_meet
from tsplcam.errors import InputError
from tsplcam.layout.layout import Layout
from tsplcam.model.boundary_stars import rings
from tsplcam.model.cage import Cage, cage_model
from tsplcam.model.formats.obj import read_obj
from tsplcam.model.formats.tsm import tsm_model
from tsplcam.model.formats.tsm_fusion import write_fusion_tsm
from tsplcam.model.quadmesh import QuadMesh
from tsplcam.model.tmesh import from_lines

N = 8                                      # the star at grid node (N, N) of a 2N x 2N grid


def height(x, y):
    return 3.0 * np.sin(x / 3.0) * np.cos(y / 4.0) + 0.02 * x * y


def l_cage(n=N):
    """The L: the 2n x 2n grid of unit squares without its lower right quarter, points on a
    wavy surface (5 mm per knot unit). Returns the cage and the star's vertex."""
    vid, pts, faces = {}, [], []

    def V(i, j):
        if (i, j) not in vid:
            vid[(i, j)] = len(pts)
            pts.append((5.0 * i, 5.0 * j, height(i, j)))
        return vid[(i, j)]
    for i in range(2 * n):
        for j in range(2 * n):
            if not (i >= n and j < n):
                faces.append([V(i, j), V(i + 1, j), V(i + 1, j + 1), V(i, j + 1)])
    return Cage(QuadMesh(np.array(faces), len(pts), "edge-and-corner"), np.array(pts)), vid[(n, n)]


def l_tmesh(shift=(0.0, 0.0, 0.0), tj=True):
    """The L as a T-mesh: knot intervals 1 within the star's five rings (grid 3 .. 13), others
    outside; with ``tj`` a column that starts at row 10 and a row that stops at column 6 (two
    T-junctions, and the faces beside them five-sided), points shifted by ``shift``."""
    X = np.array([0, 1.7, 2.4, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14.5, 15.2, 17.0])
    Y = X.copy()
    n = 2 * N
    hsegs = [(j, 0, n) for j in range(N, n + 1)] + [(j, 0, N) for j in range(N)]
    vsegs = [(i, 0, n) for i in range(N + 1)] + [(i, N, n) for i in range(N + 1, n + 1)]
    if tj:
        vsegs[1] = (1, 10, n)
        hsegs = [h for h in hsegs if h[0] != 15] + [(15, 0, 6)]
    return from_lines(X, Y, hsegs, vsegs,
                      lambda i, j: np.add((5.0 * X[i], 5.0 * Y[j], height(X[i], Y[j])), shift),
                      holes=lambda x, y: x > N and y < N)


def size_of(model):
    P = np.concatenate([p.evaluate(*np.meshgrid(np.linspace(0, 1, 9), np.linspace(0, 1, 9))).P
                        for p in model.patches])
    return float(np.linalg.norm(P.max(0) - P.min(0)))


def face_grid(faces, k=6):
    g = np.linspace(0.0, 1.0, k)
    S, T = np.meshgrid(g, g)
    return np.repeat(faces, k * k), np.tile(S.ravel(), len(faces)), np.tile(T.ravel(), len(faces))


def corner_of(mesh, v):
    """The T-mesh vertex at (knot) position v of the L's star."""
    return next(k for k in range(mesh.n_vertices) if tuple(mesh.grid_index[k]) == v)


def both_paths(test, path, faces):
    """The file at ``path`` through the cage path and the kernel: (cage model, kernel model),
    asserted equal on ``faces`` within 1e-12 of the size (positions) and 1e-10 (first
    derivatives)."""
    a, b = tsm_model(path), tsm_model(path, t_spline=True)
    test.assertEqual((a.kind, b.kind), ("catmull-clark", "t-spline"))
    assert_cage_limit(test, a, b, faces)
    return a, b


def assert_cage_limit(test, a, b, faces, label=None) -> float:
    """Kernel model ``b`` equals cage-path model ``a`` on ``faces`` (the T-mesh's numbering;
    the faces ``b`` left out found by ``model_faces``) within 1e-12 of the size in position
    and 1e-10 in first derivatives; returns the size."""
    scale = size_of(a)
    f, s, t = face_grid(faces)
    pa, pb = a.evaluate_faces(f, s, t), b.evaluate_faces(model_faces(b, f), s, t)
    test.assertLess(np.abs(pa.P - pb.P).max(), 1e-12 * scale, label)
    test.assertLess(max(np.abs(pa.Pu - pb.Pu).max(), np.abs(pa.Pv - pb.Pv).max()), 1e-10 * scale, label)
    return scale


class TempFiles(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="tsplcam-bstar-")
        self.addCleanup(shutil.rmtree, self.dir, True)

    def write(self, mesh, name):
        path = os.path.join(self.dir, name + ".tsm")
        write_fusion_tsm(mesh, path, grip_map=True)
        return path

    def write_creased(self, cage, name, creases):
        path = os.path.join(self.dir, name + ".tsm")
        write_fusion_tsm(cage, path, creases=creases)
        return path

    def write_knots(self, cage, name, knot):
        path = os.path.join(self.dir, name + ".tsm")
        write_fusion_tsm(cage, path, interval=lambda a, b: knot[(a, b)])
        return path


class BoundaryStars(TempFiles):

    def test_uniform_l_is_the_cage_limit(self):
        """The whole uniform L through the kernel equals the cage path on every face, with unit
        weights and with weights 1 + 0.3 cos k: measured at most 5e-16 of the model size in
        position and 1.8e-15 in first derivatives (the star's two rings come from a local cage,
        the third ring on is the kernel's own). Without the local cage the first two rings
        would be off by 1.1e-2 of the size in position (3.9e1 in derivatives at the star)."""
        cage, _ = l_cage()
        for w in (None, 1.0 + 0.3 * np.cos(np.arange(len(cage.points)))):
            weighted = Cage(cage.mesh, cage.points, w)
            a, b = both_paths(self, self.write(weighted, "l"), np.arange(len(cage.mesh.faces)))
            scale = size_of(a)
            # the star is the model's one extraordinary point, on the boundary, at the limit point
            self.assertEqual([(e.boundary, e.valence) for e in b.extraordinary], [(True, 3)])
            self.assertLess(np.linalg.norm(b.extraordinary[0].position - a.extraordinary[0].position),
                            1e-12 * scale)

    def test_crease_within_the_rings(self):
        """An infinitely sharp crease two rows above the star, across the L: the kernel (cut
        along the crease, the star's rings on its side) equals the cage path's creased limit
        (measured 2.5e-16 of the size, 1.5e-15 in derivatives); a crease that ends at the
        star is refused with its line."""
        cage, S = l_cage()
        at = {tuple(np.rint(cage.points[v, :2] / 5.0).astype(int)): v for v in range(len(cage.points))}
        row = [at[(i, N + 2)] for i in range(2 * N + 1)]
        path = self.write_creased(cage, "crease", list(zip(row[:-1], row[1:])))
        both_paths(self, path, np.arange(len(cage.mesh.faces)))
        up = [at[(N, j)] for j in range(N, 2 * N + 1)]
        with self.assertRaises(InputError) as cm:
            tsm_model(self.write_creased(cage, "to_star", list(zip(up[:-1], up[1:]))), t_spline=True)
        self.assertIsNotNone(cm.exception.line)

    def test_t_junctions_beyond_the_rings(self):
        """T-junctions and other knot intervals outside the star's five rings: the kernel; on
        the star's three rings the cage limit of the uniform L (the same points there); every
        pair of faces meets within 1e-12 of the size with one normal (sine of the angle below
        1e-9); moving every grip moves the surface by as much (partition of unity). Measured:
        faces meet within 2.4e-16 of the size, normals within 2.5e-15, the move within 2.4e-16."""
        mesh = l_tmesh()
        self.assertGreaterEqual(sum(len(f) > 4 for f in mesh.faces), 2)
        path = self.write(mesh, "lt")
        model = tsm_model(path)
        self.assertEqual(model.kind, "t-spline")
        scale = size_of(model)
        # the star's three rings against the uniform L (equal points and knots within five rings)
        cage, S = l_cage()
        ref = cage_model(cage)
        star = corner_of(mesh, (N, N))
        mine, theirs = rings(mesh, star, 3), rings(_Faces(cage.mesh.faces), S, 3)
        centre = lambda m, fs: sorted((tuple(np.round(m[np.asarray(list(fl))].mean(0), 9)), f)
                                      for f, fl in fs)
        a_faces = centre(mesh.points, [(f, mesh.faces[f]) for r in mine for f in r])
        b_faces = centre(cage.points, [(f, cage.mesh.faces[f]) for r in theirs for f in r])
        self.assertEqual([c for c, _ in a_faces], [c for c, _ in b_faces])
        for (_, fa), (_, fb) in zip(a_faces, b_faces):
            # the same corner first in both (the L's faces start at their lower left)
            fa_, sa, ta = face_grid([fa])
            pa, pb = model.evaluate_faces(fa_, sa, ta), ref.evaluate_faces(np.full(len(sa), fb), sa, ta)
            self.assertLess(np.abs(pa.P - pb.P).max(), 1e-12 * scale)
            self.assertLess(max(np.abs(pa.Pu - pb.Pu).max(), np.abs(pa.Pv - pb.Pv).max()), 1e-10 * scale)
        A, B = faces_meet(model, model.control, np.linspace(0.0, 1.0, 7))
        self.assertLess(np.abs(A.P - B.P).max(), 1e-12 * scale)
        sin = np.linalg.norm(np.cross(A.normal, B.normal), axis=1)       # sine of the angle
        self.assertLess(float(sin.max()), 1e-9)
        shift = np.array([3.0, -7.0, 11.0])
        moved = tsm_model(self.write(l_tmesh(shift), "moved"))
        f, s, t = face_grid(np.arange(len(mesh.faces)), 4)
        gap = moved.evaluate_faces(f, s, t).P - model.evaluate_faces(f, s, t).P - shift
        self.assertLess(np.abs(gap).max(), 1e-12 * scale)
        # the T-mesh the model keeps is not the surface next to the star: no native file of it
        from tsplcam.model.formats.native import dumps
        with self.assertRaises(InputError) as cm:
            dumps(model)
        self.assertIn("boundary star", str(cm.exception))

    def test_refusals_name_the_line(self):
        """A T-junction within the star's five rings, OpenSubdiv's boundary shapes of four and
        five faces (too small: the kernel leaves the end faces out) and of six faces, are
        refused with the vertex's line; its shape of three faces is the cage path's surface."""
        near = from_lines(mesh_X(), mesh_X(), [(j, 0, 2 * N) for j in range(N, 2 * N + 1)]
                          + [(j, 0, N) for j in range(N)],
                          [(i, 0, 2 * N) for i in range(N + 1) if i != 5] + [(5, 6, 2 * N)]
                          + [(i, N, 2 * N) for i in range(N + 1, 2 * N + 1)],
                          lambda i, j: (5.0 * i, 5.0 * j, height(i, j)), holes=lambda x, y: x > N and y < N)
        with self.assertRaises(InputError) as cm:
            tsm_model(self.write(near, "near"))
        self.assertIn("star point on the boundary", cm.exception.message)
        self.assertIn("T-junction", cm.exception.message)
        self.assertIsNotNone(cm.exception.line)
        # OpenSubdiv's extraordinary boundary shapes through the kernel, one by one: three
        # faces are taken (the cage path's surface, every face from the local cage), four
        # and five are refused for their size (the end faces' corners have no other face),
        # six for the number of faces
        for faces, (n, fragment) in zip((3, 4, 5, 6), xord_shapes()):
            path = self.write(n, f"xord{faces}")
            if fragment is None:
                a, b = tsm_model(path), tsm_model(path, t_spline=True)
                f, s, t = face_grid(np.arange(len(n.mesh.faces)))
                self.assertLess(np.abs(a.evaluate_faces(f, s, t).P - b.evaluate_faces(f, s, t).P).max(),
                                1e-12 * size_of(a))
                continue
            with self.assertRaises(InputError) as cm:
                tsm_model(path, t_spline=True)
            self.assertIn(fragment, cm.exception.message)
            self.assertIsNotNone(cm.exception.line)


def xord_shapes():
    """OpenSubdiv's catmark_xord_boundary, its four shapes (boundary stars of 3, 4, 5 and 6
    faces) as cages of their own (in mm), with what the kernel says of each."""
    cage = read_obj(external("opensubdiv", "catmark_xord_boundary.obj"))
    F = cage.mesh.faces
    shape = np.zeros(len(F), int)
    for f in range(1, len(F)):          # the shapes are runs of faces sharing vertices
        shape[f] = shape[f - 1] + (not set(map(int, F[f])) & {int(v) for g in range(f) for v in F[g]
                                                               if shape[g] == shape[f - 1]})
    out = []
    for k, fragment in enumerate((None, "has no other face", "has no other face", "has no other face")):
        fs = np.nonzero(shape == k)[0]
        vs = sorted({int(v) for f in fs for v in F[f]})
        new = {v: i for i, v in enumerate(vs)}
        out.append((Cage(QuadMesh(np.array([[new[int(v)] for v in F[f]] for f in fs]), len(vs),
                                  "edge-and-corner"), cage.points[vs] * 100.0), fragment))
    return out


def book(T, k=8, band=None):
    """T quadrants of k x k unit faces glued along their spokes around S, a boundary vertex of
    T faces, opened over 315 degrees (sector j's node (i, l) at 5 (i e_j + l e_(j+1)) mm), on
    the wavy surface. Returns the cage, S, and every edge's knot interval: 1, or ``band``
    on the outermost ring of faces."""
    th = 1.75 * np.pi / T
    vid, pts, faces, knot = {}, [], [], {}

    def V(j, i, l):
        if i == 0 and l > 0 and j + 1 < T:
            return V(j + 1, l, 0)                   # sector j's column 0 is sector j+1's row 0
        key = "S" if i == l == 0 else (j, i, l)
        if key not in vid:
            vid[key] = len(pts)
            x, y = 5.0 * (i * np.array([np.cos(j * th), np.sin(j * th)])
                          + l * np.array([np.cos((j + 1) * th), np.sin((j + 1) * th)]))
            pts.append((x, y, height(x / 5.0, y / 5.0)))
        return vid[key]
    for j in range(T):
        for i in range(k):
            for l in range(k):
                loop = [V(j, i, l), V(j, i + 1, l), V(j, i + 1, l + 1), V(j, i, l + 1)]
                faces.append(loop)
                di = band if band and i == k - 1 else 1.0
                dl = band if band and l == k - 1 else 1.0
                for m, dd in enumerate((di, dl, di, dl)):
                    a, b = loop[m], loop[(m + 1) % 4]
                    knot[(min(a, b), max(a, b))] = dd
    cage = Cage(QuadMesh(np.array(faces), len(pts), "edge-and-corner"), np.array(pts))
    return cage, vid["S"], knot


def model_faces(model, f):
    """Model faces of T-mesh faces f: the faces the kernel left out (``notch_faces``) are
    numbered after the rest."""
    out = getattr(model, "notch_faces", {})
    f = np.asarray(f)
    shift = np.searchsorted(np.array(sorted(out)), f) if out else 0
    return np.array([out.get(int(x), int(x) - int(d)) for x, d in zip(f, np.broadcast_to(shift, f.shape))])


def star_normals(model):
    """The normals at the model's (one) extraordinary point from every patch corner there."""
    from tsplcam.model.patch import CORNER_UV
    node = model.extraordinary[0].node
    return [p.evaluate(*CORNER_UV[c][:, None]).normal[0] for p in model.patches for c in range(4)
            if p.corner_nodes[c] == node]


class BookStars(TempFiles):
    def test_defective_eigenvalue_at_its_mean(self):
        """The boundary vertex of four faces: its scheme's eigenvalue 0.5 is defective, which
        ``eigvals`` gives as a pair 0.5 +- 1e-8 or 0.5 +- 4e-9 i (by the BLAS kernel's
        rounding: OpenBLAS's Haswell and Prescott kernels); its tangent mask belongs to 0.5
        to the rounding (the pair's mean), so the star's normal is the same whatever the
        kernel (it moved by 1.1e-9 with a mask from one of the pair, and by 90 deg where the
        complex pair was dropped and the mask came from 0.366)."""
        from tsplcam.model import eigen
        cage, _, _ = book(4)
        tsm_model(self.write(cage, "book4"))
        schemes = [s for s in eigen._SCHEMES.values() if s.label.startswith("boundary vertex of 4 faces")]
        self.assertTrue(schemes)
        for s in schemes:
            m = s.tangent_masks[1]
            lam = float(m @ s.A @ m / (m @ m))                  # its Rayleigh quotient
            self.assertLess(abs(lam - 0.5), 1e-13, lam)
            self.assertLess(float(np.abs(m @ s.A - 0.5 * m).max()), 1e-13)

    def test_four_and_five_faces_are_the_cage_limit(self):
        """Boundary stars of four and five faces on uniform books through the kernel, unit and
        rational weights: the cage path's surface on every face (measured at most 2.2e-16 of
        the size in position, 1.6e-13 in first derivatives, at the star), the end faces' own patches linked on
        their three inner sides, patches meeting within 1e-12 of the size with one normal
        (measured 9e-17, sine of the angle 2.1e-15)."""
        for T, weighted in ((4, False), (5, False), (4, True), (5, True)):
            cage, S, _ = book(T)
            if weighted:
                cage = Cage(cage.mesh, cage.points, 1.0 + 0.3 * np.cos(np.arange(len(cage.points))))
            path = self.write(cage, f"book{T}")
            a, b = tsm_model(path), tsm_model(path, t_spline=True)
            self.assertEqual((a.kind, b.kind), ("catmull-clark", "t-spline"))
            scale = assert_cage_limit(self, a, b, np.arange(len(cage.mesh.faces)), T)
            self.assertEqual([(e.boundary, e.valence) for e in b.extraordinary], [(True, T)])
            # every patch at the star gives the cage's limit normal there
            want = star_normals(a)[0]
            for n in star_normals(b):
                self.assertLess(float(np.linalg.norm(np.cross(n, want))), 1e-9, T)
            self.assertEqual(len(b.notch_faces), T - 3)
            for p in (b.face_pieces[m][0][0] for m in b.notch_faces.values()):
                self.assertEqual(sum(x is not None for x in b.patches[p].neighbours), 3, T)
            for link in Layout.from_model(b).edge_links:
                sa, sb = edge_pair(b, link, np.linspace(0.0, 1.0, 9))
                self.assertLess(np.abs(sa.P - sb.P).max(), 1e-12 * scale, T)
                self.assertLess(float(np.linalg.norm(np.cross(sa.normal, sb.normal), axis=1).max()), 1e-9, T)

    def test_other_intervals_beyond_the_rings(self):
        """Five faces, seven rings, the outermost of knot interval 2, just beyond the star's
        local cage (six rings): the kernel; on the four rings from the local cage the limit of
        the uniform book; faces and patches meet within 1e-12 of the size with one normal (the
        kernel's pieces next to the cage do not see knots two intervals away); a partition of
        unity. Measured: 9e-17 of the size in position and 1.8e-13 in derivatives within four
        rings (the fifth ring sees the band: 2.2e-3), faces and patches meet within 9e-17,
        normals within 2.6e-15, the move within 1.3e-16."""
        T = 5
        cage, S, knot = book(T, k=7, band=2.0)
        path = self.write_knots(cage, "band", knot)
        model = tsm_model(path)
        self.assertEqual(model.kind, "t-spline")
        scale = size_of(model)
        ref = cage_model(cage)
        near = [f for r in rings(_Faces(cage.mesh.faces), S, 4) for f in r]
        f, s, t = face_grid(near)
        pa, pb = ref.evaluate_faces(f, s, t), model.evaluate_faces(model_faces(model, f), s, t)
        self.assertLess(np.abs(pa.P - pb.P).max(), 1e-12 * scale)
        self.assertLess(max(np.abs(pa.Pu - pb.Pu).max(), np.abs(pa.Pv - pb.Pv).max()), 1e-10 * scale)
        A, B = faces_meet(model, model.control, np.linspace(0.0, 1.0, 7))
        self.assertLess(np.abs(A.P - B.P).max(), 1e-12 * scale)
        self.assertLess(float(np.linalg.norm(np.cross(A.normal, B.normal), axis=1).max()), 1e-9)
        for link in Layout.from_model(model).edge_links:
            sa, sb = edge_pair(model, link, np.linspace(0.0, 1.0, 9))
            self.assertLess(np.abs(sa.P - sb.P).max(), 1e-12 * scale)
            self.assertLess(float(np.linalg.norm(np.cross(sa.normal, sb.normal), axis=1).max()), 1e-9)
        shift = np.array([3.0, -7.0, 11.0])
        moved = tsm_model(self.write_knots(Cage(cage.mesh, cage.points + shift), "moved", knot))
        f, s, t = face_grid(model_faces(model, np.arange(len(cage.mesh.faces))), 4)
        gap = moved.evaluate_faces(f, s, t).P - model.evaluate_faces(f, s, t).P - shift
        self.assertLess(np.abs(gap).max(), 1e-12 * scale)


def native_text(cage, boundary="edge-and-corner") -> str:
    """A native ``.tspl`` t-spline of a quad cage: every knot interval 1, open boundaries
    ``boundary`` (``edge-and-corner``: not clamped, read as the Fusion reader reads them)."""
    w = np.ones(len(cage.points)) if cage.weights is None else cage.weights
    verts = ",\n".join("    " + json.dumps([*map(float, p), float(x)]) for p, x in zip(cage.points, w))
    faces = ",\n".join("    " + json.dumps({"vertices": [int(v) for v in f], "intervals": [1.0] * 4})
                        for f in cage.mesh.faces)
    return ('{\n  "format": "tsplcam-model",\n  "version": 1,\n  "units": "mm",\n  "kind": "t-spline",\n'
            f'  "boundary": "{boundary}",\n  "vertices": [\n{verts}\n  ],\n  "faces": [\n{faces}\n  ]\n}}\n')


class NativeAndManyFaces(TempFiles):
    def write_native(self, cage, name, boundary="edge-and-corner"):
        path = os.path.join(self.dir, name + ".tspl")
        with open(path, "w") as fh:
            fh.write(native_text(cage, boundary))
        return path

    def test_native_files_and_six_faces(self):
        """Native ``.tspl`` t-splines with the edge-and-corner boundary: the L (a boundary star
        of three faces) and a book of six faces (valence 7; the kernel keeps the middle three,
        its patch beside the two left-out faces split at the spoke between them) through the
        kernel equal the cage path on every face (measured 3.0e-16 of the size in position,
        4.0e-13 in first derivatives, at the star); at six faces the patches meet within 1e-12
        of the size with one normal (measured 7.3e-17, sine 1.4e-15), every patch at the star
        gives the limit normal, and no patch side without a neighbour lies along another's
        (the layout is conforming). The book with the default boundary rule (clamped) is
        refused as unclamped."""
        from tsplcam.model.formats.native import native_model
        for T, (cage, _) in ((3, l_cage(5)), (6, book(6, k=6)[:2])):
            path = self.write_native(cage, f"native{T}")
            a, b = cage_model(cage), native_model(path)
            self.assertEqual(b.kind, "t-spline")
            scale = assert_cage_limit(self, a, b, np.arange(len(cage.mesh.faces)), T)
            self.assertEqual([(e.boundary, e.valence) for e in b.extraordinary], [(True, T)])
        want = star_normals(a)[0]
        for n in star_normals(b):
            self.assertLess(float(np.linalg.norm(np.cross(n, want))), 1e-9)
        for link in Layout.from_model(b).edge_links:
            sa, sb = edge_pair(b, link, np.linspace(0.0, 1.0, 9))
            self.assertLess(np.abs(sa.P - sb.P).max(), 1e-12 * scale)
            self.assertLess(float(np.linalg.norm(np.cross(sa.normal, sb.normal), axis=1).max()), 1e-9)
        self.assert_conforming(b, scale)
        with self.assertRaises(InputError) as cm:
            native_model(self.write_native(cage, "clamped", "repeat-last-knot"))
        self.assertIn("not clamped", cm.exception.message)

    def test_split_lines_run_on(self):
        """Patch splitting (what six faces or more need) carried on across neighbours: the L's
        three patches split by a line across the first (which runs on into the second) and
        one across the second (which runs on into the third and into the part the first
        line cut off) make eight conforming patches: linked sides meet within 1e-12 of the
        size, no side without a neighbour lies along part of another, every corner node is
        its patches' corner point, and the surface is unchanged (measured 4e-16 of the size
        in position)."""
        from tsplcam.model.boundary_stars import split_at
        from tsplcam.model.formats.native import native_model
        from tsplcam.model.formats.tsm_fusion import join_across_creases
        from tsplcam.model.patch import CORNER_UV
        cage, _ = l_cage(5)
        m = native_model(self.write_native(cage, "l"))
        self.assertEqual(len(m.patches), 3)
        scale = size_of(m)
        f, s, t = face_grid([x for x in range(len(m.face_pieces)) if min(m.face_size[x]) > 0], 4)
        before = m.evaluate_faces(f, s, t).P

        def refuse(why):
            raise AssertionError(why)
        p0, p1 = m.patches[0], m.patches[1]
        split_at(m, [(0, 0, float(p0.ubreaks[2] * p0.knot_size[0])),
                     (1, 1, float(p1.vbreaks[3] * p1.knot_size[1]))], refuse)
        join_across_creases(m)
        self.assertEqual(len(m.patches), 8)
        self.assertLess(np.abs(m.evaluate_faces(f, s, t).P - before).max(), 1e-12 * scale)
        for link in Layout.from_model(m).edge_links:
            sa, sb = edge_pair(m, link, np.linspace(0.0, 1.0, 9))
            self.assertLess(np.abs(sa.P - sb.P).max(), 1e-12 * scale)
        self.assert_conforming(m, scale)
        for p in m.patches:
            self.assertLess(np.abs(p.evaluate(*CORNER_UV.T).P - m.node_points[p.corner_nodes]).max(),
                            1e-12 * scale)

    def assert_conforming(self, model, scale):
        """No patch side without a neighbour lies along part of another patch's side."""
        tau = np.linspace(0.0, 1.0, 33)
        sides = {(p.index, e): p.evaluate(*p.edge_params(e, tau)).P for p in model.patches for e in range(4)}
        for p in model.patches:
            for e in range(4):
                if p.neighbours[e] is not None:
                    continue
                mid = p.evaluate(*p.edge_params(e, np.array([0.25, 0.5, 0.75]))).P
                for key, P in sides.items():
                    if key != (p.index, e):
                        d = np.linalg.norm(P[:, None] - mid[None], axis=2).min(axis=0)
                        self.assertGreater(float(d.min()), 1e-9 * scale, (p.index, e, key))

    def test_grapetec_file(self):
        """A GrapeTec-style ``.tsm`` (grip blocks on the boundary) of a book of four faces, the
        star without a block and the blocks the edge-and-corner rule's: the cage path's
        surface on every face (measured 1.8e-16 of the size, 6.1e-14 in first derivatives)
        (``read_tsm``, the T-mesh with explicit boundary grips, refuses it by name); a
        second-row grip moved within the star's rings is refused naming the vertex and
        the line (moved further out it is kept: measured on a book of eight rings, the
        surface within five rings of the star unchanged to 1.4e-14 mm)."""
        cage, S, _ = book(4, k=6)
        fusion = self.write_creased(cage, "fusion", [])
        path = os.path.join(self.dir, "grapetec.tsm")
        with open(path, "w") as fh:
            fh.write(grapetec_text(fusion, cage))
        a, b = cage_model(cage), tsm_model(path)
        self.assertEqual(b.tsm.dialect, "rhino")
        assert_cage_limit(self, a, b, np.arange(len(cage.mesh.faces)))
        self.assertEqual([(e.boundary, e.valence) for e in b.extraordinary], [(True, 4)])
        # its T-mesh with explicit boundary grips does not exist there: read_tsm says so
        from tsplcam.model.formats.tsm import read_tsm
        with self.assertRaises(InputError) as cm:
            read_tsm(path)
        self.assertIn("star point on the boundary", cm.exception.message)
        boundary_next = next(v for v in range(len(cage.points)) if v != S
                             and abs(np.linalg.norm(cage.points[v, :2] - cage.points[S, :2]) - 5.0) < 1e-9)
        with open(path, "w") as fh:
            fh.write(grapetec_text(fusion, cage, move=(boundary_next, np.array([0.0, 0.0, 0.5]))))
        with self.assertRaises(InputError) as cm:
            tsm_model(path)
        self.assertIn("near the boundary star point", cm.exception.message)
        self.assertIsNotNone(cm.exception.line)

    def test_seven_faces_rational(self):
        """A book of seven faces with rational weights in a Fusion file through the kernel:
        the cage path's surface on every face (measured 2.5e-16 of the size, 4.0e-13 in first
        derivatives), the star the model's one boundary extraordinary point of valence 7."""
        cage, S, _ = book(7, k=6)
        cage = Cage(cage.mesh, cage.points, 1.0 + 0.3 * np.cos(np.arange(len(cage.points))))
        path = self.write(cage, "book7")
        a, b = tsm_model(path), tsm_model(path, t_spline=True)
        assert_cage_limit(self, a, b, np.arange(len(cage.mesh.faces)))
        self.assertEqual([(e.boundary, e.valence) for e in b.extraordinary], [(True, 7)])


def grapetec_text(fusion_path, cage, move=None) -> str:
    """The Fusion-dialect file of a cage with open boundaries (unit weights) rewritten as a
    GrapeTec-style ``.tsm`` (Bezier end conditions, mm): every boundary vertex but the
    boundary stars (four faces or more) gets a grip block whose grips are the clamped
    B-spline's of the edge-and-corner rule on uniform knots (boundary grip the cage point,
    the second row a third of the way inward); ``move`` = (vertex, offset): that vertex's
    grip at (0, 0) of the ring view (its second-row grip on the boundary) moved."""
    from tsplcam.model.formats.tsm import SHIFT, block_offsets
    text = open(fusion_path).read().splitlines()
    L = [list(map(int, t.split()[1:])) for t in text if t.startswith("l ")]   # prev next opp v face edge flag
    end = lambda i: L[L[i][1]][3]                                             # noqa: E731
    turns, out_link, links = {}, {}, {}
    for i, (prev, nxt, opp, v, f, e, flag) in enumerate(L):
        if f >= 0:
            turns[v] = turns.get(v, 0) + (1 if flag == 0 else 2)
            links.setdefault(v, []).append(i)
            if L[opp][4] < 0:
                out_link[v] = i                       # along the boundary, the face on its left
    P = np.asarray(cage.points, float)
    shift = lambda v: move[1] if move and move[0] == v else 0.0              # noqa: E731
    grips, gmap, cg = [], [], []

    def grip(p, v, own):
        grips.append(p)
        gmap.append(f"0m {'gvp' if own else 'gv'} {v}")
        return len(grips) - 1
    for v in range(len(P)):
        T = turns[v]
        if v not in out_link or T >= 4:
            grip(P[v] + shift(v), v, True)
            continue
        C = P[v]
        if T == 2:
            w = next(end(i) for i in links[v] if i != out_link[v])
            at = {(0, -1): C, (0, 0): C + (P[w] - C) / 3.0}
        else:                                         # a convex corner: its one face v, X, XY, Y
            i = out_link[v]
            X, XY, Y = P[end(i)], P[end(L[i][1])], P[end(L[L[i][1]][1])]
            at = {(-1, -1): C, (0, -1): C + (X - C) / 3.0, (-1, 0): C + (Y - C) / 3.0,
                  (0, 0): C + (X - C) / 3.0 + (Y - C) / 3.0 + (XY - X - Y + C) / 9.0}
        at[(0, 0)] = at[(0, 0)] + shift(v)
        sx, sy = SHIFT[T]                             # the vertex's own grip: on the boundary ring
        grip(at[(sx, sy)], v, True)
        # the v record's link points EAST along the boundary: the block needs no turn
        offs = {(x - sx, y - sy): p for (x, y), p in at.items() if (x, y) != (sx, sy)}
        dims = (max(dy for _, dy in offs), max(-dx for dx, _ in offs), max(-dy for _, dy in offs),
                max(dx for dx, _ in offs))
        dims = tuple(max(0, d) for d in dims)
        need = sum(dims[k] * (dims[(k + 1) % 4] + 1) for k in range(4))
        slot = block_offsets(dims, list(range(need)))
        ids = [-1] * need
        for o, p in offs.items():
            ids[slot[o]] = grip(p, v, False)
        cg.append(f"0m cg {v} 4 {' '.join(map(str, dims))} {' '.join(map(str, ids))}")
    body, n = [], 0
    for t in text[1:]:
        key = t.split()[:1]
        if key == ["v"]:
            t = f"v {out_link.get(n, int(t.split()[1]))} EAST"
            n += 1
        if key and key[0] in ("f", "e", "v", "l", "ec"):
            body.append(t)
    head = ["#TS0200", "degree 3", "cap-type 1", "star-smoothness 0", "units 0.001 millimeters",
            "force-bezier-end-conditions 1"]
    return "\n".join(head + body + ["0m odd-grip-map"] + gmap + cg
                     + ["0g {!r} {!r} {!r} 1.0".format(*map(float, p)) for p in grips]) + "\n"


def mesh_X():
    return np.arange(2 * N + 1, dtype=float)


class _Faces:
    def __init__(self, faces):
        self.faces = faces


if __name__ == "__main__":
    unittest.main()
