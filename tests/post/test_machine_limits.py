"""A feed or spindle speed beyond the machine's limits is refused, never posted: in the post,
in the program builder before any long work, and on the command line (exit code 2, one line
naming the option and the limit, no file).

References: the limits written in the machine files (``max_feed``, ``spindle_range``), and
the F and S words of the posted program read back with the dialect's own reader."""
import json
import os
import re
import subprocess
import tempfile
import time
import unittest

import numpy as np

from tsplcam.errors import InputError
from tsplcam.post import load_machine, post_program
from tsplcam.post.dialects import heidenhain
from tsplcam.post.machine import machine_from_dict, shipped_dir
from tsplcam.toolpath.path import Move, ToolPath
from conftest import REPO_DIR

SHIPPED = ("mikron_ucp600_heidenhain", "bc_head_table_sinumerik", "linuxcnc_xyzac_trt", "bc_head_head_fanuc")
MIKRON = "mikron_ucp600_heidenhain"


def line_path(feed, n=20):
    """A straight cut along x over the table centre, tool axis +Z."""
    x = np.linspace(-5.0, 5.0, n)
    P = np.column_stack([x, np.zeros(n), np.full(n, 10.0)])
    A = np.tile([0.0, 0.0, 1.0], (n, 1))
    return ToolPath(contact=P, normal=A, axis=A, move=np.full(n, Move.CUT, np.int8), patch=np.zeros(n, int),
                    uv=np.zeros((n, 2)), line=np.zeros(n, int), tool_radius=0.5, feed=feed)


class MachineFiles(unittest.TestCase):
    def test_every_shipped_machine_states_its_feed_and_spindle_limits(self):
        for name in SHIPPED:
            with open(os.path.join(shipped_dir(), name + ".json")) as f:
                doc = json.load(f)
            m = load_machine(name)
            self.assertEqual(m.max_feed, doc["max_feed"], name)
            self.assertEqual(m.spindle_range, tuple(doc["spindle_range"]), name)
            lo, hi = m.spindle_range
            self.assertTrue(lo <= doc["post"]["spindle"] <= hi, name)    # its own default fits
            self.assertEqual(machine_from_dict(m.to_dict()).spindle_range, m.spindle_range)

    def test_without_max_feed_the_slowest_linear_axis_limits(self):
        doc = load_machine(MIKRON).to_dict()
        del doc["max_feed"], doc["spindle_range"]
        doc["linear_axes"]["Z"]["max_velocity"] = 9000.0
        m = machine_from_dict(doc)
        self.assertEqual(m.feed_limit, 9000.0)
        with self.assertRaises(InputError) as ctx:
            m.check_feed(9500.0)
        self.assertIn("9000 mm/min", str(ctx.exception))
        m.check_spindle(1e6)                       # no range given: not checked

    def test_a_bad_range_or_a_post_default_beyond_the_limits_names_the_key(self):
        doc = load_machine(MIKRON).to_dict()
        for bad in ([20000, 100], [100], "fast", [-1, 100]):
            d = dict(doc, spindle_range=bad)
            with self.assertRaises(InputError) as ctx:
                machine_from_dict(d, "m.json")
            self.assertIn("spindle_range", str(ctx.exception))
        d = dict(doc, post=dict(doc["post"], spindle=30000))
        with self.assertRaises(InputError) as ctx:
            machine_from_dict(d, "m.json")
        self.assertIn("m.json", str(ctx.exception))
        self.assertIn("post.spindle", str(ctx.exception))
        self.assertIn("100 to 20000 rpm", str(ctx.exception))


