"""The compiled kernels (tsplcam.compiled, numba) against their references: the Viterbi
kernel against the numpy loop and against enumerating every sequence, the banded solve
against scipy's ``solveh_banded`` (LAPACK), on random problems with ties and forbidden
states, and on every problem the keycap main job poses them; the distance grids' read
against its numpy version, bit for bit."""
import importlib.util
import itertools
import os
import tempfile
import unittest
from unittest import mock

import numpy as np
from scipy.linalg import solveh_banded

from tsplcam import compiled
from tsplcam.orientation import smoothing
from tsplcam.orientation.smoothing import _Banded
from tsplcam.orientation.viterbi import TIE, from_blocks, viterbi
from tsplcam.orientation.warmup import exercise

def needs_numba(cls):
    """Skip without numba (the numpy versions run); else the kernels loaded for the class."""
    if importlib.util.find_spec("numba") is None or os.environ.get("TSPLCAM_COMPILED") == "0":
        return unittest.skip("numba is not installed (the numpy versions run)")(cls)
    cls.setUpClass = classmethod(lambda c: compiled.kernels())
    return cls


def same_result(test, node, trans, msg=""):
    """The compiled and numpy Viterbi: the same states (and so the same cost, to the bit)
    and the same break point."""
    a, ba = viterbi(node, trans, kernel=False)
    b, bb = viterbi(node, trans, kernel=True)
    test.assertEqual(ba, bb, msg)
    test.assertEqual(a is None, b is None, msg)
    if a is not None:
        np.testing.assert_array_equal(a, b, err_msg=msg)
    return b, bb


def backward_error(ab, rhs, x):
    """Componentwise relative backward error of x for H x = rhs (H in upper band form
    ``ab``): max |H x - rhs| / (|H| |x| + |rhs|), the relative change of H and rhs that makes
    x exact. A backward-stable solver gives a few machine epsilons whatever H's condition."""
    u = ab.shape[0] - 1

    def matvec(band, v):
        y = band[u] * v
        for k in range(1, u + 1):
            y[:-k] += band[u - k, k:] * v[k:]
            y[k:] += band[u - k, k:] * v[:-k]
        return y

    scale = matvec(np.abs(ab), np.abs(x)) + np.abs(rhs)
    return float((np.abs(matvec(ab, x) - rhs) / np.where(scale > 0, scale, 1.0)).max())


def chain_cost(node, trans, s):
    n = len(s)
    return sum(node[i, s[i]] for i in range(n)) + sum(trans[i, s[i], s[i + 1]] for i in range(n - 1))


def least_chain_cost(node, trans):
    """The least chain_cost over every sequence of states (all S^n of them, enumerated as one
    array; each cost summed in chain_cost's order: the node terms, then the moves)."""
    n, S = node.shape
    seq = np.array(list(itertools.product(range(S), repeat=n)), np.int64).reshape(-1, n)
    at = np.arange(n)
    cost = np.zeros(len(seq))
    for i in at:
        cost = cost + node[i, seq[:, i]]
    moves = np.zeros(len(seq))
    for i in at[:-1]:
        moves = moves + trans[i, seq[:, i], seq[:, i + 1]]
    return float((cost + moves).min())


