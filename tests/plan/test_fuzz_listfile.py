"""Fuzzing the processing-list reader (JSON) against the layouts of shipped samples.

Every mutated list (tests/conftest.py mutations, plus JSON type swaps) is either accepted,
checked against the model's layout, or refused with InputError naming the file and the line
or the key, within a time limit; read whole (``partial=False``, what the path generator
reads) and as a partial list (what the solver completes). Long run:
``TSPLCAM_FUZZ_EXAMPLES=20000 /usr/bin/python3 -m pytest -q -p no:cacheprovider -k fuzz tests``.
"""
from __future__ import annotations

import os
import unittest

from hypothesis import given
from hypothesis import strategies as st

from conftest import REPO_DIR, fuzz_ops, fuzz_read, fuzz_settings, mutate, read_refused
from tsplcam.model.formats.obj import read_obj
from tsplcam.model.cage import cage_model
from tsplcam.layout.layout import Layout
from tsplcam.plan import dumps, load, plan

SAMPLES = ("keycap.obj", "head.obj", "figure4.obj")


class FuzzProcessingList(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        cls.seeds = []
        for name in SAMPLES:
            model = cage_model(read_obj(os.path.join(REPO_DIR, "tsplcam", "data", "samples", name)))
            layout = Layout.from_model(model)
            cls.seeds.append((name.replace(".obj", ".json"), dumps(plan(layout, model=name)).encode(),
                              layout))

    @fuzz_settings(80)
    @given(st.integers(0, 1000), fuzz_ops(), st.booleans())
    def test_processing_list(self, index, ops, partial):
        name, data, layout = self.seeds[index % len(self.seeds)]
        plist = fuzz_read(self, lambda path: load(path, layout, partial=partial), mutate(data, ops),
                          name)
        if plist is not None:
            self.assertLessEqual(len(plist.steps), layout.n_patches)
            for s in plist.steps:
                self.assertTrue(0 <= s.patch < layout.n_patches)

    def test_not_utf8_names_the_line(self):
        # was a raw UnicodeDecodeError escaping plan/listfile.py
        name, data, layout = self.seeds[0]
        lines = data.split(b"\n")
        k = next(i for i, ln in enumerate(lines) if b'"patch"' in ln)
        lines[k] = lines[k].replace(b'"u"', b'"\xe9"').replace(b'"v"', b'"\xe9"')
        exc = read_refused(self, lambda p: load(p, layout), name, b"\n".join(lines), "not UTF-8")
        self.assertEqual(exc.line, k + 1)

    def test_not_an_object_names_the_document(self):
        name, data, layout = self.seeds[0]
        exc = read_refused(self, lambda p: load(p, layout), name, b"[" + data + b"]")
        self.assertEqual(exc.item, "(document)")

    def test_json_numbers_python_would_misread(self):
        # a 5000-digit patch index was Python's ValueError from the JSON decoder
        name, data, layout = self.seeds[0]
        lines = data.split(b"\n")
        k = next(i for i, ln in enumerate(lines) if b'"patch"' in ln)
        for value, what in ((b"9" * 5000, "5000 digits"), (b"NaN", "NaN"), (b"1e999", "overflows")):
            bad = lines[k].replace(b'"patch": ', b'"patch": ' + value + b', "x": ', 1)
            text = b"\n".join(lines[:k] + [bad] + lines[k + 1:])
            exc = read_refused(self, lambda p: load(p, layout), name, text, what)
            self.assertEqual(exc.line, k + 1, str(exc))


if __name__ == "__main__":
    unittest.main()
