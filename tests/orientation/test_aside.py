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


_KEPT = {}


def _build(x):
    _KEPT["built"] = (x, os.getpid())          # what the first piece leaves in its process
    return os.getpid()


def _build_here_only(main):
    if os.getpid() != main:
        raise RuntimeError("only in the forked process")
    return _build(main)


def _then(label, extra):
    if extra == "fail":
        raise ValueError(f"second piece failed in pid {os.getpid()}")
    return label, extra, _KEPT.get("built"), os.getpid()


def _pid(_):
    return os.getpid()


def _then_pool(extra):
    """A second piece that shares its work out to processes of its own: (its pid, theirs)."""
    import multiprocessing
    with multiprocessing.get_context("fork").Pool(2) as pool:
        return os.getpid(), sorted(set(pool.map(_pid, range(8), chunksize=1)))


class SecondPiece(unittest.TestCase):
    """Aside(then=...).follow(...): the second piece in the process the first ran in, on
    arguments given after; where that process is gone, failed or was never forked, here."""

    def setUp(self):
        _KEPT.clear()

    def test_same_process_keeps_what_the_first_built(self):
        if not FORK:
            self.skipTest("no forked workers here")
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}):
            with Aside(_build, 3, then=(_then, "b")) as a:
                pid = a.result()
                self.assertNotEqual(pid, os.getpid())
                with a.follow(11) as b:
                    self.assertTrue(b.forked)
                    self.assertEqual(b.result(), ("b", 11, (3, pid), pid))
        self.assertEqual(_KEPT, {})                          # nothing of it here

    def test_meanwhile_runs_there_between_the_pieces(self):
        """``meanwhile`` runs in the forked process after the first piece and before the
        second (the job builds the checker's BVH there); its failure is left alone."""
        if not FORK:
            self.skipTest("no forked workers here")
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}):
            with Aside(_build, 3, then=(_then, "b"), meanwhile=lambda: _build(4)) as a:
                pid = a.result()
                with a.follow(11) as b:
                    self.assertEqual(b.result(), ("b", 11, (4, pid), pid))
            with Aside(_build, 3, then=(_then, "b"), meanwhile=lambda: _fails(0)) as a:
                pid = a.result()
                with a.follow(12) as b:
                    self.assertTrue(b.forked)
                    self.assertEqual(b.result(), ("b", 12, (3, pid), pid))
        self.assertEqual(_KEPT, {})

    def test_second_piece_error_raised_here(self):
        if not FORK:
            self.skipTest("no forked workers here")
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}):
            with Aside(_build, 3, then=(_then, "b")) as a:
                a.result()
                b = a.follow("fail")
                with self.assertRaisesRegex(ValueError, f"failed in pid {os.getpid()}$"):
                    b.result()

    def test_first_failed_there_second_runs_here(self):
        if not FORK:
            self.skipTest("no forked workers here")
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}):
            a = Aside(_build_here_only, os.getpid(), then=(_then, "b"))
            self.assertEqual(a.result(), os.getpid())        # run again here
            b = a.follow(5)
            self.assertFalse(b.forked)
            self.assertEqual(b.result()[3], os.getpid())

    def test_closed_without_second_piece_leaves_no_process(self):
        if not FORK:
            self.skipTest("no forked workers here")
        import multiprocessing
        before = set(multiprocessing.active_children())
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}):
            with Aside(_build, 3, then=(_then, "b")) as a:
                a.result()                                   # its process now waits
        self.assertEqual(set(multiprocessing.active_children()) - before, set())

    def test_children_let_the_second_piece_start_processes(self):
        """``children``: the forked process is no daemon, so its second piece may start a
        pool of its own (a daemon may not: the piece fails there and runs here)."""
        if not FORK:
            self.skipTest("no forked workers here")
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}):
            for children in (True, False):
                with Aside(_build, 3, then=(_then_pool,), children=children) as a:
                    pid = a.result()
                    with a.follow(1) as b:
                        own, theirs = b.result()
                if children:
                    self.assertEqual(own, pid)                   # there, with a pool of its own
                    self.assertNotIn(pid, theirs)
                    self.assertNotIn(os.getpid(), theirs)
                else:
                    self.assertEqual(own, os.getpid())           # run again here

    def test_one_process(self):
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "1"}):
            a = Aside(_build, 3, then=(_then, "b"))
            self.assertFalse(a.forked)
            b = a.follow(7)
            self.assertEqual(b.result(), ("b", 7, (3, os.getpid()), os.getpid()))


def _square_there(x):
    if x == "fail":
        raise ValueError("no square")
    return x * x, os.getpid()


