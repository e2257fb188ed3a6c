"""Both cores where it pays: independent pieces of work (the patches of a path) in forked
worker processes, results in the order asked, identical to one process (each piece runs the
same code on the same data).

Workers are forked (they inherit the model without pickling it) and only on platforms that
fork; inside FreeCAD everything stays in the one process (forking a Qt application is not
safe) unless ``TSPLCAM_WORKERS`` asks for more. ``TSPLCAM_WORKERS`` (an integer) sets the
count, 1 turns processes off.

Every process making pieces (the workers, and the calling process when it is free) takes
the next one of the order asked from one shared counter, so a core that finishes early takes
the next piece instead of idling behind one handed out at the start; each worker's results go
back through a queue whose sending thread lets the worker go on meanwhile.

The calling process can be given other work first (``while_waiting``, e.g. the collision
checker the next stage needs), run after the workers are forked (so they inherit nothing it
starts: threads, numba); once it is done the calling process takes pieces too, then collects
the results. It counts as one of the processes either way: with two cores, one worker makes
pieces beside it (a second one made three processes on two cores, and the collision
checker, which the next stage waits for, then took a third longer than its CPU time: the
keycap's path stage ended 0.06-0.12 s after the pieces; keycap_mold's path 0.52 -> 0.45 s).
Pieces of work asked for meanwhile and inside the pieces it makes (:func:`worker_count`)
stay in the one process: the cores are taken by the workers.
"""
from __future__ import annotations

import contextlib
import multiprocessing
import os
import pickle
import queue
import sys

_WAITING = False       # this process works (while_waiting, pieces) beside its own workers
_IDLE = None           # while map_pieces' workers run: whether they are done (none left, none busy)


def workers_idle() -> bool:
    """Whether this process's forked workers (of the :func:`map_pieces` it waits in) have no
    piece left to take and none in hand: their cores are free for its threads (the molds'
    collision checker built beside the path: keycap_mold's path ends 0.14 s before it)."""
    return _IDLE is not None and _IDLE()


def worker_count(requested: int | None = None, pieces: int = 2) -> int:
    """Processes to use for ``pieces`` independent pieces: ``requested``, else
    ``TSPLCAM_WORKERS``, else the cores this process may run on; 1 where forking is not
    available or not safe, or while this process's workers are busy (``while_waiting``)."""
    if _WAITING or "fork" not in multiprocessing.get_all_start_methods():
        return 1
    env = os.environ.get("TSPLCAM_WORKERS", "").strip()
    if requested is None and env:
        requested = int(env)
    if requested is None:
        if "FreeCAD" in sys.modules:
            return 1
        requested = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(int(requested), int(pieces)))