@needs_numba
class CompiledViterbi(unittest.TestCase):
    def test_random_with_ties_and_forbidden(self):
        """Small integer costs (many exact ties, which the lowest state wins), costs equal up
        to a few ulps (within the relative TIE: also the lowest state), ``inf`` states and
        moves, broken chains: the kernel's states and break points are the numpy loop's, and
        where a chain exists its cost is the least over every sequence (enumerated; equal
        within TIE relative, the tolerance that decides ties)."""
        rng = np.random.default_rng(11)
        broken = 0
        for trial in range(400):
            n, S = int(rng.integers(1, 6)), int(rng.integers(3, 6))
            node = rng.integers(0, 3, (n, S)).astype(float)
            trans = rng.integers(0, 3, (max(n - 1, 0), S, S)).astype(float)
            if trial % 3 == 1:                   # near-ties: a few ulps apart
                node = node * (1.0 + 1e-15 * rng.integers(-4, 5, node.shape))
                trans = trans * (1.0 + 1e-15 * rng.integers(-4, 5, trans.shape))
            node[rng.random(node.shape) < 0.2] = np.inf
            trans[rng.random(trans.shape) < 0.3] = np.inf
            states, broke = same_result(self, node, trans, f"trial {trial}")
            for form in (lambda i: trans[i - 1], from_blocks(lambda i0, i1: trans[i0 - 1:i1 - 1])):
                if n > 1:
                    s2, b2 = viterbi(node, form)
                    self.assertEqual(b2, broke)
                    if states is not None:
                        np.testing.assert_array_equal(s2, states)
            best = least_chain_cost(node, trans)
            if states is None:
                self.assertEqual(best, np.inf, f"trial {trial}")
                broken += 1
            else:
                got = chain_cost(node, trans, states)
                self.assertLessEqual(abs(got - best), TIE * max(1.0, abs(best)) * n, f"trial {trial}")
        self.assertGreater(broken, 5)               # the break points were exercised

    def test_two_states(self):
        """Two states (the post's branch choice): the kernel's states and break points are
        the plain-float loop's (_two_states), with exact ties, near-ties within TIE, large
        costs (the relative tie), ``inf`` states and moves, broken chains."""
        rng = np.random.default_rng(12)
        broken = 0
        for trial in range(300):
            n = int(rng.integers(1, 40))
            node = rng.integers(0, 3, (n, 2)) * 10.0 ** rng.integers(0, 12)
            trans = rng.integers(0, 3, (max(n - 1, 0), 2, 2)).astype(float)
            if trial % 2:
                node = node * (1.0 + 1e-15 * rng.integers(-4, 5, node.shape))
                trans = trans * (1.0 + 1e-12 * rng.integers(-4, 5, trans.shape))
            node[rng.random(node.shape) < 0.1] = np.inf
            trans[rng.random(trans.shape) < 0.1] = np.inf
            states, broke = same_result(self, node, trans, f"trial {trial}")
            broken += states is None
        self.assertGreater(broken, 5)

    def test_large_random(self):
        """The joint programme's size (36 states, 3000 points, blocks fetched from a function
        as there), continuous costs with forbidden moves."""
        rng = np.random.default_rng(3)
        n, S = 3000, 36
        node = rng.random((n, S))
        node[rng.random(node.shape) < 0.1] = np.inf
        trans = rng.random((n - 1, S, S)) * 10.0
        trans[rng.random(trans.shape) < 0.5] = np.inf
        states, broke = same_result(self, node, trans)
        self.assertIsNone(broke)
        b, _ = viterbi(node, from_blocks(lambda i0, i1: trans[i0 - 1:i1 - 1]))
        np.testing.assert_array_equal(b, states)
        # a wall: nothing allowed into point 1700
        trans[1698] = np.inf
        self.assertEqual(same_result(self, node, trans)[1], 1698)

    def test_fallback_without_numba(self):
        """Without numba (``kernels()`` None) the numpy loop runs and gives the same states."""
        rng = np.random.default_rng(5)
        node, trans = rng.random((50, 6)), rng.random((49, 6, 6))
        want = viterbi(node, trans)[0]
        with mock.patch.dict(compiled._STATE, {"k": None}):
            np.testing.assert_array_equal(viterbi(node, trans)[0], want)
            self.assertIsNone(compiled.kernels())

    def test_loaded_once_the_work_pays(self):
        """A process loads the kernels only once the work asked of it reaches LOAD_WORK."""
        with mock.patch.dict(compiled._STATE, {"work": 0.0}):
            del compiled._STATE["k"]
            self.assertIsNone(compiled.kernels(work=0.6 * compiled.LOAD_WORK))
            self.assertIsNotNone(compiled.kernels(work=0.6 * compiled.LOAD_WORK))
            self.assertIsNotNone(compiled.kernels(work=1.0))


