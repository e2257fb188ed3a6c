"""map_pieces' ``while_waiting``: other work for the main process while forked workers make
the pieces, run once after they are started and only when there are workers; pieces asked
for meanwhile stay in the main process; the pieces are the same; and the job's collision
checker built that way (``CheckerAhead``) is the one the orientation stage would build, its
error kept for the orientation stage to raise."""
import os
import unittest
from unittest import mock

import numpy as np

from tsplcam.toolpath import parallel
from tsplcam.toolpath.parallel import map_pieces, worker_count

FORK = worker_count(2, 2) == 2          # forking available (and not inside FreeCAD)


def _square_pid(offset, i):
    return (i * i + offset, os.getpid())


class WhileWaiting(unittest.TestCase):

    def test_called_once_beside_the_workers_with_the_same_pieces(self):
        if not FORK:
            self.skipTest("no forked workers here")
        seen = []

        def meanwhile():
            # the cores are the workers': nested pieces run here, in this process
            seen.append((worker_count(), worker_count(4, 10),
                         map_pieces(_square_pid, (0,), 3, worker_count(None, 3))))

        ticks = []
        out = map_pieces(_square_pid, (7,), 6, 2, order=[5, 4, 3, 2, 1, 0],
                         tick=lambda done, total: ticks.append((done, total)), while_waiting=meanwhile)
        self.assertEqual([v for v, _ in out], [i * i + 7 for i in range(6)])
        self.assertTrue(all(pid != os.getpid() for _, pid in out))      # made by the workers
        self.assertEqual(len(seen), 1)
        counts = seen[0]
        self.assertEqual(counts[:2], (1, 1))
        self.assertEqual(counts[2], [(i * i, os.getpid()) for i in range(3)])
        self.assertEqual(ticks, [(k, 6) for k in range(1, 7)])              # every piece told
        self.assertGreaterEqual(worker_count(2, 2), 2)                       # and after: cores again
        self.assertFalse(parallel._WAITING)

    def test_not_called_without_workers(self):
        called = []
        out = map_pieces(_square_pid, (1,), 4, 1, while_waiting=lambda: called.append(1))
        self.assertEqual([v for v, _ in out], [1, 2, 5, 10])
        self.assertEqual(called, [])
        map_pieces(_square_pid, (1,), 1, 2, while_waiting=lambda: called.append(1))      # one piece
        self.assertEqual(called, [])

    def test_its_error_stops_the_work(self):
        if not FORK:
            self.skipTest("no forked workers here")

        def fails():
            raise ValueError("meanwhile")

        with self.assertRaisesRegex(ValueError, "meanwhile"):
            map_pieces(_square_pid, (0,), 4, 2, while_waiting=fails)
        self.assertFalse(parallel._WAITING)


class CheckerAheadOfTheOrientation(unittest.TestCase):
    """The keycap's checker built while the path's workers run equals the one built after
    (same triangles, same distance grids, same tool mesh), and the path is the same."""

    def test_checker_built_while_waiting_is_the_one_built_after(self):
        if not FORK:
            self.skipTest("no forked workers here")
        from tsplcam.program import (CheckerAhead, collision_checker, load_model, load_stock, load_tool,
                                     make_path, processing_list, tool_radius)
        from tsplcam.settings import JobSettings
        s = JobSettings(scallop=0.2, chord_tol=0.01)
        model = load_model(s.model)
        plist = processing_list(model, s)
        tool, stock = load_tool(s), load_stock(s)
        radius = tool_radius(s, tool)
        ahead = CheckerAhead(model, tool, stock, s.holder_clearance)
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}):
            path = make_path(model, plist, s, radius, while_waiting=ahead)
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "1"}):
            spare = CheckerAhead(model, tool, stock, s.holder_clearance)
            alone = make_path(model, plist, s, radius, while_waiting=spare)
        self.assertIsNone(spare.checker)          # one process: built later, by the orientation
        self.assertIsNone(ahead.error)
        self.assertIsNotNone(ahead.checker)
        self.assertGreater(ahead.seconds, 0.0)
        after = collision_checker(model, tool, stock, s.holder_clearance)
        a, b = ahead.checker, after
        # the same computation on the same data: the same bits
        for x, y in ((a.mesh.vertices, b.mesh.vertices), (a.mesh.triangles, b.mesh.triangles),
                     (a.mesh.owner, b.mesh.owner), (a.tool_vertices, b.tool_vertices),
                     (a.tool_triangles, b.tool_triangles), (a.broad.samples, b.broad.samples)):
            self.assertTrue(np.array_equal(x, y))
        self.assertEqual(a.margin, b.margin)
        self.assertEqual(len(a.broad.grids), len(b.broad.grids))
        for ga, gb in zip(a.broad.grids, b.broad.grids):
            self.assertTrue(np.array_equal(ga.lb, gb.lb))
            self.assertTrue(np.array_equal(ga.idx, gb.idx))
        # the path made beside it is the one made in one process (where it is not called)
        for x, y in ((path.contact, alone.contact), (path.axis, alone.axis), (path.move, alone.move)):
            self.assertEqual(x.tobytes(), y.tobytes())


if __name__ == "__main__":
    unittest.main()


class CheckerAheadError(unittest.TestCase):
    def test_an_error_is_kept_and_raised_where_the_checker_is_built(self):
        """A stock the checker refuses: the build while waiting keeps the error (the path's own
        errors come first), the orientation stage builds again and raises it, naming the mesh."""
        from tsplcam.errors import InputError
        from tsplcam.program import CheckerAhead, collision_checker, load_model, load_tool
        from tsplcam.settings import JobSettings
        s = JobSettings()
        model, tool = load_model(s.model), load_tool(s)
        stock = (np.zeros((3, 3)), np.array([[0, 1, 3]]))          # vertex 3 does not exist
        ahead = CheckerAhead(model, tool, stock, s.holder_clearance)
        ahead()
        self.assertIsNone(ahead.checker)
        self.assertIsInstance(ahead.error, InputError)
        with self.assertRaises(InputError) as again:
            collision_checker(model, tool, stock, s.holder_clearance)
        self.assertEqual(str(again.exception), str(ahead.error))
        self.assertIn("stock", str(ahead.error))
