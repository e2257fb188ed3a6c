"""Fusion-dialect .tsm files (docs/formats.md section 2.5), written here from OpenSubdiv's
cages: they load to the cage's Catmull-Clark limit (the OBJ path, itself tested against
OpenSubdiv) to 1e-9 of the model size, patches meet without gaps, infinitely sharp creases
are C0 patch boundaries with the surface smooth elsewhere, every header option and record
is acted on, and anything else is refused naming the file and the line."""
import os
import shutil
import tempfile
import unittest

import numpy as np

import tsplcam
from conftest import edge_pair, external
from tsplcam.errors import InputError
from tsplcam.layout.layout import Layout
from tsplcam.model import samples
from tsplcam.model.cage import Cage, cage_model
from tsplcam.model.formats.obj import read_obj
from tsplcam.model.formats.tsm_fusion import write_fusion_tsm
from tsplcam.model.quadmesh import INFINITE

CAGES = ("catmark_cube", "catmark_torus", "catmark_tent", "catmark_xord_boundary", "catmark_edgecorner",
         "catmark_cube_creases0")


def reference(name):
    """An OpenSubdiv cage read by the OBJ reader, under the rules the Fusion reader applies
    (edge-and-corner boundaries, its creases made infinitely sharp), and its crease edges."""
    cage = read_obj(external("opensubdiv", name + ".obj"))
    cage.mesh.boundary_rule = "edge-and-corner"
    creases = sorted(cage.mesh.sharpness or {})
    cage.mesh.sharpness = {e: INFINITE for e in creases} or None
    cage.mesh.corner_sharpness = None
    return cage, creases


def face_grid(n_faces, k=5):
    g = np.linspace(0.0, 1.0, k)
    S, T = np.meshgrid(g, g)
    return (np.repeat(np.arange(n_faces), k * k), np.tile(S.ravel(), n_faces), np.tile(T.ravel(), n_faces))


def size_of(model):
    P = np.concatenate([p.evaluate(*np.meshgrid(np.linspace(0, 1, 9), np.linspace(0, 1, 9))).P
                        for p in model.patches])
    return float(np.linalg.norm(P.max(0) - P.min(0)))


class TempDir(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="tsplcam-fusion-")
        self.addCleanup(shutil.rmtree, self.dir, True)

    def write(self, cage, name, **kw):
        path = os.path.join(self.dir, name + ".tsm")
        write_fusion_tsm(cage, path, **kw)
        return path