def random_band(rng, N, u=2, fixed=0.3):
    """A positive definite band matrix like solve_box's: weighted squared differences of
    neighbours plus a small diagonal, some rows replaced by identity rows (fixed variables)."""
    ab = np.zeros((u + 1, N))
    for c in range(1, u + 1):
        w = rng.random(N - c) * 10.0 ** rng.uniform(-3, 3, N - c)
        ab[u, :-c] += w
        ab[u, c:] += w
        ab[u - c, c:] -= 0.9 * w
    ab[u] += 1e-9 + (rng.random(N) < 0.3) * rng.random(N)
    f = np.nonzero(rng.random(N) < fixed)[0]
    for c in range(1, u + 1):
        ab[u - c, f[f + c < N] + c] = 0.0
        ab[u - c, f[f - c >= 0]] = 0.0
    ab[u, f] = 1.0
    return ab


@needs_numba
class CompiledBandedSolve(unittest.TestCase):
    def test_against_lapack(self):
        """The kernel against scipy's solveh_banded (LAPACK dpbsv) on well-conditioned
        systems: equal within 1e-12 relative to the largest |x| (bit for bit where OpenBLAS's
        dtbsv sums in LAPACK's reference order), and as exact: componentwise backward error
        within 1e-14 (measured up to 1.7e-15 for the kernel, 1e-15 for LAPACK)."""
        rng = np.random.default_rng(2)
        for N in (3, 4, 7, 100, 5000):
            for u in (2, 3):
                ab = random_band(rng, N, u)
                b = rng.standard_normal(N) * 10.0 ** rng.uniform(-3, 3, N)
                want = solveh_banded(ab, b, lower=False)
                got = smoothing._solve_banded(ab.copy(), b.copy())
                scale = np.abs(want).max()
                self.assertLessEqual(np.abs(got - want).max(), 1e-12 * scale, (N, u))
                self.assertLessEqual(backward_error(ab, b, got), 1e-14, (N, u))

    def test_not_positive_definite(self):
        ab = np.array([[0.0, 0.0, 1.0], [0.0, 2.0, 2.0], [1.0, 1.0, -1.0]])
        with self.assertRaises(np.linalg.LinAlgError):
            smoothing._solve_banded(ab, np.ones(3))

    def test_solve_box_unchanged(self):
        """solve_box's active set gives the same x with the kernel and with scipy (both
        within 1e-12; the whole loop in the solve_box kernel and the loop calling
        banded_solve: the same bits), and x is the box-constrained minimum: inside the box, and the
        gradient points out of the box where a bound is active and is 0 elsewhere."""
        rng = np.random.default_rng(4)
        N = 400
        for trial in range(4):
            B = _Banded(N, 2)
            B.ab[:] = random_band(rng, N, 2, fixed=0.0)
            B.g[:] = rng.standard_normal(N) * 10.0
            lo = rng.uniform(-2.0, 0.0, N)
            hi = lo + rng.uniform(0.0, 2.0, N)
            x = B.solve_box(lo, hi)
            with mock.patch.object(compiled, "loaded", lambda: None):     # the loop, banded_solve per step
                np.testing.assert_array_equal(B.solve_box(lo, hi), x)        # the solve_box kernel: same bits
            with mock.patch.dict(compiled._STATE, {"k": None}):
                x0 = B.solve_box(lo, hi)
            np.testing.assert_allclose(x, x0, rtol=0, atol=1e-12)
            self.assertTrue(((x >= lo) & (x <= hi)).all())
            grad = B.matvec(x) + B.g
            free = (x > lo + 1e-9) & (x < hi - 1e-9)
            self.assertLess(np.abs(grad[free]).max(initial=0.0), 1e-8 * np.abs(B.g).max())
            self.assertTrue((grad[x <= lo + 1e-9] >= -1e-8).all() and (grad[x >= hi - 1e-9] <= 1e-8).all())

    def test_solve_box_steps_again_only_where_changed(self):
        """The solve_box kernel takes again only the steps of the factor and substitutions
        whose inputs changed: on small systems whose active sets change many times (tight and
        some empty-width boxes, 1 to 40 iterations, sizes from 1 row), the same bits as the
        loop that solves every iteration whole with banded_solve."""
        self.assertIsNotNone(compiled.kernels())            # loaded: B.solve_box runs the kernel
        rng = np.random.default_rng(7)
        for trial in range(60):
            B, lo, hi = random_box(rng, int(rng.integers(1, 50)) if trial else 300)
            for iterations in (1, 2, 40):
                x = B.solve_box(lo, hi, iterations)
                with mock.patch.object(compiled, "loaded", lambda: None):
                    np.testing.assert_array_equal(B.solve_box(lo, hi, iterations), x, (trial, iterations))

    def test_solve_box_warm_start(self):
        """From a given active set (``at``): the kernel and the loop give the same x and leave
        the same active set, from random starts too; from the active set a solve ended with,
        the next ends in its first iteration on the same x, bit for bit, and leaves it as it
        was; from a random one it reaches the same minimum (within 1e-9 of the box's width)."""
        self.assertIsNotNone(compiled.kernels())
        rng = np.random.default_rng(11)
        for trial in range(30):
            N = int(rng.integers(2, 60)) if trial else 400
            B, lo, hi = random_box(rng, N)
            ended = np.zeros(N, np.int8)
            x = B.solve_box(lo, hi, 400, ended)
            again = ended.copy()
            np.testing.assert_array_equal(B.solve_box(lo, hi, 1, again), x)
            np.testing.assert_array_equal(again, ended)
            start = rng.integers(-1, 2, N).astype(np.int8)
            for iterations in (1, 3, 400):
                a, b = start.copy(), start.copy()
                got = B.solve_box(lo, hi, iterations, a)
                with mock.patch.object(compiled, "loaded", lambda: None):
                    np.testing.assert_array_equal(B.solve_box(lo, hi, iterations, b), got, (trial, iterations))
                np.testing.assert_array_equal(a, b)
            np.testing.assert_allclose(got, x, rtol=0, atol=1e-9)
        with self.assertRaises(ValueError):
            B.solve_box(lo, hi, 40, np.zeros(N, np.int64))


