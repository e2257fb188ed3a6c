"""map_pieces' ``while_waiting``: other work for the main process while forked workers make
the pieces, run once after they are started and only when there are workers (and
``when_idle``, once the main process has no piece left while a worker's is out); pieces asked
for meanwhile stay in the main process; the pieces are the same; the main process takes
pieces too once it is free, and a piece failing (or lost) in a worker is run again there, the
lowest failing index raising as in one process; and the job's collision
checker built that way (``CheckerAhead``) is the one the orientation stage would build, its
error kept for the orientation stage to raise.

The tests that watch who makes which piece hold the workers' pieces with marks in a folder
(never a sleep alone: a loaded machine can delay either process by more than any sleep)."""
import multiprocessing
import os
import signal
import tempfile
import time
import unittest
import warnings
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
        map_pieces(_square_pid, (1,), 0, 2, while_waiting=lambda: called.append(1))      # no piece
        self.assertEqual(called, [])

    def test_a_piece_alone_goes_to_a_worker(self):
        """One piece and work for this process: the piece is made in a worker beside it (the
        same value), not after it here."""
        if not FORK:
            self.skipTest("no forked workers here")
        called = []
        with tempfile.TemporaryDirectory() as marks:
            def meanwhile():
                called.append(os.getpid())
                _until_marked(marks, 1)                       # (the worker has the piece)
            out = map_pieces(_held_until_started, (1, marks), 1, 2, while_waiting=meanwhile)
        self.assertEqual(called, [os.getpid()])
        self.assertEqual(out[0][0], 100)
        self.assertNotEqual(out[0][1], os.getpid())

    def test_its_error_stops_the_work(self):
        if not FORK:
            self.skipTest("no forked workers here")

        def fails():
            raise ValueError("meanwhile")

        with self.assertRaisesRegex(ValueError, "meanwhile"):
            map_pieces(_square_pid, (0,), 4, 2, while_waiting=fails)
        self.assertFalse(parallel._WAITING)


MAIN = os.getpid()


def _slow_in_workers(seconds, marks, i):
    """A piece that takes ``seconds`` in a worker (leaving a mark in the folder ``marks``
    when it starts) and no time in the main process."""
    if os.getpid() != MAIN:
        if marks:
            open(os.path.join(marks, str(i)), "w").close()
        time.sleep(seconds)
    return (i + 100, os.getpid())


def _held_in_workers(main_pieces, after, marks, i):
    """A piece that a worker holds (leaving a mark in the folder ``marks`` when it starts)
    until the main process has made ``main_pieces`` pieces (each leaves its own mark; at most
    10 s), then ``after`` seconds more; no time in the main process. Unlike a sleep alone, a
    main process slowed by a busy machine cannot see the worker come back first."""
    if os.getpid() == MAIN:
        open(os.path.join(marks, f"m{i}"), "w").close()
    else:
        open(os.path.join(marks, str(i)), "w").close()
        end = time.monotonic() + 10.0
        while sum(f.startswith("m") for f in os.listdir(marks)) < main_pieces and time.monotonic() < end:
            time.sleep(0.005)
        time.sleep(after)
    return (i + 100, os.getpid())


def _held_until_started(workers, marks, i):
    """A piece that a worker holds (leaving a mark in the folder ``marks`` when it starts)
    until ``workers`` pieces have started in the workers (at most 10 s): no worker takes a
    second piece before the others have their first, however slowly they start; no time in
    the main process."""
    if os.getpid() != MAIN:
        open(os.path.join(marks, str(i)), "w").close()
        _until_marked(marks, workers)
    return (i + 100, os.getpid())


def _until_marked(marks, n) -> bool:
    """Wait (at most 10 s) until ``n`` pieces have started in the workers: whether they have."""
    end = time.monotonic() + 10.0
    while sum(not f.startswith("m") for f in os.listdir(marks)) < n:
        if time.monotonic() > end:
            return False
        time.sleep(0.005)
    return True


def _stalled_workers() -> str:
    """This process's forked children but a checker's pool's, as /proc tells them (pid,
    state, the kernel function it waits in), then stopped (SIGKILL: a stopped process
    ignores SIGTERM) and reaped."""
    rows = []
    for p in _own_children(0.0):
        seen = {}
        for name in ("status", "wchan"):
            try:
                with open(f"/proc/{p.pid}/{name}") as f:
                    seen[name] = f.read()
            except OSError as exc:
                seen[name] = str(exc)
        state = [ln.split(":", 1)[1].strip() for ln in seen["status"].splitlines() if ln.startswith("State:")]
        rows.append(f"{p.name} pid {p.pid}: {state[0] if state else seen['status']}, "
                    f"waits in {seen['wchan'].strip() or '-'}")
        try:
            os.kill(p.pid, signal.SIGKILL)
        except OSError:
            pass
        p.join(5.0)
    return "; ".join(rows) or "none alive"


