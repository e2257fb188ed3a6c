"""Output files are written whole or not at all: a temporary file beside the target, then
os.replace; a failure leaves the old file (or none) and no temporary file."""
import os
import tempfile
import unittest

from tsplcam.errors import InputError
from tsplcam.outfile import check_folder, check_writable, write_text, write_texts


class AtomicWrites(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.addCleanup(self.tmp.cleanup)
        self.dir = self.tmp.name

    def f(self, *name):
        return os.path.join(self.dir, *name)

    def test_bytes_exactly_and_permissions_as_open_gives(self):
        write_text(self.f("a.nc"), "G1 X1\nG1 X2\n", encoding="ascii")
        with open(self.f("a.nc"), "rb") as fh:
            self.assertEqual(fh.read(), b"G1 X1\nG1 X2\n")
        with open(self.f("b.nc"), "w") as fh:
            fh.write("x")
        self.assertEqual(os.stat(self.f("a.nc")).st_mode & 0o777, os.stat(self.f("b.nc")).st_mode & 0o777)
        self.assertEqual(sorted(os.listdir(self.dir)), ["a.nc", "b.nc"])

    def test_a_failure_leaves_the_old_files_and_no_temporary_one(self):
        write_text(self.f("a.nc"), "old\n")
        with self.assertRaises(InputError) as cm:
            write_texts([(self.f("a.nc"), "new\n", "program"), (self.f("missing", "b.cl"), "cl\n", "CL file")])
        self.assertIn("b.cl", str(cm.exception))
        with open(self.f("a.nc")) as fh:
            self.assertEqual(fh.read(), "old\n")
        self.assertEqual(os.listdir(self.dir), ["a.nc"])
        with self.assertRaises(UnicodeEncodeError):           # a text the encoding cannot hold
            write_texts([(self.f("c.nc"), "ok\n", "program"), (self.f("d.nc"), "Ø\n", "program", "ascii")])
        self.assertEqual(os.listdir(self.dir), ["a.nc"])

    def test_checks_before_the_work(self):
        with open(self.f("file"), "w") as fh:
            fh.write("x")
        for bad in (self.f("missing", "a.nc"), self.f("file", "a.nc"), self.dir):
            with self.assertRaises(InputError):
                check_writable(bad, "program", item="--gcode")
        check_writable(self.f("a.nc"))
        check_folder(self.f("new", "deeper"))                   # made when the files are written
        with self.assertRaises(InputError) as cm:
            check_folder(self.f("file", "job"), item="--out")
        self.assertIn("--out", str(cm.exception))


if __name__ == "__main__":
    unittest.main()