def random_box(rng, N: int):
    """A box-constrained problem as the polish's: (its band, lower and upper bounds), the
    boxes tight and about one in ten of them empty (lo = hi)."""
    B = _Banded(N, 2)
    B.ab[:] = random_band(rng, N, 2, fixed=0.0)
    B.g[:] = rng.standard_normal(N) * 10.0 ** rng.uniform(-1, 2)
    lo = rng.uniform(-1.0, 0.0, N)
    return B, lo, lo + rng.uniform(0.0, 1.0, N) * (rng.random(N) > 0.1)


def random_programme(rng, n, M):
    """A joint programme's transition function on random tilts (some at the pole, some
    equal along the path), spacings partly below IN_PLACE's, random free steps and air
    points, a random tool-axis step limit and random weights (beta and travel 0 or not)."""
    from tsplcam.orientation.rotary import DEG, Rotary
    from tsplcam.orientation.smoothing import MeridianGrid, SmoothingCost, joint_transitions
    rot = Rotary(theta_lo=-30 * DEG, theta_hi=115 * DEG, v_theta=1.0, v_phi=2.0)
    cost = SmoothingCost(float(rng.uniform(0.5, 8.0)), rot, w=float(rng.uniform(0.1, 3.0)),
                         alpha=float(rng.choice([1.0, 0.3])), beta=float(rng.choice([0.0, 0.7])),
                         travel=float(rng.choice([0.0, 0.05])))
    th = rng.uniform(-0.6, 2.0, (n, M))
    th[rng.random((n, M)) < 0.1] = 0.0                               # on the pole
    same = rng.random(n) < 0.2
    th[1:][same[1:]] = th[:-1][same[1:]]                             # dtheta = 0 exactly
    grid = MeridianGrid(2 * np.pi * np.arange(M) / M, th, th - 1, th + 1, np.zeros((n, M)),
                        np.ones((n, M), bool))
    ds = np.where(rng.random(n - 1) < 0.3, rng.uniform(0.001, 0.1, n - 1), rng.uniform(0.1, 2.0, n - 1))
    free = rng.random(n) < 0.3
    air = rng.random(n) < 0.2 if rng.random() < 0.7 else None
    max_step = float(rng.choice([np.pi, 20 * DEG, 3 * DEG]))
    return grid, joint_transitions(grid, cost, ds, max_step, free, air)


