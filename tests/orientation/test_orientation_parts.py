"""Orientation on the test parts: the keycap mold half and the impeller.

fcl shows the naive (vertical) axis collides (the holder with the mold's walls, the tool with
the impeller's overhanging blades), every strategy's result is collision-free when checked
again with the tool as fcl primitives, and smoothing lowers the largest angular step and the
rotary travel against the per-point closest-to-Z rule (shang2020), as xu2013 reports for its
impeller. The before/after figures go to build/artifacts/orientation_figures.json.
"""
import json
import unittest

import numpy as np

from tsplcam.errors import CollisionError, InputError
from tsplcam.model import samples
from tsplcam.model.cage import cage_model
from tsplcam.model.impeller import BLADES, R_OUT, impeller
from tsplcam.orientation.obstacles import impeller_mesh
from tsplcam.orientation import CollisionChecker, load_tool, orient
from tsplcam.orientation.testpaths import zigzag
from conftest import artifact_path

try:
    import fcl  # noqa: F401
except ImportError:                                       # pragma: no cover
    fcl = None

FIGURES = {}


def _save():
    with open(artifact_path("orientation_figures.json"), "w") as f:
        json.dump(FIGURES, f, indent=2)


class PartCase:
    """Shared checks; subclasses set up cls.model, cls.checker, cls.path."""

    def test_naive_axis_collides(self):
        z = np.tile([0.0, 0.0, 1.0], (len(self.path), 1))
        exact = self.checker.collides_exact(self.path.center, z)
        self.assertGreater(int(exact.sum()), 0)
        with self.assertRaises(CollisionError) as cm:
            orient(self.path, checker=self.checker, strategy="fixed")
        self.assertIn("patch", str(cm.exception))

    def test_strategies_collision_free_and_smoothing_wins(self):
        from tsplcam.post import load_machine
        from tsplcam.verify.orientation import orientation_metrics
        machine = load_machine("mikron_ucp600_heidenhain")
        res = {}
        for strategy in ("closest-z", "smooth"):
            out, rep = orient(self.path, checker=self.checker, strategy=strategy, machine=machine)
            self.assertEqual(int(self.checker.collides_exact(out.center, out.axis).sum()), 0, strategy)
            self.assertEqual(int(self.checker.ball_gouges(out.center).sum()), 0)
            # on the tool side of the surface, within the cone and the machine's tilt range
            self.assertTrue(np.all(np.einsum("ij,ij->i", out.axis, out.normal) > 0))
            self.assertLessEqual(np.degrees(np.arccos(np.clip(out.axis[:, 2], -1, 1))).max(), 115.0 + 1e-6)
            met = orientation_metrics(out, self.checker, machine)
            self.assertEqual(met.collisions, 0)
            self.assertGreaterEqual(met.min_clearance, 0.0)
            res[strategy] = met
            FIGURES.setdefault(self.name, {})[strategy] = {
                k: v for k, v in met.as_dict().items() if k != "extra"} | {"checks": rep.checks}
        before, after = res["closest-z"], res["smooth"]
        self.assertLess(after.max_step_deg, before.max_step_deg)
        self.assertLess(after.rotary_travel_deg, before.rotary_travel_deg)
        self.assertLess(after.time_s, before.time_s)
        _save()


