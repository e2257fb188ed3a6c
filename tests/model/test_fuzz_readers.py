"""Fuzzing the model readers (.tspl, .tsm, .iga, .obj with OpenSubdiv tags).

Every mutated file (tests/conftest.py: truncation, deleted, duplicated and swapped lines,
numbers replaced by NaN, inf, -1, 0, 1e308, huge counts and non-integers, random and
non-UTF-8 bytes, very long lines) either loads into a model whose patches evaluate to
finite positions, derivatives and normals, or raises InputError naming the file and the
line, within a time limit. The short run is fixed (derandomised); the long one:
``TSPLCAM_FUZZ_EXAMPLES=20000 /usr/bin/python3 -m pytest -q -p no:cacheprovider -k fuzz tests``.
The regression tests below pin each crash the fuzzing found, one per class.
"""
from __future__ import annotations

import os
import tempfile
import time
import tracemalloc
import unittest

from hypothesis import given
from hypothesis import strategies as st

from conftest import (assert_model_finite, external, fuzz_ops, fuzz_read, fuzz_seeds,
                      fuzz_settings, mutate)
from tsplcam.errors import InputError
from tsplcam.inputfile import COORDINATE_LIMIT
from tsplcam.model.cage import cage_model
from tsplcam.model.formats.iga import iga_model
from tsplcam.model.formats.native import native_model
from tsplcam.model.formats.obj import read_obj
from tsplcam.model.formats.tsm import tsm_model


def obj_model(path):
    return cage_model(read_obj(path))


def fusion_grid_seed() -> bytes:
    """A 3 x 3 open grid with a bump, boundary edges and a grip map, as Fusion writes it."""
    import numpy as np
    from tsplcam.model.cage import Cage
    from tsplcam.model.formats.tsm_fusion import write_fusion_tsm
    from tsplcam.model.quadmesh import QuadMesh
    ij = [(i, j) for j in range(4) for i in range(4)]
    P = np.array([(10.0 * i, 10.0 * j, 5.0 * (0 < i < 3 and 0 < j < 3)) for i, j in ij])
    faces = [[4 * j + i, 4 * j + i + 1, 4 * j + i + 5, 4 * j + i + 4] for j in range(3) for i in range(3)]
    with tempfile.TemporaryDirectory(prefix="tsplcam-seed-") as folder:
        path = os.path.join(folder, "grid.tsm")
        write_fusion_tsm(Cage(QuadMesh(np.array(faces), 16), P), path, creases=[(5, 6)], grip_map=True)
        with open(path, "rb") as fh:
            return fh.read()


def fusion_tmesh_seed() -> bytes:
    """An open T-mesh with T-junctions, non-uniform intervals and a crease along a whole knot
    line (the T-spline kernel's path: clamped boundary, cut crease)."""
    import numpy as np
    from tsplcam.model.formats.tsm_fusion import write_fusion_tsm
    from tsplcam.model.tmesh import from_lines
    X = np.array([0, 7, 15, 21, 25, 28, 30, 32, 35, 45, 60.0])
    Y = np.array([0, 6, 13, 20, 27, 34, 40.0])
    vsegs = [(i, *({4: (1, 5), 6: (1, 5)}.get(i, (0, 6)))) for i in range(len(X))]
    hsegs = [(j, 0, len(X) - 1) for j in range(len(Y))]
    mesh = from_lines(X, Y, hsegs, vsegs, lambda i, j: (X[i], Y[j], np.sin(X[i] / 9) * np.cos(Y[j] / 7)))
    gi = mesh.grid_index
    col = sorted((int(gi[v, 1]), v) for v in range(mesh.n_vertices) if gi[v, 0] == 2)
    with tempfile.TemporaryDirectory(prefix="tsplcam-seed-") as folder:
        path = os.path.join(folder, "t.tsm")
        write_fusion_tsm(mesh, path, creases=[(a, b) for (_, a), (_, b) in zip(col[:-1], col[1:])], grip_map=True)
        with open(path, "rb") as fh:
            return fh.read()


