"""Cells next to extraordinary points evaluated from cached Bezier nets of their regular
sub-patches (cells.LevelCells, stars.StarLevels) against the configuration of every point's
level (``evaluate_levels``, the route the nets are built from): positions, first and second
derivatives, normals, on the keycap sample and on the star models of valence 3 to 8 of
test_stars.py, at random points of every such cell and at points 2^-1 .. 2^-45 of a cell from
each corner (beyond the cached levels too) and on the corners themselves."""
import unittest
from unittest import mock

import numpy as np

import tsplcam
from tsplcam.model.cells import LevelCells
from tsplcam.model.patch import Patch
from tsplcam.model.stars import StarLevels, SumCells
from tsplcam.model.tmesh import quad_tmesh
from tsplcam.model.tspline import tspline_model
from test_stars import non_uniform_disc, uniform_prism

REL = 1e-12          # positions: of the model size; derivatives: of their own size at the point
# second derivatives of a star's part: the two routes sum the same terms in another order, and
# in a sub-cell 3 % of its face wide (next to the valence-7 star) the terms are (1/0.03)^2 times
# the derivative they sum to: 9e-12 there, below 3e-13 elsewhere
STAR_SECOND = 3e-11
CORNERS = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])


def ep_cell_points(patch, rng, count=24):
    """(u, v) in every cell of ``patch`` next to an extraordinary point: random, near each
    corner at distances 2^-1, 2^-3 .. 2^-45 of the cell, and on the corners."""
    kinds = (LevelCells, SumCells)
    cells = [(i, j) for i in range(patch.shape[0]) for j in range(patch.shape[1])
             if isinstance(patch.groups[patch.cell_group[i, j]], kinds)]
    ab = [rng.random((count, 2))]
    for c in CORNERS:
        r = np.ldexp(rng.random((23, 2)), -np.arange(1, 46, 2)[:, None])
        ab.append(np.abs(c - r))
    ab.append(CORNERS)
    ab = np.concatenate(ab)
    u, v = [], []
    for i, j in cells:
        wu, wv = patch.ubreaks[i + 1] - patch.ubreaks[i], patch.vbreaks[j + 1] - patch.vbreaks[j]
        u.append(patch.ubreaks[i] + ab[:, 0] * wu)
        v.append(patch.vbreaks[j] + ab[:, 1] * wv)
    return (np.concatenate(u), np.concatenate(v)) if cells else (None, None)


def by_levels():
    """Both evaluators routed through the configuration of every point's level (a patch of
    bicubic cells then takes its group-by-group route, not cubic_points' one pass)."""
    return (mock.patch.object(LevelCells, "evaluate", LevelCells.evaluate_levels),
            mock.patch.object(StarLevels, "evaluate", StarLevels.evaluate_levels),
            mock.patch.object(Patch, "_cubic_table", lambda self: None))


def star_calls(patch, u, v):
    """The patch's evaluation at (u, v) and the (star, sector, x, y, what it returned) that
    evaluation hands to its stars' subdivided parts."""
    calls = []
    nets = StarLevels.evaluate

    def spy(self, sector, x, y):
        out = nets(self, sector, x, y)
        calls.append((self, sector.copy(), x.copy(), y.copy(), tuple(np.copy(r) for r in out)))
        return out
    with mock.patch.object(StarLevels, "evaluate", spy):
        return patch.evaluate(u, v), calls


def relative(H, ref, floor):
    """Largest difference of homogeneous derivatives (6, 4, n) per derivative order (value,
    first, second) over the size of the reference's derivatives of that order at the point,
    or ``floor`` where they are smaller (where the star's part vanishes)."""
    out = []
    for rows in ((0,), (1, 2), (3, 4, 5)):
        size = np.max([np.linalg.norm(ref[k], axis=0) for k in rows], axis=0)
        err = np.max([np.linalg.norm(H[k] - ref[k], axis=0) for k in rows], axis=0)
        out.append((err / np.maximum(size, floor)).max())
    return out


