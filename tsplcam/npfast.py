"""numpy's C functions without their Python dispatch wrappers, for the hot small calls of the
surface evaluation and the line placement (thousands of calls on arrays of tens of rows per
path): the same functions, a few microseconds less a call under numpy 1.x. numpy 2 moved the
module and dispatches in C; where neither module is found the public functions stand in.
``clip``: np.clip's ufunc. ``quiet``: np.errstate's ignore modes the same way (one get and
one set of the error object). ``cross_rows`` and ``row_norms``: np.cross and np.linalg.norm
of (n, 3) rows with their operations written out (the same bits, without their axis
handling), for the surface evaluation, the line placement and the collision checker."""
from __future__ import annotations

import numpy as np

try:
    from numpy._core import _multiarray_umath as _mu            # numpy >= 2
except ImportError:
    try:
        from numpy.core import _multiarray_umath as _mu
    except ImportError:                                         # pragma: no cover
        _mu = None

where = getattr(_mu, "where", np.where)
c_einsum = getattr(_mu, "c_einsum", np.einsum)      # np.einsum (no optimize) calls c_einsum
concatenate = getattr(_mu, "concatenate", np.concatenate)
bincount = getattr(_mu, "bincount", np.bincount)
count_nonzero = getattr(_mu, "count_nonzero", np.count_nonzero)
clip = getattr(_mu, "clip", np.clip)                # np.clip's ufunc (the same for arrays)


def cross_rows(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``np.cross`` of (n, 3) rows: its products and differences in its order (the same bits),
    without its axis handling, which costs more than the products on a few hundred rows and
    about as much on 38k."""
    out = np.empty(np.broadcast(u, v).shape)
    np.subtract(u[:, 1] * v[:, 2], u[:, 2] * v[:, 1], out=out[:, 0])
    np.subtract(u[:, 2] * v[:, 0], u[:, 0] * v[:, 2], out=out[:, 1])
    np.subtract(u[:, 0] * v[:, 1], u[:, 1] * v[:, 0], out=out[:, 2])
    return out


def row_norms(x: np.ndarray) -> np.ndarray:
    """``np.linalg.norm(x, axis=1)`` of (n, 3) rows, the squares summed x, y, z as it sums
    them (the same bits)."""
    return np.sqrt(x[:, 0] * x[:, 0] + x[:, 1] * x[:, 1] + x[:, 2] * x[:, 2])

# numpy 1.x keeps the floating-point error modes in one per-thread object; np.errstate wraps its
# get and set in a Python context manager and seterr's checks (some 2 us, some two thousand
# times per path). numpy 2 has no such object, and an errstate of its own in C.
_geterrobj = getattr(_mu, "geterrobj", None)
_seterrobj = getattr(_mu, "seterrobj", None)
_SHIFT = {k: getattr(_mu, "SHIFT_" + name, default)             # 3 bits per kind
          for k, name, default in (("divide", "DIVIDEBYZERO", 0), ("over", "OVERFLOW", 3),
                                   ("under", "UNDERFLOW", 6), ("invalid", "INVALID", 9))}


class _Quiet:
    __slots__ = ("_keep", "_saved")

    def __init__(self, keep: int):
        self._keep = keep

    def __enter__(self):
        self._saved = obj = _geterrobj()
        _seterrobj([obj[0], obj[1] & self._keep, obj[2]])

    def __exit__(self, *exc):
        _seterrobj(self._saved)


def quiet(*kinds: str):
    """``np.errstate(kind="ignore", ...)`` for ``kinds`` among divide, over, under, invalid:
    the same modes inside, the caller's restored after (a new context each call, so
    nesting works)."""
    if _seterrobj is None:                                       # pragma: no cover
        return np.errstate(**dict.fromkeys(kinds, "ignore"))
    keep = -1
    for k in kinds:
        keep &= ~(7 << _SHIFT[k])
    return _Quiet(keep)
