"""The C travel the cones force (smoothing.forced_rotary_travel) against independent answers:
every state sequence of small random grids enumerated, and walls whose cones leave no tilt
within the other branch's range, where every side change is a C half-turn."""
import importlib.util
import itertools
import os
import unittest
from unittest import mock

import numpy as np

from tsplcam import compiled

from tsplcam.orientation.rotary import DEG, Rotary
from tsplcam.orientation.smoothing import (IN_PLACE, MeridianGrid, cone_halfspaces, forced_rotary_travel,
                                           meridian_grid)


def grid_of(ok, M):
    n = len(ok)
    z = np.zeros((n, M))
    return MeridianGrid(2 * np.pi * np.arange(M) / M, z, z - 1, z + 1, z, ok, z.copy(), np.zeros((n, M), bool))


class AgainstEnumeration(unittest.TestCase):
    def test_random_grids(self):
        """6 points, 8 rotary values, random allowed states, collision status and short
        blocks: the programme's travel equals the least over all 8^6 sequences."""
        rng = np.random.default_rng(5)
        n, M = 6, 8
        phis = 2 * np.pi * np.arange(M) / M
        seqs = np.array(list(itertools.product(range(M), repeat=n)))
        D = np.abs(np.pi - np.mod(np.pi - (phis[None, :] - phis[:, None]), 2 * np.pi))
        steps = D[seqs[:, :-1], seqs[:, 1:]]                       # every sequence's moves, once
        big = steps > IN_PLACE[1] + 1e-9
        for case in range(30):
            ok = rng.random((n, M)) < 0.5
            ok[:, rng.integers(M)] |= rng.random() < 0.3           # sometimes one value always open
            status = np.where(rng.random((n, M)) < 0.2, 2, rng.choice([-1, 0], size=(n, M)))
            ds = np.where(rng.random(n - 1) < 0.3, 0.05, 1.0)     # some blocks shorter than IN_PLACE
            air = rng.random(n) < 0.1
            travel, states = forced_rotary_travel(grid_of(ok, M), status, ds, air=air)
            allowed = ok & (status != 2)
            legal = allowed[np.arange(n)[None, :], seqs].all(axis=1)
            short = (ds < IN_PLACE[0]) & ~air[1:]
            legal &= ~(big & short[None, :]).any(axis=1)
            if not legal.any():
                self.assertTrue(np.isnan(travel), case)
                self.assertIsNone(states)
                continue
            best = steps[legal].sum(axis=1).min()
            self.assertAlmostEqual(travel, best, delta=1e-9, msg=f"case {case}")
            self.assertTrue(allowed[np.arange(n), states].all())


@unittest.skipUnless(importlib.util.find_spec("numba") is not None and os.environ.get("TSPLCAM_COMPILED") != "0",
                     "numba is not installed (the numpy version runs)")
class CompiledRuns(unittest.TestCase):
    def test_runs_in_the_kernel_same_as_blocks(self):
        """With the kernels loaded the programme runs in kind_steps, each move's transition
        read from its kind's matrix (runs of short blocks and of others, longer and shorter
        than a block, air points, states excluded, chains that break): the same travel and
        states as the numpy loop over the gathered blocks."""
        self.assertIsNotNone(compiled.kernels())
        rng = np.random.default_rng(9)
        broke = 0
        for case in range(25):
            n, M = int(rng.integers(2, 200)), int(rng.choice([8, 36]))
            ok = rng.random((n, M)) < rng.uniform(0.3, 1.0)
            status = np.where(rng.random((n, M)) < 0.1, 2, -1)
            runs = np.repeat(rng.random(n) < 0.5, rng.integers(1, 70, n))[:n - 1]
            ds = np.where(runs, 0.05, 1.0)
            air = rng.random(n) < 0.05
            got = forced_rotary_travel(grid_of(ok, M), status, ds, air=air)
            with mock.patch.dict(compiled._STATE, {"k": None}):
                want = forced_rotary_travel(grid_of(ok, M), status, ds, air=air)
            if want[1] is None:
                broke += 1
                self.assertTrue(np.isnan(got[0]) and got[1] is None, case)
                continue
            self.assertEqual(got[0], want[0], case)
            np.testing.assert_array_equal(got[1], want[1])
        self.assertGreater(broke, 0)
        self.assertLess(broke, 25)


class Walls(unittest.TestCase):
    def test_every_side_change_is_a_half_turn(self):
        """Vertical walls facing +x and -x in turn (a tool crossing a cavity's floor from one
        wall to the other) with the feed along the wall, lead within 15 degrees and side tilt
        within 60: the axis must lean at least 30 degrees into the open side, within 15
        degrees of the wall's normal, and the other branch reaches only 25 degrees of tilt,
        so the lean direction is C itself: on the 10-degree grid -10..10 degrees off the
        normal, each change of side costs 160 degrees of C, and nothing else is forced."""
        sides = np.array([1, 1, 1, -1, -1, 1, 1, -1, -1, -1, 1])
        n = len(sides)
        normal = np.column_stack([sides, np.zeros(n), np.zeros(n)]).astype(float)
        feed = np.tile([0.0, 1.0, 0.0], (n, 1))
        cons = [(h, np.zeros(n)) for h in cone_halfspaces(normal, feed, 15 * DEG, 60 * DEG)]
        rot = Rotary(about="X", theta_lo=-25 * DEG, theta_hi=115 * DEG)
        pref = np.tile([0.0, 0.0, 1.0], (n, 1))
        grid = meridian_grid(rot, pref, normal, cons, 36)
        status = np.where(grid.ok, -1, 2)
        travel, states = forced_rotary_travel(grid, status, np.ones(n - 1))
        changes = int(np.count_nonzero(sides[1:] != sides[:-1]))
        self.assertAlmostEqual(travel / DEG, 160.0 * changes, delta=1e-9)
        # with the whole tilt range on both branches, the tilt's sign changes side: no C at all
        rot2 = Rotary(about="X", theta_lo=-115 * DEG, theta_hi=115 * DEG)
        grid2 = meridian_grid(rot2, pref, normal, cons, 36)
        travel2, _ = forced_rotary_travel(grid2, np.where(grid2.ok, -1, 2), np.ones(n - 1))
        self.assertAlmostEqual(travel2, 0.0, delta=1e-12)


if __name__ == "__main__":
    unittest.main()
