"""The shank/holder clearance gauge against closed forms and fcl's own distance.

A ball-end tool touching a plane z = 0 at the origin with its axis tilted by theta from the
normal: every tool part is a frustum about the axis, whose lowest point lies on one of its
two rims, so the distance from part k to the plane is
``r + min(z cos(theta) - R sin(theta))`` over the rims (height z above the ball centre,
radius R). The gauge grows the parts until they touch the tessellated plane.
"""
import unittest

import numpy as np

import fcl

from conftest import cylinder_patch, keycap_mold_checker, one_patch_model
from tsplcam.model.bspline import bspline_patch
from tsplcam.orientation import CollisionChecker, load_tool
from tsplcam.orientation.collision import axis_quaternions, tool_primitives
from tsplcam.orientation.tool import ToolPart
from tsplcam.verify.orientation import (ClearanceGauge, clearance_levels, clearance_profile, min_clearance,
                                        offset_profile, revolved_mesh)


def big_plane(half=120.0):
    poles = np.array([[[-half, -half, 0], [-half, half, 0]], [[half, -half, 0], [half, half, 0]]], float)
    return one_patch_model(bspline_patch(poles, None, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1))


def within_bounds(got, want):
    """The gauge's stated accuracy: the bisection bracket (0.005 mm below 0.5 mm, 1 % above)
    above and below, and below also the circumscribed polygons (0.01 mm or 1 % of the growth)
    and corner arcs (0.005 mm or 1 % of the growth)."""
    half = np.maximum(0.005, 0.01 * want) + 1e-9
    return (got <= want + half) & (got >= want - half - np.maximum(0.01, 0.01 * want) - np.maximum(0.005, 0.01 * want))


def closed_form(tool, parts, theta, covered=False):
    """Distance from the named parts to the plane for a tilt theta (rad): the height of the
    lowest rim. ``covered``: of a part whose bottom another solid covers (the shank's on the
    flutes) only the plane's points above the bottom count: the nearest lies where the plane
    crosses the bottom's plane, at the rim's height over the sine of the tilt across the
    axis."""
    r = tool.ball_radius
    dist = []
    for p, (bottom, _) in zip(tool.parts(), tool.exposed_ends()):
        if p.name in parts:
            h = [r + p.z0 * np.cos(theta) - p.r0 * np.sin(theta), r + p.z1 * np.cos(theta) - p.r1 * np.sin(theta)]
            dist.append(min(h) if bottom or not covered else min(h) / np.sin(theta))
    return min(dist)


