"""Aside: one piece of work in a forked process beside this one, the value the same as here;
pieces it would share out stay in it; its error raised as one process raises it; with one
process (or too little work) it runs at once, here."""
import os
import unittest
from unittest import mock

from tsplcam.orientation.aside import Aside
from tsplcam.toolpath.parallel import worker_count

FORK = worker_count(2, 2) == 2          # forking available (and not inside FreeCAD)


def _value(x):
    return {"square": x * x, "pid": os.getpid(), "workers": worker_count(None, 4)}


def _fails(x):
    raise ValueError(f"no value for {x} in pid {os.getpid()}")


class AsideWork(unittest.TestCase):

    def test_forked_value_is_the_same(self):
        if not FORK:
            self.skipTest("no forked workers here")
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}):
            with Aside(_value, 7) as a:
                self.assertTrue(a.forked)
                got = a.result()
        self.assertEqual(got["square"], 49)
        self.assertNotEqual(got["pid"], os.getpid())        # made in the forked process ...
        self.assertEqual(got["workers"], 1)                 # ... which shares nothing out
        self.assertIs(a.result(), got)                      # asked again: the same value

    def test_error_raised_here_as_one_process_raises_it(self):
        if not FORK:
            self.skipTest("no forked workers here")
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}):
            with Aside(_fails, 3) as a:
                self.assertTrue(a.forked)
                # the caller's own work failed too: the piece's error comes first, raised here
                with self.assertRaisesRegex(ValueError, f"no value for 3 in pid {os.getpid()}$"):
                    a.first()

    def test_one_process_runs_at_once(self):
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "1"}):
            a = Aside(_value, 5)
            self.assertFalse(a.forked)
            self.assertEqual(a.result()["pid"], os.getpid())
            with self.assertRaisesRegex(ValueError, "no value for 2"):
                Aside(_fails, 2)                            # where one process meets it
        small = Aside(_value, 4, beside=False)              # too little work for a fork
        self.assertFalse(small.forked)
        self.assertEqual(small.result()["square"], 16)


if __name__ == "__main__":
    unittest.main()