class Post(unittest.TestCase):
    def test_the_posted_feed_is_the_path_feed_up_to_the_limit(self):
        m = load_machine(MIKRON)
        r = post_program(line_path(m.max_feed), MIKRON)
        feeds = [mv.feed for mv in heidenhain.read(r.text) if mv.feed is not None and not mv.rapid]
        self.assertTrue(feeds)
        self.assertAlmostEqual(max(feeds), m.max_feed, delta=1e-6)
        self.assertIn(f"F{m.max_feed:.0f}", r.text.replace(".000", ""))

    def test_a_feed_above_the_limit_is_refused(self):
        with self.assertRaises(InputError) as ctx:
            post_program(line_path(72000.0), MIKRON)
        text = str(ctx.exception)
        self.assertIn("feed", text)
        self.assertIn("72000 mm/min", text)
        self.assertIn("20000 mm/min", text)
        self.assertIn(MIKRON, text)
        with self.assertRaises(InputError) as ctx:
            post_program(line_path(1000.0), MIKRON, link_feed=25000.0)
        self.assertIn("link_feed", str(ctx.exception))

    def test_a_spindle_speed_outside_the_range_is_refused(self):
        with self.assertRaises(InputError) as ctx:
            post_program(line_path(1000.0), MIKRON, spindle=42000)
        self.assertIn("42000 rpm", str(ctx.exception))
        self.assertIn("100 to 20000 rpm", str(ctx.exception))
        r = post_program(line_path(1000.0), MIKRON, spindle=18000)
        self.assertIn("S18000", r.text)

    def test_progress_reaches_the_end_and_may_stop_the_post(self):
        from tsplcam.progress import Cancelled
        calls = []
        post_program(line_path(1000.0), MIKRON, progress=lambda *a: calls.append(a))
        self.assertEqual(calls[0][0], "program")
        self.assertEqual(calls[-1][1], calls[-1][2])
        self.assertEqual([c[1] for c in calls], sorted(c[1] for c in calls))

        def stop(stage, done, total):
            if done > 0:
                raise Cancelled()
        with self.assertRaises(Cancelled):
            post_program(line_path(1000.0), MIKRON, progress=stop)


class CommandLine(unittest.TestCase):
    """The refusals in their own process (exit code 2, the one line on stderr); the program
    that is written through the same entry point (tsplcam.cli.main) in this process."""

    def run_cli(self, *args):
        return subprocess.run(["/usr/bin/python3", "-m", "tsplcam", *args], cwd=REPO_DIR,
                              capture_output=True, text=True, timeout=600)

    def run_here(self, *args):
        """(exit code, stderr) of ``tsplcam ARGS`` run by tsplcam.cli.main in this process."""
        import contextlib
        import io
        from tsplcam.cli import main
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(list(args))
        return code, err.getvalue()

    def test_feed_and_spindle_refused_before_the_work_with_no_file(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "keycap.h")
            t = time.perf_counter()
            run = self.run_cli("path", "keycap", "--tool-radius", "0.5", "--scallop", "0.05", "--machine", MIKRON,
                               "--feed", "72000", "--gcode", out)
            self.assertEqual(run.returncode, 2, run.stderr)
            lines = run.stderr.strip().splitlines()
            self.assertEqual(len(lines), 1, run.stderr)          # no progress bar: refused first
            self.assertRegex(lines[0], r"--feed: 72000 mm/min is above the largest feed of machine "
                                       r"mikron_ucp600_heidenhain: 20000 mm/min")
            self.assertFalse(os.path.exists(out))
            run = self.run_cli("job", "--spindle", "42000", "--out", os.path.join(tmp, "job"))
            self.assertEqual(run.returncode, 2, run.stderr)
            self.assertIn("--spindle: 42000 rpm is outside the spindle range", run.stderr)
            self.assertEqual(len(run.stderr.strip().splitlines()), 1, run.stderr)
            self.assertFalse(os.path.exists(os.path.join(tmp, "job")))
            self.assertLess(time.perf_counter() - t, 60)

    def test_the_spindle_option_reaches_the_program(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "keycap.h")
            code, err = self.run_here("path", "keycap", "--tool-radius", "0.5", "--scallop", "0.2",
                                      "--machine", MIKRON, "--spindle", "15000", "--feed", "1200", "--gcode", out)
            self.assertEqual(code, 0, err)
            with open(out) as f:
                text = f.read()
            self.assertIn("TOOL CALL 1 Z S15000", text)
            feeds = {round(mv.feed, 3) for mv in heidenhain.read(text) if mv.feed is not None and not mv.rapid}
            self.assertIn(1200.0, feeds)
            self.assertLessEqual(max(feeds), 1200.0)
            self.assertIsNotNone(re.search(r"\bF1200\b", text))


if __name__ == "__main__":
    unittest.main()
