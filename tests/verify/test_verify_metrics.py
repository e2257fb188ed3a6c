"""The tool axes' motion figures without a machine (the simple A/C model of
:mod:`tsplcam.verify.orientation`): A is the axis's angle from +z, C its azimuth atan2(Kx, -Ky)
unwound, held through the pole; the rotary travel is the sum of their steps."""
import unittest

import numpy as np

from tsplcam.toolpath.path import ToolPath
from tsplcam.verify.orientation import _simple_ac, orientation_metrics


def axes_from(A_deg, C_deg):
    a, c = np.radians(A_deg), np.radians(C_deg)
    return np.column_stack([np.sin(a) * np.sin(c), -np.sin(a) * np.cos(c), np.cos(a)])


class SimpleAC(unittest.TestCase):
    def test_angles_unwound_and_held_at_the_pole(self):
        """Axes of known A and C (C winding past 180 deg, two points on the pole, one of them
        first): A back to within 1e-9 deg, C unwound (its steps those of the input, no jump
        of 360 deg), and held through the pole (a point on it takes the next point's C)."""
        A_deg = np.array([0.0, 10.0, 20.0, 0.0, 30.0, 40.0, 50.0])
        C_deg = np.array([77.0, 150.0, 175.0, 123.0, -170.0, -150.0, -120.0])
        A, C = _simple_ac(axes_from(A_deg, C_deg))
        np.testing.assert_allclose(A, A_deg, atol=1e-9)
        want = np.array([150.0, 150.0, 175.0, 190.0, 190.0, 210.0, 240.0])
        np.testing.assert_allclose(C - C[0], want - want[0], atol=1e-9)
        A, C = _simple_ac(np.tile([0.0, 0.0, 1.0], (4, 1)))          # every point on the pole
        np.testing.assert_array_equal(C, np.zeros(4))

    def test_metrics_without_a_machine(self):
        """orientation_metrics of a path without a machine or checker (the path command's
        tool axes with no --machine): the rotary travel is the sum of the simple model's A and C
        steps (here A 10 -> 40 deg, C 0 -> 90 deg over four points), its time at least the
        feed's."""
        n = 4
        A_deg, C_deg = np.linspace(10.0, 40.0, n), np.linspace(0.0, 90.0, n)
        contact = np.column_stack([np.arange(n, dtype=float), np.zeros(n), np.zeros(n)])
        up = np.tile([0.0, 0.0, 1.0], (n, 1))
        path = ToolPath(contact, up, axes_from(A_deg, C_deg), np.zeros(n, np.int8), np.zeros(n, int),
                        np.zeros((n, 2)), np.zeros(n, int), 0.5)
        m = orientation_metrics(path)
        self.assertAlmostEqual(m.tilt_travel_deg, 30.0, delta=1e-9)
        self.assertAlmostEqual(m.c_travel_deg, 90.0, delta=1e-9)
        self.assertAlmostEqual(m.rotary_travel_deg, 120.0, delta=1e-9)
        self.assertGreaterEqual(m.time_s, m.feed_time_s - 1e-12)


if __name__ == "__main__":
    unittest.main()
