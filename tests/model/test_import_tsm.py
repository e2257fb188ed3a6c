"""Autodesk T-Splines .tsm files: the three shipped GrapeTec files load, their surfaces lie in
the convex hull of their control points, faces meet without gaps, corners interpolate, and
bad files get errors that name the file and line."""
import os
import shutil
import tempfile
import unittest

import numpy as np
from scipy.spatial import Delaunay

import tsplcam
from tsplcam.layout.layout import Layout
from tsplcam.errors import InputError
from tsplcam.model.formats.tsm import block_offsets, read_tsm
from conftest import edge_pair, external

NAMES = ("simple", "mouse", "fan")


def path_of(name):
    return external("grapetec_tspline", name + ".tsm")


class ShippedFiles(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.models = {n: tsplcam.load(path_of(n)) for n in NAMES}

    def test_load(self):
        counts = {n: (len(m.patches), len(m.extraordinary), m.kind) for n, m in self.models.items()}
        self.assertEqual(counts, {"simple": (1, 0, "t-spline"), "mouse": (5, 0, "t-spline"),
                                  "fan": (1, 0, "t-spline")})
        # every grip of the file is a control point (null grips excepted)
        grips = {"simple": 23, "mouse": 73, "fan": 81}
        for n, m in self.models.items():
            self.assertEqual(m.control.n_vertices, grips[n], n)

    def test_inside_convex_hull_of_control_points(self):
        g = np.linspace(0, 1, 21)
        U, V = np.meshgrid(g, g)
        for n, m in self.models.items():
            P = np.concatenate([p.evaluate(U.ravel(), V.ravel()).P for p in m.patches])
            C = m.control.points
            inside = Delaunay(C).find_simplex(P, tol=1e-9 * np.abs(C).max()) >= 0
            self.assertTrue(inside.all(), f"{n}: {(~inside).sum()} points outside")

    def test_adjacent_faces_meet(self):
        """Both faces along every interior edge of the T-mesh, and both patches along every
        patch edge, give the same points."""
        tau = np.linspace(0, 1, 9)
        for n, m in self.models.items():
            mesh, topo = m.control, m.control.topology
            scale = np.abs(mesh.points).max()
            rows = {0: ([], [], []), 1: ([], [], [])}
            count = 0
            for (a, b), (f, i) in topo.edge_at.items():
                hit = topo.edge_at.get((b, a))
                if hit is None or a > b or min(m.face_size[f]) <= 0 or min(m.face_size[hit[0]]) <= 0:
                    continue
                count += 1
                for side, (face, k, ts) in enumerate(((f, i, tau), (hit[0], hit[1], tau[::-1]))):
                    W, H = m.face_size[face]
                    p0, p1 = topo.pos[face][k], topo.pos[face][(k + 1) % len(mesh.faces[face])]
                    rows[side][0].extend([face] * len(ts))
                    rows[side][1].extend((p0[0].real + (p1[0].real - p0[0].real) * ts) / W)
                    rows[side][2].extend((p0[1].real + (p1[1].real - p0[1].real) * ts) / H)
            self.assertGreaterEqual(count, 3, n)
            A, B = m.evaluate_faces(*rows[0]), m.evaluate_faces(*rows[1])
            self.assertLess(np.abs(A.P - B.P).max(), 1e-12 * scale, n)
            for link in Layout.from_model(m).edge_links:
                sa, sb = edge_pair(m, link, tau)
                self.assertLess(np.abs(sa.P - sb.P).max(), 1e-12 * scale, n)

    def test_clamped_corners_interpolate_their_grips(self):
        """Bezier end conditions: the surface passes through the corner grips of the file."""
        corners = {"simple": [(0, 0, -3.4626040428907068), (30, 0, -3.49483566732731),
                              (0, 30, -3.5023978266846547), (30, 30, -2.3707438010214226)]}
        for n, pts in corners.items():
            nodes = self.models[n].node_points
            for p in pts:
                self.assertLess(np.linalg.norm(nodes - np.array(p), axis=1).min(), 1e-12, (n, p))

    def test_grip_blocks_follow_the_geometry(self):
        """The grips as placed by the decoded blocks make a control net whose faces all turn
        counter-clockwise seen from above (simple.tsm lies over a grid in xy), with the
        extra rows 5 mm inside the boundary."""
        mesh = self.models["simple"].control
        for loop in mesh.faces:
            q = mesh.points[loop][:, :2]
            area = 0.5 * np.sum(q[:, 0] * np.roll(q[:, 1], -1) - np.roll(q[:, 0], -1) * q[:, 1])
            self.assertGreater(area, 0.0)
        xs = np.unique(np.round(mesh.points[:, 0], 9))
        np.testing.assert_allclose(xs, [0, 5, 15, 25, 30])


class BlockLayout(unittest.TestCase):
    def test_pinwheel(self):
        # simple.tsm vertex 0: one row north, one column east: north, north-east, east
        self.assertEqual(block_offsets((1, 0, 0, 1), [5, 1, 6]), {(0, 1): 5, (1, 1): 6, (1, 0): 1})
        full = block_offsets((1, 1, 1, 1), list(range(8)))
        self.assertEqual(set(full), {(x, y) for x in (-1, 0, 1) for y in (-1, 0, 1)} - {(0, 0)})
        with self.assertRaises(ValueError):
            block_offsets((1, 1, 0, 0), [1, 2])


class BadFiles(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp()
        with open(path_of("simple"), "rb") as fh:
            self.lines = fh.read().decode("latin-1").splitlines()

    def write(self, lines, name="x.tsm"):
        p = os.path.join(self.dir, name)
        with open(p, "w", encoding="latin-1") as fh:
            fh.write("\n".join(lines) + "\n")
        return p

    def refused(self, lines, *words, line=None):
        p = self.write(lines)
        with self.assertRaises(InputError) as cm:
            tsplcam.load(p)
        msg = str(cm.exception)
        self.assertIn(p, msg)
        for w in words:
            self.assertIn(w, msg)
        if line is not None:
            self.assertEqual(cm.exception.line, line, msg)

    def at(self, prefix, nth=0):
        return [k for k, l in enumerate(self.lines) if l.startswith(prefix)][nth]

    def test_unsupported_record_named_with_its_line(self):
        lines = list(self.lines)
        k = self.at("ec")
        lines.insert(k, "zz 1 2 3")
        self.refused(lines, "'zz'", "not supported", line=k + 1)

    def test_unsupported_header_values(self):
        lines = list(self.lines)
        k = self.at("degree")
        lines[k] = "degree 5"
        self.refused(lines, "degree 5", line=k + 1)
        lines = list(self.lines)
        k = self.at("force-bezier")
        lines[k] = "force-bezier-end-conditions 0"
        self.refused(lines, "end conditions", line=k + 1)

    def test_unsupported_edge_condition_and_star_block(self):
        lines = list(self.lines)
        k = self.at("ec")
        lines[k] = "ec 0 1"
        self.refused(lines, "edge condition", line=k + 1)
        lines = list(self.lines)
        k = self.at("0m cg")
        lines[k] = "0m cg 0 5 1 0 0 1 0 5 1 6"
        self.refused(lines, "valence 5", line=k + 1)

    def test_units(self):
        lines = list(self.lines)
        k = self.at("units")
        lines[k] = "units 0.0254 inches"
        mesh = read_tsm(self.write(lines, "inch.tsm"))
        ref = read_tsm(path_of("simple"))
        np.testing.assert_allclose(mesh.points, ref.points * 25.4)
        lines[k] = "units 0.0254 millimeters"
        self.refused(lines, "unit name", line=k + 1)

    def test_truncated_files(self):
        """Every cut is an InputError naming the file, never a crash or a half-built model."""
        n = self.at("0g", -1) + 1              # past the last grip only metadata follows
        for cut in range(1, n, 3):
            p = self.write(self.lines[:cut])
            with self.assertRaises(InputError) as cm:
                tsplcam.load(p)
            self.assertIn(p, str(cm.exception))

    def test_broken_links_name_the_line(self):
        lines = list(self.lines)
        k = self.at("l ", 3)
        parts = lines[k].split()
        parts[3] = "77"
        lines[k] = " ".join(parts)
        self.refused(lines, "link", line=k + 1)

    def test_grip_block_that_does_not_fit(self):
        lines = list(self.lines)
        k = self.at("v ", 1)             # vertex 1 (a straight boundary vertex) turned by a quarter
        lines[k] = lines[k].replace("EAST", "NORTH")
        self.refused(lines, "does not fit")

    def test_not_a_tsm_file(self):
        p = os.path.join(self.dir, "bin.tsm")
        with open(p, "wb") as fh:
            fh.write(b"\x00\x01binary" * 20)
        with self.assertRaises(InputError) as cm:
            tsplcam.load(p)
        self.assertIn("#TS0200", str(cm.exception))

    def tearDown(self):
        shutil.rmtree(self.dir, ignore_errors=True)