@needs_numba
class CompiledJointTransitions(unittest.TestCase):
    def test_same_bits_as_numpy(self):
        """The joint programme's transitions as the kernel computes them (read off one source
        state at a time: only that state reachable, at cost 0, node costs 0, so the costs
        after one step are that state's row of transitions, exactly) are numpy's block's bit
        for bit (the program's bytes hang on them): finite costs, moves forbidden by the
        tool-axis step limit and rotary swings on short blocks (inf), with and without the
        beta and travel terms."""
        k = compiled.kernels()
        rng = np.random.default_rng(21)
        seen = {"inf": 0, "finite": 0, "dead row": 0}
        for trial in range(40):
            n, M = int(rng.integers(2, 40)), int(rng.choice([5, 12, 36]))
            grid, tr = random_programme(rng, n, M)
            blocks = np.concatenate([tr.block(i0, min(n, i0 + 32)) for i0 in range(1, n, 32)])
            for i in range(1, n):
                want = tr.block(i, i + 1)[0]
                got = np.empty((M, M))
                for a in range(M):
                    acc = np.full(M, np.inf)
                    acc[a] = 0.0
                    tr.steps(k, acc, np.zeros((n, M)), i, i + 1, TIE, np.zeros((n, M), np.int32))
                    got[a] = acc
                np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64), f"trial {trial} point {i}")
                np.testing.assert_array_equal(blocks[i - 1].view(np.int64), want.view(np.int64))
                seen["inf"] += np.isinf(want).sum()
                seen["finite"] += np.isfinite(want).sum()
                seen["dead row"] += np.isinf(want).all(axis=1).any()
        self.assertTrue(all(v > 0 for v in seen.values()), seen)

    def test_programme_states(self):
        """The programme with transitions computed in the kernel against the numpy loop over
        numpy's blocks: the same states and break points, with forbidden states."""
        rng = np.random.default_rng(22)
        broken = 0
        for trial in range(30):
            n, M = int(rng.integers(2, 300)), int(rng.choice([5, 12, 36]))
            grid, tr = random_programme(rng, n, M)
            node = rng.random((n, M)) * rng.choice([0.01, 1.0, 100.0])
            node[rng.random((n, M)) < 0.2] = np.inf
            self.assertIsNotNone(tr.steps)
            broken += same_result(self, node, tr, f"trial {trial}")[0] is None
        self.assertGreater(broken, 0)

    def test_programme_across_row_blocks(self):
        """The kernel handed the points in blocks of ``STEPS_ROWS`` (each block's cos and sin
        made for it; a small block size here, so that chains cross many blocks and break in
        later ones): the same states and break points as the numpy loop."""
        rng = np.random.default_rng(23)
        broken = 0
        with mock.patch.object(smoothing, "STEPS_ROWS", 7):
            for trial in range(30):
                n, M = int(rng.integers(2, 120)), int(rng.choice([5, 12]))
                grid, tr = random_programme(rng, n, M)
                node = rng.random((n, M))
                node[rng.random((n, M)) < 0.2] = np.inf
                node[int(rng.integers(0, n)), :] = np.inf if trial % 3 == 0 else node[0]
                broken += same_result(self, node, tr, f"trial {trial}")[0] is None
        self.assertGreater(broken, 0)
        self.assertLess(broken, 30)

    def test_prepare_loads_aside(self):
        """``prepare(exercise)`` (the job's, while the path's workers run) loads every kernel
        into a set kept aside: numba or numpy is still chosen by the work asked, and the set
        given once the kernels load is that one, every kernel already loaded for the job's
        types."""
        with mock.patch.dict(compiled._STATE, {"work": 0.0}, clear=True):
            compiled.prepare(exercise)
            self.assertIsNone(compiled.kernels(work=1.0))
            self.assertIsNone(compiled.loaded())
            k = compiled.kernels()
            for name in ("viterbi_steps", "joint_steps", "solve_box", "two_states", "grid_read"):
                if not isinstance(k[name], compiled._Exported):     # (ahead of time: one type only)
                    self.assertEqual(len(k[name].signatures), 1, name)
            self.assertIs(compiled.loaded(), k)

    def test_programme_takes_the_set_aside(self):
        """A Viterbi programme whose work is below the load threshold runs in the set
        ``prepare(exercise)`` put aside, where there is one (the same states as numpy's loop),
        and leaves the process's choice alone: nothing loaded, the work still counted."""
        rng = np.random.default_rng(23)
        grid, tr = random_programme(rng, 60, 12)
        node = rng.random((60, 12))
        node[rng.random((60, 12)) < 0.2] = np.inf
        want = viterbi(node, tr, kernel=False)
        with mock.patch.dict(compiled._STATE, {"work": 0.0}, clear=True):
            compiled.prepare(exercise)
            calls = []
            spare = {name: (lambda f, name: lambda *a: calls.append(name) or f(*a))(f, name)
                     for name, f in compiled._STATE["spare"].items()}
            compiled._STATE["spare"] = spare
            got = viterbi(node, tr)
            self.assertIn("joint_steps", calls)
            self.assertIsNone(compiled.loaded())
            self.assertGreater(compiled._STATE["work"], 0.0)
        self.assertEqual(want[1], got[1])
        np.testing.assert_array_equal(want[0], got[0])

    def test_warm_compiles_it(self):
        """``warm(exercise)`` (the install script's) compiles numba's kernel for the types the job
        uses."""
        compiled.warm(exercise)
        self.assertEqual(len(compiled._jit()["joint_steps"].signatures), 1)