@unittest.skipIf(fcl is None, "python-fcl missing")
class KeycapMold(PartCase, unittest.TestCase):
    name = "keycap_mold"

    @classmethod
    def setUpClass(cls):
        cls.model = cage_model(samples.keycap_mold())
        V, T = samples.keycap_mold_stock()
        cls.checker = CollisionChecker(cls.model, load_tool("ball1_keycap"), meshes=[("stock", V, T)],
                                       tolerance=0.005)
        cls.path = zigzag(cls.model, 0.5, lines=8, points=30)

    def test_rotary_weight_lowers_rotary_motion(self):
        """In the cavity the tilt follows the walls around, so C turns a lot: counting the
        rotary axis in the machine's time (the default weight) against leaving it out
        (0: the tilt and the tool-axis direction only) lowers the C travel and the
        machining-time estimate, still collision-free."""
        from tsplcam.post import load_machine
        from tsplcam.verify.orientation import orientation_metrics
        machine = load_machine("linuxcnc_xyzac_trt")
        res = {}
        for w in (0.0, None):
            out, rep = orient(self.path, checker=self.checker, strategy="smooth", machine=machine,
                              rotary_weight=w)
            self.assertEqual(int(self.checker.collides_exact(out.center, out.axis).sum()), 0)
            res[w] = orientation_metrics(out, self.checker, machine)
        # exact by construction: the default setting itself, reported back
        self.assertEqual(rep.settings["rotary_weight"], 2.0)      # equal A and C speeds, ROTARY_WEIGHT 2
        angle_only, weighted = res[0.0], res[None]
        self.assertLess(weighted.c_travel_deg, angle_only.c_travel_deg)
        self.assertLess(weighted.time_s, angle_only.time_s)
        for bad in ({"rotary_weight": -1.0}, {"smoothing_length": 0.0}, {"max_step": float("nan")}):
            with self.assertRaises(InputError):
                orient(self.path, checker=self.checker, strategy="smooth", machine=machine, **bad)
        with self.assertRaises(InputError):
            orient(self.path, checker=self.checker, strategy="smooth", rotary_weight=1.0)   # no machine
        FIGURES.setdefault(self.name, {})["rotary_weight"] = {
            "c_travel_deg": [angle_only.c_travel_deg, weighted.c_travel_deg],
            "time_s": [angle_only.time_s, weighted.time_s]}
        _save()

    def test_holder_hits_near_the_bottom(self):
        """On the cavity bottom near the walls a vertical axis puts the holder into the
        walls or the block (the shank and flutes stay clear there)."""
        bottom = self.path.patch == 4
        C = self.path.center[bottom]
        hits = [self.checker.hit(c, [0.0, 0.0, 1.0]) for c in C]
        parts = {h.part for h in hits if h is not None}
        self.assertEqual(parts, {"holder 1"})
        # the hits are near the walls: away from the centre of the bottom
        hit_xy = np.array([c[:2] for c, h in zip(C, hits) if h is not None])
        self.assertGreater(np.abs(hit_xy).max(axis=1).min(), 2.0)


@unittest.skipIf(fcl is None, "python-fcl missing")
class Impeller(PartCase, unittest.TestCase):
    name = "impeller"

    @classmethod
    def setUpClass(cls):
        cls.model = impeller()
        cls.checker = CollisionChecker(cls.model, load_tool("ball5_impeller"), meshes=impeller_mesh(cls.model),
                                       tolerance=0.01)
        cls.path = zigzag(cls.model, 2.5, lines=8, points=40)

    def test_part(self):
        V = np.vstack([m[1] for m in impeller_mesh(self.model)])
        r = np.hypot(V[:, 0], V[:, 1])
        self.assertAlmostEqual(2 * r.max(), 2 * R_OUT, delta=0.1)        # about 108 mm
        self.assertEqual(BLADES, 9)
        self.assertEqual([p.neighbours[2].patch if p.neighbours[2] else None for p in self.model.patches],
                         [1, 2, None])

    def test_only_tilted_axes_reach_the_root(self):
        """At the root of blade 0's pressure side in the exducer half, where the twisted
        blade overhangs the passage, the vertical axis is ruled out (collision, or the
        surface faces down) at nine points in ten or more; the smoothed axes reach all."""
        root = (self.path.patch == 0) & (self.path.uv[:, 1] > 0.7) & (self.path.uv[:, 0] < 0.5)
        z = np.tile([0.0, 0.0, 1.0], (int(root.sum()), 1))
        blocked = self.checker.collides_exact(self.path.center[root], z) | (self.path.normal[root, 2] <= 0)
        self.assertGreaterEqual(blocked.mean(), 0.9)
        out, _ = orient(self.path, checker=self.checker, strategy="smooth")
        tilt = np.degrees(np.arccos(np.clip(out.axis[root, 2], -1, 1)))
        self.assertGreater(tilt[blocked].min(), 0.5)

if __name__ == "__main__":
    unittest.main()
