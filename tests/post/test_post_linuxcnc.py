"""LinuxCNC programs through LinuxCNC's own interpreter (rs274, Debian linuxcnc-uspace).

Every program must interpret without error; the canonical moves rs274 prints, put through
the machine's forward kinematics (xyzac-trt with the machine file's pins), give back the CL
data: tip within 1 um, tool axis within 1e-6 rad. rs274 prints canonical moves with 4
decimals (1e-4 deg = 1.7e-6 rad), so the axis check reads the interpreter's own position
parameters (#5420.., 6 decimals) through (DEBUG) lines added after each motion block; the
4-decimal canonical moves are checked against the print resolution.
"""
import re
import unittest

import numpy as np

from tsplcam.post import post_program, rs274
from tsplcam.post.dialects import linuxcnc
from tsplcam.post.kinematics import angle_between, forward
from tsplcam.post.synthetic import helix, hemisphere_sweep, pole_pass, two_passes_with_retract
from conftest import artifact_path

PRINT_AXIS = np.sqrt(2) * 0.5e-4 * np.pi / 180 * 1.001     # axis error of 4-decimal angles


def programs():
    """(label, ToolPath, options) of every LinuxCNC program the test runs."""
    return [("hemisphere", hemisphere_sweep(n=300), {}),
            ("helix 3 turns", helix(n=500, turns=3.0, tilt=30.0, radius=30.0), {}),
            ("helix -2 turns G94", helix(n=300, turns=-2.0, tilt=40.0, radius=20.0), {"inverse_time": False}),
            ("through the pole", pole_pass(miss=0.0, tilt=20.0, length=40.0), {}),
            ("beside the pole", pole_pass(miss=0.2, tilt=20.0, length=40.0), {}),
            ("retract, rapid, link", two_passes_with_retract(), {}),
            ("coarse tolerance", hemisphere_sweep(n=200), {"linear_tolerance": 0.01, "coolant": "mist"})]


class Rs274Interpreter(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        if rs274.executable() is None:
            raise unittest.SkipTest("rs274 (linuxcnc-uspace) not installed")

    def test_programs_run_and_reproduce_the_cl_data(self):
        report = []
        for label, tp, options in programs():
            r = post_program(tp, "linuxcnc_xyzac_trt", "linuxcnc", **options)
            res = rs274.run(r.text, "XYZAC", tools=(r.settings["tool"],))
            self.assertTrue(res.ok, f"{label}: rs274 said: {res.errors}")
            self.assertIn("PROGRAM_END()", res.canon)
            moves = linuxcnc.read(r.text)
            self.assertEqual(len(res.moves), len(moves), label)
            self.assertEqual(res.kinds, ["traverse" if mv.rapid else "feed" for mv in moves], label)
            # rs274 reads the numbers we wrote (to its print precision)
            ours = np.array([[mv.words.get(a, 0.0) for a in "XYZABC"] for mv in moves])
            self.assertLess(np.abs(res.moves - ours).max(), 5.1e-5, label)
            self.assertLess(np.abs(res.precise - ours).max(), 5.1e-7, label)
            prog = np.array([mv.program for mv in moves])
            cols = [0, 1, 2, 3, 5]
            m, s = r.machine, r.settings
            tip4, ax4 = forward(m, res.moves[prog][:, cols], s["tool_length"], s["part_origin"])
            tip6, ax6 = forward(m, res.precise[prog][:, cols], s["tool_length"], s["part_origin"])
            # Against the CL data: path points, inserted points on their segments, approach and
            # retract on the tool axis. Inside the singular cone the axis moved (at most the
            # cone, centre kept); compare those with the posted axis.
            src = r.motion.source
            on = (src >= 0) & (src == np.floor(src))
            idx = src[on].astype(int)
            ref_tip = r.motion.tip.copy()
            ref_axis = r.motion.axis.copy()
            sing = r.solution.singular[idx]
            ref_tip[np.nonzero(on)[0][~sing]] = tp.tip[idx[~sing]]
            ref_axis[np.nonzero(on)[0][~sing]] = tp.axis[idx[~sing]]
            e_tip4 = np.linalg.norm(tip4 - ref_tip, axis=1).max()
            e_tip6 = np.linalg.norm(tip6 - ref_tip, axis=1).max()
            e_ax4 = angle_between(ax4, ref_axis).max()
            e_ax6 = angle_between(ax6, ref_axis).max()
            self.assertLess(e_tip4, 1e-3, label)
            self.assertLess(e_tip6, 1e-3, label)
            self.assertLess(e_ax4, PRINT_AXIS, label)
            self.assertLess(e_ax6, 1e-6, label)
            # The CL points themselves (outside the cone): every one is in the program.
            self.assertEqual(len(set(idx.tolist())), len(tp))
            if options.get("inverse_time", True):
                self.check_inverse_time(res.canon, moves, label)
            report.append(f"  {label:<22} {len(res.moves):5d} moves, {r.inserted:4d} inserted: tip "
                          f"{e_tip4 * 1000:.4f} um (4 dec.) {e_tip6 * 1000:.4f} um (#54xx), axis "
                          f"{e_ax4:.2e} rad (4 dec.) {e_ax6:.2e} rad (#54xx)")
        print("\n" + "\n".join(report))
        with open(artifact_path("post_rs274.txt"), "w") as f:
            f.write("\n".join(report) + "\n")

    def check_inverse_time(self, canon, moves, label):
        """In G93, rs274 turns F into a feed rate over the block: rate = F x XYZ length
        (or x ABC length for a pure rotary move, docs/post.md section 2.5)."""
        rates, rate = [], None
        for line in canon.splitlines():
            m = re.search(r"SET_FEED_RATE\(([-0-9.]+)\)", line)
            if m:
                rate = float(m.group(1))
            if "STRAIGHT_FEED" in line or "STRAIGHT_TRAVERSE" in line:
                rates.append(rate)
        checked = 0
        for i in range(1, len(moves)):
            mv, pv = moves[i], moves[i - 1]
            if mv.rapid or not mv.inverse_time:
                continue
            d = np.array([mv.words[a] - pv.words[a] for a in "XYZ"])
            dl = np.linalg.norm(d)
            if dl < 1e-2:
                continue
            self.assertAlmostEqual(rates[i] / dl, mv.feed, delta=1e-3 * mv.feed + 0.05 / dl, msg=label)
            checked += 1
        self.assertGreater(checked, 0, label)

    def test_error_is_reported(self):
        # The harness itself: rs274 must flag a G93 move without F.
        res = rs274.run("G21 G90\nG93\nG1 X1 Y2 Z3 A4 C5\nM2\n", precise=False)
        self.assertFalse(res.ok)
        self.assertIn("F word missing", res.errors)


if __name__ == "__main__":
    unittest.main()
