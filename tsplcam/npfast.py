"""numpy's C functions without their Python dispatch wrappers, for the hot small calls of the
surface evaluation and the line placement (thousands of calls on arrays of tens of rows per
path): the same functions, a few microseconds less a call under numpy 1.x. numpy 2 moved the
module and dispatches in C; where neither module is found the public functions stand in."""
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
