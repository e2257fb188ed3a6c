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

# numpy's C functions without their Python dispatch wrappers: the same calls, a few
# microseconds less each on the many small arrays here
from ..npfast import quiet as _quiet, where as _where, c_einsum as _einsum, concatenate as _concatenate
from ..npfast import row_norms

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


def _evaluate(frame, along: np.ndarray, fixed: np.ndarray, x: np.ndarray, second: bool = True):
    """Frame geometry at parameter x of curves with these ``along`` flags (True: 't');
    ``second`` as for ``LineFrame.evaluate``."""
    return frame.evaluate(_where(along, fixed, x), _where(along, x, fixed), second)


def _first_points(frame, curves: list[Curve], r, tol_in, tol_out, max_step):
    """First parameters per curve from the integrated density (module doc). Every curve's
    samples, integral and inversion are made for all curves at once (:func:`_linspaces`,
    :func:`_interp_many`): the same arithmetic per curve as ``np.linspace``, ``np.cumsum``
    and ``np.interp`` of the curve alone, without some ten array calls per curve."""
    lo = np.array([min(c.x0, c.x1) for c in curves])
    hi = np.array([max(c.x0, c.x1) for c in curves])
    num = np.array([max(int(c.dense), 3) for c in curves])
    xa, cid, bounds = _linspaces(lo, hi, num)
    along = np.array([c.along == "t" for c in curves])
    fixed = np.array([c.fixed for c in curves])
    span = (hi - lo)[cid]
    # the curvature is read slightly inside the ends: at an extraordinary corner the second
    # derivatives are singular (the kernel's values there are meaningless)
    with _quiet("invalid", "divide"):
        inner = lo[cid] + span * (END_EPS + (1 - 2 * END_EPS) * (xa - lo[cid]) / span)
    g = _evaluate(frame, along[cid], fixed[cid], inner)
    at = along[cid]
    speed = row_norms(_where(at[:, None], g.St, g.Ss))
    kft, kgt = g.curve_curvature("t")
    kfs, kgs = g.curve_curvature("s")
    kf, kg = _where(at, kft, kfs), _where(at, kgt, kgs)
    kf = _where(np.isfinite(kf), kf, 0.0)
    kg = _where(np.isfinite(kg), np.minimum(kg, 1e6), 1e6)
    tol = _where(kf > 0, tol_out, tol_in)
    step = np.minimum(forward_step(r, tol, kf, kg), max_step)
    step = np.minimum(step, forward_step(r, tol_in, 0.0, kg))
    dens = speed / np.maximum(step, 1e-12)
    # the trapezoids of every curve's integral (pairs across two curves dropped), and the
    # running sums per curve: one row per curve, the curves of one length at a time
    trap = 0.5 * (dens[1:] + dens[:-1]) * (xa[1:] - xa[:-1])
    cum = np.zeros(len(xa))
    for m in np.unique(num).tolist():
        rows = np.flatnonzero(num == m)
        first = bounds[rows]
        sel = (first[:, None] + np.arange(m - 1)[None, :]).ravel()
        cum[(first[:, None] + np.arange(1, m)[None, :]).ravel()] = np.cumsum(
            trap[sel].reshape(len(rows), m - 1), axis=1).ravel()
    total = cum[bounds + num - 1]
    ok = (hi - lo > 0) & (total > 0) & np.isfinite(total)
    out = [None] * len(curves)
    if ok.any():
        kk = np.flatnonzero(ok)
        nseg = np.maximum(1, np.ceil(total[kk] / SAFETY).astype(int))
        q, qcid, qfirst = _linspaces(np.zeros(len(kk)), total[kk], nseg + 1)
        pts = _interp_many(q, kk[qcid], cum, xa, bounds, num)
        pts[qfirst] = lo[kk]
        pts[qfirst + nseg] = hi[kk]
        # np.unique per curve: sorted, repeats dropped (the points of a curve mostly come
        # sorted: then the stable sort would leave them as they are)
        qc = qcid
        if not ((pts[1:] >= pts[:-1]) | (qc[1:] > qc[:-1])).all():
            order = np.lexsort((pts, qcid))
            pts, qc = pts[order], qcid[order]
        keep = np.ones(len(pts), bool)
        keep[1:] = (pts[1:] != pts[:-1]) | (qc[1:] != qc[:-1])
        pts, qc = pts[keep], qc[keep]
        cuts = [0] + (np.flatnonzero(qc[1:] != qc[:-1]) + 1).tolist() + [len(pts)]
        for i, k in enumerate(kk.tolist()):
            out[k] = pts[cuts[i]:cuts[i + 1]]
    for k in np.flatnonzero(~ok).tolist():               # as one curve alone (rare)
        if hi[k] - lo[k] <= 0:
            out[k] = np.array([curves[k].x0])
            continue
        x = xa[bounds[k]:bounds[k] + num[k]]
        c = cum[bounds[k]:bounds[k] + num[k]]
        nseg = max(1, int(np.ceil(c[-1] / SAFETY)))
        if c[-1] > 0:
            p = np.interp(np.linspace(0.0, c[-1], nseg + 1), c, x)
        else:
            p = np.linspace(lo[k], hi[k], nseg + 1)
        p[0], p[-1] = lo[k], hi[k]
        out[k] = np.unique(p)
    return out, lo, hi, along, fixed