READERS = {"tspl": native_model, "tsm": tsm_model, "tsm-fusion": tsm_model, "iga": iga_model,
           "obj": obj_model}
SEEDS = {
    "tspl": fuzz_seeds(["samples/tjunction_mold.tspl"]),
    "tsm": fuzz_seeds((), ["grapetec_tspline/*.tsm"]),
    # the Fusion dialect: the shipped sample (stars of valence 3 and 5, a crease, grips in
    # vertex order) and a small open cage with a grip map, both written by write_fusion_tsm
    "tsm-fusion": (fuzz_seeds(["samples/fusion_mold.tsm"]) + [("grid_map.tsm", fusion_grid_seed())]
                   + [("tgrid_crease.tsm", fusion_tmesh_seed())]),
    "iga": fuzz_seeds((), ["geopdes/*.iga", "msolve/*.iga"]),
    "obj": fuzz_seeds(["samples/keycap.obj", "samples/head.obj", "samples/figure4.obj"],
                      ["opensubdiv/*.obj"]),
}


class FuzzModelReaders(unittest.TestCase):
    """Mutated model files: a finite model or InputError with file and line, in bounded time."""

    def case(self, kind, index, ops):
        seeds = SEEDS[kind]
        if not seeds:
            self.skipTest(f"no {kind} seed files (../shared/data/external absent)")
        name, data = seeds[index % len(seeds)]
        model = fuzz_read(self, READERS[kind], mutate(data, ops), name)
        if model is not None:
            assert_model_finite(self, model)

    @fuzz_settings(60)
    @given(st.integers(0, 1000), fuzz_ops())
    def test_native(self, index, ops):
        self.case("tspl", index, ops)

    @fuzz_settings(60)
    @given(st.integers(0, 1000), fuzz_ops())
    def test_tsm(self, index, ops):
        self.case("tsm", index, ops)

    @fuzz_settings(60)
    @given(st.integers(0, 1000), fuzz_ops())
    def test_tsm_fusion(self, index, ops):
        self.case("tsm-fusion", index, ops)

    @fuzz_settings(60)
    @given(st.integers(0, 1000), fuzz_ops())
    def test_iga(self, index, ops):
        self.case("iga", index, ops)

    @fuzz_settings(80)
    @given(st.integers(0, 1000), fuzz_ops())
    def test_obj(self, index, ops):
        self.case("obj", index, ops)


