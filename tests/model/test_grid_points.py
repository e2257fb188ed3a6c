"""Patch.grid_points and grids_points (the collision checker's tessellation route: positions alone)
and Patch.evaluate_grid without second derivatives (the verification's grid) against
Patch.evaluate_grid's P, first derivatives and normals. The claim is not closeness but the
same values bit for bit, since the tessellation's triangles and measured error feed the
collision margins and the program bytes: a patch of bicubic cells gives each grid point as
Patch.evaluate gives it (point by point, whatever else is asked with it; evaluate_grid's BLAS
products round otherwise, within 1e-15 of the part's size), any other patch evaluate_grid's P
(the same products on the same arrays, LevelCells point by point). Grids: uniform, on the cell
breaks, within 2^-30 of a cell's corner (below the cached nets' levels), unsorted (blocks that
are not one run); cells: polynomial and rational Bezier, Catmull-Clark cells next to
extraordinary points (LevelCells), T-spline star cells."""
import unittest

import numpy as np

from tsplcam.model import samples
from tsplcam.model.cage import cage_model
from tsplcam.model.cells import BezierCells
from tsplcam.model.patch import Patch
from tsplcam.model.tspline import tspline_model
from tsplcam.orientation import collision
from tsplcam.orientation.collision import tessellate_patch
from test_stars import random_intervals, star_disc


def grids(patch, rng):
    """(us, vs) pairs that take every route of grid_points."""
    deep = np.ldexp(1.0, -30)
    yield np.linspace(0, 1, 23), np.linspace(0, 1, 17)
    yield patch.ubreaks, patch.vbreaks
    yield (np.sort(np.concatenate([patch.ubreaks[:-1] + deep, patch.ubreaks[1:] - deep, [0.0, 1.0]])),
           np.sort(np.concatenate([patch.vbreaks[:-1] + deep, patch.vbreaks[1:] - deep, [0.0, 1.0]])))
    yield rng.permutation(np.linspace(0, 1, 11)), rng.random(7)


def rational_patch(rng) -> Patch:
    """Two rational bicubic Bezier cells side by side (random weights)."""
    ctrl = np.empty((2, 4, 4, 4))
    j, i = np.meshgrid(np.arange(4), np.arange(4), indexing="ij")
    for c in range(2):
        w = rng.uniform(0.5, 2.0, (4, 4))
        xyz = np.stack([i + 3 * c, j, rng.random((4, 4))], axis=-1)
        ctrl[c] = np.concatenate([xyz * w[..., None], w[..., None]], axis=-1)
    return Patch(0, [0.0, 0.5, 1.0], [0.0, 1.0], np.zeros((2, 1), int), np.array([[0], [1]]),
                 [BezierCells(ctrl)])