def _pool_then_wait(marks, extra):
    """A second piece that starts a pool of two, notes its workers' pids and keeps them busy."""
    import multiprocessing
    import time
    pool = multiprocessing.get_context("fork").Pool(2)
    with open(os.path.join(marks, "pids.tmp"), "w") as fh:
        fh.write(" ".join(str(p.pid) for p in pool._pool))
    os.replace(os.path.join(marks, "pids.tmp"), os.path.join(marks, "pids"))
    return pool.map(time.sleep, [5.0] * 4)


def _held_build(x, marks):
    """_build(x) once the file ``go`` is in the folder ``marks`` (at most 10 s): the process
    stays busy until the test lets it go, however slowly either runs."""
    import time
    end = time.monotonic() + 10.0
    while not os.path.exists(os.path.join(marks, "go")) and time.monotonic() < end:
        time.sleep(0.005)
    _build(x)


class Requests(unittest.TestCase):
    """Aside(serve=...): while its process waits for the second piece it answers requests,
    once it says it is ready (after ``meanwhile``); a failed request is answered None (the
    caller computes it); the second piece follows as without them."""

    def test_served_there_then_the_second_piece(self):
        if not FORK:
            self.skipTest("no forked workers here")
        import tempfile
        import time
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}), tempfile.TemporaryDirectory() as marks:
            with Aside(_build, 3, then=(_then, "b"), meanwhile=lambda: _held_build(4, marks),
                       serve=_square_there) as a:
                pid = a.result()
                self.assertFalse(a.serving())                 # meanwhile still runs there
                open(os.path.join(marks, "go"), "w").close()
                end = time.monotonic() + 10.0
                while not a.serving() and time.monotonic() < end:
                    time.sleep(0.01)
                self.assertTrue(a.serving())
                self.assertTrue(a.request(7))
                self.assertEqual(a.answer(), (49, pid))
                self.assertTrue(a.request("fail"))
                self.assertIsNone(a.answer())                 # failed there: None, and it goes on
                self.assertTrue(a.request(5))
                self.assertEqual(a.answer(), (25, pid))
                a.request(6)                                  # an answer never read
                with a.follow(11) as b:
                    self.assertFalse(a.serving())
                    self.assertEqual(b.result(), ("b", 11, (4, pid), pid))

    def test_exit_with_a_process_left_serving(self):
        """A process that exits with such an Aside left open (no daemon: multiprocessing waits
        for it at exit, and it waits for a request) stops it first instead of hanging."""
        if not FORK:
            self.skipTest("no forked workers here")
        import subprocess
        import sys
        import time
        code = ("import os; os.environ['TSPLCAM_WORKERS'] = '2'\n"
                "from tsplcam.orientation.aside import Aside\n"
                "a = Aside(os.getpid, then=(abs,), children=True, serve=abs)\n"
                "print(a.forked, a.result() != os.getpid())\n")
        t = time.monotonic()
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                             cwd=os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
        self.assertEqual(out.stdout.split(), ["True", "True"], out.stderr)
        self.assertLess(time.monotonic() - t, 20.0)

    def test_stopped_with_its_pool(self):
        """Closed while its second piece runs a pool of its own, the forked process stops
        that pool's workers too (its process group: none left running on, to meet a broken
        pipe)."""
        if not FORK:
            self.skipTest("no forked workers here")
        import tempfile
        import time
        with tempfile.TemporaryDirectory() as marks, mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}):
            a = Aside(_build, 3, then=(_pool_then_wait, marks), children=True)
            a.result()
            b = a.follow(1)
            end = time.monotonic() + 10.0
            while not os.path.exists(os.path.join(marks, "pids")) and time.monotonic() < end:
                time.sleep(0.01)
            with open(os.path.join(marks, "pids")) as fh:
                pids = [int(x) for x in fh.read().split()]
            b.close()

            def running(pid):                            # (a zombie waits for init to reap it)
                try:
                    with open(f"/proc/{pid}/stat") as fh:
                        return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
                except OSError:
                    return False
            end = time.monotonic() + 2.5                 # (their tasks take 5 s)
            while any(running(p) for p in pids) and time.monotonic() < end:
                time.sleep(0.02)
        self.assertEqual([p for p in pids if running(p)], [])

    def test_no_requests_without_a_process(self):
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "1"}):
            a = Aside(_build, 3, then=(_then, "b"), serve=_square_there)
            self.assertFalse(a.serving())
            self.assertEqual(a.follow(2).result()[1], 2)

    def test_closed_while_serving_leaves_no_process(self):
        if not FORK:
            self.skipTest("no forked workers here")
        import multiprocessing
        import time
        before = set(multiprocessing.active_children())
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}):
            with Aside(_build, 3, then=(_then, "b"), serve=_square_there) as a:
                a.result()
                end = time.monotonic() + 10.0
                while not a.serving() and time.monotonic() < end:
                    time.sleep(0.01)
                a.request(3)
        self.assertEqual(set(multiprocessing.active_children()) - before, set())