class CatmullClarkCages(TempDir):
    def test_limit_of_the_cage_and_watertight(self):
        """Uniform intervals (2, not 1), no T-junctions: the OBJ path's limit surface, with
        and without a grip map, and adjacent patches agree along every shared edge."""
        for k, name in enumerate(CAGES):
            cage, creases = reference(name)
            ref = cage_model(cage)
            scale = size_of(ref)
            model = tsplcam.load(self.write(cage, name, creases=creases, grip_map=bool(k % 2), interval=2.0))
            self.assertEqual(model.kind, "catmull-clark", name)
            self.assertEqual((len(model.patches), len(model.extraordinary)),
                             (len(ref.patches), len(ref.extraordinary)), name)
            f, s, t = face_grid(len(cage.mesh.faces))
            gap = np.abs(model.evaluate_faces(f, s, t).P - ref.evaluate_faces(f, s, t).P).max()
            self.assertLess(gap, 1e-9 * scale, name)
            tau = np.linspace(0.0, 1.0, 11)
            for link in Layout.from_model(model).edge_links:
                sa, sb = edge_pair(model, link, tau)
                self.assertLess(np.abs(sa.P - sb.P).max(), 1e-9 * scale, name)
            self.assertEqual(model.tsm.crease_edges, len(creases), name)

    def test_weights_are_honoured(self):
        cage, _ = reference("catmark_torus")
        w = 1.0 + 0.5 * np.cos(np.arange(len(cage.points)))
        weighted = Cage(cage.mesh, cage.points, w)
        model = tsplcam.load(self.write(weighted, "weighted", grip_map=True))
        ref = cage_model(weighted)
        f, s, t = face_grid(len(cage.mesh.faces))
        gap = np.abs(model.evaluate_faces(f, s, t).P - ref.evaluate_faces(f, s, t).P).max()
        self.assertLess(gap, 1e-9 * size_of(ref))
        plain = cage_model(cage)
        self.assertGreater(np.abs(plain.evaluate_faces(f, s, t).P - ref.evaluate_faces(f, s, t).P).max(),
                           1e-3 * size_of(ref))

    def test_units_are_centimetres_whatever_the_line_says(self):
        cage, _ = reference("catmark_cube")
        a = tsplcam.load(self.write(cage, "cm", units="1 centimeters"))
        b = tsplcam.load(self.write(cage, "m", units="1 meters"))
        np.testing.assert_allclose(a.node_points, b.node_points, rtol=0, atol=1e-12)
        ref = cage_model(cage)
        f, s, t = face_grid(len(cage.mesh.faces), 3)
        np.testing.assert_allclose(a.evaluate_faces(f, s, t).P, ref.evaluate_faces(f, s, t).P, atol=1e-12)
        self.assertEqual(b.tsm.mm_per_unit, 10.0)
        self.assertIn("centimetres", b.tsm.scale_rule)
        self.assertIn("1 meters", b.tsm.scale_rule)
        self.assertEqual(b.tsm.footer, {"tol": 1e-05, "geom-tol": 1e-05, "ver": 2, "behavior-version": "4.0.1",
                                        "compat-version": "4.0.1"})
        self.assertEqual((b.tsm.dialect, b.tsm.cap_type, b.tsm.star_knot_rule, b.tsm.end_conditions),
                         ("fusion", "G1CAPS", "NURCCS", "MULTIPLE_KNOTS"))

    def test_non_uniform_closed_body_goes_to_the_t_spline_kernel(self):
        """A torus with two knot intervals (rings of 1 and 3): no star points, closed: the
        T-spline kernel, watertight, and a different surface from the uniform one."""
        cage, _ = reference("catmark_torus")
        faces = cage.mesh.faces
        # a ring of the torus: the faces' second edges run along it; intervals per ring
        ring_of = {}
        for f in faces:
            for k in (0, 2):
                a, b = sorted((int(f[k]), int(f[k + 1])))
                ring_of[(a, b)] = 3.0 if min(a, b) % 2 else 1.0
        path = self.write(cage, "torus_nu", interval=lambda a, b: ring_of.get((a, b), 1.0))
        try:
            model = tsplcam.load(path)
        except InputError as exc:                      # inconsistent intervals are refused with a line
            self.assertIsNotNone(exc.line)
            return
        self.assertEqual(model.kind, "t-spline")
        self.assertIn("T-spline", model.tsm.surface)
        scale = size_of(model)
        for link in Layout.from_model(model).edge_links:
            sa, sb = edge_pair(model, link, np.linspace(0, 1, 7))
            self.assertLess(np.abs(sa.P - sb.P).max(), 1e-9 * scale)


def tjunction_grid():
    """An open T-mesh with T-junctions and non-uniform knot intervals (60 x 40 knot units,
    lines near the middle stopping short of the rim), a wavy surface."""
    from tsplcam.model.tmesh import from_lines
    X = np.array([0, 7, 15, 21, 25, 28, 30, 32, 35, 39, 45, 53, 60.0])
    Y = np.array([0, 6, 13, 16.5, 20, 23.5, 27, 34, 40.0])
    short_v = {4: (1, 7), 8: (1, 7), 5: (2, 6), 7: (2, 6)}
    short_h = {3: (3, 9), 5: (3, 9)}
    vsegs = [(i, *short_v.get(i, (0, len(Y) - 1))) for i in range(len(X))]
    hsegs = [(j, *short_h.get(j, (0, len(X) - 1))) for j in range(len(Y))]
    return X, Y, from_lines(X, Y, hsegs, vsegs,
                            lambda i, j: (X[i], Y[j], 3 * np.sin(X[i] / 9) * np.cos(Y[j] / 7)))


