"""APT CL data (tsplcam/toolpath/CLDATA.md): writer and reader agree, the text is what the
format says (records, 72 columns, deterministic), bad files are refused with file and line."""
import os
import re
import tempfile
import unittest

import numpy as np

from tsplcam import load
from tsplcam.errors import InputError
from tsplcam.model.samples import sample_path
from tsplcam.plan.steps import ProcessingList, Step
from tsplcam.toolpath.cldata import APPROACH, RETREAT, cl_text, parse_cl, read_cl, write_cl
from tsplcam.toolpath.path import Move, ToolPath
from tsplcam.toolpath.zigzag import default_plan, zigzag_path

GOTO = re.compile(r"^GOTO/(-?\d+\.\d{5}),(-?\d+\.\d{5}),(-?\d+\.\d{5}),(-?\d\.\d{7}),(-?\d\.\d{7}),(-?\d\.\d{7})$")


class RoundTrip(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        model = load(sample_path("keycap"))
        plist = default_plan(model)
        steps = [Step(s.patch, s.start, s.finish, s.crossfeed, s.retract_before) for s in plist.steps]
        steps[3].retract_before = True                   # every kind of move in one path
        cls.path = zigzag_path(model, ProcessingList(steps), 0.5, 0.1)
        cls.text = cl_text(cls.path)

    def test_records(self):
        lines = self.text.splitlines()
        self.assertTrue(all(len(s) <= 72 for s in lines))
        words = [s.split("/")[0] for s in lines if not s.startswith("$$")]
        self.assertEqual(words[:4], ["PARTNO", "UNITS", "MULTAX", "CUTTER"])
        self.assertIn("UNITS/MM", lines)
        self.assertIn("CUTTER/1.00000,0.50000", lines)
        self.assertEqual(lines[-1], "FINI")
        gotos = [s for s in lines if s.startswith("GOTO/")]
        self.assertEqual(len(gotos), len(self.path) + 2)          # + approach and retreat
        self.assertTrue(all(GOTO.match(s) for s in gotos))
        # RAPID comes right before the approach and each rapid move, nowhere else
        rapid_next = [lines[i + 1].startswith("GOTO/") for i, s in enumerate(lines) if s == "RAPID"]
        self.assertTrue(all(rapid_next))
        self.assertEqual(len(rapid_next), 1 + int(np.count_nonzero(self.path.move == Move.RAPID)))

    def test_read_back(self):
        cl = parse_cl(self.text)
        p = self.path
        self.assertEqual(cl.kind[0], APPROACH)
        self.assertEqual(cl.kind[-1], RETREAT)
        inner = slice(1, -1)
        np.testing.assert_allclose(cl.tip[inner], p.tip, atol=5.1e-6)
        np.testing.assert_allclose(cl.axis[inner], p.axis, atol=1e-6)
        np.testing.assert_array_equal(cl.kind[inner][1:], p.move[1:])
        np.testing.assert_array_equal(cl.rapid[inner], p.move == Move.RAPID)
        np.testing.assert_array_equal(cl.patch[inner], np.where(p.line >= 0, p.patch, cl.patch[inner]))
        np.testing.assert_array_equal(cl.line[inner][p.line >= 0], p.line[p.line >= 0])
        # exact by construction: the tool's radius 0.5 and whole-number feeds (mm/min) are
        # written in full and read back
        self.assertEqual(cl.tool_radius, 0.5)
        self.assertEqual(cl.units, "MM")
        self.assertTrue(np.all(cl.feed[1:] == p.feed))
        tp = cl.to_toolpath()
        self.assertEqual(len(tp), len(p))
        self.assertEqual(tp.retractions, p.retractions)
        np.testing.assert_allclose(tp.center, p.center, atol=1e-5)
        # the approach point lies 5 mm along the first axis
        np.testing.assert_allclose(cl.tip[0], p.tip[0] + 5.0 * p.axis[0], atol=1e-5)

    def test_markers_only_where_things_change(self):
        """A MOVE marker where the kind changes (the first point is a LINK after the approach),
        a PATCH marker where the patch or line changes or follows a point without one."""
        lines = self.text.splitlines()
        p = self.path
        kinds = np.asarray(p.move).copy()
        kinds[0] = Move.LINK
        moves = [s for s in lines if s.startswith("$$ MOVE/")]
        self.assertEqual(len(moves), 3 + int(np.count_nonzero(kinds[1:] != kinds[:-1])))
        ok = (p.patch >= 0) & (p.line >= 0)
        prev = np.r_[False, ok[:-1]]
        changed = np.r_[True, (p.patch[1:] != p.patch[:-1]) | (p.line[1:] != p.line[:-1])]
        marks = [s for s in lines if s.startswith("$$ PATCH/")]
        self.assertEqual(len(marks), int(np.count_nonzero(ok & (~prev | changed))))

    def test_deterministic_file(self):
        with tempfile.TemporaryDirectory() as d:
            a, b = os.path.join(d, "a.cl"), os.path.join(d, "b.cl")
            write_cl(self.path, a)
            write_cl(self.path, b)
            with open(a, "rb") as fa, open(b, "rb") as fb:
                da = fa.read()
                self.assertEqual(da, fb.read())
            self.assertEqual(da.decode("ascii"), self.text)
            self.assertEqual(len(read_cl(a)), len(self.path) + 2)


class Numbers(unittest.TestCase):

    def test_numbers_that_print_as_zero_have_no_sign(self):
        """A coordinate within half a unit of the last decimal of zero prints as 0.00000, never
        -0.00000, in every column; the others print as Python's correctly rounded format."""
        tip = [[-4e-6, -1e-12, -0.0], [-6e-6, 2.0, -3.000004], [1e-7, -5.1e-6, 0.0]]
        axis = [[-4e-8, -1e-9, 1.0], [0.0, -0.6, -0.8], [-0.6, -0.8, -4.9e-8]]
        # normal = axis: the tip is the contact point itself
        text = cl_text(ToolPath(tip, axis, axis, [Move.CUT] * 3, [0] * 3, [[0.5, 0.5]] * 3, [0] * 3, 0.5), approach=0)
        rows = [s[5:].split(",") for s in text.splitlines() if s.startswith("GOTO/")]
        self.assertEqual(rows[0], ["0.00000", "0.00000", "0.00000", "0.0000000", "0.0000000", "1.0000000"])
        self.assertEqual(rows[1], ["-0.00001", "2.00000", "-3.00000", "0.0000000", "-0.6000000", "-0.8000000"])
        self.assertEqual(rows[2], ["0.00000", "-0.00001", "0.00000", "-0.6000000", "-0.8000000", "0.0000000"])


class Reader(unittest.TestCase):

    def test_continuation_and_foreign_records(self):
        big = ToolPath([[123456.5, -234567.25, 345678.125]], [[0, 0, 1.0]], [[0, 0.6, 0.8]], [Move.CUT], [0],
                       [[0.5, 0.5]], [0], 3.0)
        text = cl_text(big, approach=0)
        self.assertTrue(any(s.endswith("$") for s in text.splitlines()))
        self.assertTrue(all(len(s) <= 72 for s in text.splitlines()))
        cl = parse_cl(text.replace("MULTAX/ON", "MULTAX/ON\nSPINDL/12000,CLW\nCOOLNT/ON"))
        np.testing.assert_allclose(cl.tip[0], big.tip[0], atol=1e-5)
        self.assertEqual([w for _, w in cl.ignored], ["SPINDL", "COOLNT"])
        # three-number GOTO keeps the axis; FEDRAT without MMPM
        cl = parse_cl("CUTTER/6.0\nFEDRAT/500\nGOTO/1,2,3,0,0,1\nGOTO/4,5,6\nFINI\n")
        np.testing.assert_allclose(cl.axis[1], [0, 0, 1])
        self.assertEqual(cl.tool_radius, 3.0)       # exact: the literal 6.0 halved
        self.assertEqual(cl.feed[1], 500.0)         # exact: the literal

    def test_errors_name_file_and_line(self):
        cases = [("CUTTER/1,0.5\nUNITS/INCHES\nGOTO/0,0,0\n", 2, "UNITS"),
                 ("CUTTER/1,0.5\nGOTO/0,0,x\n", 2, "not a list of numbers"),
                 ("CUTTER/1,0.5\nGOTO/0,0,0,0,0,0\n", 2, "zero"),
                 ("CUTTER/1,0.5\nGOTO/0,0\n", 2, "3 or 6 numbers"),
                 ("CUTTER/1,0.5\nGOTO/0,0,0\nFINI\nGOTO/1,1,1\n", 4, "after FINI"),
                 ("CUTTER/1,0.5\n$$ MOVE/SIDEWAYS\nGOTO/0,0,0\n", 2, "unknown move kind")]
        for text, line, what in cases:
            with self.assertRaises(InputError) as cm:
                parse_cl(text, path="job.cl")
            self.assertIn(f"job.cl, line {line}", str(cm.exception))
            self.assertIn(what, str(cm.exception))
        with self.assertRaises(InputError) as cm:
            parse_cl("GOTO/0,0,0\n", path="job.cl")
        self.assertIn("CUTTER", str(cm.exception))
        with self.assertRaises(InputError):
            read_cl(os.path.join(tempfile.gettempdir(), "no-such-file-tsplcam.cl"))


if __name__ == "__main__":
    unittest.main()
