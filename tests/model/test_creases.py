"""Creased Catmull-Clark cages (OpenSubdiv's ``t crease`` and ``t corner`` tags, uniform
creasing) against an independent reference written here: a plain uniform refinement of the
whole cage with OpenSubdiv's crease rules, level by level, and the exact limit of the refined
vertices whose neighbourhood no longer changes (closed-form smooth mask, the cubic B-spline
of an infinitely sharp crease, fixed corners), with first and second derivatives from the
3 x 3 B-spline masks at regular vertices. Nothing here uses the kernel's refinement."""
import os
import tempfile
import unittest

import numpy as np

import tsplcam
from tsplcam.errors import InputError
from tsplcam.layout.layout import Layout
from tsplcam.model.formats.obj import read_obj
from conftest import edge_pair, external

INF = np.float32(10.0)


def decrement(s):
    s = np.asarray(s, np.float32)
    return np.where(s >= INF, INF, np.where(s > 1, s - np.float32(1), np.float32(0))).astype(np.float32)


class RefMesh:
    """A cage with per-edge sharpness (float32), refined by the rules written out here."""

    def __init__(self, faces, points, sharp: dict, corner: dict, rule: str):
        self.F = np.asarray(faces, int)
        self.P = np.asarray(points, float)
        self.rule = rule
        nv = len(self.P)
        a = self.F.reshape(-1)
        b = np.roll(self.F, -1, axis=1).reshape(-1)
        key = np.minimum(a, b) * nv + np.maximum(a, b)
        self.ukey, self.einv = np.unique(key, return_inverse=True)
        self.E = np.column_stack([self.ukey // nv, self.ukey % nv])
        self.nfaces_e = np.bincount(self.einv, minlength=len(self.E))
        s = np.zeros(len(self.E), np.float32)
        pos = {tuple(e): i for i, e in enumerate(self.E)}
        for e, v in sharp.items():
            s[pos[tuple(sorted(e))]] = v
        self.s = s
        self.cs = np.zeros(nv, np.float32)
        for v, x in corner.items():
            self.cs[v] = x
        self.val = np.bincount(self.F.reshape(-1), minlength=nv)
        self.bnd_e = self.nfaces_e == 1
        bv = np.zeros(nv, bool)
        bv[self.E[self.bnd_e].reshape(-1)] = True
        self.bnd_v = bv

    def edge_s(self):
        return np.where(self.bnd_e, INF, self.s)

    def vertex_s(self):
        cs = self.cs.copy()
        if self.rule == "edge-and-corner":
            cs[self.bnd_v & (self.val == 1)] = INF
        return cs

    def _rules(self, es, vs):
        nv = len(self.P)
        sharp = es > 0
        count = np.bincount(self.E[sharp].reshape(-1), minlength=nv)
        ends = np.zeros((nv, 4))
        np.add.at(ends, self.E[sharp, 0], self.P[self.E[sharp, 1]])
        np.add.at(ends, self.E[sharp, 1], self.P[self.E[sharp, 0]])
        corner = (vs > 0) | (count > 2)
        crease = ~corner & (count == 2)
        return corner, crease, ends

    def refine(self) -> "RefMesh":
        F, P, E = self.F, self.P, self.E
        nv, ne, nf = len(P), len(E), len(F)
        FP = P[F].mean(axis=1)
        fsum = np.zeros((ne, 4))
        np.add.at(fsum, self.einv, np.repeat(FP, 4, axis=0))
        es = self.edge_s()
        mid = 0.5 * (P[E[:, 0]] + P[E[:, 1]])
        smooth_e = 0.25 * (P[E[:, 0]] + P[E[:, 1]]) + 0.25 * fsum
        w = np.clip(es, 0, 1)[:, None].astype(float)
        EP = np.where((es >= 1)[:, None], mid, w * mid + (1 - w) * smooth_e)
        # vertex points
        n = self.val.astype(float)
        nsum = np.zeros((nv, 4))
        np.add.at(nsum, E[:, 0], P[E[:, 1]])
        np.add.at(nsum, E[:, 1], P[E[:, 0]])
        fpsum = np.zeros((nv, 4))
        np.add.at(fpsum, F.reshape(-1), np.repeat(FP, 4, axis=0))
        with np.errstate(divide="ignore", invalid="ignore"):
            smooth_v = ((n - 2) / n)[:, None] * P + (nsum + fpsum) / (n * n)[:, None]
        vs = self.vertex_s()
        pc, pk, pends = self._rules(es, vs)
        ces, cvs = decrement(es), decrement(vs)
        cc, ck, cends = self._rules(ces, cvs)

        def mask(corner, crease, ends):
            return np.where(corner[:, None], P, np.where(crease[:, None], 0.75 * P + 0.125 * ends, smooth_v))

        mp, mc = mask(pc, pk, pends), mask(cc, ck, cends)
        same = (pc == cc) & (pk == ck)
        psmooth = ~pc & ~pk
        # fractional weight: edges becoming smooth (0 < s <= 1) and the vertex's own sharpness
        tr = (es > 0) & (es <= 1)
        tcount = np.bincount(E[tr].reshape(-1), minlength=nv).astype(float)
        tsum = np.zeros(nv)
        np.add.at(tsum, E[tr, 0], es[tr])
        np.add.at(tsum, E[tr, 1], es[tr])
        vt = (vs > 0) & (cvs <= 0)
        tcount += vt
        tsum += np.where(vt, vs, 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            fw = np.minimum(1.0, np.where(tcount > 0, tsum / tcount, 0.0))
        VP = np.where((psmooth | same)[:, None], mp, fw[:, None] * mp + (1 - fw)[:, None] * mc)
        # children
        e_of = self.einv.reshape(nf, 4)
        child = np.empty((4 * nf, 4), int)
        for k in range(4):
            child[k::4] = np.column_stack([F[:, k], nv + e_of[:, k], nv + ne + np.arange(nf), nv + e_of[:, (k + 3) % 4]])
        sharp = {}
        cs_e = decrement(self.s)
        for i in np.nonzero(cs_e > 0)[0]:
            a, b = E[i]
            sharp[(a, nv + i)] = cs_e[i]
            sharp[(b, nv + i)] = cs_e[i]
        corner = {int(v): decrement(self.cs[v]) for v in np.nonzero(decrement(self.cs) > 0)[0]}
        out = RefMesh(child, np.vstack([VP, EP, FP]), sharp, corner, self.rule)
        # where each child face lies in the root face: corner 0 and the two axes
        C = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
        O, X, Y = self.O, self.X, self.Y
        out.root = np.repeat(self.root, 4)
        out.O, out.X, out.Y = np.empty((4 * nf, 2)), np.empty((4 * nf, 2)), np.empty((4 * nf, 2))
        for k in range(4):
            def at(c):
                return O + X * c[0] + Y * c[1]
            ck, cn, cp = C[k], C[(k + 1) % 4], C[(k + 3) % 4]
            out.O[k::4] = at(ck)
            out.X[k::4] = at(ck + (cn - ck) / 2) - at(ck)
            out.Y[k::4] = at(ck + (cp - ck) / 2) - at(ck)
        return out

    def subset(self, keep: np.ndarray) -> "RefMesh":
        """The faces ``keep`` (mask) as a mesh of their own, with their places in the roots.
        Rules at the cut are wrong: use only what lies well inside."""
        F = self.F[keep]
        used = np.unique(F)
        new = np.full(len(self.P), -1)
        new[used] = np.arange(len(used))
        sharp = {}
        for i in np.nonzero(self.s > 0)[0]:
            a, b = self.E[i]
            if new[a] >= 0 and new[b] >= 0:
                sharp[(new[a], new[b])] = self.s[i]
        corner = {int(new[v]): self.cs[v] for v in np.nonzero(self.cs > 0)[0] if new[v] >= 0}
        out = RefMesh(new[F], self.P[used], sharp, corner, self.rule)
        out.root, out.O, out.X, out.Y = self.root[keep], self.O[keep], self.X[keep], self.Y[keep]
        out.ids = used
        return out

    def rings(self, v: int, count: int) -> np.ndarray:
        """Mask of the faces within ``count`` rings of vertex v (faces sharing a vertex)."""
        verts = np.zeros(len(self.P), bool)
        verts[v] = True
        faces = np.zeros(len(self.F), bool)
        for _ in range(count):
            faces |= verts[self.F].any(axis=1)
            verts[self.F[faces].reshape(-1)] = True
        return faces

    def start(self):
        nf = len(self.F)
        self.root = np.arange(nf)
        self.O = np.zeros((nf, 2))
        self.X = np.tile([1.0, 0.0], (nf, 1))
        self.Y = np.tile([0.0, 1.0], (nf, 1))
        return self

    def exact_limits(self):
        """Limit position of every vertex whose neighbourhood's rules no longer change, NaN
        elsewhere (semi-sharp edges or vertices left, darts, mixed creases)."""
        nv = len(self.P)
        es, vs = self.edge_s(), self.vertex_s()
        semi_e = (es > 0) & (es < INF)
        semi_v = (vs > 0) & (vs < INF)
        touch = np.zeros(nv, bool)
        touch[self.E[semi_e].reshape(-1)] = True
        out = np.full((nv, 3), np.nan)
        inf_e = es >= INF
        count = np.bincount(self.E[inf_e].reshape(-1), minlength=nv)
        ok = ~touch & ~semi_v
        corner = ok & ((vs >= INF) | (count > 2))
        out[corner] = self.P[corner, :3] / self.P[corner, 3:]
        crease = ok & ~corner & (count == 2)
        ends = np.zeros((nv, 4))
        np.add.at(ends, self.E[inf_e, 0], self.P[self.E[inf_e, 1]])
        np.add.at(ends, self.E[inf_e, 1], self.P[self.E[inf_e, 0]])
        Lc = (4 * self.P + ends) / 6
        out[crease] = Lc[crease, :3] / Lc[crease, 3:]
        smooth = ok & ~corner & (count == 0) & ~self.bnd_v
        n = self.val.astype(float)
        nsum = np.zeros((nv, 4))
        np.add.at(nsum, self.E[:, 0], self.P[self.E[:, 1]])
        np.add.at(nsum, self.E[:, 1], self.P[self.E[:, 0]])
        diag = np.zeros((nv, 4))
        for k in range(4):
            np.add.at(diag, self.F[:, k], self.P[self.F[:, (k + 2) % 4]])
        with np.errstate(divide="ignore", invalid="ignore"):
            L = ((n * n)[:, None] * self.P + 4 * nsum + diag) / (n * (n + 5))[:, None]
        out[smooth] = L[smooth, :3] / L[smooth, 3:]
        return out

    def regular_jets(self, count: int = 4000, seed: int = 0):
        """At corner 0 of up to ``count`` random faces whose 3 x 3 control points around it
        are smooth, regular and unsharpened: (faces, P, Ps, Pt, Pss, Pst, Ptt) of the bicubic
        B-spline there, in the face's own parameters."""
        F, nv = self.F, len(self.P)
        es, vs = self.edge_s(), self.vertex_s()
        sharp_v = np.zeros(nv, bool)
        sharp_v[self.E[es > 0].reshape(-1)] = True
        good_v = (~sharp_v) & (vs <= 0) & (self.val == 4) & ~self.bnd_v
        # directed edge a -> b to (face, position of a), by one sorted search
        a = F.reshape(-1).astype(np.int64)
        b = np.roll(F, -1, axis=1).reshape(-1).astype(np.int64)
        keys = a * nv + b
        order = np.argsort(keys)
        skeys = keys[order]

        def across(x, y):                         # the face with directed edge x -> y, and x's place
            i = order[np.searchsorted(skeys, x.astype(np.int64) * nv + y)]
            return i // 4, i % 4

        cand = np.nonzero(good_v[F[:, 0]])[0]
        rng = np.random.default_rng(seed)
        cand = rng.permutation(cand)[:4 * count]
        v0, v1, v2, v3 = F[cand].T
        g, p = across(v0, v3)
        G = F[g]
        gp2, gp3 = G[np.arange(len(g)), (p + 2) % 4], G[np.arange(len(g)), (p + 3) % 4]
        h, r = across(v0, gp3)
        Hh = F[h]
        hr2, hr3 = Hh[np.arange(len(h)), (r + 2) % 4], Hh[np.arange(len(h)), (r + 3) % 4]
        k_, t = across(v0, hr3)
        kt2 = F[k_][np.arange(len(k_)), (t + 2) % 4]
        grid = {(0, 0): v0, (1, 0): v1, (1, 1): v2, (0, 1): v3, (-1, 1): gp2, (-1, 0): gp3,
                (-1, -1): hr2, (0, -1): hr3, (1, -1): kt2}
        ok = np.all([good_v[x] for x in grid.values()], axis=0)
        sel = np.nonzero(ok)[0][:count]
        Q = {key: self.P[x[sel], :3] / self.P[x[sel], 3:] for key, x in grid.items()}
        w = {-1: 1 / 6, 0: 4 / 6, 1: 1 / 6}
        P = sum(w[i] * w[j] * Q[(i, j)] for i in w for j in w)
        Ps = sum(w[j] * (Q[(1, j)] - Q[(-1, j)]) / 2 for j in w)
        Pt = sum(w[i] * (Q[(i, 1)] - Q[(i, -1)]) / 2 for i in w)
        Pss = sum(w[j] * (Q[(1, j)] - 2 * Q[(0, j)] + Q[(-1, j)]) for j in w)
        Ptt = sum(w[i] * (Q[(i, 1)] - 2 * Q[(i, 0)] + Q[(i, -1)]) for i in w)
        Pst = (Q[(1, 1)] - Q[(1, -1)] - Q[(-1, 1)] + Q[(-1, -1)]) / 4
        return cand[sel], P, Ps, Pt, Pss, Pst, Ptt


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
        cage = read_obj(external("opensubdiv", name + ".obj"))
        model = tsplcam.load(external("opensubdiv", name + ".obj"))
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
        cage = read_obj(external("opensubdiv", "catmark_single_crease.obj"))
        model = tsplcam.load(external("opensubdiv", "catmark_single_crease.obj"))
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
        path = external("opensubdiv", "catmark_single_crease.obj")
        model = tsplcam.load(path)
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
        cage = read_obj(external("opensubdiv", "catmark_single_crease.obj"))
        model = tsplcam.load(external("opensubdiv", "catmark_single_crease.obj"))
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


if __name__ == "__main__":
    unittest.main()


class NativeFile(unittest.TestCase):
    def test_creases_round_trip_through_the_native_file(self):
        """A creased cage written as .tspl (version 2: creases and corners) reads back to the
        same surface; write -> read -> write gives the same bytes."""
        from tsplcam.model.formats.native import dumps, read_native
        path = external("opensubdiv", "catmark_single_crease.obj")
        model = tsplcam.load(path)
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