def _with_started_workers(test, run):
    """``run(marks, started)``: map_pieces with a fresh folder ``marks``, whose
    ``while_waiting`` appends to ``started`` whether the workers started the pieces it waits
    for. Once more when they did not within 10 s (two CI runs in about forty: a forked worker
    that took no piece at all while the main process made them all, cause not found; not
    reproduced in 30,000 forks beside a pool's threads on a loaded machine nor in 16 loaded
    runs of the suite), with a warning that names the workers' state; twice fails the
    test. map_pieces gives the right pieces either way; what these tests look at needs the
    worker's piece."""
    for attempt in (1, 2):
        started = []
        with tempfile.TemporaryDirectory() as marks:
            out = run(marks, started)
        if started and all(started):
            return out
        state = _stalled_workers()
        if attempt == 2:
            test.fail(f"map_pieces' workers took no piece within 10 s, twice; their state: {state}")
        warnings.warn(f"map_pieces' worker took no piece within 10 s; tried again (its state: {state})")


def _fails(bad, i):
    if i in bad:
        raise ValueError(f"piece {i} fails")
    return i


def _fails_in_workers(how, i):
    if os.getpid() != MAIN and i == 1:
        if how == "die":
            os._exit(3)                          # the worker is gone with the piece it took
        raise RuntimeError("only in a worker")
    return (i, os.getpid())


def _own_children(wait: float = 5.0) -> list:
    """This process's children that map_pieces could have left (a collision checker's pool,
    which tests before may leave to the garbage collector, is not map_pieces'), once they
    had ``wait`` seconds to exit: workers whose pieces are all in exit by themselves, not
    waited for."""
    end = time.monotonic() + wait
    while True:
        left = [p for p in multiprocessing.active_children() if not p.name.startswith("ForkPoolWorker")]
        if not left or time.monotonic() > end:
            return left
        time.sleep(0.01)