def _linspaces(lo: np.ndarray, hi: np.ndarray, num: np.ndarray):
    """``np.linspace(lo[k], hi[k], num[k])`` (num >= 2) of every k one after the other, with
    its arithmetic (i * step + start; (i / div) * delta + start where the step is 0; the last
    value the stop itself): (values, curve of each, first index of each curve)."""
    num = np.asarray(num)
    first = np.cumsum(num) - num
    cid = np.repeat(np.arange(len(num)), num)
    i = (np.arange(len(cid)) - first[cid]).astype(float)
    div = (num - 1).astype(float)
    delta = hi - lo
    step = delta / div
    y = i * step[cid]
    zero = step == 0
    if zero.any():
        z = zero[cid]
        y[z] = (i[z] / div[cid][z]) * delta[cid][z]
    y += lo[cid]
    y[first + num - 1] = hi
    return y, cid, first


def _interp_many(x: np.ndarray, xcid: np.ndarray, xp: np.ndarray, fp: np.ndarray, first: np.ndarray,
                 num: np.ndarray) -> np.ndarray:
    """``np.interp(x, xp_k, fp_k)`` with xp_k, fp_k the rows first[k] .. first[k] + num[k] of
    xp, fp (xp_k increasing), for points x of curves xcid: numpy's arithmetic (the interval
    with xp[j] <= x < xp[j + 1]; fp[j] where x is xp[j] or the last; else slope (x - xp[j]) +
    fp[j], from the right end where that is NaN), for all curves at once."""
    # j: how many of the curve's xp are <= x, less one (queries sorted in after equal xp)
    pcid = np.repeat(np.arange(len(num)), num)
    allc = _concatenate([pcid, xcid])
    allv = _concatenate([xp[:len(pcid)], x])
    kind = _concatenate([np.zeros(len(pcid), np.int8), np.ones(len(x), np.int8)])
    order = np.lexsort((kind, allv, allc))
    before = np.cumsum(kind[order] == 0)                 # xp rows at or before each position
    jq = np.empty(len(x), int)
    isq = kind[order] == 1
    jq[order[isq] - len(pcid)] = before[isq]
    j = jq - first[xcid] - 1                             # local index, -1 .. num
    n = num[xcid]
    jc = np.minimum(np.maximum(j, 0), n - 2)
    g0 = first[xcid] + jc
    x0, x1, f0, f1 = xp[g0], xp[g0 + 1], fp[g0], fp[g0 + 1]
    with _quiet("invalid", "divide", "over"):
        slope = (f1 - f0) / (x1 - x0)
        res = slope * (x - x0) + f0
        nan = np.isnan(res)
        if nan.any():
            res2 = slope * (x - x1) + f1
            res = _where(nan, _where(np.isnan(res2) & (f0 == f1), f0, res2), res)
    res = _where((j == n - 1) | (x0 == x), fp[first[xcid] + np.minimum(np.maximum(j, 0), n - 1)], res)
    res = _where(j < 0, fp[first[xcid]], res)
    res = _where(j >= n, fp[first[xcid] + n - 1], res)
    return res


