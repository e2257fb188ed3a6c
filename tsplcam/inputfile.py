"""Reading a person's input file: text, JSON and the numbers in them.

Every reader of tsplcam (models, processing lists, machines, tools) goes through these, so
that one rule holds for all of them: a file that is not UTF-8, not valid JSON, or carries a
number no geometry can use becomes an :class:`~tsplcam.errors.InputError` naming the file
and the line, never a ``UnicodeDecodeError``, ``ValueError`` or ``RecursionError`` from
the standard library, nor a NaN that surfaces later in numpy.

Numbers: JSON's non-standard ``NaN`` and ``Infinity`` and literals that overflow a double
(``1e309``) are refused where they stand, and so are integers longer than Python converts
(4300 digits). Coordinates and lengths are refused beyond :data:`COORDINATE_LIMIT` mm:
a 1000 km part is no mold, and the bound keeps every product the kernel forms (squares
for normals, cubes for curvatures, a k-d tree's distances) far from overflow.
"""
from __future__ import annotations

import json
import math
import re
from contextlib import contextmanager

import numpy as np

from .errors import InputError

#: Largest magnitude of a coordinate or length (mm) or knot interval read from a file.
COORDINATE_LIMIT = 1e9
#: Weights of rational control points lie in [1 / WEIGHT_LIMIT, WEIGHT_LIMIT]: a larger
#: ratio between neighbours leaves nothing of the others in double precision.
WEIGHT_LIMIT = 1e6
#: JSON nested deeper than this is refused (Python's decoder would hit its recursion limit).
JSON_DEPTH_LIMIT = 200
_INT_DIGITS = 4300              # Python's default int <-> str conversion limit


def excerpt(text: str, limit: int = 80) -> str:
    """``repr`` of ``text`` cut to about ``limit`` characters, for an error message."""
    text = text.strip()
    if len(text) > limit:
        return repr(text[:limit]) + f"... ({len(text)} characters)"
    return repr(text)


def line_of(text, pos: int) -> int:
    """1-based line of position ``pos`` in ``text`` (str or bytes)."""
    return text.count("\n" if isinstance(text, str) else b"\n", 0, pos) + 1


def decode(data: bytes, path=None) -> str:
    """``data`` as UTF-8 text (a BOM is dropped); a byte that is not UTF-8 is an InputError
    naming its line and column."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = line_of(data, exc.start)
        column = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise InputError(f"not UTF-8 text: byte 0x{data[exc.start]:02x} at column {column} "
                         f"({exc.reason})", path=path, line=line) from None
    return text[1:] if text.startswith("\ufeff") else text


def read_bytes(path, what: str = "file") -> bytes:
    try:
        with open(path, "rb") as fh:
            return fh.read()
    except OSError as exc:
        raise InputError(f"cannot read the {what}: {exc.strerror}", path=str(path)) from None


def read_text(path, what: str = "file") -> str:
    """The UTF-8 text of ``path`` (see :func:`decode`)."""
    return decode(read_bytes(path, what), str(path))


class _Refused(ValueError):
    def __init__(self, token: str, why: str):
        super().__init__(why)
        self.token, self.why = token, why


def _constant(token):
    raise _Refused(token, f"{token} is not a number JSON allows (give a finite number)")


def _int(token):
    if len(token) > _INT_DIGITS:
        raise _Refused(token, f"an integer of {len(token)} digits")
    return int(token)


def _float(token):
    value = float(token)
    if not math.isfinite(value):
        raise _Refused(token, f"{excerpt(token, 20)} overflows a double")
    return value


# JSON tokens outside strings: a string (skipped), a number or a bracket
_TOKENS = re.compile(r'"(?:[^"\\]|\\.)*"|(NaN|-?Infinity|-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?|[\[\]{}])')


def _position(text: str, want) -> int | None:
    """Position of the first token (outside strings) for which ``want(token, depth)`` holds."""
    depth = 0
    for m in _TOKENS.finditer(text):
        tok = m.group(1)
        if tok is None:
            continue
        if tok in "[{":
            depth += 1
        elif tok in "]}":
            depth -= 1
        if want(tok, depth):
            return m.start()
    return None


def loads_json(text: str, path=None):
    """Parse JSON text; bad JSON, NaN/Infinity, overflowing or over-long numbers and
    pathological nesting are InputErrors naming the line."""
    try:
        return json.loads(text, parse_constant=_constant, parse_int=_int, parse_float=_float)
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg} (column {exc.colno}); the file may be "
                         f"truncated or corrupt", path=path, line=exc.lineno) from None
    except _Refused as exc:
        pos = _position(text, lambda tok, depth: tok == exc.token)
        raise InputError(f"the number {excerpt(exc.token, 20)} cannot be used: {exc.why}",
                         path=path, line=None if pos is None else line_of(text, pos)) from None
    except RecursionError:
        pos = _position(text, lambda tok, depth: depth > JSON_DEPTH_LIMIT)
        raise InputError(f"JSON nested more than {JSON_DEPTH_LIMIT} levels deep", path=path,
                         line=None if pos is None else line_of(text, pos)) from None


def read_json(path, what: str = "file"):
    """(the parsed JSON document, its text) of ``path``; every failure an InputError."""
    text = read_text(path, what)
    return loads_json(text, str(path)), text


def coordinate_error(values) -> str | None:
    """Why coordinates (mm) cannot be used, or None: not finite, or beyond COORDINATE_LIMIT."""
    v = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(v)):
        return "a coordinate is not a number or is infinite"
    big = np.abs(v) > COORDINATE_LIMIT
    if big.any():
        return (f"coordinate {v[big].flat[0]:g} mm is beyond +-{COORDINATE_LIMIT:g} mm "
                f"(no part is that large; wrong units or a corrupt file?)")
    return None


def weight_error(w) -> str | None:
    """Why a rational weight cannot be used, or None."""
    w = float(w)
    if not math.isfinite(w) or w <= 0:
        return f"weight {w:g} is not a positive number"
    if not 1.0 / WEIGHT_LIMIT <= w <= WEIGHT_LIMIT:
        return f"weight {w:g} is outside [{1.0 / WEIGHT_LIMIT:g}, {WEIGHT_LIMIT:g}]"
    return None


def first_coordinate_error(points) -> tuple[int, str] | None:
    """(row, reason) of the first row of ``points`` (n, 3) that :func:`coordinate_error`
    refuses, or None: one array test for the whole file, the row only when one is bad."""
    P = np.asarray(points, dtype=float).reshape(len(points), -1)
    bad = ~np.isfinite(P).all(axis=1) | (np.abs(P) > COORDINATE_LIMIT).any(axis=1)
    if not bad.any():
        return None
    k = int(np.nonzero(bad)[0][0])
    return k, coordinate_error(P[k])


def split_lines(text: str) -> list:
    """The lines of ``text`` as an editor numbers them: split at LF (a CR before it dropped)
    only, not at the other characters ``str.splitlines`` breaks at (NEL, LS, FF, ...), so
    that the line an error names is the line a person finds."""
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return [ln[:-1] if ln.endswith("\r") else ln for ln in lines]


@contextmanager
def naming(path):
    """Errors raised inside name ``path`` when they name no file: the kernel's errors about
    a whole surface (a patch, an irregular vertex's scheme) do not know which file it came
    from."""
    try:
        yield
    except InputError as exc:
        if exc.path is not None:
            raise
        raise InputError(exc.message, path=str(path), line=exc.line, item=exc.item) from exc
