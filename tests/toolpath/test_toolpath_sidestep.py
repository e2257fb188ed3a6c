"""Side-step, cusp and forward-step formulas (docs/method.md sections 3.2-3.4, 3.7)
and the curvature sign convention, against closed forms written here from the geometry."""
import unittest

import numpy as np

from tsplcam.model.bspline import bspline_patch
from conftest import arc_poles
from tsplcam.toolpath.lines import LineFrame
from tsplcam.toolpath.sidestep import (cusp_height, first_order_side_step, forward_step,
                                       parameter_step, side_step)




def sphere_band(R: float, beta: float = np.radians(40), alpha: float = np.radians(40), outward=True):
    """Exact NURBS piece of a sphere of radius R: azimuth -beta..beta (u), latitude
    -alpha..alpha (v). S_u x S_v points outward; ``outward=False`` reverses u."""
    az, wa = arc_poles(-beta, beta)
    pr, wp = arc_poles(-alpha, alpha)                  # (x, z) of the meridian
    poles = np.zeros((3, 3, 3))
    w = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            poles[i, j] = R * np.array([pr[j, 0] * az[i, 0], pr[j, 0] * az[i, 1], pr[j, 1]])
            w[i, j] = wa[i] * wp[j]
    if not outward:
        poles, w = poles[::-1], w[::-1]
    k = [0, 0, 0, 1, 1, 1]
    return bspline_patch(poles, w, k, k, 2, 2)




class SignConvention(unittest.TestCase):
    """Curvatures follow the normal: with the normal toward the tool, convex < 0."""

    def test_sphere_outward_normal_is_convex_negative(self):
        R = 7.0
        p = sphere_band(R)
        g = np.linspace(0.05, 0.95, 7)
        U, V = np.meshgrid(g, g)
        sp = p.evaluate(U.ravel(), V.ravel())
        # the normal points away from the centre (toward a tool outside the ball)
        self.assertTrue(np.all(np.einsum("ij,ij->i", sp.normal, sp.P) > 0.99 * R))
        k1, k2 = sp.principal_curvatures
        np.testing.assert_allclose(k1, -1.0 / R, atol=1e-9)
        np.testing.assert_allclose(k2, -1.0 / R, atol=1e-9)
        for crossfeed in ("u", "v"):
            fg = LineFrame(p, crossfeed, 0).evaluate(U.ravel(), V.ravel())
            np.testing.assert_allclose(fg.cross_curvature(), -1.0 / R, atol=1e-9)
            np.testing.assert_allclose(sp.cross_curvature("v" if crossfeed == "u" else "u"), -1.0 / R, atol=1e-9)

    def test_sphere_inner_side_is_concave_positive(self):
        R = 7.0
        p = sphere_band(R, outward=False)
        sp = p.evaluate([0.3, 0.5, 0.8], [0.5, 0.2, 0.7])
        self.assertTrue(np.all(np.einsum("ij,ij->i", sp.normal, sp.P) < -0.99 * R))
        np.testing.assert_allclose(sp.principal_curvatures[0], 1.0 / R, atol=1e-9)
        fg = LineFrame(p, "u", 0).evaluate([0.3, 0.5], [0.5, 0.5])
        np.testing.assert_allclose(fg.cross_curvature(), 1.0 / R, atol=1e-9)

    def test_convex_steps_shorter_than_flat_concave_longer(self):
        r, h = 1.0, 0.01
        flat = side_step(r, h, 0.0)
        self.assertLess(side_step(r, h, -0.1), flat)      # convex: k < 0
        self.assertGreater(side_step(r, h, 0.1), flat)    # concave: k > 0


class Formulas(unittest.TestCase):

    def test_post_notes_numbers(self):
        # docs/method.md 3.2: R=3, rho=8, h=0.02: exact 0.58915 convex, 0.87610 concave;
        # approximations 0.59084, 0.87636
        self.assertAlmostEqual(float(side_step(3.0, 0.02, -1 / 8)), 0.58915, places=5)
        self.assertAlmostEqual(float(side_step(3.0, 0.02, 1 / 8)), 0.87610, places=5)
        self.assertAlmostEqual(float(first_order_side_step(3.0, 0.02, -1 / 8)), 0.59084, places=5)
        self.assertAlmostEqual(float(first_order_side_step(3.0, 0.02, 1 / 8)), 0.87636, places=5)
        # flat: w = 2 sqrt(2 R h - h^2)
        self.assertAlmostEqual(float(side_step(3.0, 0.02, 0.0)), 2 * np.sqrt(2 * 3 * 0.02 - 0.02 ** 2), places=12)
        # 4.2: R=3, rho=5, delta=2 um: CL-based step 0.224 mm (convex)
        self.assertAlmostEqual(float(forward_step(3.0, 0.002, -1 / 5)), 2 * 5 * np.sqrt(2 * 0.002 / (5 + 3)),
                               places=12)
        self.assertAlmostEqual(float(forward_step(3.0, 0.002, -1 / 5)), 0.224, places=3)

    def test_side_step_leaves_exactly_h(self):
        """The step from side_step, turned into ball centres on the offset circle, leaves a cusp
        of exactly h; the cusp is found here by intersecting the two circles."""
        rng = np.random.default_rng(3)
        for _ in range(200):
            r = rng.uniform(0.2, 5.0)
            h = r * 10 ** rng.uniform(-5, -1.5)
            rho = r * 10 ** rng.uniform(0.05, 3)
            for sgn in (-1, 1):
                k = sgn / rho
                g = float(side_step(r, h, k))
                th = g / rho
                Rc = rho + r if sgn < 0 else rho - r           # ball centres' circle
                half = Rc * np.sin(th / 2)
                root = np.sqrt(r * r - half * half)
                q = Rc * np.cos(th / 2) + (-root if sgn < 0 else root)
                height = q - rho if sgn < 0 else rho - q
                self.assertAlmostEqual(height / h, 1.0, places=7, msg=(r, h, rho, sgn))
                w = 2 * half
                self.assertAlmostEqual(float(cusp_height(r, w, k)) / h, 1.0, places=7)

    def test_near_flat_is_stable(self):
        for k in (1e-12, -1e-12, 1e-9, -1e-9):
            self.assertAlmostEqual(float(side_step(2.0, 0.01, k)), float(side_step(2.0, 0.01, 0.0)), places=9)
            self.assertAlmostEqual(float(cusp_height(2.0, 0.4, k)), 2.0 - np.sqrt(4 - 0.04), places=10)

    def test_parameter_step_on_sheared_plane(self):
        """S(s, t) = (a s + b t, c t, 0): iso-lines s and s + ds are a c ds / sqrt(b^2 + c^2) apart."""
        a, b, c = 3.0, 1.5, 2.0
        E, F, G = a * a, a * b, b * b + c * c
        g = 0.2
        ds = float(parameter_step(g, E, F, G))
        self.assertAlmostEqual(a * c * ds / np.sqrt(b * b + c * c), g, places=12)
        # the paper's printed eq. (6) would give zero step for F = 0; this gives g / |S_s|
        self.assertAlmostEqual(float(parameter_step(g, E, 0.0, G)), g / a, places=12)


if __name__ == "__main__":
    unittest.main()
