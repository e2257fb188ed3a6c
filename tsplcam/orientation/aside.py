"""One piece of work beside this process: ``fn(*args)`` in a forked process while this one goes
on with other work (the orientation's metrics while the program is posted, the ball gouge
check while the axes are searched), the result the same as computed here (the same code on
the same data, inherited by the fork).

:class:`Aside` forks only where :func:`tsplcam.toolpath.parallel.worker_count` allows more
than one process (not inside FreeCAD, not with ``TSPLCAM_WORKERS=1``, not while that
module's workers are busy); otherwise ``fn`` runs at once, in this process, where it ran
before. The forked process runs with ``TSPLCAM_WORKERS=1`` (pieces it would share out stay
in it: the pool a collision checker keeps belongs to this process) and sends back its
result, pickled. A piece that fails there is run again here by :meth:`Aside.result`, so its
error is raised as without the fork. A caller that meets an error of its own while the piece
is out asks for the result first (:meth:`Aside.first`): the piece's error, when there is one,
is the one a single process would have met first.

A fork of the job's process costs it about 5 ms, and its pages, shared with the child until
written, cost its next work more (the keycap's post: 0.091 -> 0.109 s beside an idle
child): worth it for pieces of 50 ms and more (:data:`MIN_POINTS`; the forced C travel's
30-45 ms on the keycap did not pay). Where other sessions keep both cores busy, a job's
processes share its one fair share of them (the kernel's autogroups) and the fork only
costs: about the same total CPU time, spread over two processes.
"""
from __future__ import annotations

import multiprocessing
import os
import pickle

from ..toolpath.parallel import worker_count

#: path points from which the orientation's pieces of work beside the main one (ball gouges,
#: metrics: 3-12 us a point) pay for a fork
MIN_POINTS = 5000


class Aside:
    """``fn(*args)`` in a forked process (or here, at once, with one process or ``beside``
    False: too little work to pay for the fork); the value by :meth:`result`; ``forked``:
    whether it runs in another process. Use as a context manager: leaving it stops a process
    still running."""

    def __init__(self, fn, *args, beside: bool = True):
        self.fn, self.args = fn, args
        self._proc = self._conn = None
        self._done, self._value = False, None
        self.forked = bool(beside) and self.can_fork()
        if self.forked:
            ctx = multiprocessing.get_context("fork")
            recv, send = ctx.Pipe(duplex=False)
            try:
                self._proc = ctx.Process(target=_child, args=(send, fn, args), daemon=True)
                self._proc.start()
            except OSError:                      # no process to be had: here, at once
                self._proc, self.forked = None, False
                recv.close()
            send.close()
            self._conn = recv if self.forked else None
        if not self.forked:
            self._value, self._done = fn(*args), True

    @staticmethod
    def can_fork() -> bool:
        """Whether an Aside would fork now (more than one process allowed; a daemonic
        process, e.g. a pool's worker, may not have children)."""
        return worker_count(None, 2) > 1 and not multiprocessing.current_process().daemon

    def result(self):
        """``fn(*args)``: the forked process's value, or ``fn`` run here when it failed there
        (raising its error as without the fork)."""
        if self._done:
            return self._value
        try:
            got = pickle.loads(self._conn.recv_bytes())
        except (EOFError, OSError, pickle.PickleError):   # (the process died: run it here)
            got = None
        self._conn.close()
        self._conn = None
        if got is None:
            self.close()
        else:                  # it exits by itself; multiprocessing reaps it at its next start
            self._proc = None
        if got is not None and got[0]:
            self._value = got[1]
        else:
            self._value = self.fn(*self.args)
        self._done = True
        return self._value

    def first(self) -> None:
        """Raise the piece's error, if it has one (call where this process's own work failed:
        one process would have met the piece's error first)."""
        self.result()

    def close(self) -> None:
        """Stop the forked process if it still runs, and reap it."""
        proc, self._proc = self._proc, None
        conn, self._conn = self._conn, None
        if conn is not None:
            conn.close()
        if proc is not None:
            if proc.is_alive():
                proc.terminate()
            proc.join()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        if not self._done:
            self.close()


def _child(conn, fn, args) -> None:
    """The forked process: ``fn(*args)`` with one process, (True, value) or (False, None) back."""
    os.environ["TSPLCAM_WORKERS"] = "1"
    try:
        out = (True, fn(*args))
    except BaseException:                        # run again by the caller, which raises it
        out = (False, None)
    try:
        data = pickle.dumps(out, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:                            # a value that does not pickle: run it there
        data = pickle.dumps((False, None))
    conn.send_bytes(data)
    conn.close()
