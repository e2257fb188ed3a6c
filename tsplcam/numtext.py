"""Numbers as text, a column at a time: shared by the CL data writer (tsplcam/toolpath)
and the machine program writers (tsplcam/post), which format tens of thousands of numbers
per job (one ``format`` call per number, no per-number Python branches)."""
from __future__ import annotations

import numpy as np


def fmt_col(values, decimals: int, plus: bool = False) -> list:
    """Each of ``values`` with fixed ``decimals``, no negative zero ("-0.000" -> "0.000"),
    an explicit '+' on the others with ``plus`` (Heidenhain), in one pass."""
    f = f"{{:.{decimals}f}}".format
    negzero = "-" + f(0.0)
    zero = negzero[1:]
    texts = map(f, np.asarray(values, float).tolist())
    if plus:
        signed = "+" + zero
        return [signed if t == negzero else t if t[0] == "-" else "+" + t for t in texts]
    return [zero if t == negzero else t for t in texts]