@needs_numba
class KeycapJob(unittest.TestCase):
    def test_every_call_of_the_main_job(self):
        """The keycap main job (model to G-code): every Viterbi programme it runs (the joint
        programme's, the forced-travel figure's, the post's pose choice) is solved both ways,
        compiled and numpy, with the same states; every box-constrained problem of the polish
        both in the solve_box kernel and in the loop calling banded_solve, with the same bits;
        every banded system the polish solves is
        solved as exactly by the kernel as by LAPACK: componentwise backward error within
        1e-14 (45 machine epsilons; both measure 2.2e-16 to 2.5e-16 on these). The solutions
        themselves need not agree to the bit: the polish's systems are ill-conditioned (on an
        AVX-512 machine, whose OpenBLAS orders dtbsv's sums otherwise, the two differ by up to
        1.1e-6 rad, and the programs in the fourth decimal of some angles)."""
        from tsplcam.job import run_job
        from tsplcam.settings import JobSettings
        from tsplcam.orientation import rotary

        seen = {"viterbi": 0, "banded": 0, "boxes": 0}
        real_solve = smoothing._solve_banded

        def both_viterbi(node, trans, kernel=True):
            a = viterbi(node, trans, kernel=False)
            b = viterbi(node, trans, kernel=True)
            self.assertEqual(a[1], b[1])
            if a[0] is not None:
                np.testing.assert_array_equal(a[0], b[0])
            seen["viterbi"] += np.shape(node)[1] > 2
            return b

        def both_solve(ab, rhs):
            want = solveh_banded(ab, rhs, lower=False, check_finite=False)
            got = real_solve(ab.copy(), rhs.copy())
            self.assertLessEqual(backward_error(ab, rhs, want), 1e-14)
            self.assertLessEqual(backward_error(ab, rhs, got), 1e-14)
            seen["banded"] += 1
            return got

        real_box = smoothing._Banded.solve_box

        def both_box(box, lo, hi, iterations=40, at=None):
            start = None if at is None else at.copy()
            got = real_box(box, lo, hi, iterations, at)          # the solve_box kernel
            again = None if start is None else start.copy()
            with mock.patch.object(compiled, "loaded", lambda: None):
                np.testing.assert_array_equal(real_box(box, lo, hi, iterations, again), got)   # the loop
            if at is not None:
                np.testing.assert_array_equal(again, at)         # and the same active set left
            seen["boxes"] += 1
            return got

        with tempfile.TemporaryDirectory() as tmp, \
                mock.patch.object(smoothing, "viterbi", both_viterbi), \
                mock.patch.object(rotary, "viterbi", both_viterbi), \
                mock.patch.object(smoothing._Banded, "solve_box", both_box), \
                mock.patch.object(smoothing, "_solve_banded", both_solve):
            figures = run_job(JobSettings(out=os.path.join(tmp, "job"), verify=False, html_report=False),
                              log=None, progress=lambda stage, done, total: None)
        self.assertGreaterEqual(seen["viterbi"], 2)       # the joint programme and the forced travel
        self.assertGreaterEqual(seen["boxes"], 4)
        self.assertGreater(seen["banded"], 40)         # (57: the first solves' loops, the rest warm)
        self.assertEqual(figures["orientation"]["collisions"], 0)


