"""Points along curves on the surface, spaced by a chord tolerance on the ball-centre path.

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

All curves of a zigzag (its lines and the links between them) are placed together: the
dense samples of every curve in one surface evaluation, the first points of every curve in
another, and each splitting round measures the midpoints of all curves' open segments at
once, so a patch costs a few dozen array calls however many lines it has.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sidestep import forward_step

SAFETY = 0.85            # first placement at this fraction of the formula's step
MAX_ROUNDS = 40
END_EPS = 1e-5


@dataclass
class Curve:
    """An iso-curve of a line frame: ``along`` 't' (a line, s = ``fixed``) or 's' (a link
    along the edge t = ``fixed``), from x0 to x1 (either order); ``dense`` samples for the
    density."""
    along: str
    fixed: float
    x0: float
    x1: float
    dense: int


def _evaluate(frame, along: np.ndarray, fixed: np.ndarray, x: np.ndarray):
    """Frame geometry at parameter x of curves with these ``along`` flags (True: 't')."""
    return frame.evaluate(np.where(along, fixed, x), np.where(along, x, fixed))


def _first_points(frame, curves: list[Curve], r, tol_in, tol_out, max_step):
    """First parameters per curve from the integrated density (module doc)."""
    lo = np.array([min(c.x0, c.x1) for c in curves])
    hi = np.array([max(c.x0, c.x1) for c in curves])
    xs = [np.linspace(lo[k], hi[k], max(int(c.dense), 3)) for k, c in enumerate(curves)]
    cid = np.repeat(np.arange(len(curves)), [len(a) for a in xs])
    xa = np.concatenate(xs)
    along = np.array([c.along == "t" for c in curves])
    fixed = np.array([c.fixed for c in curves])
    span = (hi - lo)[cid]
    # the curvature is read slightly inside the ends: at an extraordinary corner the second
    # derivatives are singular (the kernel's values there are meaningless)
    with np.errstate(invalid="ignore", divide="ignore"):
        inner = lo[cid] + span * (END_EPS + (1 - 2 * END_EPS) * (xa - lo[cid]) / span)
    g = _evaluate(frame, along[cid], fixed[cid], inner)
    at = along[cid]
    speed = np.linalg.norm(np.where(at[:, None], g.St, g.Ss), axis=1)
    kft, kgt = g.curve_curvature("t")
    kfs, kgs = g.curve_curvature("s")
    kf, kg = np.where(at, kft, kfs), np.where(at, kgt, kgs)
    kf = np.where(np.isfinite(kf), kf, 0.0)
    kg = np.where(np.isfinite(kg), np.minimum(kg, 1e6), 1e6)
    tol = np.where(kf > 0, tol_out, tol_in)
    step = np.minimum(forward_step(r, tol, kf, kg), max_step)
    step = np.minimum(step, forward_step(r, tol_in, 0.0, kg))
    dens = speed / np.maximum(step, 1e-12)
    bounds = np.concatenate([[0], np.cumsum([len(a) for a in xs])])
    out = []
    for k in range(len(curves)):
        if hi[k] - lo[k] <= 0:
            out.append(np.array([curves[k].x0]))
            continue
        d, x = dens[bounds[k]:bounds[k + 1]], xs[k]
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (d[1:] + d[:-1]) * np.diff(x))])
        nseg = max(1, int(np.ceil(cum[-1] / SAFETY)))
        if cum[-1] > 0:
            p = np.interp(np.linspace(0.0, cum[-1], nseg + 1), cum, x)
        else:
            p = np.linspace(lo[k], hi[k], nseg + 1)
        p[0], p[-1] = lo[k], hi[k]
        out.append(np.unique(p))
    return out, lo, hi, along, fixed


def place_curves(frame, curves: list[Curve], r: float, tol_in: float, tol_out: float, max_step: float):
    """Parameters along every curve and the surface geometry there: per curve (x, P, n, u,
    v), ordered from x0 to x1, ends included exactly (a curve of zero length: one point)."""
    if not curves:
        return []
    first, lo, hi, along, fixed = _first_points(frame, curves, r, tol_in, tol_out, max_step)
    cid = np.repeat(np.arange(len(curves)), [len(a) for a in first])
    x = np.concatenate(first)
    g = _evaluate(frame, along[cid], fixed[cid], x)
    P, n, u, v = g.P, g.n, g.u, g.v
    same = cid[1:] == cid[:-1]
    pending = same.copy()
    tiny = 1e-12 * np.maximum(1.0, hi - lo)
    for _ in range(MAX_ROUNDS):
        idx = np.nonzero(pending)[0]
        if len(idx) == 0:
            break
        xm = 0.5 * (x[idx] + x[idx + 1])
        gm = _evaluate(frame, along[cid[idx]], fixed[cid[idx]], xm)
        cm = gm.P + r * gm.n
        chord = 0.5 * ((P[idx] + r * n[idx]) + (P[idx + 1] + r * n[idx + 1]))
        dev = cm - chord
        dn = np.einsum("ij,ij->i", dev, gm.n)        # > 0: chord below the centre curve
        lat = np.linalg.norm(dev - dn[:, None] * gm.n, axis=1)
        ok = (dn <= tol_in) & (-dn <= tol_out) & (lat <= tol_in)
        ok |= (x[idx + 1] - x[idx]) < tiny[cid[idx]]                 # cannot split further
        bad = ~ok
        if not bad.any():
            break
        x = np.concatenate([x, xm[bad]])
        cid = np.concatenate([cid, cid[idx[bad]]])
        P = np.concatenate([P, gm.P[bad]])
        n = np.concatenate([n, gm.n[bad]])
        u = np.concatenate([u, gm.u[bad]])
        v = np.concatenate([v, gm.v[bad]])
        new = np.concatenate([np.zeros(len(x) - bad.sum(), bool), np.ones(bad.sum(), bool)])
        order = np.lexsort((x, cid))
        x, cid, P, n, u, v, new = x[order], cid[order], P[order], n[order], u[order], v[order], new[order]
        same = cid[1:] == cid[:-1]
        pending = same & (new[1:] | new[:-1])
    bounds = np.concatenate([[0], np.cumsum(np.bincount(cid, minlength=len(curves)))])
    out = []
    for k, c in enumerate(curves):
        sl = slice(bounds[k], bounds[k + 1])
        piece = (x[sl], P[sl], n[sl], u[sl], v[sl])
        if c.x0 > c.x1:
            piece = tuple(a[::-1] for a in piece)
        out.append(piece)
    return out
