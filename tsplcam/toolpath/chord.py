"""Points along a curve on the surface, spaced by a chord tolerance on the ball-centre path.

The machine moves the tool linearly between path points, so the ball centre follows the
chord of the centre curve c(x) = S(x) + r n(x), not the curve. Between two points the chord
may run inside the centre curve (convex along the feed: the ball cuts below the surface, an
overcut) or outside it (concave: material left). The points are placed so that

* the overcut is at most ``tol_in`` (the chord tolerance),
* the undercut at most ``tol_out`` (the path generator passes min(tol, 0.1 h) and lowers
  the side-step target by the same amount, so chords cannot push a cusp over h),
* the sideways deviation at most ``tol_in``, and no step is longer than ``max_step``.

Placement (the paper is silent here, docs/method.md 3.7): a density from the curvature
(``L = sqrt(8 tol / (|k| (1 - r k_f)))``) on dense samples, integrated and
inverted for a first set of points; then every segment is measured at its middle against
the real centre curve and split in two while it deviates more than allowed.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .sidestep import forward_step

SAFETY = 0.85            # first placement at this fraction of the formula's step
MAX_ROUNDS = 40
END_EPS = 1e-5


def place_points(evaluate: Callable, x0: float, x1: float, along: str, r: float, tol_in: float,
                 tol_out: float, max_step: float, dense: int = 33):
    """Parameters from x0 to x1 (either order) and the surface geometry there.

    ``evaluate(x)`` returns a :class:`~tsplcam.toolpath.lines.FrameGeom` along the curve,
    whose parameter is the frame's ``along`` coordinate ('t' for lines, 's' for links).
    Returns (x, P, n, u, v), ordered from x0 to x1, ends included exactly.
    """
    lo, hi = (x0, x1) if x0 <= x1 else (x1, x0)
    if hi - lo <= 0:
        g = evaluate(np.array([x0]))
        return np.array([x0]), g.P, g.n, g.u, g.v
    # the curvature is read slightly inside the ends: at an extraordinary corner the second
    # derivatives are singular (the kernel's values there are meaningless)
    xs = np.linspace(lo, hi, max(int(dense), 3))
    g = evaluate(lo + (hi - lo) * (END_EPS + (1 - 2 * END_EPS) * (xs - lo) / (hi - lo)))
    d1 = g.St if along == "t" else g.Ss
    speed = np.linalg.norm(d1, axis=1)
    kf, kg = g.curve_curvature(along)
    kf = np.where(np.isfinite(kf), kf, 0.0)
    kg = np.where(np.isfinite(kg), np.minimum(kg, 1e6), 1e6)
    tol = np.where(kf > 0, tol_out, tol_in)
    step = np.minimum(forward_step(r, tol, kf, kg), max_step)
    step = np.minimum(step, forward_step(r, tol_in, 0.0, kg))
    dens = speed / np.maximum(step, 1e-12)
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(xs))])
    nseg = max(1, int(np.ceil(cum[-1] / SAFETY)))
    if cum[-1] > 0:
        x = np.interp(np.linspace(0.0, cum[-1], nseg + 1), cum, xs)
    else:
        x = np.linspace(lo, hi, nseg + 1)
    x[0], x[-1] = lo, hi
    x = np.unique(x)
    g = evaluate(x)
    P, n, u, v = g.P, g.n, g.u, g.v
    pending = np.ones(len(x) - 1, bool)
    for _ in range(MAX_ROUNDS):
        idx = np.nonzero(pending)[0]
        if len(idx) == 0:
            break
        xm = 0.5 * (x[idx] + x[idx + 1])
        gm = evaluate(xm)
        cm = gm.P + r * gm.n
        chord = 0.5 * ((P[idx] + r * n[idx]) + (P[idx + 1] + r * n[idx + 1]))
        dev = cm - chord
        dn = np.einsum("ij,ij->i", dev, gm.n)        # > 0: chord below the centre curve
        lat = np.linalg.norm(dev - dn[:, None] * gm.n, axis=1)
        ok = (dn <= tol_in) & (-dn <= tol_out) & (lat <= tol_in)
        ok |= (x[idx + 1] - x[idx]) < 1e-12 * max(1.0, hi - lo)     # cannot split further
        bad = ~ok
        if not bad.any():
            break
        x = np.concatenate([x, xm[bad]])
        P = np.concatenate([P, gm.P[bad]])
        n = np.concatenate([n, gm.n[bad]])
        u = np.concatenate([u, gm.u[bad]])
        v = np.concatenate([v, gm.v[bad]])
        new = np.concatenate([np.zeros(len(x) - bad.sum(), bool), np.ones(bad.sum(), bool)])
        order = np.argsort(x, kind="stable")
        x, P, n, u, v, new = x[order], P[order], n[order], u[order], v[order], new[order]
        pending = new[1:] | new[:-1]
    if x0 > x1:
        x, P, n, u, v = x[::-1], P[::-1], n[::-1], u[::-1], v[::-1]
    return x, P, n, u, v
