"""Machining-time estimate against hand-computed trapezoidal profiles."""
import json
import os
import unittest

import numpy as np

from tsplcam.post import post_program
from tsplcam.post import dialects
from tsplcam.post.machine import machine_from_dict, shipped_dir
from tsplcam.post.timing import axis_block_times, estimate
from tsplcam.toolpath.path import Move, ToolPath

V = np.array([100.0, 100.0, 100.0, 60.0, 150.0])        # mm/s, deg/s
A = np.array([1000.0, 1000.0, 1000.0, 600.0, 1800.0])   # mm/s^2, deg/s^2


def run(joints, t_min=None):
    j = np.asarray(joints, float)
    t_min = np.zeros(len(j) - 1) if t_min is None else np.asarray(t_min, float)
    return estimate(j, t_min, V, A)


def straight_path(points, axis, feed):
    points = np.asarray(points, float)
    n = len(points)
    axis = np.tile(np.asarray(axis, float) / np.linalg.norm(axis), (n, 1)) if np.ndim(axis) == 1 else np.asarray(axis, float)
    return ToolPath(contact=points, normal=axis, axis=axis, move=np.full(n, Move.CUT, np.int8),
                    patch=np.zeros(n, int), uv=np.zeros((n, 2)), line=np.zeros(n, int), tool_radius=0.0,
                    feed=feed)


class HandComputed(unittest.TestCase):
    def test_single_axis_trapezoid(self):
        # 100 mm at v = 100 mm/s, a = 1000 mm/s^2: ramps 0.1 s each (5 mm each), cruise 90 mm.
        r = run([[0, 0, 0, 0, 0], [100, 0, 0, 0, 0]])
        self.assertAlmostEqual(r.total_s, 100 / 100 + 100 / 1000, places=12)
        # Too short to reach v: triangle, 2 sqrt(d / a).
        r = run([[0, 0, 0, 0, 0], [1, 0, 0, 0, 0]])
        self.assertAlmostEqual(r.total_s, 2 * np.sqrt(1 / 1000), places=12)

    def test_feed_limited_block(self):
        # The block may not take less than 2 s: the axis cruises at 50 mm/s.
        r = run([[0, 0, 0, 0, 0], [100, 0, 0, 0, 0]], t_min=[2.0])
        self.assertAlmostEqual(r.total_s, 100 / 50 + 50 / 1000, places=12)
        self.assertEqual(r.feed_limited_blocks, 0)        # the ramps make the axis the limit

    def test_chain_equals_one_move(self):
        # 100 blocks of 1 mm in one direction run like one 100 mm move (forward/backward pass).
        x = np.linspace(0, 100, 101)
        j = np.zeros((101, 5))
        j[:, 0] = x
        self.assertAlmostEqual(run(j).total_s, 1.1, places=9)
        # Junction speeds: each block's time is set by the passes, not by stopping.
        self.assertAlmostEqual(run(j).block_time[50], 0.01, places=9)

    def test_reversal_stops_the_axis(self):
        # +50, +50, -50: the first two run as one 100 mm move (1.1 s), the reversal starts
        # from rest: 50 mm -> 0.5 + 0.1 s.
        r = run([[0, 0, 0, 0, 0], [50, 0, 0, 0, 0], [100, 0, 0, 0, 0], [50, 0, 0, 0, 0]])
        self.assertTrue(np.allclose(r.block_time, [0.55, 0.55, 0.6]))
        self.assertAlmostEqual(r.total_s, 1.7, places=12)

    def test_rotary_axis_limits_the_block(self):
        # X moves 1 mm, C 90 deg at 150 deg/s, 1800 deg/s^2: C sets the time.
        r = run([[0, 0, 0, 0, 0], [1, 0, 0, 0, 90]])
        self.assertAlmostEqual(r.total_s, 90 / 150 + 150 / 1800, places=12)
        self.assertEqual(list(r.limiting_blocks), [0, 0, 0, 0, 1])
        self.assertAlmostEqual(r.average_speed[4], 90 / r.total_s * 60, places=9)

    def test_time_by_limit_names_what_sets_each_block(self):
        # Block 1: X 1 mm in at least 1 s, cruising at the feed's pace after its ramp (the
        # ramps make X the limit, as above); block 2: C 90 deg, no feed minimum: C sets it.
        # An axis exactly at the feed's pace, no ramp (the middle of a chain): the feed.
        r = run([[0, 0, 0, 0, 0], [1, 0, 0, 0, 0], [1, 0, 0, 0, 90]], t_min=[1.0, 0.0])
        by = r.time_by_limit()
        self.assertAlmostEqual(sum(by.values()), r.total_s, places=12)
        self.assertAlmostEqual(by["X"], r.block_time[0], places=12)
        self.assertAlmostEqual(by["C"], r.block_time[1], places=12)
        x = np.linspace(0, 10, 11)
        j = np.zeros((11, 5))
        j[:, 0] = x
        r = run(j, t_min=np.full(10, 0.5))            # 2 mm/s: the ramps take 2 um, within block 1
        by = r.time_by_limit()
        self.assertEqual(list(r.block_limit[1:-1]), [-1] * 8)
        self.assertAlmostEqual(by["feed"], 0.5 * 8, places=9)
        self.assertAlmostEqual(sum(by.values()), r.total_s, places=12)

    def test_vectorised_passes_match_a_plain_loop(self):
        rng = np.random.default_rng(3)
        d = rng.normal(size=400) * rng.uniform(0, 3, 400)
        d[rng.uniform(size=400) < 0.1] = 0.0
        t_min = rng.uniform(0, 0.05, 400)
        v, a = 40.0, 500.0
        got = axis_block_times(d, t_min, v, a)
        # Plain reference: caps, forward and backward loops, trapezoid per block.
        D = np.abs(d)
        Vc = [min(v, D[k] / t_min[k]) if t_min[k] > 0 else v for k in range(400)]
        cap = [0.0] + [min(Vc[k], Vc[k + 1]) if np.sign(d[k]) == np.sign(d[k + 1]) != 0 else 0.0
                       for k in range(399)] + [0.0]
        w = cap[:]
        for k in range(1, 401):
            w[k] = min(w[k], np.sqrt(w[k - 1] ** 2 + 2 * a * D[k - 1]))
        for k in range(399, -1, -1):
            w[k] = min(w[k], np.sqrt(w[k + 1] ** 2 + 2 * a * D[k]))
        ref = []
        for k in range(400):
            w0, w1, Dk, Vk = w[k], w[k + 1], D[k], Vc[k]
            if Dk == 0:
                ref.append(0.0)
                continue
            peak = np.sqrt(a * Dk + (w0 ** 2 + w1 ** 2) / 2)
            if peak <= Vk:
                ref.append((2 * peak - w0 - w1) / a)
            else:
                ref.append((Vk - w0) / a + (Vk - w1) / a + (Dk - (2 * Vk ** 2 - w0 ** 2 - w1 ** 2) / (2 * a)) / Vk)
        self.assertLess(np.abs(got - np.array(ref)).max(), 1e-9)