class TSplineKernel(TempDir):
    def test_kernel_equals_the_cage_on_uniform_cages(self):
        """The kernel's clamped boundary (second grip row a / (2a + b) of the way inward) and
        its star points give the cage path's surface on uniform cages: open grids, single
        faces, an open box with stars, a closed head with stars."""
        from tsplcam.model.formats.tsm import tsm_model
        cages = {n: reference(n)[0] for n in ("catmark_tent", "catmark_edgecorner")}
        cages["keycap"] = samples.keycap()
        cages["head"] = samples.head()
        for name, cage in cages.items():
            path = self.write(cage, name, grip_map=True)
            a, b = tsm_model(path), tsm_model(path, t_spline=True)
            self.assertEqual((a.kind, b.kind), ("catmull-clark", "t-spline"), name)
            f, s, t = face_grid(len(cage.mesh.faces))
            gap = np.abs(a.evaluate_faces(f, s, t).P - b.evaluate_faces(f, s, t).P).max()
            self.assertLess(gap, 1e-9 * size_of(a), name)

    def test_non_uniform_boundary_is_the_reflected_b_spline(self):
        """T-junctions and non-uniform intervals: the kernel; its boundary curve is the cubic
        B-spline of the boundary grips continued by reflection through the end grips (knots
        mirrored too), evaluated by scipy; corners interpolate their grips."""
        from scipy.interpolate import BSpline
        X, Y, mesh = tjunction_grid()
        self.assertGreaterEqual(sum(len(f) > 4 for f in mesh.faces), 8)
        model = tsplcam.load(self.write(mesh, "tgrid", grip_map=True))
        self.assertEqual(model.kind, "t-spline")
        scale = size_of(model)
        gi = mesh.grid_index
        row = sorted((int(gi[v, 0]), v) for v in range(mesh.n_vertices) if gi[v, 1] == 0)
        x = X[[i for i, _ in row]]
        P = mesh.points[[v for _, v in row]]
        n = len(x) - 1
        ext = np.concatenate([2 * x[0] - x[3:0:-1], x, 2 * x[-1] - x[-2:-5:-1]])
        ctrl = np.vstack([2 * P[0] - P[1], P, 2 * P[-1] - P[-2]])
        curve = BSpline(ext, ctrl, 3)
        faces, ss, xs = [], [], []
        for f, loop in enumerate(mesh.faces):
            c = [int(loop[k]) for k in mesh.corners[f]]
            if gi[c[0], 1] == 0 and gi[c[1], 1] == 0:
                x0, x1 = X[gi[c[0], 0]], X[gi[c[1], 0]]
                tau = np.linspace(0, 1, 7)
                faces += [f] * 7
                ss += list(tau)
                xs += list(x0 + (x1 - x0) * tau)
        self.assertAlmostEqual(min(xs), x[0])
        self.assertAlmostEqual(max(xs), x[n])
        got = model.evaluate_faces(faces, ss, np.zeros(len(ss))).P
        self.assertLess(np.abs(got - curve(np.array(xs))).max(), 1e-9 * scale)
        corners = [v for v in range(mesh.n_vertices) if gi[v, 0] in (0, len(X) - 1) and gi[v, 1] in (0, len(Y) - 1)]
        for v in corners:
            self.assertLess(np.linalg.norm(model.node_points - mesh.points[v], axis=1).min(), 1e-9 * scale)

    def test_kernel_creases_equal_the_cage_creases(self):
        """A crease in the kernel: the T-mesh is cut along it and each side clamped like a
        boundary (knot multiplicity three on the crease line), the sides linked again. On
        uniform knots that is OpenSubdiv's infinitely sharp crease (the cage path): a
        straight crease, and two crossing ones (every edge at the crossing sharp: a corner)."""
        from tsplcam.model.formats.tsm import tsm_model
        from tsplcam.model.quadmesh import QuadMesh
        nx, ny = 6, 5
        P = np.array([(10.0 * i, 10.0 * j, 4 * np.sin(i) * np.cos(0.7 * j)) for j in range(ny + 1)
                      for i in range(nx + 1)])
        vid = lambda i, j: j * (nx + 1) + i                          # noqa: E731
        faces = [[vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)] for j in range(ny) for i in range(nx)]
        cage = Cage(QuadMesh(np.array(faces), len(P)), P)
        column = [(vid(2, j), vid(2, j + 1)) for j in range(ny)]
        row = [(vid(i, 3), vid(i + 1, 3)) for i in range(nx)]
        for name, creases, links in (("straight", column, 1), ("crossing", column + row, 4)):
            path = self.write(cage, name, creases=creases)
            a, b = tsm_model(path), tsm_model(path, t_spline=True)
            self.assertEqual((a.kind, b.kind), ("catmull-clark", "t-spline"))
            f, s, t = face_grid(len(faces))
            gap = np.abs(a.evaluate_faces(f, s, t).P - b.evaluate_faces(f, s, t).P).max()
            self.assertLess(gap, 1e-9 * size_of(a), name)
            la, lb = Layout.from_model(a), Layout.from_model(b)
            self.assertEqual((len(la.edge_links), len(lb.edge_links), len(b.node_points)),
                             (links, links, len(a.node_points)), name)
        # a crease that turns at a vertex: each side would be clamped differently: refused
        path = self.write(cage, "turning", creases=column[:3] + row[2:])
        with self.assertRaises(InputError) as cm:
            tsm_model(path, t_spline=True)
        self.assertIn("turns", str(cm.exception))
        self.assertTrue(open(path).read().split("\n")[cm.exception.line - 1].startswith("100edges"))

    def test_kernel_crease_on_a_non_uniform_t_mesh(self):
        """T-junctions, non-uniform intervals, a crease along a whole knot line: C0 along it,
        the crease curve the reflected B-spline of its grips (scipy), the two sides linked."""
        from scipy.interpolate import BSpline
        X, Y, mesh = tjunction_grid()
        gi = mesh.grid_index
        col = sorted((int(gi[v, 1]), v) for v in range(mesh.n_vertices) if gi[v, 0] == 2)
        creases = [(a, b) for (_, a), (_, b) in zip(col[:-1], col[1:])]
        model = tsplcam.load(self.write(mesh, "tcrease", creases=creases))
        self.assertEqual(model.kind, "t-spline")
        scale = size_of(model)
        y = Y[[j for j, _ in col]]
        P = mesh.points[[v for _, v in col]]
        ext = np.concatenate([2 * y[0] - y[3:0:-1], y, 2 * y[-1] - y[-2:-5:-1]])
        curve = BSpline(ext, np.vstack([2 * P[0] - P[1], P, 2 * P[-1] - P[-2]]), 3)
        tau = np.linspace(0, 1, 7)
        sides = 0
        for f, loop in enumerate(mesh.faces):
            for k in range(4):
                c0, c1 = int(loop[mesh.corners[f][k]]), int(loop[mesh.corners[f][(k + 1) % 4]])
                if gi[c0, 0] == 2 and gi[c1, 0] == 2:
                    st = [(tau, 0 * tau), (1 + 0 * tau, tau), (1 - tau, 1 + 0 * tau), (0 * tau, 1 - tau)][k]
                    got = model.evaluate_faces(np.full(7, f), *st).P
                    yy = Y[gi[c0, 1]] + (Y[gi[c1, 1]] - Y[gi[c0, 1]]) * tau
                    self.assertLess(np.abs(got - curve(yy)).max(), 1e-9 * scale)
                    sides += 1
        self.assertGreaterEqual(sides, 2 * len(creases) - 2)     # both sides (T-junction faces span two)
        self.assertGreaterEqual(len(Layout.from_model(model).edge_links), 1)

    def test_kernel_refuses_a_crease_ending_inside(self):
        X, Y, mesh = tjunction_grid()
        gi = mesh.grid_index
        col = sorted((int(gi[v, 1]), v) for v in range(mesh.n_vertices) if gi[v, 0] == 2)
        path = self.write(mesh, "dart", creases=[(col[0][1], col[1][1]), (col[1][1], col[2][1])])
        with self.assertRaises(InputError) as cm:
            tsplcam.load(path)
        self.assertIn("crease ends inside", str(cm.exception))
        lines = open(path).read().split("\n")
        self.assertTrue(lines[cm.exception.line - 1].startswith("100edges"))