class ProgramBeside(unittest.TestCase):
    """make_program with the metrics measured beside the post: the same metrics and program
    bytes as one process; where both fail, the metrics' error (one process meets it first)."""

    @classmethod
    def setUpClass(cls):
        from tsplcam.program import (collision_checker, load_model, load_stock, load_tool, make_path,
                                     processing_list, tool_radius)
        from tsplcam.settings import JobSettings
        cls.s = s = JobSettings(scallop=0.2, chord_tol=0.01)
        cls.model = load_model(s.model)
        cls.plist = processing_list(cls.model, s)
        tool, cls.stock = load_tool(s), load_stock(s)
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "1"}):
            cls.path = make_path(cls.model, cls.plist, s, tool_radius(s, tool))
        cls.checker = collision_checker(cls.model, tool, cls.stock, s.holder_clearance)

    def program(self, workers: str):
        from tsplcam.program import make_program
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": workers}), \
                mock.patch("tsplcam.orientation.aside.MIN_POINTS", 0):       # fork whatever the size
            return make_program(self.path, self.model, self.s, stock=self.stock, plist=self.plist,
                                checker=self.checker)

    def test_same_metrics_and_program(self):
        if not FORK:
            self.skipTest("no forked workers here")
        beside, alone = self.program("2"), self.program("1")
        a, b = beside.metrics.as_dict(), alone.metrics.as_dict()
        self.assertEqual(set(a), set(b))
        # the same figures; a real number to 1e-12 of itself: a few axes differed in their
        # last bit now and then (numpy's arctan2 code chosen by the heap's layout, see
        # numerics.components), which a sum of a thousand steps shows in its 15th digit
        def same(x, y, key):
            if isinstance(x, dict):
                self.assertEqual(set(x), set(y), key)
                for k in x:
                    same(x[k], y[k], f"{key}.{k}")
            elif isinstance(x, float):
                self.assertAlmostEqual(x, y, delta=1e-12 * max(1.0, abs(y)), msg=key)
            else:
                self.assertEqual(x, y, key)
        for key in a:
            same(a[key], b[key], key)
        self.assertEqual(beside.posted.text, alone.posted.text)
        self.assertEqual(beside.metrics.gouges, 0)
        self.assertEqual(set(beside.seconds), {"orientation_s", "post_s"})

    def test_clearance_shared_out_in_the_forked_process(self):
        """The job's forked process measures the smallest clearance with a pool of its own for
        its large collision batches (the main process only posts, then waits): the same
        figure as one process (the keycap with its axes 20 deg off the normals, whose search
        asks fcl; every batch shared out here)."""
        if not FORK:
            self.skipTest("no forked workers here")
        import tempfile

        import numpy as np

        from tsplcam.model import samples
        from tsplcam.model.cage import cage_model
        from tsplcam.orientation import collision
        from tsplcam.orientation.orient import ball_check
        from tsplcam.orientation.testpaths import zigzag
        from tsplcam.orientation.tool import load_tool
        from tsplcam.program import _clearance_beside
        from tsplcam.verify.orientation import min_clearance
        keycap = cage_model(samples.keycap())
        checker = collision.CollisionChecker(keycap, load_tool("ball1_keycap"), clearance=0.3)
        path = zigzag(keycap, 0.5, lines=10, points=30)
        side = np.cross(path.normal, np.random.default_rng(5).normal(size=(len(path), 3)))
        side /= np.linalg.norm(side, axis=1, keepdims=True)
        axes = np.cos(np.radians(20)) * path.normal + np.sin(np.radians(20)) * side
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "1"}):
            alone = min_clearance(checker, path.center, axes)
        start = collision.CollisionChecker._pool
        with tempfile.TemporaryDirectory() as marks:
            def pool(checker, workers):                  # (a mark left where a pool starts)
                open(os.path.join(marks, str(os.getpid())), "w").close()
                return start(checker, workers)
            with mock.patch.object(collision, "POOL_START", 1), mock.patch.object(collision, "POOL_MIN", 1), \
                    mock.patch.object(collision.CollisionChecker, "_pool", pool), \
                    mock.patch("tsplcam.orientation.orient.MIN_POINTS", 0), \
                    mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}):
                with ball_check(path, checker, then=(_clearance_beside, checker, os.getpid(), "2")) as a:
                    a.result()
                    with a.follow(path.center, axes) as b:
                        self.assertTrue(b.forked)
                        beside = b.result()
            started = [int(f) for f in os.listdir(marks)]
        self.assertTrue(started)
        self.assertNotIn(os.getpid(), started)           # started there, not here
        self.assertEqual(beside[1], alone[1])
        self.assertAlmostEqual(beside[0], alone[0], delta=1e-12)

    def test_search_batches_shared_with_the_process_beside(self):
        """While the axes are searched the job's forked process answers half of each large
        batch (the centres of every other cell): the same answers as this process alone."""
        if not FORK:
            self.skipTest("no forked workers here")
        import time

        import numpy as np

        from tsplcam.orientation import collision
        from tsplcam.orientation.orient import ball_check
        rng = np.random.default_rng(3)
        rows = rng.integers(0, len(self.path), 3000)
        tilt = np.radians(rng.uniform(30.0, 100.0, len(rows)))
        side = np.cross(self.path.normal[rows], rng.normal(size=(len(rows), 3)))
        side /= np.linalg.norm(side, axis=1, keepdims=True)
        C = self.path.center[rows]
        A = np.cos(tilt)[:, None] * self.path.normal[rows] + np.sin(tilt)[:, None] * side
        alone = self.checker.collides(C, A)
        self.assertTrue(0.05 < alone.mean() < 0.95, alone.mean())
        asked = []
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}), \
                mock.patch("tsplcam.orientation.orient.MIN_POINTS", 0):
            with ball_check(self.path, self.checker, then=(_then, "b")) as a:
                end = time.monotonic() + 10.0
                while not a.serving() and time.monotonic() < end:
                    time.sleep(0.01)
                request = a.request
                with mock.patch.object(a, "request", lambda *x: asked.append(len(x[0])) or request(*x)):
                    self.checker.beside = a
                    try:
                        shared = self.checker.collides(C, A)
                        small = self.checker.collides(C[:collision.BESIDE_MIN - 1], A[:collision.BESIDE_MIN - 1])
                    finally:
                        self.checker.beside = None
        np.testing.assert_array_equal(shared, alone)
        np.testing.assert_array_equal(small, alone[:collision.BESIDE_MIN - 1])
        self.assertEqual(len(asked), 1)                          # the small batch stayed here
        self.assertTrue(0.3 * len(C) < asked[0] < 0.7 * len(C))

    def test_metrics_error_first(self):
        if not FORK:
            self.skipTest("no forked workers here")

        def fails(*a, **k):
            raise ValueError(f"the {k.get('what', 'metrics')} failed")
        with mock.patch("tsplcam.verify.orientation.orientation_metrics", fails), \
                mock.patch("tsplcam.post.post_program", lambda *a, **k: fails(what="post")):
            with self.assertRaisesRegex(ValueError, "the metrics failed"):
                self.program("2")

    def test_clearance_error_before_the_post_and_joints(self):
        """The smallest clearance is measured in the fork; its error comes before the post's
        and the joints' (one process measures the clearance before them)."""
        if not FORK:
            self.skipTest("no forked workers here")

        def fails(*a, **k):
            raise ValueError(f"the {k.get('what', 'clearance')} failed")
        with mock.patch("tsplcam.verify.orientation.min_clearance", fails), \
                mock.patch("tsplcam.verify.orientation._motion_metrics", lambda *a: fails(what="joints")), \
                mock.patch("tsplcam.post.post_program", lambda *a, **k: fails(what="post")):
            with self.assertRaisesRegex(ValueError, "the clearance failed"):
                self.program("2")


