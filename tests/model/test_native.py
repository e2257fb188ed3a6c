"""The native model file (.tspl): exact round trips, cages as Catmull-Clark models, errors
that name the file and line, truncated and corrupt files."""
import os
import tempfile
import unittest

import numpy as np

import tsplcam
from tsplcam.errors import InputError
from tsplcam.model import samples
from tsplcam.model.cage import cage_model
from tsplcam.model.formats.native import dumps, read_native, write_native
from tsplcam.model.tmesh import from_lines
from tsplcam.model.tspline import tspline_model


def small_tmesh():
    """A clamped T-mesh with T-junctions, rational weights and awkward floats."""
    rng = np.random.default_rng(11)
    X = np.array([0.0, 0.0, 0.1, 0.7, 1.3, 2.0, 2.0])
    Y = np.array([0.0, 0.0, 1.0 / 3.0, 1.1, 1.5, 1.5])
    h = [(j, 0, 6) for j in range(6)]
    v = [(i, 0, 5) for i in range(7)]
    h[2] = (2, 0, 3)
    v[3] = (3, 1, 5)
    P = rng.standard_normal((7, 6, 3)) * 1e3
    W = rng.uniform(0.3, 3.0, (7, 6))
    return from_lines(X, Y, h, v, P, W, name="small")



def same_to_rounding(test, a, b):
    """Two evaluations of one surface from the same doubles agree to 1e-12 of their size (the
    same arithmetic, but nothing promises bit-equal results on every CPU and BLAS)."""
    scale = max(1.0, float(np.abs(b).max()))
    test.assertLess(float(np.abs(a - b).max()), 1e-12 * scale)

