"""Both cores where it pays: independent pieces of work (the patches of a path) in forked
worker processes, results in the order asked, identical to one process (each piece runs the
same code on the same data).

Workers are forked (they inherit the model without pickling it) and only on platforms that
fork; inside FreeCAD everything stays in the one process (forking a Qt application is not
safe) unless ``TSPLCAM_WORKERS`` asks for more. ``TSPLCAM_WORKERS`` (an integer) sets the
count, 1 turns processes off.

While the workers make the pieces the calling process has nothing to do: ``map_pieces`` can
be given other work for it (``while_waiting``, e.g. the collision checker the next stage
needs), run after the workers are forked (so they inherit nothing it starts: threads, numba)
and before the results are collected. Pieces of work asked for meanwhile
(:func:`worker_count`) stay in the one process: the cores are taken by the workers.
"""
from __future__ import annotations

import multiprocessing
import os
import sys

_TASK = None                   # (function, shared arguments) the forked workers inherit
_WAITING = False               # a while_waiting callable runs beside this process's workers


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


def _run(index):
    fn, shared = _TASK
    try:
        return index, fn(*shared, index), None
    except Exception as exc:                               # re-raised by the caller's own run
        return index, None, repr(exc)


def map_pieces(fn, shared: tuple, count: int, workers: int, order=None, tick=None,
               while_waiting=None) -> list:
    """[fn(*shared, i) for i in range(count)], in forked processes when ``workers`` > 1.
    ``order``: the indices to hand out first (largest pieces first balances the cores). A
    piece that fails in a worker is run again here, so its error is raised as it would be
    without workers. ``tick(done, count)``, when given, is called in this process as each
    piece is made (for progress; it may raise to stop the work; pieces made while
    ``while_waiting`` runs are told when it returns). ``while_waiting()``, when given, is
    called once in this process after the workers are started and before their results are
    read, and only then: with one process (or one piece) it is not called, and the caller
    does that work later as it would without it. Its exceptions propagate (the workers are
    stopped); a caller that wants the pieces' errors first catches its own."""
    if workers <= 1 or count <= 1:
        out = []
        for i in range(count):
            out.append(fn(*shared, i))
            if tick is not None:
                tick(i + 1, count)
        return out
    global _TASK
    _TASK = (fn, shared)
    try:
        ctx = multiprocessing.get_context("fork")
        with ctx.Pool(min(workers, count)) as pool:
            got, made = [], 0
            results = pool.imap_unordered(_run, list(order) if order is not None else range(count))
            if while_waiting is not None:
                _waiting(while_waiting)
            for g in results:
                got.append(g)
                made += g[2] is None
                if tick is not None and g[2] is None:
                    tick(made, count)
    finally:
        _TASK = None
    out = [None] * count
    for index, result, error in sorted(got, key=lambda g: g[0]):      # the first failure raises
        out[index] = fn(*shared, index) if error is not None else result
    return out


def _waiting(work) -> None:
    """``work()`` with :func:`worker_count` at 1 (nested pieces stay in this process)."""
    global _WAITING
    before, _WAITING = _WAITING, True
    try:
        work()
    finally:
        _WAITING = before
