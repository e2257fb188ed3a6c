"""Creased Catmull-Clark cages (OpenSubdiv's ``t crease`` and ``t corner`` tags, uniform
creasing) against an independent reference written here: a plain uniform refinement of the
whole cage with OpenSubdiv's crease rules, level by level, and the exact limit of the refined
vertices whose neighbourhood no longer changes (closed-form smooth mask, the cubic B-spline
of an infinitely sharp crease, fixed corners), with first and second derivatives from the
3 x 3 B-spline masks at regular vertices. Nothing here uses the kernel's refinement."""
import functools
import os
import tempfile
import unittest

import numpy as np

import tsplcam
from tsplcam.errors import InputError
from tsplcam.layout.layout import Layout
from tsplcam.model.formats.obj import read_obj
from conftest import RefMesh, edge_pair, external


@functools.lru_cache(maxsize=None)
def loaded(name: str):
    """OpenSubdiv's shape ``name``: its cage as read and its model (loaded once for the
    module's tests: the single crease's sharpness-10 line takes some seconds)."""
    path = external("opensubdiv", name + ".obj")
    return read_obj(path), tsplcam.load(path)

def reference(cage, levels):
    mesh = cage.mesh
    H = cage.homogeneous()
    ref = RefMesh(mesh.faces, H, dict(mesh.sharpness or {}), dict(mesh.corner_sharpness or {}),
                  mesh.boundary_rule).start()
    for _ in range(levels):
        ref = ref.refine()
    return ref


def compare(test, model, ref, derivatives=True, tol=1e-9, name=""):
    """Positions at refined vertices with exact limits, and first and second derivatives at
    regular ones, against the model's evaluation in the cage's face coordinates."""
    scale = np.abs(model.node_points).max()
    L = ref.exact_limits()
    # corner 0 of every refined face: its vertex and its root-face coordinates
    v0 = ref.F[:, 0]
    keep = ~np.isnan(L[v0, 0])
    _, first = np.unique(v0[keep], return_index=True)
    rows = np.nonzero(keep)[0][first]
    sp = model.evaluate_faces(ref.root[rows], ref.O[rows, 0], ref.O[rows, 1])
    err = np.abs(sp.P - L[v0[rows]]).max()
    test.assertLess(err, tol * scale, f"{name}: limit positions off by {err:.3g} ({len(rows)} points)")
    count = len(rows)
    if derivatives:
        f, P, Ps, Pt, Pss, Pst, Ptt = ref.regular_jets()
        test.assertGreater(len(f), 10, name)
        sp = model.evaluate_faces(ref.root[f], ref.O[f, 0], ref.O[f, 1])
        A = np.linalg.inv(np.stack([ref.X[f], ref.Y[f]], axis=2))       # d(local)/d(root), per point
        g1 = np.einsum("nia,inc->anc", A, np.array([Ps, Pt]))
        Hl = np.array([[Pss, Pst], [Pst, Ptt]])                          # (2, 2, n, 3)
        g2 = np.einsum("nia,ijnc,njb->abnc", A, Hl, A)
        got = (sp.P, sp.Pu, sp.Pv, sp.Puu, sp.Puv, sp.Pvv)
        want = (P, g1[0], g1[1], g2[0, 0], g2[0, 1], g2[1, 1])
        for k, (a, b) in enumerate(zip(got, want)):
            err = np.abs(a - b).max()
            test.assertLess(err, tol * scale, f"{name}: derivative {k} off by {err:.3g} ({len(f)} points)")
        count += len(f)
    return count


class OpenSubdivShapes(unittest.TestCase):
    def check(self, name, levels, derivatives=True):
        cage, model = loaded(name)
        ref = reference(cage, levels)
        return compare(self, model, ref, derivatives, name=name)

    def test_cube_creases(self):
        # two semi-sharp edges of sharpness 2 meeting at a vertex, on a cube (valence 3)
        self.assertGreater(self.check("catmark_cube_creases0", 4), 100)

    def test_torus_creases(self):
        # a ring of edges of sharpness 4.7 around the torus
        self.assertGreater(self.check("catmark_torus_creases0", 5), 1000)

    def test_single_crease(self):
        # crease lines of sharpness 10 (infinite), 5.7, 5, 2.8, 2, 1.4, 1, 0.8, 0.2
        self.assertGreater(self.check("catmark_single_crease", 6), 1000)

    def test_infinitely_sharp_crease_is_the_cubic_bspline_of_its_vertices(self):
        """Along the sharpness-10 line of catmark_single_crease the limit is the uniform cubic
        B-spline of the crease vertices (with its own end rule): at the middle vertices it is
        (a + 4 v + b) / 6."""
        cage, model = loaded("catmark_single_crease")
        line = [1, 22, 43, 64, 85]                     # 0-based, the tag's pairs
        P = cage.points
        mesh = cage.mesh
        for a, v, b in zip(line, line[1:], line[2:]):
            want = (P[a] + 4 * P[v] + P[b]) / 6
            f, k = mesh.fan(v)[0][0]
            s, t = ((0, 0), (1, 0), (1, 1), (0, 1))[k]
            got = model.evaluate_faces([f], [s], [t]).P[0]
            self.assertLess(np.abs(got - want).max(), 1e-12 * np.abs(P).max())


