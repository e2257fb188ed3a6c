"""Numbers as text, a column at a time: shared by the CL data writer (tsplcam/toolpath)
and the machine program writers (tsplcam/post), which format tens of thousands of numbers
per job.

:func:`fmt_col` returns exactly the strings of Python's ``"{:.Nf}".format`` (the exact
binary value correctly rounded, ties to even) but builds them in numpy from integers, 2-4x
faster than one ``format`` call per number (80-125 ns a number on 6k-15k-number columns
against 260-360, most of it making the str objects): ``k = rint(x * 10**N)`` is the right integer unless
``x * 10**N`` lies so close to a half that the product's own rounding could have moved it
across; those numbers (and |x| >= 10**8, more than 8 decimals, nan, inf) still go through
``format``."""
from __future__ import annotations

import sys
from functools import cache

import numpy as np

_REL = 2.0 ** -50          # > the product's relative rounding error (2**-53), with margin
_SPACES = 0x2020202020202020
_DOT = ord(".")


@cache
def _tables() -> tuple[np.ndarray, np.ndarray]:
    """Digit tables as machine words: "0000".."9999" (4 bytes each) and, 8 bytes each,
    right-aligned "i." for i < 10**4 unsigned, then with '-', then with '+'."""
    i = np.arange(10000)
    digits = np.stack([i // 10 ** e % 10 for e in (3, 2, 1, 0)], axis=1) + 48
    four = np.ascontiguousarray(digits, np.uint8).view(np.uint32)[:, 0].astype(np.uint64)
    nd = 1 + (i >= 10) + (i >= 100) + (i >= 1000)       # digits shown
    col = np.arange(8)
    text = np.where(col[3:7] >= 7 - nd[:, None], digits, 32)   # columns 3..6: the digits
    ints = np.full((3, 10000, 8), 32, np.uint8)
    ints[:, :, 3:7] = text
    ints[:, :, 7] = _DOT
    ints[1, i, 6 - nd] = ord("-")
    ints[2, i, 6 - nd] = ord("+")
    return four, ints.reshape(30000, 8).view(np.uint64)[:, 0]


def _fmt_py(values: list, decimals: int, plus: bool) -> list:
    """The reference: Python's format per number, negative zero dropped, '+' with ``plus``."""
    f = f"{{:.{decimals}f}}".format
    negzero = "-" + f(0.0)
    zero = negzero[1:]
    texts = map(f, values)
    if plus:
        signed = "+" + zero
        return [signed if t == negzero else t if t[0] == "-" else "+" + t for t in texts]
    return [zero if t == negzero else t for t in texts]


def fmt_col(values, decimals: int, plus: bool = False) -> list:
    """Each of ``values`` with fixed ``decimals``, no negative zero ("-0.000" -> "0.000"),
    an explicit '+' on the others with ``plus`` (Heidenhain): the strings of
    :func:`_fmt_py`. Each number becomes two or three 8-byte words of text, padded with
    spaces (sign and integer part right-aligned, '.', fraction), split into strings at once."""
    x = np.asarray(values, float)
    if isinstance(decimals, np.integer):
        decimals = int(decimals)
    if (x.ndim != 1 or not x.size or type(decimals) is not int or not 0 <= decimals <= 8
            or sys.byteorder != "little"):
        return _fmt_py(x.tolist(), decimals, plus)
    d, p = decimals, 10 ** decimals
    with np.errstate(over="ignore", invalid="ignore"):
        s = x * float(p)
        r = np.rint(s)
        a = np.abs(s)
        # s - r is exact (|s| < 2**50); the exact x * 10**N is within a * 2**-53 of s, so
        # s rounds to the integer the exact value rounds to while it is farther from a half.
        ok = (0.5 - np.abs(s - r) > a * _REL) & (a < min(10.0 ** (8 + d) - 1, 2.0 ** 50))
    bad = np.flatnonzero(~ok)
    r[bad] = 0.0
    k = r.astype(np.int64)
    m = np.abs(k)
    ip = m // p                                 # integer part, < 10**8
    four, ints = _tables()
    if d == 0:                                  # no '.': a space in its place
        ints = (ints & np.uint64(2 ** 56 - 1)) | np.uint64(0x20 << 56)
    # the fraction's d digits, then spaces, in one word
    if d == 0:
        frac = np.full(x.size, _SPACES, np.uint64)
    else:
        f8 = (m - ip * p) * 10 ** (8 - d)       # 8 digits, the last 8 - d of them zeros
        frac = four[f8 // 10000] | (four[f8 % 10000] << np.uint64(32))
        if d < 8:
            keep = (1 << 8 * d) - 1
            frac &= np.uint64(keep)
            frac |= np.uint64(_SPACES & ~keep)
    sign = (k < 0) * 10000 + (0 if not plus else (k >= 0) * 20000)
    dot = _DOT if d else 0x20
    wide = ip >= 10000
    if not wide.any():
        w0 = ints[ip + sign]                    # "  -123." right-aligned
        words = np.stack((w0, frac), axis=1)
    else:                   # at or above 10**4: "  -123", "4567.fff", "fffff   "
        hi = np.where(wide, ip // 10000, ip)
        w0 = ints[hi + sign]
        lo_words = four[ip % 10000] | np.uint64(dot << 32) | (frac << np.uint64(40))
        words = np.empty((x.size, 3), np.uint64)
        words[:, 0] = np.where(wide, (w0 << np.uint64(8)) | np.uint64(0x20), w0)
        words[:, 1] = np.where(wide, lo_words, frac)
        tail = (frac >> np.uint64(24)) | np.uint64(_SPACES << 40 & 2 ** 64 - 1)
        words[:, 2] = np.where(wide, tail, np.uint64(_SPACES))
    texts = words.tobytes().decode("ascii").split()
    if bad.size:
        for i, v in zip(bad.tolist(), _fmt_py(x[bad].tolist(), d, plus)):
            texts[i] = v
    return texts
