"""One piece of work beside this process: ``fn(*args)`` in a forked process while this one goes
on with other work (the ball gouge check while the axes are searched, then the axes'
smallest clearance while the program is posted), the result the same as computed here (the
same code on the same data, inherited by the fork).

:class:`Aside` forks only where :func:`tsplcam.toolpath.parallel.worker_count` allows more
than one process (not inside FreeCAD, not with ``TSPLCAM_WORKERS=1``, not while that
module's workers are busy); otherwise ``fn`` runs at once, in this process, where it ran
before. The forked process runs with ``TSPLCAM_WORKERS=1`` (pieces it would share out stay
in it: the pool a collision checker keeps belongs to this process) and sends back its
result, pickled. A piece that should share its work out while this process waits for it
sets its own workers there (the job's smallest clearance: the checker's pool of its own;
``children``, as a daemon may have none). A piece that fails there is run again here by
:meth:`Aside.result`, so its error is raised as without the fork. A caller that meets an
error of its own while the piece is out asks for the result first (:meth:`Aside.first`): the
piece's error, when there is one, is the one a single process would have met first.

An Aside may have a second piece (``then``) that its forked process runs after the first,
on arguments given later (:meth:`Aside.follow`), keeping what the first built there, and
work to do while it waits for them (``meanwhile``): the ball gouge check (which the broad
phase answers without fcl) is followed there by building the checker's BVH while the axes
are searched here, and the same process then measures the axes' smallest clearance with it
while this one posts the program (the main process builds a BVH of its own only where many
of its questions reach fcl, as on the molds; a few are answered from the triangles near them,
:mod:`~tsplcam.orientation.nearby`). The arguments are written by a thread, so this process
goes on with its own work where the forked one is still busy with its ``meanwhile`` work.

While it waits for the second piece's arguments, the forked process may also answer
requests (``serve``): the job's process hands it half of each large batch of collision
questions while the axes are searched (:meth:`Aside.serving`, :meth:`Aside.request`,
:meth:`Aside.answer`), from the time its BVH is built (it says so); on the molds the search
leaves that core idle otherwise.

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
import signal
import threading
import weakref
from multiprocessing import util

from ..toolpath.parallel import worker_count

#: path points from which the orientation's pieces of work beside the main one (ball gouges,
#: metrics: 3-12 us a point) pay for a fork
MIN_POINTS = 5000


class Aside:
    """``fn(*args)`` in a forked process (or here, at once, with one process or ``beside``
    False: too little work to pay for the fork); the value by :meth:`result`; ``forked``:
    whether it runs in another process. Use as a context manager: leaving it stops a process
    still running. ``children``: the forked process may start processes of its own (a daemon
    may not), for a piece that shares its work out while this one waits for it."""

    def __init__(self, fn, *args, beside: bool = True, then=None, meanwhile=None, children: bool = False,
                 serve=None):
        self.fn, self.args = fn, args
        self.then = then
        self._proc = self._conn = self._ask = self._reply = None
        self._done, self._value, self._ok = False, None, False
        self._ready = self._pending = False
        self.forked = bool(beside) and self.can_fork()
        if self.forked:
            ctx = multiprocessing.get_context("fork")
            recv, send = ctx.Pipe(duplex=False)
            ask_r, ask_w = ctx.Pipe(duplex=False) if then is not None else (None, None)
            rep_r, rep_w = ctx.Pipe(duplex=False) if then is not None and serve is not None else (None, None)
            try:
                self._proc = ctx.Process(target=_child, args=(send, fn, args, then, ask_r, meanwhile, serve,
                                                              rep_w, children), daemon=not children)
                self._proc.start()
                if children:
                    _own_group(self._proc.pid)
                    _LIVE.add(self._proc)
            except OSError:                      # no process to be had: here, at once
                self._proc, self.forked = None, False
                recv.close()
                for c in (ask_w, rep_r):
                    if c is not None:
                        c.close()
            for c in (send, ask_r, rep_w):
                if c is not None:
                    c.close()
            self._conn = recv if self.forked else None
            self._ask = ask_w if self.forked else None
            self._reply = rep_r if self.forked else None
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
        got = None
        if self._conn is not None:
            try:
                got = pickle.loads(self._conn.recv_bytes())
            except (EOFError, OSError, pickle.PickleError):   # (the process died: run it here)
                got = None
        ok = got is not None and got[0]
        if got is None:
            self.close()
        elif not (ok and self._ask is not None):    # else it waits for its second piece
            # it exits by itself; multiprocessing reaps it at its next start
            self._conn.close()
            self._conn = self._proc = None
            if self._ask is not None:
                self._ask.close()
                self._ask = None
        value = got[1] if ok else self.fn(*self.args)
        self._value, self._ok, self._done = value, ok, True
        return value

    # --- requests while the forked process waits for the second piece --------------------
    def serving(self) -> bool:
        """Whether the forked process answers requests now (it has said it is ready, and no
        request failed to go or come back); never waits."""
        if self._reply is None:
            return False
        if not self._ready:
            try:
                if not self._reply.poll():
                    return False
                self._ready = self._reply.recv_bytes() == b"ready"
            except (EOFError, OSError):
                self._stop_serving()
                return False
        return self._ready

    def request(self, *args) -> bool:
        """Send ``serve(*args)`` to the forked process (after :meth:`serving`); whether it
        went. Its answer must be read (:meth:`answer`) before the next request."""
        try:
            self._ask.send_bytes(pickle.dumps(("serve", args), protocol=pickle.HIGHEST_PROTOCOL))
        except (OSError, pickle.PickleError):
            self._stop_serving()
            return False
        self._pending = True
        return True

    def answer(self):
        """The value of the last request, or None where it failed there (the caller then
        computes it itself; requests stop where the process is gone)."""
        self._pending = False
        try:
            ok, value = pickle.loads(self._reply.recv_bytes())
        except (EOFError, OSError, pickle.PickleError):
            self._stop_serving()
            return None
        return value if ok else None

    def _stop_serving(self) -> None:
        self._ready = False
        if self._reply is not None:
            self._reply.close()
            self._reply = None

    def follow(self, *extra) -> "Aside":
        """The second piece, ``then[0](*then[1:], *extra)``, in the same forked process (which
        keeps what the first built, e.g. the checker's BVH), after :meth:`result`: an Aside
        whose :meth:`result` gives its value (run here where the forked process is gone or
        failed, and with one process)."""
        if self.then is None:
            raise ValueError("this Aside has no second piece (then=)")
        self.result()
        fn, args = self.then[0], tuple(self.then[1:]) + extra
        nxt = object.__new__(Aside)
        nxt.fn, nxt.args, nxt.then = fn, args, None
        nxt._ask = nxt._reply = None
        nxt._ready = nxt._pending = False
        nxt._done, nxt._value, nxt._ok = False, None, False
        nxt.forked = self._ok and self._ask is not None
        nxt._proc, nxt._conn = None, None
        if self._pending:                         # (an answer never read: it would come first)
            self.answer()
        self._stop_serving()
        data = None
        if nxt.forked:
            try:
                data = pickle.dumps(("then", extra), protocol=pickle.HIGHEST_PROTOCOL)
            except pickle.PickleError:
                nxt.forked = False
        if nxt.forked:                            # the process and its pipe go to the second piece
            # the arguments written by a thread: the forked process reads them only once done
            # with its ``meanwhile`` work, and a pipe holds 64 kB, so this process goes on with
            # its own work meanwhile (tjunction_mold's: its 85k triangles' BVH, 0.18 s, ended
            # 0.12 s after the axes, which waited for it; the poses' 1.4 MB). Where the write
            # fails the process is gone: the second piece's result is computed here.
            threading.Thread(target=_write_close, args=(self._ask, data), daemon=True).start()
            nxt._proc, nxt._conn = self._proc, self._conn
            self._proc = self._conn = self._ask = None
        else:
            self.close()
        return nxt

    def first(self) -> None:
        """Raise the piece's error, if it has one (call where this process's own work failed:
        one process would have met the piece's error first)."""
        self.result()

    def close(self) -> None:
        """Stop the forked process if it still runs (or waits for its second piece), and
        reap it."""
        proc, self._proc = self._proc, None
        conn, self._conn = self._conn, None
        ask, self._ask = self._ask, None
        self._stop_serving()
        for c in (conn, ask):
            if c is not None:
                c.close()
        if proc is not None:
            _end(proc)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        if not self._done or self._ask is not None:
            self.close()


# the forked processes that may have children: each leads a process group of its own, which
# is stopped whole (a pool's workers left to run on met broken pipes, and printed them); and
# at this process's exit multiprocessing would wait for one still running (no daemon; as it
# waits for a request), so they are stopped first
_LIVE = weakref.WeakSet()


def _own_group(pid: int) -> None:
    """Make the process ``pid`` lead a process group of its own (from both sides of the fork:
    whichever comes first)."""
    try:
        os.setpgid(pid, pid)
    except OSError:                              # (it did so itself, or is gone)
        pass


def _end(proc, wait: float | None = None) -> None:
    """Stop a forked process still running (with its group: the processes it started) and
    reap it."""
    if proc.is_alive():
        if proc in _LIVE:
            try:
                os.killpg(proc.pid, signal.SIGTERM)
            except OSError:
                proc.terminate()
        else:
            proc.terminate()
    proc.join(wait)


def _stop_live() -> None:
    for proc in list(_LIVE):
        _end(proc, 5.0)


util.Finalize(None, _stop_live, exitpriority=0)


def _child(conn, fn, args, then=None, ask=None, meanwhile=None, serve=None, reply=None,
           children: bool = False) -> None:
    """The forked process: ``fn(*args)`` with one process, (True, value) or (False, None) back;
    with ``then``, once that went well, ``meanwhile()`` (its failure left to the second piece
    to meet again), then requests answered by ``serve`` on ``reply`` (after b"ready") until the
    second piece's arguments come on ``ask``, then that piece (none: the caller closed it,
    nothing more to do). With ``children`` it leads a process group of its own (stopped
    whole, with the processes it starts)."""
    if children:
        _own_group(os.getpid())
    os.environ["TSPLCAM_WORKERS"] = "1"
    ok = _send(conn, fn, args)
    if then is not None and ok:
        if meanwhile is not None:
            try:
                meanwhile()
            except Exception:                    # noqa: BLE001  (the second piece meets it)
                pass
        if reply is not None:
            try:
                reply.send_bytes(b"ready")
            except OSError:
                reply = None
        extra = None
        while True:
            try:
                kind, got = pickle.loads(ask.recv_bytes())
            except (EOFError, OSError, pickle.PickleError):
                break
            if kind == "then":
                extra = got
                break
            if reply is not None:                  # (a broken pipe: the caller stopped asking)
                _send(reply, serve, got, quiet=True)
        if extra is not None:
            _send(conn, then[0], tuple(then[1:]) + tuple(extra))
    conn.close()


def _write_close(conn, data: bytes) -> None:
    """Write ``data`` to the pipe ``conn`` and close it (a broken pipe: the reader is gone)."""
    try:
        conn.send_bytes(data)
    except OSError:
        pass
    finally:
        conn.close()


def _send(conn, fn, args, quiet: bool = False) -> bool:
    """``fn(*args)`` sent on ``conn`` as (True, value), or (False, None) where it failed or its
    value does not pickle (the caller runs it again and raises its error); whether it went.
    ``quiet``: a request's failure (``Exception``) is answered as such and the process goes on."""
    try:
        out = (True, fn(*args))
    except Exception if quiet else BaseException:  # run again by the caller, which raises it
        out = (False, None)
    try:
        data = pickle.dumps(out, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:                            # a value that does not pickle: run it there
        out, data = (False, None), pickle.dumps((False, None))
    try:
        conn.send_bytes(data)
    except OSError:                              # the caller is gone
        return False
    return out[0]