class PlaneClearance(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tool = load_tool("ball1_keycap")
        cls.checker = CollisionChecker(big_plane(), cls.tool)
        theta = np.radians(np.linspace(2.0, 50.0, 13))
        phi = np.radians(np.linspace(0.0, 330.0, 13))          # the azimuth changes nothing
        cls.theta = theta
        cls.axes = np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
        cls.centers = np.tile([0.0, 0.0, cls.tool.ball_radius], (len(theta), 1))

    def check(self, parts, got, top=10.0, covered=False):
        want = np.array([closed_form(self.tool, parts, t, covered) for t in self.theta])
        far = want > top
        self.assertTrue(np.all(np.isinf(got[far])), (got[far], want[far]))
        near = ~far
        err = got[near] - want[near]
        self.assertTrue(np.all(within_bounds(got[near], want[near])), (got[near], want[near]))
        return want

    def test_shank(self):
        got = clearance_profile(self.checker, self.centers, self.axes, parts=["shank"])
        want = self.check(["shank"], got)
        self.assertLess(want.min(), 0.8)                  # the steep poses come close
        above = clearance_profile(self.checker, self.centers, self.axes, parts=["shank"], covered=True)
        self.check(["shank"], above, covered=True)

    def test_holder(self):
        names = [p.name for p in self.tool.parts() if p.name.startswith("holder")]
        gauge = ClearanceGauge(self.checker, names)
        got = gauge.measure(self.centers, self.axes)
        self.check(names, got)
        again = gauge.measure(self.centers, self.axes)    # grown tools kept: same answers
        self.assertTrue(np.array_equal(got, again, equal_nan=True))

    def test_default_parts_are_shank_and_holder(self):
        got = clearance_profile(self.checker, self.centers, self.axes)
        self.check([p.name for p in self.tool.parts() if p.name != "flutes"], got)
        with self.assertRaises(ValueError):
            ClearanceGauge(self.checker, ["spindle"])

    def test_smallest_clearance_is_the_shank_and_holder(self):
        """The orientation metrics' smallest clearance: of the parts that keep it (the flutes,
        which come closer at the steep poses, are left out), the closed form's smallest over
        the poses, and the same pose and value as fcl.distance measured at every pose."""
        keep = [p.name for p in self.tool.parts() if p.name != "flutes"]
        want = np.array([closed_form(self.tool, keep, t, covered=True) for t in self.theta])
        solid = np.array([closed_form(self.tool, keep, t) for t in self.theta])
        flutes = np.array([closed_form(self.tool, ["flutes"], t) for t in self.theta])
        self.assertLess(flutes.min(), solid.min() - 0.3)
        got, at = min_clearance(self.checker, self.centers, self.axes)
        only, margin = self.checker.clearance_parts()
        every = self.checker.clearance_of(self.centers, self.axes, only) + margin
        self.assertEqual(at, int(np.argmin(every)))
        self.assertAlmostEqual(got, float(every.min()), delta=1e-12)
        # the shank's bottom rim is the closest: measured to the grown shank (not grown below
        # its bottom, which the flutes cover), so between the rim's own distance and the
        # margin more, and below what the gauge measures above the bottom
        self.assertGreaterEqual(got, float(solid.min()) - 1e-3)
        self.assertLessEqual(got, float(solid.min()) + self.checker.margin + 1e-3)
        self.assertLess(got, float(want.min()))
        # the shortcut the mold's tests take: every pose within reach measured as here
        first = np.argsort(every, kind="stable")[:4]
        near = fcl_distances_up_to(self.checker, self.centers, self.axes, only,
                                   float(every[first[-1]] - margin) + 1e-6) + margin
        self.assertTrue(np.array_equal(near[first], every[first]))
        self.assertTrue(np.all(near >= every))


    def test_touching_bound(self):
        """A pose that touches at a growth lies within ``touching_bound`` of it (fcl.distance
        on the primitives), and the smallest distance measured against that bound is the
        same value at the same first pose as measured without it."""
        only, _ = self.checker.clearance_parts()
        every = self.checker.clearance_of(self.centers, self.axes, only)
        for grow in (0.05, 0.2, 0.5, 1.0, 3.0):
            hit, _ = self.checker.collides_parts(self.centers, self.axes, grow, only=only)
            bound = self.checker.touching_bound(grow)
            self.assertTrue(np.all(every[hit] <= bound), (grow, every[hit], bound))
            if hit.any():
                rows = np.nonzero(hit)[0]
                plain = self.checker.clearance_of(self.centers[rows], self.axes[rows], only, smallest=True)
                bounded = self.checker.clearance_of(self.centers[rows], self.axes[rows], only, smallest=True,
                                                    below=bound)
                self.assertEqual(int(np.argmin(plain)), int(np.argmin(bounded)))
                self.assertEqual(float(plain.min()), float(bounded.min()))   # the same fcl query


class CurvedClearance(unittest.TestCase):
    """Poses on a convex and a concave cylinder (R 6 mm), axes tilted up to 45 deg from the
    normal at random, against fcl.distance on the exact shank and holder primitives."""

    def test_against_fcl_distance(self):
        tool = load_tool("ball1_keycap")
        rng = np.random.default_rng(7)
        prims = [(fcl.CollisionObject(g, fcl.Transform()), z)
                 for name, g, z in tool_primitives(tool, 0.0, 0.001) if name != "flutes"]
        for outward in (True, False):
            model = one_patch_model(cylinder_patch(6.0, 40.0, beta=1.2, outward=outward))
            checker = CollisionChecker(model, tool, tolerance=0.002)
            u, v = rng.uniform(0.3, 0.7, 24), rng.uniform(0.3, 0.7, 24)
            sp = model.patches[0].evaluate(u, v)
            n = sp.normal
            side = np.cross(n, rng.normal(size=(24, 3)))
            side /= np.linalg.norm(side, axis=1, keepdims=True)
            tilt = np.radians(rng.uniform(0.0, 45.0, 24))[:, None]
            axes = np.cos(tilt) * n + np.sin(tilt) * side
            centers = sp.P + tool.ball_radius * n
            got = clearance_profile(checker, centers, axes, top=20.0)
            above = clearance_profile(checker, centers, axes, top=20.0, covered=True)   # above the shank's bottom
            self.assertTrue(np.all(above >= got), np.column_stack([above, got]))
            exact = np.empty(len(axes))
            for i, q in enumerate(axis_quaternions(axes)):
                best = np.inf
                for obj, z in prims:
                    obj.setQuatRotation(q)
                    obj.setTranslation(centers[i] + z * axes[i])
                    best = min(best, fcl.distance(obj, checker._wp, fcl.DistanceRequest(), fcl.DistanceResult()))
                exact[i] = max(best, 0.0)
            self.assertTrue(np.all(np.isfinite(got)))
            # the mesh lies within the tessellation tolerance of the surface: both see the mesh
            self.assertTrue(np.all(within_bounds(got, exact)), np.column_stack([got, exact]))


class Offsets(unittest.TestCase):
    def test_grown_profile_contains_the_offset_and_stays_close(self):
        for part in (ToolPart("holder", 2.0, 8.0, 2.5, 5.0), ToolPart("shank", 1.0, 5.0, 0.5, 0.5),
                     ToolPart("neck", 1.0, 3.0, 2.0, 1.0)):
            g = 0.7
            r, z = offset_profile(part, g)
            self.assertEqual((r[0], r[-1]), (0.0, 0.0))
            self.assertAlmostEqual(z[0], part.z0 - g)
            self.assertAlmostEqual(z[-1], part.z1 + g)
            # every point of the grown profile lies between g and g / cos(7.5 deg) from the
            # part's profile polygon, and its edges never come closer than g either
            t = np.linspace(0.0, 1.0, 50)
            pts = np.concatenate([np.column_stack([r[k] + (r[k + 1] - r[k]) * t, z[k] + (z[k + 1] - z[k]) * t])
                                  for k in range(len(r) - 1)])
            pts = pts[pts[:, 0] > 1e-9]                   # the axis ends are inside the solid
            corners = np.array([[0.0, part.z0], [part.r0, part.z0], [part.r1, part.z1], [0.0, part.z1]])
            dist = np.full(len(pts), np.inf)
            for a, b in zip(corners[:-1], corners[1:]):
                w = np.clip(((pts - a) @ (b - a)) / ((b - a) @ (b - a)), 0.0, 1.0)
                dist = np.minimum(dist, np.linalg.norm(pts - (a + w[:, None] * (b - a)), axis=1))
            self.assertGreaterEqual(dist.min(), g - 1e-9, part)
            self.assertLessEqual(dist.max(), g / np.cos(np.radians(7.5)) + 1e-9, part)
        self.assertEqual(len(offset_profile(ToolPart("x", 0.0, 1.0, 1.0, 1.0), 0.0)[0]), 4)

    def test_exposed_ends(self):
        """Which end faces are the tool's surface: the keycap tool's flutes sit on the ball
        and its shank on flutes as wide (covered), its holder cone's bottom is wider than the
        shank and its cylinder wider than the cone's top (exposed), the cone's top lies under
        the cylinder; a shank wider than the flutes shows its bottom; a shank narrower than the
        ball that starts at its centre (no flutes above the ball) sits on the ball."""
        self.assertEqual(load_tool("ball1_keycap").exposed_ends(),
                         [(False, False), (False, False), (True, False), (True, True)])
        from tsplcam.orientation.tool import Tool
        wide = Tool("wide", ball_radius=0.5, flute_length=1.5, shank_diameter=3.0, shank_length=6.0)
        self.assertEqual(wide.exposed_ends(), [(False, False), (True, True)])
        neck = Tool("neck", ball_radius=1.0, flute_length=1.0, shank_diameter=1.5, shank_length=6.0)
        self.assertEqual(neck.exposed_ends(), [(False, True)])

    def test_grown_frustum_holds_the_offset(self):
        """The checker's grown part (:func:`grown_frustum`) holds the part's offset (every
        vertex of :func:`offset_profile`'s polyline, which contains the arcs) and touches it
        along the side: its side lies exactly ``g`` from the part's side, across the side."""
        from tsplcam.orientation.collision import grown_frustum
        for part in (ToolPart("holder", 2.0, 8.0, 2.5, 5.0), ToolPart("shank", 1.0, 5.0, 0.5, 0.5),
                     ToolPart("neck", 1.0, 3.0, 2.0, 1.0), ToolPart("steep", 1.0, 1.5, 1.0, 4.0)):
            for g in (0.05, 0.3, 1.7):
                for bottom in (True, False):
                    z0, z1, r0, r1 = grown_frustum(part.z0, part.z1, part.r0, part.r1, g, bottom=bottom)
                    r, z = offset_profile(part, g, max_angle=5.0, bottom=bottom)
                    self.assertGreaterEqual(z.min(), z0 - 1e-12)
                    self.assertLessEqual(z.max(), z1 + 1e-12)
                    R = r0 + (z - z0) * (r1 - r0) / (z1 - z0)
                    # the polyline's corners stray g (1 / cos 2.5 deg - 1) outside the arcs
                    self.assertTrue(np.all(r <= R + g * (1.0 / np.cos(np.radians(2.5)) - 1.0) + 1e-12),
                                    (part, g, bottom))
                    s = (part.r1 - part.r0) / (part.z1 - part.z0)
                    mid = 0.5 * (part.z0 + part.z1)
                    across = (r0 + (mid - z0) * (r1 - r0) / (z1 - z0) - (part.r0 + (mid - part.z0) * s)) \
                        / np.sqrt(1.0 + s * s)
                    self.assertAlmostEqual(across, g, delta=1e-12)

    def test_revolved_mesh_is_closed(self):
        V, T = revolved_mesh([offset_profile(ToolPart("shank", 1.0, 5.0, 0.5, 0.5), 0.3)], 0.01)
        edges = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
        _, count = np.unique(edges, axis=0, return_counts=True)
        self.assertTrue(np.all(count == 2))                 # every edge shared by two triangles
        rad = np.hypot(V[:, 0], V[:, 1])
        self.assertLessEqual(rad.max(), 0.8 / np.cos(np.radians(7.5)) / np.cos(np.pi / 12) + 1e-9)

    def test_levels(self):
        lv = clearance_levels(10.0)
        self.assertEqual(lv[0], 0.0)
        self.assertAlmostEqual(lv[-1], 10.0)
        self.assertTrue(np.all(np.diff(lv) > 0))
        fine = lv[lv < 0.5]
        self.assertTrue(np.allclose(np.diff(fine), 0.01))
        big = lv[lv >= 0.5]
        self.assertLess((big[1:] / big[:-1]).max(), 1.0201)


if __name__ == "__main__":
    unittest.main()


def fcl_distances_up_to(checker, centers, axes, only: int, reach: float, slices: int = 16) -> np.ndarray:
    """fcl.distance of every pose (``checker.clearance_of``, the parts in the bit mask
    ``only``) wherever it may be at most ``reach``, inf where fcl.collide proves it larger:
    the smallest value and its first pose are those of clearance_of at every pose whenever
    that smallest value is below ``reach`` (else the smallest here is larger than it, or inf).

    Every point within ``reach`` of a part's primitive (a cylinder, or a frustum's
    circumscribed polygon, its corners within ``polygon_tolerance`` of the circle) lies in one
    of the cylinders of ``slices`` slices of its length, each of the slice's largest radius
    (plus the polygon's excess) and ``reach`` more, and ``2 reach`` longer; where none of them
    touches the workpiece, the part lies farther (a distance query costs about a hundred
    collision queries: on the mold, 20 poses of 542 are measured, 0.7 s instead of 10 s)."""
    Q = axis_quaternions(axes)
    req = fcl.CollisionRequest()
    near = np.zeros(len(centers), np.int64)                  # per pose: the parts within reach
    prof = checker.profile(0.0)                              # the primitives: the grown parts
    for j in range(len(prof.z0)):
        if not (only >> j) & 1:
            continue
        z0, z1, r0, r1 = prof.z0[j], prof.z1[j], prof.rin0[j], prof.rin1[j]
        k, excess = (1, 0.0) if abs(r1 - r0) < 1e-12 else (slices, checker.polygon_tolerance)
        length = (z1 - z0) / k
        cyl = []
        for i in range(k):
            rho = max(r0 + (r1 - r0) * i / k, r0 + (r1 - r0) * (i + 1) / k) + excess
            cyl.append((fcl.CollisionObject(fcl.Cylinder(rho + reach, length + 2 * reach), fcl.Transform()),
                        z0 + (i + 0.5) * length))
        for q in range(len(centers)):
            for obj, z in cyl:
                obj.setQuatRotation(Q[q])
                obj.setTranslation(centers[q] + z * axes[q])
                if fcl.collide(obj, checker._wp, req, fcl.CollisionResult()):
                    near[q] |= 1 << j
                    break
    out = np.full(len(centers), np.inf)
    for mask in np.unique(near[near != 0]):
        sel = near == mask
        out[sel] = checker.clearance_of(centers[sel], axes[sel], int(mask))
    return out


class MoldSmallestClearance(unittest.TestCase):
    """The smallest clearance over collision-free poses in the keycap mold's cavity (the holder
    near the block): the search that starts from scouts stands where the descent from every pose does,
    so both give the same pose and value, those of fcl.distance measured at every pose (at every
    pose fcl.collide cannot prove farther: :func:`fcl_distances_up_to`)."""

    def assert_scouts_find_fcl_smallest(self, checker, centers, axes):
        """min_clearance from its scouts gives the pose and distance of the search without
        them, with fewer fcl queries, and both those of fcl.distance at every pose."""
        only, margin = checker.clearance_parts()
        n0 = checker.fcl_checks
        got = min_clearance(checker, centers, axes)
        n1 = checker.fcl_checks
        plain = min_clearance(checker, centers, axes, scouts=0)
        n2 = checker.fcl_checks
        self.assertEqual(got[1], plain[1])                        # the same pose
        self.assertAlmostEqual(got[0], plain[0], delta=1e-12)      # and its fcl distance
        self.assertLess(n1 - n0, n2 - n1)
        every = fcl_distances_up_to(checker, centers, axes, only, got[0] - margin + 1e-3) + margin
        self.assertEqual(got[1], int(np.argmin(every)))
        self.assertAlmostEqual(got[0], float(every.min()), delta=1e-12)

    def test_scouts_against_every_pose(self):
        from tsplcam.orientation.testpaths import zigzag
        from tsplcam.verify.orientation import _bounded, _scouted
        mold, checker = keycap_mold_checker(clearance=0.3)
        path = zigzag(mold, 0.5, lines=12, points=32)
        rng = np.random.default_rng(3)
        up = np.array([0.0, 0.0, 1.0])                          # axes within 25 deg of +z
        tilt = np.radians(rng.uniform(0.0, 25.0, len(path)))[:, None]
        side = np.cross(up, rng.normal(size=(len(path), 3)))
        side /= np.linalg.norm(side, axis=1, keepdims=True)
        axes = np.cos(tilt) * up + np.sin(tilt) * side
        centers = path.contact + 0.5 * path.normal
        free = ~checker.collides(centers, axes)                 # the poses an orientation keeps
        centers, axes = centers[free], axes[free]
        only, _ = checker.clearance_parts()
        levels = sorted((0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0))
        self.assertIsNotNone(_scouted(checker, centers, axes, levels, 3, only, 40, 32))   # the scouts' way
        self.assertIsNotNone(_bounded(checker, centers, axes, levels[3], only, 32))       # and their bound
        self.assert_scouts_find_fcl_smallest(checker, centers, axes)

    def test_free_poses_keep_the_clearance(self):
        """Every pose the checker passes keeps the shank and holder the clearance from the
        keycap mold and its stock, by the gauge (true offsets, rounded at the rims; shank
        above its bottom, which the flutes cover): axes up to 40 deg from the vertical in the
        cavity, where the holder's lower rim meets the stock's top edge. With the parts grown
        across the axis only (before 2026-11-29), 20 of the 828 free poses brought the holder
        0.085-0.29 mm close."""
        from tsplcam.orientation.testpaths import zigzag
        mold, checker = keycap_mold_checker(clearance=0.3)
        path = zigzag(mold, 0.5, lines=16, points=40)
        rng = np.random.default_rng(11)
        up = np.array([0.0, 0.0, 1.0])
        tilt = np.radians(rng.uniform(0.0, 40.0, len(path)))[:, None]
        side = np.cross(up, rng.normal(size=(len(path), 3)))
        side /= np.linalg.norm(side, axis=1, keepdims=True)
        axes = np.cos(tilt) * up + np.sin(tilt) * side
        centers = path.contact + 0.5 * path.normal
        free = ~checker.collides(centers, axes)
        self.assertGreater(free.sum(), 100)
        got = clearance_profile(checker, centers[free], axes[free], covered=True)
        # the gauge reads up to half its 0.01 mm bracket high and the polygons' 0.01 mm low
        self.assertGreaterEqual(got.min(), checker.clearance - 0.005, np.sort(got)[:5])

    @staticmethod
    def tilted_keycap(tilt_deg: float = 20.0, seed: int = 8):
        """(checker, centres, axes): a keycap path with every axis ``tilt_deg`` off its normal."""
        from tsplcam.model import samples
        from tsplcam.model.cage import cage_model
        from tsplcam.orientation.testpaths import zigzag
        keycap = cage_model(samples.keycap())
        checker = CollisionChecker(keycap, load_tool("ball1_keycap"), clearance=0.3)
        path = zigzag(keycap, 0.5, lines=10, points=30)
        rng = np.random.default_rng(seed)
        side = np.cross(path.normal, rng.normal(size=(len(path), 3)))
        side /= np.linalg.norm(side, axis=1, keepdims=True)
        tilt = np.radians(tilt_deg)
        return checker, path.contact + 0.5 * path.normal, np.cos(tilt) * path.normal + np.sin(tilt) * side

    def test_ascent_on_the_keycap(self):
        """The keycap with every axis 20 deg off its normal: no pose touches at 0.5 mm (the
        grown parts first touch at 3 mm), so the scouts go up the levels first; every pose is
        asked at the level below their first touching one and at that one only, and the
        search gives the pose and value of the ascent over every pose (scouts=0)."""
        from tsplcam.verify.orientation import CLEARANCE_LEVELS, _ascended, _bounded
        checker, centers, axes = self.tilted_keycap()
        only, _ = checker.clearance_parts()
        levels = sorted(CLEARANCE_LEVELS)
        self.assertIsNone(_bounded(checker, centers, axes, levels[3], only, 32))   # none near at 0.5 mm
        first = next(i for i in range(3, len(levels))                            # the ascent's level
                     if checker.collides_parts(centers, axes, levels[i], only=only)[0].any())
        self.assertGreater(first, 3)                                               # above the start
        hit, _ = checker.collides_parts(centers, axes, levels[first], only=only)
        for scouts in (32, 8):          # (8 scouts touch first at 4 mm, above the ascent's 3 mm: a descent)
            up = _ascended(checker, centers, axes, levels, 3, only, scouts)
            self.assertIsNotNone(up)
            self.assertEqual(up[2], first, scouts)
            np.testing.assert_array_equal(up[0], np.nonzero(hit)[0])
        got = min_clearance(checker, centers, axes)
        plain = min_clearance(checker, centers, axes, scouts=0)
        self.assertEqual(got[1], plain[1])
        self.assertAlmostEqual(got[0], plain[0], delta=1e-12)

    def test_sampled_narrowing(self):
        """Where many poses touch, the bisection first narrows by a spread sample of them
        (figure4: 72,755 poses touching at 5 mm, its search 2.5 -> 1.5 s): the same pose and
        value as bisecting them all (the keycap tilted 20 deg, 93 poses touching at 3 mm:
        sampled from 64 poses up against never, bisected down to 4 poses)."""
        from unittest import mock

        from tsplcam.verify import orientation as VO
        checker, centers, axes = self.tilted_keycap()
        with mock.patch.object(VO, "SAMPLED", 10 ** 9):
            whole = min_clearance(checker, centers, axes, exact=4)
        asked = []
        ask = checker.collides_parts

        def counted(C, A, grow, parts=None, only=-1):
            asked.append(len(C))
            return ask(C, A, grow, parts=parts, only=only)
        with mock.patch.object(VO, "SAMPLED", 64), mock.patch.object(checker, "collides_parts", counted):
            sampled = min_clearance(checker, centers, axes, exact=4)
        self.assertIn(16, asked)                                   # the sample was bisected
        self.assertEqual(sampled[1], whole[1])
        self.assertAlmostEqual(sampled[0], whole[0], delta=1e-12)

    @unittest.expectedFailure
    def test_smallest_next_to_a_part_end(self):
        """KNOWN TO FAIL (left for a later pass): on the keycap tilted 20 deg the search gives
        1.42795 mm at pose 1342 where fcl.distance at every pose gives 1.42766 mm at pose 1401
        (figure4's job: 1.61241 mm at 49056). The growths do not grow a bottom another solid
        covers (the shank's on the flutes: below it the flutes rule, as in the checker),
        while fcl.distance measures to the grown shank from below it too; so a pose nearest
        the workpiece there need not touch at a growth above that distance, and the
        bisection keeps other poses. Growing those bottoms too makes the answers fcl's
        (1.14942 mm at 1342, both) but the keycap job's search asked 18,440 poses of fcl
        instead of 3,561 (0.25 s against 0.10): a distance measured above the bottom only is
        the way. Both figures are lower bounds of the gauge's (test below)."""
        checker, centers, axes = self.tilted_keycap()
        only, margin = checker.clearance_parts()
        got = min_clearance(checker, centers, axes)
        every = fcl_distances_up_to(checker, centers, axes, only, got[0] - margin + 1e-3) + margin
        self.assertEqual(got[1], int(np.argmin(every)))

    def test_smallest_is_a_lower_bound_of_the_gauge(self):
        """The keycap tilted 20 deg: the smallest clearance lies below the gauge's (the true
        offsets of the shank above its bottom, which the flutes cover, and of the holder:
        2.77 mm) and above the distance to the parts' whole solids (the shank's bottom rim:
        1.23 mm), within the gauge's bracket: the grown shank lies within the margin of
        the shank (its bottom is not grown), so from below it too the figure is no more than
        the margin short of the solid's distance."""
        checker, centers, axes = self.tilted_keycap()
        got, _ = min_clearance(checker, centers, axes)
        above = clearance_profile(checker, centers, axes, covered=True).min()
        whole = clearance_profile(checker, centers, axes).min()
        self.assertLess(whole, above - 1.0)
        self.assertLessEqual(got, above * 1.01)
        self.assertGreaterEqual(got, whole * 0.98 - 0.01)

    def test_bound_on_the_keycap(self):
        """The keycap (convex): no scout touches below 0.5 mm, so no level is skipped; the
        scouts' own smallest clearance bounds it instead, and the search from there gives the
        pose and value of fcl.distance at every pose, with fewer collision queries than the
        descent from the levels."""
        from tsplcam.model import samples
        from tsplcam.model.cage import cage_model
        from tsplcam.orientation.testpaths import zigzag
        from tsplcam.verify.orientation import _bounded
        keycap = cage_model(samples.keycap())
        checker = CollisionChecker(keycap, load_tool("ball1_keycap"), clearance=0.3)
        path = zigzag(keycap, 0.5, lines=10, points=30)
        rng = np.random.default_rng(5)
        side = np.cross(path.normal, rng.normal(size=(len(path), 3)))
        side /= np.linalg.norm(side, axis=1, keepdims=True)
        tilt = np.radians(rng.uniform(20.0, 60.0, len(path)))[:, None]
        axes = np.cos(tilt) * path.normal + np.sin(tilt) * side
        centers = path.contact + 0.5 * path.normal
        free = ~checker.collides(centers, axes)
        centers, axes = centers[free], axes[free]
        only, _ = checker.clearance_parts()
        got = _bounded(checker, centers, axes, 0.5, only, 32)
        self.assertIsNotNone(got)
        self.assertLess(got[2], 0.5)
        self.assert_scouts_find_fcl_smallest(checker, centers, axes)
        self.bound_from_a_scout_measured_too_near(checker, centers, axes)

    def bound_from_a_scout_measured_too_near(self, checker, centers, axes):
        """A scout whose distance lies below the growth at which it touches (a part's covered
        bottom, measured by fcl.distance but never grown: the keycap job's closest scout, 0.3025
        mm against 0.3409), made here by taking 0.05 mm off the scouts' distances: the
        bound still stands (the scouts' touching growth, then every pose bisected up from
        below it), and the search gives the pose and value of the search without scouts."""
        from unittest import mock
        from tsplcam.verify import orientation as VO
        only, _ = checker.clearance_parts()
        real = VO._smallest_of
        calls = []

        def too_near(*args):
            d = real(*args)
            calls.append(len(calls))
            return d - 0.05 if len(calls) == 1 else d          # the scouts' distances only
        with mock.patch.object(VO, "_smallest_of", too_near):
            bound = VO._bounded(checker, centers, axes, 0.5, only, 32)
        self.assertIsNotNone(bound)
        pick, parts, g, below = bound
        calls.clear()
        near = real(checker, centers[VO._scout_rows(len(centers), 32)], axes[VO._scout_rows(len(centers), 32)],
                    only, 0.5)
        self.assertGreater(g, float(near[np.isfinite(near)].min()) - 0.05 + 1e-4)   # not the measured bound
        self.assertTrue(checker.collides_parts(centers[pick], axes[pick], g, only=only)[0].all())
        if below > 0:                                             # none touches there
            self.assertFalse(checker.collides_parts(centers, axes, below, only=only)[0].any())
        with mock.patch.object(VO, "_smallest_of", too_near):
            got = min_clearance(checker, centers, axes)
        plain = min_clearance(checker, centers, axes, scouts=0)
        self.assertEqual(got[1], plain[1])
        self.assertAlmostEqual(got[0], plain[0], delta=1e-12)


class GrownPartTouches(unittest.TestCase):
    """``CollisionChecker._touches_grown`` (whether a part, grown by the smallest distance so
    far, could lie nearer: else its distance query is spared) asked as meshes: wherever the
    grown primitive touches the workpiece, so does the mesh of its circumscribed polygons, and
    a piece of the workpiece wholly inside (which meets no triangle of it) is found too."""

    @staticmethod
    def primitive_touches(checker, part, center, axis, by):
        """The reference: the grown primitive itself (an ``fcl.Cylinder`` or ``fcl.Convex``)."""
        from tsplcam.orientation.collision import frustum_shape, grown_frustum
        _, z0, z1, r0, r1 = checker._frustums[part]
        z0, z1, r0, r1 = grown_frustum(z0, z1, r0, r1, by)
        pad = checker.polygon_tolerance if abs(r1 - r0) > 1e-12 else 0.0
        obj = fcl.CollisionObject(frustum_shape(r0 + pad, r1 + pad, z1 - z0, checker.polygon_tolerance),
                                  fcl.Transform())
        obj.setQuatRotation(axis_quaternions(axis)[0])
        obj.setTranslation(center + 0.5 * (z0 + z1) * axis)
        return bool(fcl.collide(obj, checker._wp, checker._req, fcl.CollisionResult()))

    def test_holds_the_grown_primitive(self):
        checker, centers, axes = MoldSmallestClearance.tilted_keycap()
        rows = np.arange(0, len(centers), 7)
        q = axis_quaternions(axes[rows])
        n = same = 0
        for part in (1, 2, 3):                                   # shank, holder cone, holder
            for by in (0.3, 1.0, 2.5):
                for k, i in enumerate(rows):
                    want = self.primitive_touches(checker, part, centers[i], axes[i], by)
                    got = checker._touches_grown(part, q[k], centers[i], axes[i], by)
                    if want:
                        self.assertTrue(got, (part, by, int(i)))
                    n += 1
                    same += want == got
        self.assertGreater(same, 0.97 * n)                       # a hair larger: seldom more

    def test_a_piece_wholly_inside(self):
        """A small triangle by itself inside the grown holder, far from the keycap: no triangle
        of the grown mesh meets it, one of its vertices inside shows it."""
        from tsplcam.model import samples
        from tsplcam.model.cage import cage_model
        tool = load_tool("ball1_keycap")
        keycap = cage_model(samples.keycap())
        center, axis = np.array([0.0, 0.0, 80.0]), np.array([0.0, 0.0, 1.0])
        _, z0, z1, r0, r1 = CollisionChecker(keycap, tool, clearance=0.3)._frustums[-1]    # the holder's top
        z = center[2] + 0.5 * (z0 + z1)
        chip = ("chip", np.array([[0.0, 0.0, z], [0.2, 0.0, z], [0.0, 0.2, z]]), np.array([[0, 1, 2]]))
        checker = CollisionChecker(keycap, tool, meshes=[chip], clearance=0.3)
        part = len(checker._frustums) - 1
        q = axis_quaternions(axis[None])[0]
        self.assertTrue(self.primitive_touches(checker, part, center, axis, 0.5))
        self.assertTrue(checker._touches_grown(part, q, center, axis, 0.5))
        grown = checker._grown_objects[(part, 0.5)]                  # its mesh meets no triangle
        self.assertFalse(fcl.collide(grown, checker._wp, checker._req, fcl.CollisionResult()))
        self.assertFalse(checker._touches_grown(part, q, center + [0.0, 0.0, z1 - z0 + 5.0], axis, 0.5))


class GrownShankLeftToFcl(unittest.TestCase):
    def test_same_hits_as_fcl_alone(self):
        """A grown tool (the clearance measurement) whose shank (a cylinder) the spheres
        leave open is left to fcl whole: the side pass does not bound its cones (it could not
        make the pose free; figure4's search spent 9.6 s there). The answers are fcl's: the
        same hits as fcl alone, at growths where most poses are open by the shank and some
        touch; and the side grid made no node for them."""
        import tsplcam
        model = tsplcam.load_model("keycap")
        tool = load_tool("ball1_keycap")
        rng = np.random.default_rng(4)
        patch = model.patches[4]
        sp = patch.evaluate(rng.random(400), rng.random(400))
        tilt = np.radians(rng.uniform(0.0, 40.0, 400))
        az = rng.uniform(0.0, 2 * np.pi, 400)
        A = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
        C = sp.P + tool.ball_radius * sp.normal
        broad = CollisionChecker(model, tool, clearance=0.3)
        alone = CollisionChecker(model, tool, clearance=0.3, broad_phase=False)
        only, _ = broad.clearance_parts()
        for grow in (3.0, 5.0):
            got, masks = broad.collides_parts(C, A, grow, only=only)
            want, _ = alone.collides_parts(C, A, grow, only=only)
            np.testing.assert_array_equal(got, want, err_msg=f"grow {grow}")
            self.assertTrue(0 < got.sum() < len(got), grow)
        grid = broad.broad._side_grid
        self.assertTrue(grid is None or grid.nodes == 0)
