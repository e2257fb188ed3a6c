"""Fuzzing the tool readers: ``tsplcam-tool`` JSON files and FreeCAD ``.fctb`` tool bits.

Every mutated shipped tool either loads with all lengths finite and positive or is refused
with InputError naming the file and the key (or the line), within a time limit. Long run:
``TSPLCAM_FUZZ_EXAMPLES=20000 /usr/bin/python3 -m pytest -q -p no:cacheprovider -k fuzz tests``.
"""
from __future__ import annotations

import unittest

from hypothesis import given
from hypothesis import strategies as st

from conftest import (assert_fields_finite, fuzz_ops, fuzz_read, fuzz_seeds, fuzz_settings, mutate,
                      read_refused)
from tsplcam.orientation.tool import read_fctb, read_tool

TOOLS = fuzz_seeds(["tools/ball1_keycap.json", "tools/ball5_impeller.json",
                    "tools/ball6_freecad_holder.json"])
BITS = fuzz_seeds(["tools/ball6_freecad.fctb"])


class FuzzTool(unittest.TestCase):

    def check(self, tool):
        if tool is not None:
            assert_fields_finite(self, tool, tool.name)
            for part in tool.parts():
                self.assertTrue(0 <= part.r0 < 1e5 and 0 <= part.r1 < 1e5 and part.z0 < part.z1, part)

    @fuzz_settings(50)
    @given(st.integers(0, 1000), fuzz_ops())
    def test_tool_file(self, index, ops):
        name, data = TOOLS[index % len(TOOLS)]
        # the holder file names its .fctb beside it
        self.check(fuzz_read(self, read_tool, mutate(data, ops), name, companions=dict(BITS)))

    @fuzz_settings(30)
    @given(fuzz_ops())
    def test_fctb(self, ops):
        name, data = BITS[0]
        self.check(fuzz_read(self, read_fctb, mutate(data, ops), name))

    def refused(self, name, text, what, item=None):
        exc = read_refused(self, read_tool, name, text, what)
        if item is not None:
            self.assertEqual(exc.item, item)
        return exc

    def test_regressions(self):
        """Non-UTF-8 (was UnicodeDecodeError), a missing key (was an error naming no key), a
        length '1/0 in' (was ZeroDivisionError), a holder of huge or denormal length (was accepted),
        an 'fctb' that is not a file name (was TypeError) or names no file (was an error
        about the missing file, naming no key)."""
        name, data = TOOLS[0]
        self.assertIn(b'"shank_length": 5.5', data)
        self.refused(name, data.replace(b'"mm"', b'"\xb5m"'), "not UTF-8")
        self.refused(name, data.replace(b'"shank_length": 5.5,', b""), "missing", item="shank_length")
        self.refused(name, data.replace(b'"shank_length": 5.5', b'"shank_length": "1/0 in"'),
                     "divides by zero", item="shank_length")
        self.refused(name, data.replace(b'"length": 30.0', b'"length": 1e300'), "holder segment 2",
                     item="holder[1]")
        # a denormal length passed "> 0": a holder segment of zero height (long run)
        self.refused(name, data.replace(b'"length": 30.0', b'"length": 1e-320'), "holder segment 2",
                     item="holder[1]")
        self.refused(name, data.replace(b'"shank_length": 5.5', b'"fctb": 7, "shank_length": 5.5'),
                     "'fctb'", item="fctb")
        nowhere = b'"fctb": "nowhere.fctb", "shank_length": 5.5'
        self.refused(name, data.replace(b'"shank_length": 5.5', nowhere), "not a file", item="fctb")
        bit_name, bit = BITS[0]
        self.refused(bit_name, bit.replace(b'"Length": "40.0000 mm",', b""), "missing",
                     item="parameter.Length")
        # inconsistent lengths in a bit without a name named neither key nor tool (long run)
        unnamed = bit.replace(b'"6mm Ball End"', b'""').replace(b'"20.0000 mm"', b'"2.5 mm"')
        self.refused(bit_name, unnamed, "shorter than the ball radius", item="flute_length")


if __name__ == "__main__":
    unittest.main()
