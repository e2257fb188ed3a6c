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


def components(V):
    """The components of vectors ``V`` (..., k) as k contiguous arrays (...).

    numpy 1.24 computes arctan2, arccos, arcsin, power and other transcendental ufuncs in
    SVML's AVX-512 code unless an input may overlap the output, and it judges a strided input
    by its step times its length: a column ``V[:, 2]`` of an (n, 3) array then reaches 16
    bytes past the array's end, where the next heap block, a new output, can start. Such a
    call runs libm's scalar code instead, whose results differ in the last bit (469 of 1,351
    arctan2 values on the keycap's constraints), as the heap happens to be laid out: about one
    job in two hundred. Contiguous inputs never look overlapping, so they always take the
    same code."""
    import numpy as np
    C = np.ascontiguousarray(np.moveaxis(np.asarray(V, float), -1, 0))
    return tuple(C)


def component(V, k: int):
    """Component ``k`` of vectors ``V`` (..., k) as one contiguous array (see
    :func:`components`), for a caller that needs only that one."""
    import numpy as np
    return np.ascontiguousarray(np.asarray(V, float)[..., k])
