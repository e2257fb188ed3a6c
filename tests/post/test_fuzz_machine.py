"""Fuzzing the machine reader (JSON): every mutated shipped machine either loads with all
numbers finite or is refused with InputError naming the file and the key (or the line),
within a time limit. Long run:
``TSPLCAM_FUZZ_EXAMPLES=20000 /usr/bin/python3 -m pytest -q -p no:cacheprovider -k fuzz tests``.
"""
from __future__ import annotations

import os
import re
import unittest

from hypothesis import given
from hypothesis import strategies as st

from conftest import REPO_DIR, assert_fields_finite, fuzz_ops, fuzz_read, fuzz_seeds, fuzz_settings, \
    mutate, read_refused
from tsplcam.inputfile import COORDINATE_LIMIT
from tsplcam.post.machine import read_machine

SEEDS = fuzz_seeds([f"machines/{f}" for f in sorted(os.listdir(os.path.join(REPO_DIR, "tsplcam", "data",
                                                                            "machines")))])


class FuzzMachine(unittest.TestCase):

    @fuzz_settings(60)
    @given(st.integers(0, 1000), fuzz_ops())
    def test_machine_file(self, index, ops):
        name, data = SEEDS[index % len(SEEDS)]
        machine = fuzz_read(self, read_machine, mutate(data, ops), name)
        if machine is not None:
            assert_fields_finite(self, machine, machine.name)
            for axis in machine.linear.values():
                self.assertLessEqual(max(abs(axis.min), abs(axis.max)), COORDINATE_LIMIT)

    def test_regressions(self):
        """A non-UTF-8 byte (was UnicodeDecodeError), a 5000-digit number (was ValueError),
        deep nesting (was RecursionError), an empty key (was an error naming no key), a travel
        of 1e308 mm and a velocity of 1e-320 (were accepted)."""
        name, data = SEEDS[0]
        lines = data.split(b"\n")
        k = next(i for i, ln in enumerate(lines) if b'"kind"' in ln)
        cases = [(b"\xff", "not UTF-8", k + 1, None),
                 (b'"x": ' + b"9" * 5000 + b",", "5000 digits", k + 1, None),
                 (b'"x": ' + b"[" * 5000 + b"]" * 5000 + b",", "nested", k + 1, None),
                 (b'"": 1,', "unknown key", None, '""')]
        for insert, what, line, item in cases:
            text = b"\n".join(lines[:k] + [insert] + lines[k:])
            exc = self.refused(name, text, what)
            if line:
                self.assertEqual(exc.line, line, str(exc))
            if item:
                self.assertEqual(exc.item, item, str(exc))
        m = next(i for i, ln in enumerate(lines) if b'"min"' in ln)
        text = b"\n".join(lines[:m] + [re.sub(rb'"min": *-?[0-9.]+', b'"min": -1e308', lines[m], count=1)]
                          + lines[m + 1:])
        self.assertNotEqual(text, data)
        exc = self.refused(name, text, "beyond")
        self.assertTrue(exc.item.endswith(".min"), exc.item)
        # a denormal velocity passed "> 0" and made every time estimate infinite
        v = next(i for i, ln in enumerate(lines) if b'"max_velocity"' in ln)
        text = b"\n".join(lines[:v] + [re.sub(rb'"max_velocity": *[0-9.e+]+', b'"max_velocity": 1e-320',
                                               lines[v], count=1)] + lines[v + 1:])
        exc = self.refused(name, text, "too small")
        self.assertTrue(exc.item.endswith(".max_velocity"), exc.item)

    def refused(self, name, text, what):
        return read_refused(self, read_machine, name, text, what)


if __name__ == "__main__":
    unittest.main()
