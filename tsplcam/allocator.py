"""The C allocator of a process that runs the engine as its own program (``python3 -m
tsplcam``, the FreeCAD workbench's worker process): freed memory kept for the next arrays
rather than handed back to the system at once.

glibc gives every block above its mmap threshold (128 kB at start, raised up to 32 MB as
such blocks are freed) a fresh mapping, whose pages the kernel zeroes at their first touch,
and hands the heap's free top back above 128 kB. numpy's temporaries are such blocks, made
and freed thousands of times a job. With the threshold at its 32 MB ceiling from the start
and 64 MB kept at the heap's top (``mallopt``), measured in alternate runs: the head sample
with ball1_long (1.34 M checker triangles, 257k points) 539-672k -> 272-435k page faults,
system time 4.0-4.6 -> 2.7-3.5 s, the job 10.55 -> 10.17 s and 10.03 -> 9.17 s; the
five-keycap job 218-226k -> 138-144k faults, system time 0.66-1.05 -> 0.42-0.86 s, its time
within the machine's noise (medians of five pairs 4.04 -> 3.68 s), peak memory 397-404 ->
436-451 MB; the keycap job 94k -> 60k faults, no change in its time. The same arrays and
values: only where their memory comes from. Not inside FreeCAD (its process is not ours)
nor where the C library has no ``mallopt`` (not glibc): there nothing changes.
"""
from __future__ import annotations

import ctypes
import sys

M_TOP_PAD = -2                     # glibc's mallopt parameters (malloc.h)
M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD = 32 * 1024 * 1024  # glibc's largest (DEFAULT_MMAP_THRESHOLD_MAX on 64 bits)
TOP_PAD = 64 * 1024 * 1024

_DONE = False


def keep_freed_memory() -> bool:
    """Set the allocator as the module says, once per process; whether it took (False where
    there is no glibc ``mallopt``, or inside FreeCAD)."""
    global _DONE
    if _DONE:
        return True
    if not sys.platform.startswith("linux") or "FreeCAD" in sys.modules:
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    _DONE = bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(M_TOP_PAD, TOP_PAD))
    return _DONE