class SharedHandOut(unittest.TestCase):
    """Pieces are taken from one counter by the workers and by the main process once free."""

    def setUp(self):
        if not FORK:
            self.skipTest("no forked workers here")

    def test_the_main_process_takes_pieces_once_free(self):
        def held(marks, started):
            # while_waiting ends once the worker has a piece: the main process takes the
            # rest meanwhile (the worker holds its piece until then)
            ticks = []
            out = map_pieces(_held_in_workers, (5, 0.0, marks), 6, 2, order=[5, 4, 3, 2, 1, 0],
                             tick=lambda done, total: ticks.append(done),
                             while_waiting=lambda: started.append(_until_marked(marks, 1)))
            return out, ticks

        out, ticks = _with_started_workers(self, held)
        self.assertEqual([v for v, _ in out], [i + 100 for i in range(6)])
        made_here = [i for i, (_, pid) in enumerate(out) if pid == MAIN]
        self.assertEqual(len(made_here), 5)
        # two processes on two cores: while_waiting's counts as one, so one worker beside it
        self.assertEqual(len(set(p for _, p in out) - {MAIN}), 1)
        self.assertEqual(ticks, list(range(1, 7)))
        # three processes: two workers, each holding its first piece until both have one
        out = _with_started_workers(self, lambda marks, started: map_pieces(
            _held_until_started, (2, marks), 6, 3, order=[5, 4, 3, 2, 1, 0],
            while_waiting=lambda: started.append(_until_marked(marks, 2))))
        self.assertEqual([v for v, _ in out], [i + 100 for i in range(6)])
        self.assertEqual(len(set(p for _, p in out) - {MAIN}), 2)
        # without while_waiting: the main process and one worker from the start (the worker
        # holds its first piece until the main process has made one; a worker that never
        # starts leaves them all here)
        with tempfile.TemporaryDirectory() as marks:
            out = map_pieces(_held_in_workers, (1, 0.0, marks), 3, 2)
        self.assertEqual([v for v, _ in out], [100, 101, 102])
        self.assertIn(MAIN, [pid for _, pid in out])
        self.assertEqual(_own_children(), [])

    def test_when_idle_runs_once_while_a_worker_makes_the_last_piece(self):
        """when_idle: called once, in the main process, when it has no piece left to take and
        a worker's piece is still out (forking allowed there again: the Aside of the report's
        clearance forks from it); not when every piece is in, nor with one process."""
        seen = []

        def idle():
            seen.append((os.getpid(), worker_count(None, 2) > 1 or not FORK, parallel._WAITING))

        def held(marks, started):
            # the worker takes piece 5 and holds it until the main process has taken the
            # rest, and 0.3 s more
            seen.clear()
            return map_pieces(_held_in_workers, (5, 0.3, marks), 6, 2, order=[5, 4, 3, 2, 1, 0],
                              while_waiting=lambda: started.append(_until_marked(marks, 1)), when_idle=idle)

        out = _with_started_workers(self, held)
        self.assertEqual([v for v, _ in out], [i + 100 for i in range(6)])
        self.assertNotEqual(out[5][1], MAIN)
        self.assertEqual(seen, [(MAIN, True, False)])

        def all_sent(marks, started):
            # every piece made in the worker and sent before the main process looks: the
            # worker has exited (its queue's thread sends them all first)
            seen.clear()
            return map_pieces(_slow_in_workers, (0.0, marks), 3, 2, when_idle=idle,
                              while_waiting=lambda: started.append(_until_marked(marks, 3)
                                                                   and not _own_children(10.0)))

        out = _with_started_workers(self, all_sent)
        self.assertEqual([v for v, _ in out], [100, 101, 102])
        self.assertEqual(seen, [])
        map_pieces(_square_pid, (1,), 4, 1, when_idle=idle)                 # one process
        self.assertEqual(seen, [])

    def test_workers_idle_once_their_pieces_are_done(self):
        """workers_idle: inside while_waiting, False while a worker holds a piece, True once
        every piece is taken and made (the broad phase's threads may then use two cores);
        False outside map_pieces."""
        from tsplcam.orientation.broadphase import threads
        seen = []

        def waiting(marks, started):
            seen.clear()
            seen.append(parallel.workers_idle())
            started.append(_until_marked(marks, 1))      # the worker holds piece 1
            seen.append(parallel.workers_idle())
            open(os.path.join(marks, "m0"), "w").close()  # let it go (it takes piece 0 next)
            end = time.monotonic() + 10.0
            while not parallel.workers_idle() and time.monotonic() < end:
                time.sleep(0.005)
            seen.append(parallel.workers_idle())
            seen.append(threads())

        self.assertFalse(parallel.workers_idle())
        with mock.patch.dict(os.environ, {"TSPLCAM_WORKERS": "2"}):
            out = _with_started_workers(self, lambda marks, started: map_pieces(
                _held_in_workers, (1, 0.0, marks), 2, 2, order=[1, 0],
                while_waiting=lambda: waiting(marks, started)))
        self.assertEqual([v for v, _ in out], [100, 101])
        self.assertEqual(seen[1:], [False, True, min(2, len(os.sched_getaffinity(0)))])
        self.assertFalse(parallel.workers_idle())

    def test_the_lowest_failing_piece_raises_wherever_it_was_made(self):
        with self.assertRaisesRegex(ValueError, "piece 2 fails"):
            map_pieces(_fails, ({2, 4},), 6, 2, order=[5, 4, 3, 2, 1, 0])
        with self.assertRaisesRegex(ValueError, "piece 2 fails"):
            map_pieces(_fails, ({2, 4},), 6, 2, order=[5, 4, 3, 2, 1, 0], while_waiting=lambda: None)
        self.assertFalse(parallel._WAITING)

    def test_a_piece_failing_or_lost_in_a_worker_is_made_again_here(self):
        for how in ("raise", "die"):
            out = map_pieces(_fails_in_workers, (how,), 4, 2, while_waiting=lambda: time.sleep(0.05))
            self.assertEqual([v for v, _ in out], [0, 1, 2, 3])
            self.assertEqual(out[1][1], MAIN)

    def test_a_tick_raising_stops_the_workers(self):
        def tick(done, total):
            raise KeyboardInterrupt("stop")

        with self.assertRaises(KeyboardInterrupt):
            map_pieces(_slow_in_workers, (0.5, ""), 4, 2, tick=tick)
        self.assertEqual(_own_children(), [])
        with self.assertRaisesRegex(ValueError, "not an ordering"):
            map_pieces(_fails, ((),), 3, 2, order=[0, 0, 1])


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