class CachedNetsEqualLevels(unittest.TestCase):

    def check(self, model, label, seed=0, patches=None):
        """Every cell next to an extraordinary point. Cage cells: the patch's derivatives.
        Star cells add a Bezier part and the star's part whose second derivatives grow like
        4^level and cancel in the sum (1e8 against 13 at 2^-22 of a cell next to a star of
        valence 7): there the star's part itself is compared, and the patch's positions.
        ``patches``: the first so many patches with such cells (time)."""
        rng = np.random.default_rng(seed)
        scale = max(np.abs(p.evaluate_grid(np.linspace(0, 1, 5), np.linspace(0, 1, 5)).P).max()
                    for p in model.patches)
        checked = done = 0
        for patch in model.patches:
            u, v = ep_cell_points(patch, rng)
            if u is None or done == patches:
                continue
            done += 1
            a, calls = star_calls(patch, u, v)       # the cached nets' route, its star calls seen
            m1, m2, m3 = by_levels()
            with m1, m2, m3:
                b = patch.evaluate(u, v)
            checked += len(u)
            self.assertLess(np.abs(a.P - b.P).max(), REL * scale, (label, patch.index))
            if not calls:
                for ks in (("Pu", "Pv"), ("Puu", "Puv", "Pvv")):
                    size = np.max([np.linalg.norm(getattr(b, k), axis=1) for k in ks], axis=0)
                    err = np.max([np.linalg.norm(getattr(a, k) - getattr(b, k), axis=1) for k in ks], axis=0)
                    self.assertLess((err / np.maximum(size, 1e-300)).max(), REL, (label, patch.index, ks))
                self.assertLess(np.abs(a.normal - b.normal).max(), 1e-12, (label, patch.index))
            for star, sector, x, y, (H, at) in calls:
                H0, at0 = star.evaluate_levels(sector, x, y)
                np.testing.assert_array_equal(at, at0)
                for order, err in enumerate(relative(H, H0, np.linalg.norm(star.limit))):
                    self.assertLess(err, STAR_SECOND if order == 2 else REL, (label, patch.index, order))
        self.assertGreater(checked, 0, label)

    def test_keycap(self):
        self.check(tsplcam.load_model("keycap"), "keycap")

    def test_rounded_off_the_cell_at_the_vertex(self):
        """(a, b) a rounding outside the cell at its irregular corner: the vertex itself, by
        both routes (the patch clamps u, v, not the cell's a, b)."""
        model = tsplcam.load_model("keycap")
        for group in {id(g): g for p in model.patches for g in p.groups if isinstance(g, LevelCells)}.values():
            idx = np.repeat(np.arange(len(group)), 3)
            corner = group._corner[:, idx]
            off = np.tile([0.0, 2e-16, -2e-16], len(group))
            a, b = corner[0] + np.where(corner[0] > 0, off, -off), corner[1] + np.where(corner[1] > 0, off, -off)
            H, at, nrm = group.evaluate(idx, a, b)
            H0, at0, nrm0 = group.evaluate_levels(idx, a, b)
            np.testing.assert_array_equal(at, at0)
            self.assertTrue(at[::3].all() and at[1::3].all())
            np.testing.assert_array_equal(H[:, :, at], H0[:, :, at])
            np.testing.assert_array_equal(nrm, nrm0)

    def test_catmull_clark_and_uniform_stars(self):
        """test_stars' prisms of valence 3, 5, 6, 8: the cage (LevelCells) and the T-spline
        with uniform intervals (StarLevels)."""
        for n in (3, 5, 6, 8):
            _, _, uniform, cage = uniform_prism(n)          # (built once for test_stars too)
            self.check(cage, f"cage {n}", n)
            self.check(uniform, f"uniform {n}", n, patches=8)

    def test_non_uniform_and_rational_stars(self):
        rng = np.random.default_rng(12)
        for n in (3, 5, 6, 7, 8):
            mesh, model = non_uniform_disc(n)                # (built once for test_stars too)
            self.check(model, f"non-uniform {n}", n)
            mesh = mesh.copy()
            mesh.weights = rng.uniform(0.5, 2.0, mesh.n_vertices)
            self.check(tspline_model(mesh), f"rational {n}", n)

    def test_head_sample(self):
        from tsplcam.model import samples
        cage = samples.head(5)
        self.check(tspline_model(quad_tmesh(cage.points, cage.mesh.faces)), "head")