class RoundTrip(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp()

    def path(self, name):
        return os.path.join(self.dir, name)

    def test_tspline_bytes_and_surface(self):
        rng = np.random.default_rng(1)
        for mesh in (small_tmesh(), samples.tjunction_mold()):
            a, b = self.path("a.tspl"), self.path("b.tspl")
            write_native(mesh, a)
            model = tsplcam.load(a)
            self.assertEqual(model.kind, "t-spline")
            write_native(model, b)
            with open(a, "rb") as fa, open(b, "rb") as fb:
                self.assertEqual(fa.read(), fb.read())
            # exact by construction: numbers are written with repr, which reads back the same double
            self.assertTrue(np.array_equal(model.control.points, mesh.points))
            self.assertTrue(np.array_equal(model.control.weights, mesh.weights))
            for x, y in zip(model.control.intervals, mesh.intervals):
                self.assertTrue(np.array_equal(x, y))
            ref = tspline_model(mesh)
            u, v = rng.random(500), rng.random(500)
            for p, q in zip(model.patches, ref.patches):
                s, t = p.evaluate(u, v), q.evaluate(u, v)
                same_to_rounding(self, s.P, t.P)
                same_to_rounding(self, s.Puv, t.Puv)

    def test_cage_loads_as_the_same_catmull_clark_model(self):
        rng = np.random.default_rng(2)
        cage = samples.keycap()
        a, b = self.path("k.tspl"), self.path("k2.tspl")
        write_native(cage, a)
        model = tsplcam.load(a)
        self.assertEqual(model.kind, "catmull-clark")
        write_native(model, b)
        with open(a) as fa, open(b) as fb:
            self.assertEqual(fa.read(), fb.read())
        ref = cage_model(cage)
        self.assertEqual(len(model.patches), len(ref.patches))
        F = len(cage.mesh.faces)
        f, s, t = rng.integers(0, F, 800), rng.random(800), rng.random(800)
        x, y = model.evaluate_faces(f, s, t), ref.evaluate_faces(f, s, t)
        same_to_rounding(self, x.P, y.P)
        same_to_rounding(self, x.normal, y.normal)

    def test_documented_header_and_units(self):
        text = dumps(small_tmesh())
        head = text.splitlines()[:7]
        self.assertEqual(head[1:4], ['  "format": "tsplcam-model",', '  "version": 1,', '  "units": "mm",'])
        p = self.path("cm.tspl")
        with open(p, "w") as fh:
            fh.write(text.replace('"units": "mm"', '"units": "cm"'))
        kind, mesh, _ = read_native(p)
        # exact by construction: the reader multiplies the same doubles by the same 10.0 (one
        # correctly rounded product each)
        np.testing.assert_array_equal(mesh.points, small_tmesh().points * 10.0)


class Errors(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp()
        self.text = dumps(small_tmesh())

    def load_text(self, text, name="x.tspl"):
        p = os.path.join(self.dir, name)
        with open(p, "w") as fh:
            fh.write(text)
        return p, tsplcam.load

    def refused(self, text, *words, line=None):
        p, load = self.load_text(text)
        with self.assertRaises(InputError) as cm:
            load(p)
        msg = str(cm.exception)
        self.assertIn(p, msg)
        for w in words:
            self.assertIn(w, msg)
        if line is not None:
            self.assertEqual(cm.exception.line, line, msg)
        return cm.exception

    def line_of(self, needle, nth=0):
        hits = [k + 1 for k, l in enumerate(self.text.splitlines()) if needle in l]
        return hits[nth]

    def test_truncated_files(self):
        """Every cut of the file is an InputError naming the file, never a crash or a model."""
        n = len(self.text)
        for cut in np.linspace(1, n - 3, 40).astype(int):
            p, load = self.load_text(self.text[:cut])
            with self.assertRaises(InputError) as cm:
                load(p)
            self.assertIn(p, str(cm.exception))

    def test_corrupt_bytes(self):
        p = os.path.join(self.dir, "bin.tspl")
        with open(p, "wb") as fh:
            fh.write(b"\x89PNG\r\n\x1a\n\x00\xff" * 10)
        with self.assertRaises(InputError):
            tsplcam.load(p)

    def test_bad_vertex_names_its_line(self):
        lines = self.text.splitlines()
        k = self.line_of("[", 3)                 # the third vertex
        lines[k - 1] = "    [1.0, 2.0],"
        self.refused("\n".join(lines), "vertex 3", line=k)

    def test_face_with_unknown_vertex_names_face_and_line(self):
        lines = self.text.splitlines()
        k = self.line_of('{"vertices"', 4)
        lines[k - 1] = lines[k - 1].replace('"vertices": [', '"vertices": [999, ', 1)
        e = self.refused("\n".join(lines), "face 5")
        self.assertIn(f"line {k}", str(e))

    def test_inconsistent_intervals_name_the_faces_line(self):
        lines = self.text.splitlines()
        k = self.line_of('{"vertices"', 10)
        head, tail = lines[k - 1].split('"intervals": [')
        vals = tail.split("]")[0].split(", ")
        vals[0] = repr(float(vals[0]) + 0.25)
        lines[k - 1] = head + '"intervals": [' + ", ".join(vals) + "]" + tail.split("]", 1)[1]
        e = self.refused("\n".join(lines), "knot interval")
        self.assertIn(f"line {k}", str(e))

    def test_header_errors(self):
        self.refused(self.text.replace('"tsplcam-model"', '"other"'), "not a tsplcam model")
        self.refused(self.text.replace('"version": 1', '"version": 3'), "newer")
        self.refused(self.text.replace('"units": "mm"', '"units": "furlong"'), "units")
        self.refused(self.text.replace('"kind": "t-spline"', '"kind": "nurbs"'), "kind")
        self.refused(self.text.replace('"name": "small",', '"name": "small", "extra": 1,'), "unknown keys")
        self.refused("[1, 2, 3]\n", "not a tsplcam model")

    def test_bad_weight_names_vertex_and_line(self):
        lines = self.text.splitlines()
        k = self.line_of("[", 6)                 # the sixth vertex
        nums = lines[k - 1].strip().strip(",").strip("[]").split(", ")
        nums[3] = "-1.0"
        lines[k - 1] = "    [" + ", ".join(nums) + "],"
        self.refused("\n".join(lines), "vertex 6", "weight", f"line {k}")
