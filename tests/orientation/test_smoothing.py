"""The joint-space smoothing's pieces against brute force: the admissible arcs of a meridian
and of a circle of latitude (closed form) against sampling the cone test of the candidates
module, the programme's transition cost against the joint motion of every pair of poses,
the banded box-constrained solve against scipy's L-BFGS-B."""
import unittest

import numpy as np
from scipy.optimize import minimize

from tsplcam.orientation.candidates import Limits, admissible, feed_directions
from tsplcam.orientation.rotary import DEG, Rotary
from tsplcam.orientation.rotary import angle_between
from tsplcam.orientation.smoothing import (MeridianGrid, SmoothingCost, _Banded, _azimuth_window, _deviation, _meridian_dots,
                                           _quadratic, cone_halfspaces, meridian_grid,
                                           joint_transitions, phi_interval, theta_interval)


def random_frames(rng, n):
    normal = rng.normal(size=(n, 3))
    normal[:, 2] = np.abs(normal[:, 2]) + 0.2
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    pts = np.cumsum(rng.normal(size=(n, 3)), axis=0)
    return normal, feed_directions(pts, normal)


class AdmissibleArcs(unittest.TestCase):
    def setUp(self):
        rng = np.random.default_rng(11)
        self.n = 300
        self.normal, self.feed = random_frames(rng, self.n)
        self.limits = Limits(50 * DEG, 35 * DEG, 10 * DEG)
        self.cons = [(h, np.zeros(self.n)) for h in
                     cone_halfspaces(self.normal, self.feed, self.limits.lead_max, self.limits.tilt_max)]
        self.rot = Rotary(about="Y")
        self.rng = rng

    def sampled(self, axes):
        return admissible(axes, self.normal, self.feed, self.limits, None)

    def test_tilt_interval_on_a_meridian(self):
        phi = self.rng.uniform(-np.pi, np.pi, self.n)
        lo, hi = theta_interval(self.rot, phi, self.cons, self.rot.best_theta(self.normal, phi))
        t = np.linspace(-np.pi, np.pi, 3601)
        ok = self.sampled(self.rot.axis(t[None, :], phi[:, None]))
        inside = (t[None, :] >= lo[:, None]) & (t[None, :] <= hi[:, None])
        # every sample inside the interval passes, and the sampled set is no wider (one arc)
        self.assertFalse((inside & ~ok).any())
        miss = ok & ~inside
        self.assertFalse(miss.any(), f"{int(miss.sum())} admissible samples outside")

    def test_grid_dots_are_einsums_bits(self):
        """The grid's dot products with the meridians are np.einsum's bit for bit (signed
        zeros and tiny products included), and so the grid's arcs and tilts are the same
        as with the meridians broadcast to (n, M, 3)."""
        for about in ("X", "Y"):
            rot = Rotary(about=about)
            m = rot.meridian(2 * np.pi * np.arange(36) / 36)
            V = np.concatenate([self.normal, [[0.0, -0.0, -1.0], [-0.0, 0.0, 1.0], [-0.0, -0.0, -0.0],
                                              [1e-300, -1e-300, -0.0], [-1e-200, 1e-200, 2.0]]])
            ref = np.einsum("nj,nkj->nk", V, np.broadcast_to(m, (len(V),) + m.shape))
            self.assertEqual(_meridian_dots(V, m).tobytes(), ref.tobytes())
            PH = np.broadcast_to(2 * np.pi * np.arange(36) / 36, (self.n, 36))
            mb = np.broadcast_to(m, (self.n, 36, 3))
            ref_t = rot.best_theta(self.normal[:, None, :], PH, mb)
            a = theta_interval(rot, PH, self.cons, ref_t, mb)
            b = theta_interval(rot, PH, self.cons, ref_t, m)
            self.assertEqual(a[0].tobytes() + a[1].tobytes(), b[0].tobytes() + b[1].tobytes())
            g = meridian_grid(rot, self.normal, self.normal, self.cons, 36)
            self.assertEqual(g.pref.tobytes(), rot.best_theta(self.normal[:, None, :], PH, mb).tobytes())

    def test_grid_in_chunks_and_deviation_bits(self):
        """meridian_grid a few points at a time is the grid in one piece bit for bit; the
        poses' angles to preferred axes along +-z (_deviation: no (n, M, 3) arrays) are
        angle_between's of rot.axis bit for bit, zero and right-angle tilts, signed zeros
        and tiny axes included; other preferred axes take angle_between itself."""
        th = self.rng.uniform(-3.5, 3.5, (self.n, 36))
        th[::7] = 0.0
        th[::11, ::3] = -0.0
        th[::17, ::5] = np.pi / 2
        for about in ("X", "Y"):
            rot = Rotary(about=about)
            whole = meridian_grid(rot, self.normal, self.normal, self.cons, 36)
            parts = meridian_grid(rot, self.normal, self.normal, self.cons, 36, rows=7)
            for f in ("theta", "lo", "hi", "pref", "ok"):
                self.assertEqual(getattr(whole, f).tobytes(), getattr(parts, f).tobytes(), f)
            phis = np.concatenate([2 * np.pi * np.arange(32) / 32, [np.pi / 2, -np.pi, 7.0, -0.0]])
            pz = np.zeros((self.n, 3))
            pz[:, 2] = self.rng.choice([1.0, -1.0, 0.5, -0.0, 1e-300], self.n)
            pz[::13, 1] = -0.0
            for pref in (pz, self.normal):
                want = angle_between(rot.axis(th, phis[None, :]), pref[:, None, :])
                self.assertEqual(_deviation(rot, th, phis, pref, rows=50).tobytes(), want.tobytes())

    def test_azimuth_window_walks_the_free_cells(self):
        """The window through azimuth cells whose free tilt is at most the pose's: counted
        cell by cell from the pose's nearest cell, each way (at most half a turn)."""
        rng = np.random.default_rng(5)
        for M in (36, 13):
            n, d = 200, 2 * np.pi / M
            A = np.where(rng.random((n, M)) < 0.6, 0.0, rng.random((n, M)))
            A[rng.random((n, M)) < 0.05] = np.inf
            az, tilt = rng.uniform(-7.0, 7.0, n), rng.random(n)
            wl, wr = _azimuth_window(A, az, tilt, M)
            for i in range(n):
                f = np.mod(az[i], 2 * np.pi) / d
                c, off = int(np.rint(f)) % M, (f - np.rint(f)) * d
                ok = A[i] <= tilt[i] + 1e-12
                if not ok[c]:
                    self.assertEqual((wl[i], wr[i]), (0.0, 0.0))
                    continue
                runs = [next((j - 1 for j in range(1, M // 2 + 1) if not ok[(c + s * j) % M]), M // 2)
                        for s in (-1, 1)]
                self.assertAlmostEqual(wl[i], max(0.0, runs[0] * d + off), delta=1e-12)   # rad
                self.assertAlmostEqual(wr[i], max(0.0, runs[1] * d - off), delta=1e-12)

    def test_rotary_interval_on_a_circle_of_latitude(self):
        # start from admissible poses; the arc around them must contain only admissible ones
        phi0 = self.rng.uniform(-np.pi, np.pi, self.n)
        lo, hi = theta_interval(self.rot, phi0, self.cons, self.rot.best_theta(self.normal, phi0))
        keep = lo <= hi
        theta = np.where(keep, 0.5 * (lo + hi), 0.0)
        plo, phi_hi = phi_interval(self.rot, theta, self.cons, phi0)
        p = np.linspace(-np.pi, np.pi, 721)
        for i in np.nonzero(keep)[0][:80]:
            grid = phi0[i] + p
            ok = admissible(self.rot.axis(np.full((1, len(p)), theta[i]), grid[None, :]),
                            self.normal[i:i + 1], self.feed[i:i + 1], self.limits, None)[0]
            inside = (grid >= plo[i] - 1e-9) & (grid <= phi_hi[i] + 1e-9)
            self.assertFalse((inside & ~ok).any(), i)
            # and it reaches the first inadmissible sample on either side of the start
            j0 = np.argmin(np.abs(p))
            run = ok.copy()
            r = j0
            while r + 1 < len(p) and run[r + 1]:
                r += 1
            self.assertLess(abs(grid[r] - min(phi_hi[i], grid[-1])), 2 * (p[1] - p[0]) + 1e-9, i)


class TransitionCost(unittest.TestCase):
    def test_joint_cost_of_every_pair(self):
        rng = np.random.default_rng(3)
        rot = Rotary(theta_lo=-30 * DEG, theta_hi=115 * DEG, v_theta=1.0, v_phi=2.0)
        cost = SmoothingCost(2.0, rot, w=rot.weight)
        M = 12
        th = rng.uniform(-0.5, 1.5, (2, M))
        grid = MeridianGrid(2 * np.pi * np.arange(M) / M, th, th - 1, th + 1, np.zeros((2, M)),
                            np.ones((2, M), bool))
        T = joint_transitions(grid, cost, np.array([0.5]), np.pi, np.zeros(2, bool))(1)
        for a in range(M):
            for b in range(M):
                dphi = (grid.phi[b] - grid.phi[a] + np.pi) % (2 * np.pi) - np.pi
                want = cost.length / 0.5 * ((th[1, b] - th[0, a]) ** 2 + cost.w * dphi ** 2)
                self.assertAlmostEqual(T[a, b], want, places=10)

    def test_kept_blocks_follow_the_tilts(self):
        """Blocks kept between the programme's rounds: given again while their tilts stand,
        made again (the same bits as a fresh transition function's) where a tilt changed."""
        rng = np.random.default_rng(5)
        rot = Rotary(theta_lo=-30 * DEG, theta_hi=115 * DEG, v_theta=1.0, v_phi=2.0)
        cost = SmoothingCost(2.0, rot, w=rot.weight, beta=0.5)
        n, M = 100, 12
        th = rng.uniform(-0.5, 1.5, (n, M))
        grid = MeridianGrid(2 * np.pi * np.arange(M) / M, th, th - 1, th + 1, np.zeros((n, M)),
                            np.ones((n, M), bool))
        ds = rng.uniform(0.05, 0.5, n - 1)
        free = rng.random(n) < 0.5
        kept = joint_transitions(grid, cost, ds, 20 * DEG, free).block
        first = [kept(i, min(n, i + 32)) for i in range(1, n, 32)]
        grid.theta[40, 3] += 0.01                          # the programme moves one tilt
        again = [kept(i, min(n, i + 32)) for i in range(1, n, 32)]
        fresh = joint_transitions(grid, cost, ds, 20 * DEG, free).block
        for k, i in enumerate(range(1, n, 32)):
            np.testing.assert_array_equal(again[k], fresh(i, min(n, i + 32)))
            self.assertEqual(again[k] is first[k], not (i - 1 <= 40 < i + 32))


class BoxSolve(unittest.TestCase):
    def test_matches_lbfgsb(self):
        rng = np.random.default_rng(1)
        for trial in range(4):
            n = 80
            ds = rng.uniform(0.05, 0.9, n - 1)
            Q = _quadratic(n, ds, rng.uniform(size=n - 1) > 0.05, 5.0, 1.0, 1.25)
            B = _Banded(n, 2)
            B.ab[:] = Q.ab
            half = np.zeros(n)
            half[:-1] += ds / 2
            half[1:] += ds / 2
            B.add(half / 5, np.arange(n)[:, None], np.ones((n, 1)), -rng.uniform(-0.5, 0.5, n))
            lo = rng.uniform(-0.2, 0.3, n)
            hi = lo + rng.uniform(0.0, 1.0, n)
            x = B.solve_box(lo, hi)
            H = np.zeros((n, n))
            for k in range(3):
                for i in range(n - k):
                    H[i, i + k] = H[i + k, i] = B.ab[2 - k, i + k]
            f = lambda z: 0.5 * z @ H @ z + B.g @ z           # noqa: E731
            ref = minimize(f, np.clip(np.zeros(n), lo, hi), jac=lambda z: H @ z + B.g, bounds=list(zip(lo, hi)),
                           method="L-BFGS-B", options=dict(ftol=1e-15, gtol=1e-12, maxiter=20000))
            self.assertLessEqual(f(x), ref.fun + 1e-10)
            self.assertTrue(np.all(x >= lo - 1e-12) and np.all(x <= hi + 1e-12))

    def test_same_bits_whatever_the_process_ran_before(self):
        """A box solve in a process that has asked the kernels for no work yet (a job's first
        smoothing) gives the bits of one whose kernels are loaded (a second job in the same
        FreeCAD session): LAPACK's banded solve rounds otherwise, and the active set carried
        that to the 7th digit of a job's axes."""
        from unittest import mock

        from tsplcam import compiled
        rng = np.random.default_rng(3)
        n = 200
        ds = rng.uniform(0.05, 0.9, n - 1)

        def solve():
            B = _Banded(n, 2)
            B.ab[:] = _quadratic(n, ds, np.ones(n - 1, bool), 5.0, 1.0, 1.25).ab
            B.add(np.full(n, 0.1), np.arange(n)[:, None], np.ones((n, 1)), -np.sin(np.arange(n) * 0.1))
            return B.solve_box(np.full(n, -0.5), np.full(n, 0.4))
        with mock.patch.dict(compiled._STATE, {"work": 0.0}, clear=True):
            first = solve()
        compiled.kernels()
        self.assertEqual(first.tobytes(), solve().tobytes())


class SameCodeWhateverTheHeap(unittest.TestCase):
    def test_components_do_not_look_overlapping(self):
        """numpy takes libm's scalar arctan2 instead of SVML's where an input may overlap the
        output; a column h[:, 2] is judged to reach 16 bytes past h, where the next heap block
        can start (a smoothing's arcs differed in the last bit about one run in two hundred).
        Through ``components`` the output right after h gets the bits of one far away."""
        from tsplcam.numerics import components
        rng = np.random.default_rng(4)
        n = 1351
        buf = np.empty(3 * n + 1 + n)
        h = buf[:3 * n].reshape(n, 3)
        h[:] = rng.normal(size=(n, 3))
        y = rng.normal(size=n)
        right_after = buf[3 * n + 1:]                     # 8 bytes past h's last element
        far = np.arctan2(y, components(h)[2])
        self.assertEqual(np.arctan2(y, components(h)[2], out=right_after).tobytes(), far.tobytes())
        self.assertTrue(components(h)[2].flags.c_contiguous)
        np.testing.assert_array_equal(components(h)[2], h[:, 2])


class AtThePole(unittest.TestCase):
    def test_flat_square_under_a_fork_head(self):
        """A flat square (GeoPDEs' unstructured square) under the fork head, whose C is
        limited: every axis at the pole, where the rotary value hardly weighs, so runs of
        points were held to the programme by almost nothing and the rotary solve's factor
        lost definiteness (numpy's LinAlgError from deep inside, 149th leading minor); the
        axes now come out vertical, collision-free, C not moving."""
        from conftest import external
        from tsplcam import load_model
        from tsplcam.orientation import CollisionChecker, load_tool, orient
        from tsplcam.orientation.testpaths import zigzag
        from tsplcam.post import load_machine
        model = load_model(external("geopdes", "square_unstructured.iga"))
        checker = CollisionChecker(model, load_tool("ball1_keycap"), clearance=0.3)
        path = zigzag(model, 0.5, lines=12, points=40)
        out, rep = orient(path, checker=checker, machine=load_machine("bc_head_head_fanuc"))
        self.assertEqual(int(checker.collides_exact(out.center, out.axis).sum()), 0)
        self.assertLess(np.degrees(angle_between(out.axis, out.normal)).max(), 1e-6)


class StepsWithinTheLimit(unittest.TestCase):
    def test_points_go_back_to_the_programme_until_every_hard_move_keeps_it(self):
        """``_within_steps``: a polished pair turning the axis by more than the limit on a hard
        move goes back to the programme, and on while a boundary still turns too far; moves
        that are not hard (links) are left alone."""
        from tsplcam.orientation.smoothing import _within_steps
        t = np.radians(np.array([0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 14.0]))
        K0 = np.column_stack([np.sin(t), np.zeros_like(t), np.cos(t)])       # the programme: 2 deg a move
        tp = t.copy()
        tp[3], tp[4] = np.radians(-3.0), np.radians(12.0)                   # a polished pair 15 deg apart
        tp[5] = np.radians(20.0)                            # 12 deg from point 4 once that is back
        tp[6] = np.radians(40.0)                                            # and a link's far end
        K = np.column_stack([np.sin(tp), np.zeros_like(tp), np.cos(tp)])
        hard = np.array([True, True, True, True, True, False, False])
        back = _within_steps(K, K0, hard, np.radians(5.0))
        A = np.where(back[:, None], K0, K)
        steps = np.degrees(angle_between(A[1:], A[:-1]))
        self.assertLessEqual(steps[hard].max(), 5.0 + 1e-9)
        np.testing.assert_array_equal(np.nonzero(back)[0], [2, 3, 4, 5])  # both pairs, then the next
        self.assertFalse(back[6])                                           # behind links: as polished


if __name__ == "__main__":
    unittest.main()