def _merge_rows(old: np.ndarray, add: np.ndarray, is_new: np.ndarray) -> np.ndarray:
    """The rows of ``old`` and ``add`` in one array: ``add``'s where ``is_new``, ``old``'s in
    their order elsewhere."""
    out = np.empty((len(is_new),) + old.shape[1:], old.dtype)
    out[is_new] = add
    out[~is_new] = old
    return out


def place_curves(frame, curves: list[Curve], r: float, tol_in: float, tol_out: float, max_step: float):
    """Parameters along every curve and the surface geometry there: per curve (x, P, n, u,
    v), ordered from x0 to x1, ends included exactly (a curve of zero length: one point)."""
    if not curves:
        return []
    first, lo, hi, along, fixed = _first_points(frame, curves, r, tol_in, tol_out, max_step)
    cid = np.repeat(np.arange(len(curves)), [len(a) for a in first])
    x = _concatenate(first)
    g = _evaluate(frame, along[cid], fixed[cid], x, second=False)
    P, n, u, v = g.P, g.n, g.u, g.v
    same = cid[1:] == cid[:-1]
    pending = same.copy()
    tiny = 1e-12 * np.maximum(1.0, hi - lo)
    for _ in range(MAX_ROUNDS):
        idx = np.nonzero(pending)[0]
        if len(idx) == 0:
            break
        xm = 0.5 * (x[idx] + x[idx + 1])
        gm = _evaluate(frame, along[cid[idx]], fixed[cid[idx]], xm, second=False)
        cm = gm.P + r * gm.n
        chord = 0.5 * ((P[idx] + r * n[idx]) + (P[idx + 1] + r * n[idx + 1]))
        dev = cm - chord
        dn = _einsum("ij,ij->i", dev, gm.n)        # > 0: chord below the centre curve
        lat = np.linalg.norm(dev - dn[:, None] * gm.n, axis=1)
        ok = (dn <= tol_in) & (-dn <= tol_out) & (lat <= tol_in)
        ok |= (x[idx + 1] - x[idx]) < tiny[cid[idx]]                 # cannot split further
        bad = ~ok
        if not bad.any():
            break
        # each new point goes between its segment's ends: the points stay sorted by curve
        # and parameter (a split segment is at least ``tiny`` long, so its middle lies
        # strictly inside), the order a sort by (curve, x) would give, without sorting
        split = idx[bad]
        new = np.zeros(len(x) + len(split), bool)
        new[split + 1 + np.arange(len(split))] = True
        x = _merge_rows(x, xm[bad], new)
        cid = _merge_rows(cid, cid[split], new)
        P = _merge_rows(P, gm.P[bad], new)
        n = _merge_rows(n, gm.n[bad], new)
        u = _merge_rows(u, gm.u[bad], new)
        v = _merge_rows(v, gm.v[bad], new)
        same = cid[1:] == cid[:-1]
        pending = same & (new[1:] | new[:-1])
    bounds = _concatenate([[0], np.cumsum(np.bincount(cid, minlength=len(curves)))])
    out = []
    for k, c in enumerate(curves):
        sl = slice(bounds[k], bounds[k + 1])
        piece = (x[sl], P[sl], n[sl], u[sl], v[sl])
        if c.x0 > c.x1:
            piece = tuple(a[::-1] for a in piece)
        out.append(piece)
    return out
