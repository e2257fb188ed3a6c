"""The reader registry (``tsplcam.model.formats.READERS``): every surface format it lists is
read by ``tsplcam.load`` into a model of the right kind, extensions name one reader each,
and a file type it does not list is refused with the list of those it does."""
import os
import tempfile
import unittest

import tsplcam
from tsplcam.errors import InputError
from tsplcam.model.formats import READERS, reader_for, reader_named, surface_readers
from tsplcam.model.model import Model
from tsplcam.model.samples import sample_path
from conftest import external

# a file of every surface format, and how the kind of model it makes begins
EXAMPLES = {
    "obj": (lambda: sample_path("keycap"), "catmull-clark"),
    "tspl": (lambda: sample_path("tjunction_mold"), "t-spline"),
    "tsm": (lambda: external("grapetec_tspline", "simple.tsm"), "t-spline"),
    "iga": (lambda: external("geopdes", "square_unstructured.iga"), "t-spline (iga"),
}


class Registry(unittest.TestCase):
    def test_every_surface_reader_loads_its_format(self):
        self.assertEqual(sorted(r.name for r in surface_readers()), sorted(EXAMPLES))
        for reader in surface_readers():
            with self.subTest(reader.name):
                path_of, kind = EXAMPLES[reader.name]
                path = path_of()
                self.assertIs(reader_for(path), reader)
                model = tsplcam.load(path)
                self.assertIsInstance(model, Model)
                self.assertTrue(model.kind.startswith(kind), model.kind)
                self.assertGreater(len(model.patches), 0)

    def test_names_and_extensions_are_unique(self):
        names = [r.name for r in READERS]
        self.assertEqual(len(names), len(set(names)))
        for surface in (True, False):
            exts = [e for r in READERS if r.surface == surface for e in r.extensions]
            self.assertEqual(len(exts), len(set(exts)), surface)
            self.assertTrue(all(e.startswith(".") and e == e.lower() for e in exts))
        for r in READERS:
            self.assertIs(reader_named(r.name), r)
            self.assertTrue(r.description)
        self.assertIsNone(reader_named("no such format"))

    def test_extension_case_is_ignored(self):
        self.assertIs(reader_for("PART.OBJ"), reader_named("obj"))
        self.assertIsNone(reader_for("part.stl"))

    def test_unknown_and_missing_files_are_refused(self):
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "part.xyz")
            with open(path, "w") as fh:
                fh.write("v 0 0 0\n")
            with self.assertRaises(InputError) as ctx:
                tsplcam.load(path)
            msg = str(ctx.exception)
            self.assertIn("unknown model file type '.xyz'", msg)
            for r in surface_readers():
                for e in r.extensions:
                    self.assertIn(e, msg)
            with self.assertRaises(InputError) as ctx:
                tsplcam.load(os.path.join(folder, "missing.obj"))
            self.assertIn("no such file", str(ctx.exception))


if __name__ == "__main__":
    unittest.main()