class PostedPrograms(unittest.TestCase):
    def machine(self, **changes):
        doc = json.load(open(os.path.join(shipped_dir(), "mikron_ucp600_heidenhain.json")))
        for n in "XYZ":
            doc["linear_axes"][n].update(max_velocity=6000.0, max_acceleration=1000.0)
        doc["rotary_axes"]["C"].update(max_velocity=9000.0, max_acceleration=1800.0)
        doc.update(changes)
        return machine_from_dict(doc, "<test>")

    def test_straight_cut_time(self):
        # Vertical tool along X, 100 mm at 6000 mm/min on axes of 6000 mm/min, 1000 mm/s^2: the
        # cutting block takes 1 s + 0.1 s of ramps (its neighbours move only Z).
        m = self.machine()
        tp = straight_path([[-50, 0, 10], [50, 0, 10]], [0, 0, 1], feed=6000.0)
        r = post_program(tp, m, "sinumerik")
        cut = np.nonzero(r.motion.move[1:] == Move.CUT)[0]
        self.assertEqual(len(cut), 1)
        self.assertAlmostEqual(r.time.block_time[cut[0]], 1.1, places=9)
        self.assertAlmostEqual(r.time.cut_s, 1.1, places=9)
        self.assertIn("machining time", r.time.summary())

    def test_rotary_limited_cut(self):
        # The tool axis turns 90 deg about C over 1 mm of tip motion near the C axis: C at
        # 9000 deg/min, 1800 deg/s^2 needs 90/150 + 150/1800 s; the block's F (Sinumerik, TRAORI:
        # the tip's feed) is 1 mm / (90/9000 min) = 100 mm/min, as G93 would ask 1/(90/9000).
        m = self.machine()
        th = np.radians(30)
        axis = np.array([[np.sin(th), 0, np.cos(th)], [0, np.sin(th), np.cos(th)]])
        tp = straight_path([[0.5, 0, 10], [-0.5, 0, 10]], axis, feed=1500.0)
        r = post_program(tp, m, "sinumerik", approach_distance=5.0)
        cut = np.nonzero(r.motion.move[1:] == Move.CUT)[0][0]
        self.assertAlmostEqual(abs(r.motion.joints[cut + 1, 4] - r.motion.joints[cut, 4]), 90.0, places=9)
        self.assertAlmostEqual(r.time.block_time[cut], 90 / 150 + 150 / 1800, places=9)
        self.assertEqual(r.time.limiting_blocks[4], 1 + 0)
        moves = [mv for mv in dialects.get("sinumerik").read(r.text) if mv.program]
        self.assertAlmostEqual(moves[cut + 1].feed, 100.0, places=3)

    def test_time_compares_orientation_strategies(self):
        # Same tips and feed, two tool-axis fields: constant lean versus a lean that wobbles
        # about the C axis. Length over feed is the same; the axis-limited time is not.
        n = 400
        x = np.linspace(-60, 60, n)
        pts = np.column_stack([x, 10 * np.sin(x / 15), np.full(n, 10.0)])
        steady = np.tile([np.sin(0.4), 0, np.cos(0.4)], (n, 1))
        phi = 0.9 * np.sin(np.arange(n) * 0.35)
        wobble = np.column_stack([np.sin(0.4) * np.cos(phi), np.sin(0.4) * np.sin(phi), np.full(n, np.cos(0.4))])
        m = self.machine()
        a = post_program(straight_path(pts, steady, 2000.0), m, "sinumerik")
        b = post_program(straight_path(pts, wobble, 2000.0), m, "sinumerik")
        self.assertAlmostEqual(a.time.feed_only_s, b.time.feed_only_s, delta=0.05 * a.time.feed_only_s)
        self.assertGreater(b.time.total_s, 1.5 * a.time.total_s)
        self.assertGreater(b.time.travel[4], 10 * a.time.travel[4] + 100)
        print(f"\n  steady lean {a.time.total_s:.2f} s, wobbling lean {b.time.total_s:.2f} s "
              f"(length/feed {a.time.feed_only_s:.2f} s)")


if __name__ == "__main__":
    unittest.main()
