"""cubic_points: patches of bicubic cells evaluated point by point in one pass.

Against the patch's group-by-group route (``Patch._evaluate_h``: Bezier cells by BLAS
products run by run, extraordinary cells from their nets, deep points by their level's
configuration; test_ep_nets checks that route against the configuration of every level): the
same surface to rounding, 1e-12 of the size of the derivatives of each order at the point (or
of a hundredth of its median, where they vanish). And the claim the
module makes: the compiled kernel and its numpy route give the same bits (each point one
fixed sequence of operations), so a program does not depend on whether numba is there.
Patches: the keycap's (polynomial Bezier and extraordinary cells), figure4's (extraordinary
cells whose subdivided weights are 1 only to rounding: the homogeneous route), rational
Bezier cells (and weights 0 for the bits: numpy's division by zero, not numba's error); points random, crowded to the corners, on cell breaks, within 2^-20 .. 2^-40
of a corner (past the cached nets' levels) and on the corners."""
import unittest
from unittest import mock

import numpy as np

import tsplcam
from tsplcam import compiled
from tsplcam.model import cubic_points
from tsplcam.model.cells import BezierCells
from tsplcam.model.patch import Patch
from test_grid_points import rational_patch

REL = 1e-12


def points(patch, rng, n=1500):
    u, v = rng.random(n), rng.random(n)
    u[:300], v[:300] = rng.random(300) ** 8, rng.random(300) ** 8
    u[300:400], v[300:400] = 1 - rng.random(100) ** 8, rng.random(100) ** 12
    deep = np.ldexp(1.0, -rng.integers(20, 41, 40))
    u[400:440], v[400:440] = deep, deep[::-1]
    u[440:460] = patch.ubreaks[rng.integers(0, len(patch.ubreaks), 20)]
    v[460:480] = patch.vbreaks[rng.integers(0, len(patch.vbreaks), 20)]
    c = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    u[480:484], v[480:484] = c[:, 0], c[:, 1]
    return u, v


def patches():
    rng = np.random.default_rng(7)
    yield from ((f"keycap {p.index}", p) for p in tsplcam.load_model("keycap").patches)
    yield from ((f"figure4 {p.index}", p) for p in tsplcam.load_model("figure4").patches[:3])
    yield "rational", rational_patch(rng)
    # weights 0 (a patch assembled before its cells are filled in): numpy's x / 0, inf and nan
    zero = rational_patch(rng)
    zero.groups[0].ctrl[:] = 0.0
    zero.groups[0]._cj[:] = 0.0
    zero._cubic = None
    yield "weight 0", zero
    # a polynomial cell 1e-170 wide: its second derivatives' widths (1e-340) underflow to 0,
    # which the kernel's written-out route for polynomial cells leaves to its generic loop
    ctrl = np.empty((2, 4, 4, 4))
    j, i = np.meshgrid(np.arange(4), np.arange(4), indexing="ij")
    for c in range(2):
        ctrl[c] = np.stack([i + 3.0 * c, j, rng.random((4, 4)), np.ones((4, 4))], axis=-1)
    yield "tiny cell", Patch(0, [0.0, 1e-170, 1.0], [0.0, 1.0], np.zeros((2, 1), int), np.array([[0], [1]]),
                             [BezierCells(ctrl)])


class CubicPoints(unittest.TestCase):

    def test_same_surface_as_the_group_route(self):
        rng = np.random.default_rng(1)
        kinds = set()
        for name, patch in patches():
            if name in ("weight 0", "tiny cell"):       # (inf and nan: the bits test's)
                continue
            table = patch._cubic_table()
            self.assertIsNotNone(table, name)
            kinds.add(table.nets.shape[1])
            u, v = points(patch, rng)
            for nd in (6, 3):
                H, ep = cubic_points.evaluate_points(table, u, v, nd)
                order, R, ep0 = patch._evaluate_h(u, v)
                inv = np.arange(len(u)) if order is None else np.argsort(order)
                if R.shape[1] == 4 and not table.nets.shape[1] == 3:
                    from tsplcam.model.diffgeom import rational_from_homogeneous
                    R = np.stack(rational_from_homogeneous(R))
                R = R[:nd, :3].take(inv, axis=2)
                for rows in ((0,), (1, 2), (3, 4, 5))[:2 if nd == 3 else 3]:
                    # of the derivatives' size of that order at the point, or of a hundredth
                    # of its median where they vanish (ruled stretches: 1e-14 there)
                    norm = np.max([np.linalg.norm(R[k], axis=0) for k in rows], axis=0)
                    size = np.maximum(norm, 0.01 * np.median(norm))
                    err = np.max([np.linalg.norm(H[k] - R[k], axis=0) for k in rows], axis=0) / size
                    self.assertLess(err.max(), REL, (name, nd, rows))
                rows0 = np.sort(ep0[0] if order is None else order[ep0[0]]) if ep0 is not None else np.zeros(0, int)
                rows = ep[0] if ep is not None else np.zeros(0, int)
                np.testing.assert_array_equal(np.sort(rows), rows0, err_msg=name)
        self.assertEqual(kinds, {3, 4})          # both the polynomial and the homogeneous route

    def test_kernel_and_numpy_route_same_bits(self):
        if compiled.kernels() is None:
            self.skipTest("no compiled kernels (numba absent or TSPLCAM_COMPILED=0)")
        rng = np.random.default_rng(2)
        for name, patch in patches():
            table = patch._cubic_table()
            u, v = points(patch, rng)
            for nd in (6, 3):
                H, ep = cubic_points.evaluate_points(table, u, v, nd)
                with mock.patch.object(compiled, "kernels", lambda work=None: None), np.errstate(all="ignore"):
                    H0, ep0 = cubic_points.evaluate_points(table, u, v, nd)
                self.assertTrue(np.array_equal(H, H0, equal_nan=True), (name, nd))   # bits, not closeness
                self.assertTrue(np.array_equal(np.signbit(H) | np.isnan(H), np.signbit(H0) | np.isnan(H0)),
                                (name, nd))                                          # (0.0 and -0.0)
                self.assertEqual(ep is None, ep0 is None, name)
                if ep is not None:
                    self.assertTrue(np.array_equal(ep[0], ep0[0]) and np.array_equal(ep[1], ep0[1]), name)

    def test_numpy_route_in_passes(self):
        """More points than one numpy pass: the same values as pass by pass."""
        patch = tsplcam.load_model("keycap").patches[4]
        table = patch._cubic_table()
        u, v = points(patch, np.random.default_rng(3), 2 * cubic_points.NUMPY_POINTS + 5)
        with mock.patch.object(compiled, "kernels", lambda work=None: None):
            H, _ = cubic_points.evaluate_points(table, u, v)
            H1, _ = cubic_points.evaluate_points(table, u[-5:], v[-5:])
        self.assertTrue(np.array_equal(H[:, :, -5:], H1))


if __name__ == "__main__":
    unittest.main()