class ReaderRegressions(unittest.TestCase):
    """One case per crash class the fuzzing found, each read straight from a small edit of a
    real file; and the promise that an announced huge count is refused before anything big
    is allocated."""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.addCleanup(self.tmp.cleanup)

    def write(self, name, data: bytes) -> str:
        path = os.path.join(self.tmp.name, name)
        with open(path, "wb") as fh:
            fh.write(data)
        return path

    def refused(self, read, path, *fragments, line=None) -> InputError:
        with self.assertRaises(InputError) as cm:
            read(path)
        exc = cm.exception
        self.assertEqual(exc.path, path)
        if line is not None:
            self.assertEqual(exc.line, line, str(exc))
        for f in fragments:
            self.assertIn(f, str(exc))
        return exc

    @staticmethod
    def edit_line(data: bytes, line: int, new: bytes) -> bytes:
        lines = data.split(b"\n")
        lines[line - 1] = new
        return b"\n".join(lines)

    def test_iga_coordinate_beyond_the_limit_names_node_and_line(self):
        # was numpy's LinAlgError surfacing as SystemError from bezier_mesh (and a k-d tree's
        # overflow ValueError): 1e308 is finite but no geometry survives squaring it
        with open(external("geopdes", "square_structured.iga"), "rb") as fh:
            data = fh.read()
        lines = data.split(b"\n")
        k = next(i for i, ln in enumerate(lines) if ln.startswith(b"node "))
        for value in (b"1e308", b"2e9", b"-1e12"):
            path = self.write("big.iga", self.edit_line(data, k + 1, b"node " + value + b" 0 0 1\r"))
            self.refused(iga_model, path, "node 0", "beyond", line=k + 1)
        # the whole square scaled to a tenth of the limit still loads and evaluates
        scale = COORDINATE_LIMIT / 10
        scaled = [b"node " + b" ".join(repr(float(x) * scale).encode() for x in ln.split()[1:4])
                  + b" " + ln.split()[4] + b"\r" if ln.startswith(b"node ") else ln for ln in lines]
        model = iga_model(self.write("fine.iga", b"\n".join(scaled)))
        assert_model_finite(self, model)
        self.assertGreater(float(abs(model.patches[0].evaluate(1.0, 1.0).P).max()), 0.5 * scale)

    def test_iga_huge_extraction_coefficient(self):
        # was a model that evaluates to NaN derivatives (Bezier weight 1e308)
        with open(external("geopdes", "square_structured.iga"), "rb") as fh:
            lines = fh.read().split(b"\n")
        b = next(i for i, ln in enumerate(lines) if ln.startswith(b"belem"))
        content = [i for i in range(b + 1, len(lines)) if lines[i].strip() and not lines[i].startswith(b"#")]
        k = content[1]                            # after the indices: extraction row 1
        row = lines[k].split()
        row[1] = b"1e308"
        lines[k] = b" ".join(row)
        path = self.write("coef.iga", b"\n".join(lines))
        self.refused(iga_model, path, "element 0, extraction row 1", "coefficient", line=k + 1)

    def test_announced_huge_counts_are_refused_before_allocating(self):
        """nodeN / elemN / belem of 10^9, a .tsm grip block of 10^9 x 10^9: refused in well under
        a second, with less than 20 MB allocated on the way."""
        iga = external("geopdes", "square_structured.iga")
        with open(iga, "rb") as fh:
            data = fh.read()
        cases = [("iga", data.replace(b"nodeN 25", b"nodeN 1000000000")),
                 ("iga", data.replace(b"elemN 4", b"elemN 1000000000")),
                 ("iga", data.replace(b"belem 16 3 3", b"belem 1000000000 3 3", 1))]
        with open(external("grapetec_tspline", "simple.tsm"), "rb") as fh:
            tsm = fh.read()
        at = tsm.index(b"0m cg ")
        end = tsm.index(b"\n", at)
        rec = tsm[at:end].split()
        rec[4:8] = [b"1000000000"] * 4
        cases.append(("tsm", tsm[:at] + b" ".join(rec) + tsm[end:]))
        for k, (ext, content) in enumerate(cases):
            self.assertNotEqual(content, data if ext == "iga" else tsm, f"case {k}: no edit made")
            path = self.write(f"huge{k}.{ext}", content)
            tracemalloc.start()
            t0 = time.perf_counter()
            try:
                self.refused(READERS[ext], path)
                peak = tracemalloc.get_traced_memory()[1]
            finally:
                tracemalloc.stop()
            self.assertLess(time.perf_counter() - t0, 5.0, f"case {k}")
            self.assertLess(peak, 20e6, f"case {k}: {peak / 1e6:.0f} MB allocated")

    def test_native_not_utf8_names_the_line(self):
        # was an error without a line ("not a text file ... at byte N")
        with open(os.path.join(os.path.dirname(__file__), "..", "..", "tsplcam", "data", "samples",
                               "tjunction_mold.tspl"), "rb") as fh:
            data = fh.read()
        path = self.write("bad.tspl", self.edit_line(data, 12, b"    [0.0, \xff0.0, 0.0],"))
        self.refused(native_model, path, "not UTF-8", "0xff", line=12)

    def test_native_json_numbers_python_would_misread(self):
        # a 5000-digit integer was Python's ValueError from the JSON decoder; NaN, Infinity and
        # 1e309 were read as floats and refused later without a line; 1e308 had no bound
        with open(os.path.join(os.path.dirname(__file__), "..", "..", "tsplcam", "data", "samples",
                               "tjunction_mold.tspl"), "rb") as fh:
            data = fh.read()
        for value, what in ((b"9" * 5000, "5000 digits"), (b"NaN", "NaN"), (b"-Infinity", "Infinity"),
                            (b"1e309", "overflows"), (b"1e308", "beyond")):
            path = self.write("num.tspl", self.edit_line(data, 12, b"    [0.0, " + value + b", 0.0],"))
            self.refused(native_model, path, what, line=12)

    def test_denormal_knot_interval(self):
        # was a model whose positions are NaN near a face with a knot interval of 1e-320
        # (accepted as equal to the 0 across the face)
        with open(os.path.join(os.path.dirname(__file__), "..", "..", "tsplcam", "data", "samples",
                               "tjunction_mold.tspl"), "rb") as fh:
            lines = fh.read().split(b"\n")
        k = next(i for i, ln in enumerate(lines) if b'"intervals": [6.0, 0.0, 6.0, 0.0]' in ln)
        lines[k] = lines[k].replace(b"[6.0, 0.0, 6.0, 0.0]", b"[6.0, 1e-320, 6.0, 0.0]")
        path = self.write("tiny.tspl", b"\n".join(lines))
        self.refused(native_model, path, "neither 0 nor a length", line=k + 1)

    def test_native_deep_nesting(self):
        # was RecursionError from the JSON decoder
        deep = b"[" * 100000 + b"]" * 100000
        path = self.write("deep.tspl", b'{"format": "tsplcam-model",\n"x": ' + deep + b"}")
        self.refused(native_model, path, "nested", line=2)

    def test_text_formats_count_lines_as_editors_do(self):
        # a form feed or a Unicode line separator inside a line used to shift every later
        # line number (str.splitlines breaks there)
        with open(external("grapetec_tspline", "simple.tsm"), "rb") as fh:
            data = fh.read()
        lines = data.split(b"\n")
        k = next(i for i, ln in enumerate(lines) if ln.startswith(b"0g "))
        lines[1] = lines[1] + b" #\x0c\xe2\x80\xa8\x1c"
        lines[k] = b"0g nan 0 0 1"
        path = self.write("ff.tsm", b"\n".join(lines))
        self.refused(tsm_model, path, "not a number", line=k + 1)

    def test_very_long_record_gives_a_short_message(self):
        with open(external("grapetec_tspline", "simple.tsm"), "rb") as fh:
            data = fh.read()
        path = self.write("long.tsm", data + b"\n" + b"7" * 200000 + b"\n")
        exc = self.refused(tsm_model, path, "not supported")
        self.assertLess(len(str(exc)), 1000)

    def test_degenerate_tangent_plane_names_this_file(self):
        # the subdivision scheme of a kind of vertex is shared by every file; its error named
        # the file that first built it, with no line (found by the long run)
        tent = external("opensubdiv", "catmark_tent.obj")
        obj_model(tent)                                   # builds the shared schemes
        with open(tent, "rb") as fh:
            data = mutate(fh.read(), [(2, 330, 0, 0), (1, 87, 0, 0)])    # a line doubled, one lost
        path = self.write("tent.obj", data)
        exc = self.refused(obj_model, path, "vertex 1", "degenerate tangent plane")
        self.assertIsNotNone(exc.line)

    def test_obj_unused_vertex_and_missing_faces_name_lines(self):
        path = self.write("unused.obj", b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 5 5 5\nf 1 2 3 4\n")
        self.refused(obj_model, path, "vertex 5 is not used", line=5)
        path = self.write("nofaces.obj", b"v 0 0 0\nv 1 0 0\n")
        self.refused(obj_model, path, "no faces", line=2)
        path = self.write("far.obj", b"v 0 0 0\nv 1 0 1e300\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
        self.refused(obj_model, path, "vertex 2", "beyond", line=2)


if __name__ == "__main__":
    unittest.main()