@needs_numba
class CompiledMeridianGrid(unittest.TestCase):
    def test_cone_arcs_same_bits_as_numpy(self):
        """``cone_arcs`` (a cone's arc on the branch nearest ref, into lo and hi) against
        theta_interval's numpy operations, bit for bit: arc centres far from ref (the float
        mod's fmod, its sign rule and its zero), +-pi, nan and inf in al, ref and the bounds."""
        k = compiled.kernels()
        rng = np.random.default_rng(31)
        half = smoothing._HALF_PI
        for case in range(200):
            rows, M = int(rng.integers(1, 30)), int(rng.choice([3, 12, 36]))
            al = rng.uniform(-4, 4, (rows, M)) * rng.choice([1.0, 1e-8, 1e3, 1e17], (rows, M))
            sp = rng.random((rows, M))
            al[sp < 0.03] = np.nan
            al[(sp >= 0.03) & (sp < 0.05)] = np.inf
            al[(sp >= 0.05) & (sp < 0.08)] = -np.pi
            ref = rng.uniform(-7, 7, (rows, M))
            ref[rng.random((rows, M)) < 0.02] = np.nan
            whole = rng.random((rows, M)) < 0.2                 # pi - (al - ref) a multiple of 2 pi
            ref = np.where(whole, al + np.pi - 2 * np.pi * rng.integers(-3, 4, (rows, M)), ref)
            lo = np.where(rng.random((rows, M)) < 0.5, -np.inf, rng.uniform(-3, 3, (rows, M)))
            hi = np.where(rng.random((rows, M)) < 0.5, np.inf, rng.uniform(-3, 3, (rows, M)))
            lo[rng.random((rows, M)) < 0.02] = np.nan
            with np.errstate(invalid="ignore"):
                centre = ref + (np.pi - np.mod(np.pi - (al - ref), 2 * np.pi))
                want_lo, want_hi = np.maximum(lo, centre - half), np.minimum(hi, centre + half)
            got_lo, got_hi = lo.copy(), hi.copy()
            k["cone_arcs"](al, ref, half, got_lo, got_hi)
            np.testing.assert_array_equal(got_lo.view(np.int64), want_lo.view(np.int64), f"case {case}")
            np.testing.assert_array_equal(got_hi.view(np.int64), want_hi.view(np.int64), f"case {case}")

    def test_meridian_dots_same_bits_as_numpy(self):
        """``meridian_dots`` against ``_meridian_dots``' three numpy passes, bit for bit, on
        finite vectors of every magnitude (products that overflow and underflow), signed zeros
        in V and the meridians."""
        rng = np.random.default_rng(32)
        for case in range(200):
            n, M = int(rng.integers(1, 60)), int(rng.choice([3, 12, 36]))
            V = rng.normal(size=(n, 3)) * rng.choice([1.0, 1e-200, 1e200], (n, 3))
            V[rng.random((n, 3)) < 0.05] = -0.0
            m = np.column_stack([np.cos(np.arange(M)), np.sin(np.arange(M)), np.zeros(M)])
            m[:, :2][rng.random((M, 2)) < 0.1] = -0.0
            got = smoothing._meridian_dots(V, m)
            with mock.patch.object(compiled, "kernels", lambda work=None: None), np.errstate(all="ignore"):
                want = smoothing._meridian_dots(V, m)
            np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64), f"case {case}")

    def test_grid_same_bits_as_numpy(self):
        """meridian_grid with the kernels against numpy alone: the same tilts, bounds,
        preferred tilts and admissible poses bit for bit, on the lead/tilt cones of random
        normals and feeds (rows whose constraint lies horizontal take the numpy form), with a
        controls' half-space of b != 0, on a pole tilt, across its row blocks."""
        from tsplcam.orientation.rotary import DEG, Rotary
        rng = np.random.default_rng(33)
        for case in range(24):
            n, M = int(rng.integers(1, 2600)), int(rng.choice([12, 36]))
            N = rng.normal(size=(n, 3))
            N[:, 2] = np.abs(N[:, 2]) + rng.choice([0.0, 1.0])
            N /= np.linalg.norm(N, axis=1)[:, None]
            F = np.cross(N, rng.normal(size=(n, 3)))
            F /= np.linalg.norm(F, axis=1)[:, None]
            cons = [(h, np.zeros(n)) for h in smoothing.cone_halfspaces(N, F, 0.6, 1.0)]
            if case % 3 == 0:
                cons[1][0][: n // 2, 2] = 0.0
            if case % 4 == 1:
                cons.append((rng.normal(size=(n, 3)), rng.normal(size=n) * 0.2))
            P = rng.normal(size=(n, 3))
            P /= np.linalg.norm(P, axis=1)[:, None]
            rot = Rotary(about=str(rng.choice(["X", "Z"])), theta_lo=-30 * DEG, theta_hi=115 * DEG)
            pole = float(rng.choice([0.0, 2 * DEG]))
            got = smoothing.meridian_grid(rot, P, N, cons, M, pole, rows=int(rng.choice([64, 1024])))
            with mock.patch.object(compiled, "kernels", lambda work=None: None):
                want = smoothing.meridian_grid(rot, P, N, cons, M, pole)
            for f in ("theta", "lo", "hi", "pref", "ok"):
                np.testing.assert_array_equal(getattr(got, f).view(np.int8), getattr(want, f).view(np.int8),
                                              f"case {case} {f}")


@needs_numba
class CompiledGridRead(unittest.TestCase):
    def test_same_bits_as_numpy(self):
        """The broad phase's distance grids of the keycap mold read by the kernel and by numpy:
        the same bounds (bit for bit), samples and inside flags, at points inside, on node
        planes and outside the grids."""
        from tsplcam.model import samples
        from tsplcam.model.cage import cage_model
        from tsplcam.orientation import CollisionChecker, load_tool
        from tsplcam.orientation.broadphase import DistanceGrid
        mold = cage_model(samples.keycap_mold())
        V, T = samples.keycap_mold_stock()
        bp = CollisionChecker(mold, load_tool("ball1_keycap"), meshes=[("stock", V, T)]).broad
        rng = np.random.default_rng(4)
        for grid in bp.grids:
            lo = grid.origin - 3.0
            hi = grid.origin + grid.h * (grid.shape - 1) + 3.0
            x = lo + rng.random((60000, 3)) * (hi - lo)
            x[:2000] = grid.origin + grid.h * rng.integers(0, grid.shape, (2000, 3))   # on nodes
            got = grid(x)
            with mock.patch.object(compiled, "kernels", lambda work=None: None):
                want = grid(x)
            self.assertTrue(got[2].any() and not got[2].all())
            for g, w in zip(got, want):
                self.assertEqual(g.dtype, w.dtype)
                np.testing.assert_array_equal(g, w)
        self.assertIsInstance(bp.grids[0], DistanceGrid)


if __name__ == "__main__":
    unittest.main()
