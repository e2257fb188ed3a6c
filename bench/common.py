"""What the benchmarks in bench/ share: the checkout on sys.path, timing, the shared data folder.

A bench is run as a script (``/usr/bin/python3 bench/bench_x.py``), so this module is found
beside it; it puts the checkout first on ``sys.path`` so ``import tsplcam`` is this checkout.
"""
from __future__ import annotations

import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO_DIR = os.path.dirname(HERE)
if REPO_DIR not in sys.path:
    sys.path.insert(0, REPO_DIR)


def shared_dir() -> str:
    """``../shared`` beside the checkout (or ``$TSPLCAM_SHARED``)."""
    return os.environ.get("TSPLCAM_SHARED", os.path.join(os.path.dirname(REPO_DIR), "shared"))


def best_of(fn, repeat: int = 3):
    """(seconds, result) of the fastest of ``repeat`` calls of ``fn()``: other processes only
    ever make a run slower."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out