def map_pieces(fn, shared: tuple, count: int, workers: int, order=None, tick=None,
               while_waiting=None, when_idle=None) -> list:
    """[fn(*shared, i) for i in range(count)], in forked processes when ``workers`` > 1.
    ``order``: the order the pieces are taken in (largest first balances the cores). A
    piece that fails in a worker (or whose result cannot be sent) is run again here, so its
    error is raised as it would be without workers; of several failures, the lowest index
    raises. ``tick(done, count)``, when given, is called in this process as each piece is
    made (for progress; it may raise to stop the work; pieces made while ``while_waiting``
    runs are told when it returns). ``while_waiting()``, when given, is called once in this
    process after the workers are started and before their results are read, and only then:
    with one process (or no piece) it is not called, and the caller does that work later as
    it would without it; a piece alone goes to a worker (tjunction_mold's one patch: its path,
    0.21 s, beside its collision checker's 0.17 s, which came after it before). Its exceptions
    propagate (the workers are stopped); a caller that wants the pieces' errors first catches
    its own. ``when_idle()``, when given, is called
    once in this process when no piece is left to take while the workers still make theirs
    (not with one process, nor when every piece is in): work for the core this process would
    leave idle meanwhile; it may fork (no piece, thread or ``while_waiting`` of this call runs
    here then). Its exceptions propagate as ``while_waiting``'s.

    ``workers`` processes work at once: this process and ``workers`` - 1 forked ones, which
    make pieces; this process makes pieces too, from the start, or with ``while_waiting``
    once that has returned. They all take the next piece of ``order`` from one shared
    counter, so whoever is free takes the next and no one waits at the end for a piece
    handed out early to a busy process."""
    if workers <= 1 or count == 0 or (count == 1 and while_waiting is None):
        out = []
        for i in range(count):
            out.append(fn(*shared, i))
            if tick is not None:
                tick(i + 1, count)
        return out
    order = list(range(count)) if order is None else [int(i) for i in order]
    if sorted(order) != list(range(count)):
        raise ValueError(f"map_pieces: order {order} is not an ordering of the {count} pieces")
    ctx = multiprocessing.get_context("fork")
    nxt = ctx.Value("q", 0)                                   # the next position in order
    out_there = ctx.Value("q", 0, lock=False)                 # pieces in the workers' hands (nxt's lock)
    sent = ctx.Queue()                                        # pickled (index, result, error)
    # (``while_waiting`` keeps this process busy: a piece alone goes to a worker beside it)
    forks = min(workers, count + (while_waiting is not None)) - 1
    got = {}                            # index -> (result, None) or (None, error: str | Exception)
    made, finished = 0, False

    def take(worker: bool = False):
        with nxt.get_lock():
            k = nxt.value
            if k >= count:
                return None
            nxt.value = k + 1
            if worker:
                out_there.value += 1
        return order[k]

    def done() -> None:
        with nxt.get_lock():
            out_there.value -= 1

    def idle() -> bool:
        with nxt.get_lock():
            return nxt.value >= count and out_there.value == 0

    def told(msg) -> None:
        nonlocal made
        index, result, error = pickle.loads(msg)
        got[index] = (result, error)
        if error is None:
            made += 1
            if tick is not None:
                tick(made, count)

    procs = [ctx.Process(target=_work, args=(fn, shared, take, sent, done), daemon=True)
             for _ in range(forks)]
    global _IDLE
    try:
        for p in procs:
            p.start()
        if while_waiting is not None:
            before, _IDLE = _IDLE, idle
            try:
                with _busy():
                    while_waiting()
            finally:
                _IDLE = before
        while True:                                           # this process's share
            while True:
                try:
                    told(sent.get_nowait())
                except queue.Empty:
                    break
            index = take()
            if index is None:
                break
            try:
                with _busy():
                    result = fn(*shared, index)
            except Exception as exc:                          # raised below, in index order
                got[index] = (None, exc)
            else:
                got[index] = (result, None)
                made += 1
                if tick is not None:
                    tick(made, count)
        if when_idle is not None and len(got) < count:
            when_idle()
        while len(got) < count:                               # the workers' last pieces
            ended = all(p.exitcode is not None for p in procs)
            try:
                told(sent.get(timeout=0 if ended else 0.05))
            except queue.Empty:
                if ended:
                    break                     # a worker died: its piece is run again below
        finished = True
    finally:
        if not finished:                   # stopped when the work was: an error, a tick raising
            for p in procs:
                if p.exitcode is None:
                    p.terminate()
                p.join()
        # (else every piece is in: the workers exit by themselves, reaped at multiprocessing's
        # next start, as an Aside's process is; their exit, a 400 MB process's teardown,
        # took 3.3-4.1 ms of the keycap job's path stage when waited for)
        sent.close()
    out = [None] * count
    for index in range(count):                                # the first failure raises
        result, error = got.get(index, (None, "lost"))
        if isinstance(error, Exception):
            raise error
        out[index] = fn(*shared, index) if error is not None else result
    return out


def _work(fn, shared: tuple, take, sent, done) -> None:
    """A forked worker: pieces from the shared counter until none are left, each result sent
    pickled (an error as its repr: the caller runs that piece again), each counted out and
    back in (``done``: the caller's threads may use the core once none is out). The queue's
    thread sends, so the worker goes on while the caller is busy."""
    while (index := take(True)) is not None:
        try:
            msg = pickle.dumps((index, fn(*shared, index), None), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:
            msg = pickle.dumps((index, None, repr(exc)))
        done()
        sent.put(msg)


@contextlib.contextmanager
def _busy():
    """:func:`worker_count` at 1 meanwhile (the cores are this process's workers': nested
    pieces stay in this process)."""
    global _WAITING
    before, _WAITING = _WAITING, True
    try:
        yield
    finally:
        _WAITING = before