class Creases(TempDir):
    def crease_sides(self, model, cage, creases, n=9):
        """Per crease edge (a, b): the surface along it evaluated from the faces on both sides,
        and where those points lie in their patches."""
        faces = cage.mesh.faces
        out = []
        for a, b in creases:
            sides = []
            for f, quad in enumerate(faces):
                for k in range(4):
                    if {int(quad[k]), int(quad[(k + 1) % 4])} == {a, b}:
                        tau = np.linspace(0, 1, n) if quad[k] == a else np.linspace(1, 0, n)
                        st = [(tau, 0 * tau), (1 + 0 * tau, tau), (1 - tau, 1 + 0 * tau), (0 * tau, 1 - tau)][k]
                        sides.append((f, st))
            out.append(sides)
        return out

    def test_creases_are_c0_patch_boundaries_smooth_elsewhere(self):
        for name in ("catmark_cube_creases0", "fusion_mold"):
            if name == "fusion_mold":
                cage, creases, _ = samples.fusion_mold_cage()
                model = tsplcam.load(samples.sample_path("fusion_mold"))
            else:
                cage, creases = reference(name)
                model = tsplcam.load(self.write(cage, name, creases=creases))
            scale = size_of(model)
            fm = model.face_map
            kinks = []
            for sides in self.crease_sides(model, cage, creases):
                self.assertEqual(len(sides), 2, name)
                (fa, (sa_, ta_)), (fb, (sb_, tb_)) = sides
                A = model.evaluate_faces(np.full(len(sa_), fa), sa_, ta_)
                B = model.evaluate_faces(np.full(len(sb_), fb), sb_, tb_)
                self.assertLess(np.abs(A.P - B.P).max(), 1e-9 * scale, name)          # C0
                kinks.append(np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", A.normal, B.normal), -1, 1))).max())
                # on a patch boundary: the two sides lie in different patches or on a patch edge
                for f, s, t in ((fa, sa_, ta_), (fb, sb_, tb_)):
                    p = fm.patch[f]
                    self.assertTrue(fa != fb and (fm.patch[fa] != fm.patch[fb] or self.on_patch_edge(fm, f, s, t)),
                                    f"{name}: crease edge inside patch {p}")
            self.assertGreater(max(kinks), 1.0, name)               # a real kink along the crease
            # away from creases: the normals agree across every other patch edge (G1 at least)
            crease_pts = np.concatenate([model.evaluate_faces(np.full(9, s[0][0]), *s[0][1]).P
                                         for s in self.crease_sides(model, cage, creases)])
            for link in Layout.from_model(model).edge_links:
                tau = np.linspace(0.05, 0.95, 7)
                sa, sb = edge_pair(model, link, tau)
                d = np.linalg.norm(sa.P[:, None] - crease_pts[None], axis=2).min(axis=1)
                smooth = d > 1e-6 * scale
                if smooth.all():
                    dot = np.abs(np.einsum("ij,ij->i", sa.normal, sb.normal))
                    self.assertGreater(dot.min(), 1 - 1e-9, f"{name}: patches {link.a}, {link.b}")

    @staticmethod
    def on_patch_edge(fm, f, s, t):
        from tsplcam.model.cells import SQUARE_MAPS
        A, o = SQUARE_MAPS[fm.map_index[f]]
        a = A[0, 0] * s + A[0, 1] * t + o[0]
        b = A[1, 0] * s + A[1, 1] * t + o[1]
        u = (fm.cell[f, 0] + a) / fm.cells[f, 0]
        v = (fm.cell[f, 1] + b) / fm.cells[f, 1]
        return (np.all(np.minimum(u, 1 - u) < 1e-12) or np.all(np.minimum(v, 1 - v) < 1e-12))


class Sample(unittest.TestCase):
    def test_fusion_mold(self):
        """The shipped Fusion-dialect sample: stars of valence 3 and 5, a crease of 10 edges,
        a 14.4 x 14.4 x 6.8 mm cavity whose rim lies on the block's top face."""
        model = tsplcam.load(samples.sample_path("fusion_mold"))
        self.assertEqual(model.kind, "catmull-clark")
        self.assertEqual(sorted(e.valence for e in model.extraordinary if not e.boundary), [3] * 6 + [5] * 2)
        self.assertEqual(model.tsm.crease_edges, 10)
        self.assertEqual(model.tsm.end_conditions, "SUBD_CREASES")
        lo, hi = samples._limit_box(model.control, 65)
        np.testing.assert_allclose(hi - lo, [14.4, 14.4, 6.8], atol=2e-3)
        self.assertAlmostEqual(hi[2], samples.FUSION_MOLD_BLOCK[2], delta=2e-3)
        bottom = min(model.patches, key=lambda p: p.evaluate(0.5, 0.5).P[0, 2])
        self.assertGreater(bottom.evaluate(0.5, 0.5).normal[0, 2], 0.9)


class Refused(TempDir):
    """Every option or record outside the dialect's list, and every inconsistency, is an
    InputError naming the file and the line."""

    def setUp(self):
        super().setUp()
        cage, creases = reference("catmark_xord_boundary")
        self.lines = open(self.write(cage, "base", creases=[], grip_map=True)).read().split("\n")

    def refused(self, lines, *fragments, line=None):
        path = os.path.join(self.dir, "bad.tsm")
        with open(path, "w") as fh:
            fh.write("\n".join(lines))
        with self.assertRaises(InputError) as cm:
            tsplcam.load(path)
        exc = cm.exception
        self.assertEqual(os.path.realpath(exc.path), os.path.realpath(path))
        for frag in fragments:
            self.assertIn(frag, str(exc))
        if line is None:
            self.assertIsNotNone(exc.line, str(exc))
        else:
            self.assertEqual(exc.line, line, str(exc))
        return exc

    def at(self, prefix, k=0):
        return [i for i, l in enumerate(self.lines) if l.startswith(prefix)][k]

    def replaced(self, i, new):
        return self.lines[:i] + [new] + self.lines[i + 1:]

    def test_header_options(self):
        for key, bad, frag in (("cap-type", "cap-type G2CAPS", "cap-type"),
                               ("end-conditions", "end-conditions BEZIER", "end-conditions"),
                               ("star-knot-rule", "star-knot-rule UNIFORM", "star-knot-rule"),
                               ("units", "units 1 furlongs", "unit name"),
                               ("star-smoothness", "star-smoothness -1", "star-smoothness")):
            i = self.at(key)
            self.refused(self.replaced(i, bad), frag, line=i + 1)

    def test_star_smoothness_with_stars(self):
        i = self.at("star-smoothness")
        self.refused(self.replaced(i, "star-smoothness 2"), "star-smoothness 2", line=i + 1)

    def test_unknown_records(self):
        i = self.at("tol")
        for rec in ("107foo 1 2", "0m gv 3", "0m cg 1 4 0 0 0 0", "0m frob 2"):
            self.refused(self.lines[:i] + [rec] + self.lines[i:], line=i + 1)

    def test_vendor_records_are_skipped(self):
        i = self.at("tol")
        ok = self.lines[:i] + ["50000grip 3", "105sym 1 0 0", "105plane 0 0 1 0", "105a 1", "105r 2"] + self.lines[i:]
        path = os.path.join(self.dir, "vendor.tsm")
        with open(path, "w") as fh:
            fh.write("\n".join(ok))
        self.assertEqual(tsplcam.load(path).kind, "catmull-clark")

    def test_boundary_records(self):
        i = self.at("ec")
        self.refused(self.lines[:i] + self.lines[i + 1:], "no ec record")
        e = int(self.lines[i].split()[1])
        interior = next(k for k in range(100) if f"ec {k} 0" not in self.lines)
        self.refused(self.replaced(i, f"ec {interior} 0"), "not a boundary edge", line=i + 1)
        j = next(k for k, l in enumerate(self.lines) if l.startswith("l ") and l.split()[5] == "-1")
        parts = self.lines[j].split()
        parts[7] = str((int(parts[7]) + 1) % 3)
        self.refused(self.replaced(j, " ".join(parts)), "flag", line=j + 1)
        self.assertGreaterEqual(e, 0)

    def test_106ek_must_repeat_the_intervals(self):
        i = self.at("tol")
        n_edges = sum(l.startswith("e ") for l in self.lines)
        ek = [f"106ek 1.0" for _ in range(n_edges)]
        path = os.path.join(self.dir, "ek.tsm")
        with open(path, "w") as fh:
            fh.write("\n".join(self.lines[:i] + ek + self.lines[i:]))
        self.assertEqual(tsplcam.load(path).kind, "catmull-clark")
        ek[3] = "106ek 1.5"
        self.refused(self.lines[:i] + ek + self.lines[i:], "106ek", line=i + 4)
        self.refused(self.lines[:i] + ek[:-1] + self.lines[i:], "106ek", line=i + n_edges - 1)

    def test_creases_and_grips(self):
        i = self.at("tol")
        self.refused(self.lines[:i] + ["100edges 99999"] + self.lines[i:], "100edges", line=i + 1)
        self.refused(self.lines[:i] + ["100verts 99999"] + self.lines[i:], "100verts", line=i + 1)
        g = self.at("0g")
        self.refused(self.lines[:g] + self.lines[g + 1:], "grip map")
        m = self.at("0m gvp", 1)
        self.refused(self.replaced(m, self.lines[self.at("0m gvp")]), "two grips", line=m + 1)