class PatchLayout(unittest.TestCase):
    def test_sharp_creases_split_patches_and_are_shared_edges(self):
        """The infinitely sharp line of catmark_single_crease is a patch boundary: patches on
        both sides share it as whole edges (boundary-linked, so a path can change patch there)
        and no patch contains a crease edge inside; semi-sharp lines do not split."""
        _, model = loaded("catmark_single_crease")
        layout = Layout.from_model(model)
        self.assertEqual(len(model.patches), 2)
        self.assertEqual(len(layout.edge_links), 1)
        link = layout.edge_links[0]
        tau = np.linspace(0, 1, 21)
        sa, sb = edge_pair(model, link, tau)
        self.assertLess(np.abs(sa.P - sb.P).max(), 1e-12 * np.abs(model.node_points).max())
        # the normals jump across it
        ang = np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", sa.normal, sb.normal)), 0, 1)))
        self.assertGreater(ang[5:16].min(), 1.0)

    def test_no_crease_edge_inside_a_patch(self):
        cage, model = loaded("catmark_single_crease")
        fm = model.face_map
        for (a, b) in cage.mesh.crease_edges():
            fa, _ = cage.mesh.edges.get((a, b))
            fb, _ = cage.mesh.edges.get((b, a))
            self.assertNotEqual(fm.patch[fa], fm.patch[fb], (a, b))


class CornerTags(unittest.TestCase):
    GRID = "".join(f"v {i} {j} {0.3 * ((i * 7 + j * 3) % 5)}\n" for j in range(5) for i in range(5))
    FACES = "".join(f"f {j * 5 + i + 1} {j * 5 + i + 2} {j * 5 + i + 7} {j * 5 + i + 6}\n"
                    for j in range(4) for i in range(4))

    def load(self, tags):
        with tempfile.NamedTemporaryFile("w", suffix=".obj", delete=False) as fh:
            fh.write(self.GRID + self.FACES + tags)
        try:
            return read_obj(fh.name), tsplcam.load(fh.name)
        finally:
            os.unlink(fh.name)

    def test_corner_and_crease_tags(self):
        for tags, levels in (("t corner 1/1/0 12 10\n", 2), ("t corner 1/1/0 12 2.5\n", 4),
                             ("t crease 2/1/0 10 11 11 12 10\nt crease 2/1/0 12 13 13 14 1.5\n", 3),
                             ("t crease 4/2/0 2 7 7 12 10 0.6\nt corner 1/1/0 12 1.2\n", 3)):
            cage, model = self.load(tags + "t interpolateboundary 1/0/0 1\n")
            compare(self, model, reference(cage, levels), derivatives=False, name=tags)

    def test_bad_tags_named_with_their_line(self):
        for tags, words in (("t crease 2/1/0 0 6 10\n", ("line 42", "not joined")),
                            ("t crease 2/1/0 0 99 10\n", ("line 42", "does not exist")),
                            ("t crease 3/1/0 0 1 2 10\n", ("line 42", "pairs")),
                            ("t creasemethod 0/0/1 chaikin\n", ("line 42", "chaikin")),
                            ("t hole 1/0/0 3\n", ("line 42", "hole"))):
            with self.assertRaises(InputError) as cm:
                self.load(tags)
            for w in words:
                self.assertIn(w, str(cm.exception))


class NativeFile(unittest.TestCase):
    def test_creases_round_trip_through_the_native_file(self):
        """A creased cage written as .tspl (version 2: creases and corners) reads back to the
        same surface; write -> read -> write gives the same bytes."""
        from tsplcam.model.formats.native import dumps, read_native
        _, model = loaded("catmark_single_crease")
        text = dumps(model)
        self.assertIn('"version": 2', text)
        with tempfile.NamedTemporaryFile("w", suffix=".tspl", delete=False) as fh:
            fh.write(text)
        try:
            again = tsplcam.load(fh.name)
            self.assertEqual(dumps(again), text)
            _, cage, _ = read_native(fh.name)
            self.assertEqual(cage.mesh.sharpness, model.control.mesh.sharpness)
        finally:
            os.unlink(fh.name)
        rng = np.random.default_rng(4)
        f = rng.integers(0, 80, 500)
        s, t = rng.random(500), rng.random(500)
        a, b = model.evaluate_faces(f, s, t), again.evaluate_faces(f, s, t)
        self.assertEqual(np.abs(a.P - b.P).max(), 0.0)


if __name__ == "__main__":
    unittest.main()