class SameWhateverTheBlas(unittest.TestCase):
    """What must not depend on the rounding of the BLAS's sums (OpenBLAS picks its kernels by
    processor): a polynomial cage's cells next to extraordinary points have weights exactly 1
    and weight derivatives exactly 0 (with its Haswell kernels the keycap's limit weight came
    out 1 - 2^-53, its vertex's weight derivatives 0.022, and no patch of the keycap evaluated
    as polynomial; with its SkylakeX kernels all five), and the tangent masks of a defective
    eigenvalue (test_boundary_stars)."""

    def test_limit_mask_off_by_an_ulp(self):
        """A limit mask summing to 1 +- an ulp (as another kernel's sums may) still gives a
        polynomial configuration the weight 1 and weight differences 0, exactly; a rational
        one's weights are computed as they are."""
        model = tsplcam.load_model("keycap")
        group = next(g for g in model.patches[0].groups if isinstance(g, LevelCells))
        scheme = group.scheme
        C0 = np.column_stack([np.random.default_rng(3).normal(size=(scheme.K, 3)), np.ones(scheme.K)])
        mask = scheme.limit_mask
        for off in (np.finfo(float).eps, -np.finfo(float).eps / 2):
            scheme.limit_mask = mask * (1.0 + off)              # a sum 1 +- an ulp, as another BLAS's
            try:
                L, d = scheme.levels(C0, 8)
            finally:
                scheme.limit_mask = mask
            self.assertEqual(L[3], 1.0)
            self.assertTrue(np.all(d[..., 3] == 0.0))
            self.assertLess(np.abs(L[:3] - mask @ C0[:, :3]).max(), 1e-14)
        rational = C0.copy()
        rational[0, 3] = 1.5                                    # a weight not 1: computed as it is
        L, d = scheme.levels(rational, 2)
        self.assertEqual(L[3], mask @ rational[:, 3])

    def test_refined_weights_stay_one(self):
        """A refinement of a polynomial cage keeps its weights exactly 1 (its rows sum to 1:
        computed, the sums leave 1 - 1e-16 here and there); a rational cage's are R's."""
        from tsplcam.model.quadmesh import QuadMesh, refined_points
        mesh = QuadMesh(np.array([[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]]), 9)
        child, R, _ = mesh.refine()
        rng = np.random.default_rng(5)
        H = np.column_stack([rng.normal(size=(9, 3)) * 10.0, np.ones(9)])
        out = refined_points(R, H)
        self.assertTrue(np.all(out[:, 3] == 1.0))
        self.assertEqual(np.abs(out[:, :3] - R @ H[:, :3]).max(), 0.0)
        H[0, 3] = 1.5
        self.assertEqual(np.abs(refined_points(R, H) - R @ H).max(), 0.0)

    def test_the_same_with_every_kernel(self):
        """With the BLAS kernels this processor runs (OPENBLAS_CORETYPE: Prescott, SSE3 only,
        with numpy's own SIMD loops off too, as on an old processor; Haswell with AVX2;
        SkylakeX with AVX-512; each in a process of its own, as both are read when the
        libraries load): the samples' patches evaluate as polynomial (keycap 5 of 5, figure4
        12 of 12, the Fusion mold 32 of 32, whose cage is refined once first), and the
        four-face boundary star's defective eigenvalue 0.5 gives its tangent mask to the
        rounding (eigvals splits it along the real axis or across it by the kernel: Haswell
        0.5 +- 1e-8, Prescott 0.5 +- 4e-9 i, which once gave normals 90 deg off), so every
        patch there has one normal."""
        import json
        import os
        import subprocess
        import sys
        import tempfile
        if not os.path.exists("/proc/cpuinfo") or os.uname().machine != "x86_64":
            self.skipTest("OpenBLAS's x86-64 kernels only")
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            flags = fh.read()
        old = "SSSE3 SSE41 POPCNT SSE42 AVX F16C FMA3 AVX2 AVX512F AVX512CD AVX512_SKX AVX512_CLX " \
              "AVX512_CNL AVX512_ICL"
        kinds = [("Prescott", {"NPY_DISABLE_CPU_FEATURES": old})]
        kinds += [(k, {}) for k, flag in (("Haswell", " avx2"), ("SkylakeX", " avx512f")) if flag in flags]
        here = os.path.dirname(os.path.abspath(__file__))
        root = os.path.dirname(os.path.dirname(here))
        code = """if True:
            import json, sys
            import numpy as np
            import tsplcam
            from tsplcam.model import eigen
            sys.path[:0] = [sys.argv[1], sys.argv[2]]
            import test_boundary_stars as B
            counts = [sum(p._polynomial() for p in tsplcam.load_model(m).patches)
                      for m in ("keycap", "figure4", "fusion_mold")]
            path = sys.argv[3] + "/book4.tsm"
            B.write_fusion_tsm(B.book(4)[0], path, grip_map=True)
            model = B.tsm_model(path)
            s = next(s for s in eigen._SCHEMES.values() if s.label.startswith("boundary vertex of 4 faces"))
            m = s.tangent_masks[1]
            normals = B.star_normals(model)
            spread = max(float(np.linalg.norm(np.cross(n, normals[0]))) for n in normals)
            print(json.dumps([counts, float(m @ s.A @ m / (m @ m)), spread]))
        """
        for kind, extra in kinds:
            env = dict(os.environ, OPENBLAS_CORETYPE=kind, PYTHONPATH=root, **extra)
            with tempfile.TemporaryDirectory() as tmp:
                out = subprocess.run([sys.executable, "-c", code, here, os.path.dirname(here), tmp], env=env,
                                     capture_output=True, text=True, cwd=root)
            self.assertEqual(out.returncode, 0, (kind, out.stderr[-2000:]))
            counts, lam, spread = json.loads(out.stdout.strip().splitlines()[-1])
            self.assertEqual(counts, [5, 12, 32], kind)
            self.assertLess(abs(lam - 0.5), 1e-13, kind)
            self.assertLess(spread, 1e-12, kind)


if __name__ == "__main__":
    unittest.main()