if __name__ == "__main__":
    unittest.main()


class ComponentForms(unittest.TestCase):
    """Rotary.axis and angle_between component by component give numpy's (..., 3) forms bit
    for bit (the programs' bytes depend on it), on the smoothing's grid shapes."""

    def test_same_bits(self):
        import numpy as np
        from tsplcam.orientation.rotary import Rotary, angle_between
        rng = np.random.default_rng(5)
        th = rng.uniform(-3.2, 3.2, (400, 36))
        th[rng.random(th.shape) < 0.1] = 0.0
        phi = 2 * np.pi * np.arange(36) / 36
        pref = rng.normal(size=(400, 3))
        pref /= np.linalg.norm(pref, axis=1, keepdims=True)
        pref[:200] = (0.0, 0.0, 1.0)
        for about in "XY":
            rot = Rotary(about=about)
            K = rot.axis(th, phi[None, :])
            ref = np.cos(th)[..., None] * np.array([0.0, 0.0, 1.0]) + np.sin(th)[..., None] * rot.meridian(phi[None, :])
            self.assertEqual(K.tobytes(), ref.tobytes())
            got = angle_between(K, pref[:, None, :])
            ref = np.arctan2(np.linalg.norm(np.cross(K, pref[:, None, :]), axis=-1),
                             np.einsum("...i,...i->...", K, pref[:, None, :]))
            self.assertEqual(got.tobytes(), ref.tobytes())
            self.assertEqual(rot.axis(0.3, 1.2).shape, (3,))