class GridPoints(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.keycap = cage_model(samples.keycap())

    def check(self, patches, seed=0):
        rng = np.random.default_rng(seed)
        for patch in patches:
            points = patch._cubic_table() is not None
            for us, vs in grids(patch, rng):
                got = patch.grid_points(us, vs)
                full = patch.evaluate_grid(us, vs)
                self.assertEqual(got.shape, (len(us) * len(vs), 3))
                where = f"{patch.name}: {len(us)} x {len(vs)}"
                if points:
                    U, V = np.meshgrid(us, vs, indexing="ij")
                    np.testing.assert_array_equal(got, patch.evaluate(U.ravel(), V.ravel(), second=False).P,
                                                  err_msg=where)
                    size = np.abs(full.P).max()
                    np.testing.assert_allclose(got, full.P, rtol=0, atol=1e-14 * size, err_msg=where)
                else:
                    np.testing.assert_array_equal(got, full.P, err_msg=where)
                # without the second derivatives (the verification's grid): the rest the same
                first = patch.evaluate_grid(us, vs, second=False)
                self.assertIsNone(first.Puu)
                for k in ("P", "Pu", "Pv", "normal", "u", "v"):
                    np.testing.assert_array_equal(getattr(first, k), getattr(full, k), err_msg=f"{patch.name} {k}")
            # several grids at once: their extraordinary cells together (the first three), or
            # grid by grid when one has points next to a cell's corner (all four)
            every = list(grids(patch, np.random.default_rng(seed)))
            for some in (every[:2] + every[3:], every):
                for (us, vs), got in zip(some, patch.grids_points(some)):
                    np.testing.assert_array_equal(got, patch.grid_points(us, vs), err_msg=patch.name)

    def test_keycap_bezier_and_extraordinary_cells(self):
        self.check([self.keycap.patches[0], self.keycap.patches[4]])     # 2 and 4 such cells

    def test_rational_bezier_cells(self):
        self.check([rational_patch(np.random.default_rng(1))])

    def test_tspline_star_cells(self):
        model = tspline_model(star_disc(3, random_intervals(3, 3, k=2)))
        self.check(model.patches[:1])

    def test_bad_grid_is_refused_naming_the_patch(self):
        patch = rational_patch(np.random.default_rng(2))
        with self.assertRaisesRegex(Exception, "patch 0"):
            patch.grid_points([0.0, 1.5], [0.5])

    def test_tessellation_uv_is_the_grid(self):
        """tessellate_patch's (u, v) per vertex: the grid in evaluate_grid's row order."""
        patch = self.keycap.patches[0]
        V, T, uv, err = tessellate_patch(patch, 0.05)
        self.assertEqual(len(uv), len(V))
        np.testing.assert_allclose(patch.evaluate(uv[:, 0], uv[:, 1]).P, V, atol=1e-9, rtol=0)
        self.assertLessEqual(err, 0.05)

    def test_coarse_first_grid_skips_only_what_cannot_change_the_grid(self):
        """A first grid whose edge errors alone give the factor's cap is refined without its
        cells' points measured: the kept grid, its points and measured error are those of the
        full measurement on every grid (exact: the same grids evaluated by the same calls).
        ``_capped_error`` is the least error the factor's formula caps, in floats."""
        for tol in (0.005, 0.0123):
            e = collision._capped_error(tol)
            self.assertGreaterEqual(1.1 * np.sqrt(e / tol), 4.0)
            self.assertLess(1.1 * np.sqrt(np.nextafter(e, 0.0) / tol), 4.0)
        patch = self.keycap.patches[4]
        full = collision._patch_grid_error
        try:
            collision._patch_grid_error = lambda p, gu, gv, coarse=np.inf: full(p, gu, gv)
            ref = tessellate_patch(patch, 0.005)
        finally:
            collision._patch_grid_error = full
        new = tessellate_patch(patch, 0.005)
        for a, b in zip(ref, new):
            self.assertTrue(np.array_equal(a, b))


if __name__ == "__main__":
    unittest.main()


class PointByPoint(unittest.TestCase):
    """Patch.evaluate gives a point the same values whatever else is in the call: alone, twice,
    or among others (a cell's points are contracted in one BLAS product, and numpy hands a
    one-column product to gemv, which rounds otherwise than gemm: a point alone in its cell
    is computed as a two-column product). The verification's ridges and the line placement's
    batched trials rely on it."""

    def test_alone_or_among_others(self):
        rng = np.random.default_rng(5)
        keycap = cage_model(samples.keycap())
        star = tspline_model(star_disc(5, random_intervals(5, 5)))
        for patch in list(keycap.patches) + [rational_patch(rng)] + list(star.patches)[:3]:
            uv = rng.random((40, 2))
            others = rng.random((40, 7, 2))
            for (u, v), o in zip(uv, others):
                one = patch.evaluate(np.array([u]), np.array([v]))
                among = patch.evaluate(np.append(o[:3, 0], [u, *o[3:, 0]]), np.append(o[:3, 1], [v, *o[3:, 1]]))
                for k in ("P", "Pu", "Pv", "Puu", "Puv", "Pvv", "normal"):
                    np.testing.assert_array_equal(getattr(one, k)[0], getattr(among, k)[3],
                                                  err_msg=f"{patch.name} {k} at ({u}, {v})")
