"""Floating-point ground rules the engine runs under, so the same input gives the same bytes.

OpenBLAS splits some products across its threads, and how many threads it has changes the
last bits of results: enough to move a rotary value in the 6th decimal of a program written
on an 8-core machine against one written on 2 cores, or in one run against the next while
other threads of the process are busy. The engine parallelises with processes over patches,
steps and collision batches instead, so BLAS runs on one thread: :func:`one_blas_thread`,
called where the program builder starts (and by the package before numpy loads, through the
environment).
"""
from __future__ import annotations

import ctypes
import os
import re

_DONE = False

#: the environment that gives a process (and the processes it starts) one BLAS thread
BLAS_THREADS = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def one_blas_thread() -> None:
    """Make the BLAS numpy is using run on one thread (OpenBLAS; a no-op for others, and
    after the first call)."""
    global _DONE
    if _DONE:
        return
    _DONE = True
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as fh:
            libs = sorted(set(re.findall(r"(/\S*openblas\S*\.so[.\d]*)", fh.read())))
    except OSError:                     # not Linux: the environment variable is all there is
        return
    for lib in libs:
        try:
            setter = getattr(ctypes.CDLL(lib), "openblas_set_num_threads", None)
        except OSError:
            continue
        if setter is not None:
            setter(1)


def blas_environment() -> None:
    """Ask for one BLAS thread through the environment (read when numpy loads its BLAS)."""
    os.environ.update(BLAS_THREADS)
