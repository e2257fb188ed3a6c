"""Patches of bicubic cells evaluated point by point, in one pass.

Every sample's patches, and those of most cages and T-spline files, are made of bicubic
Bezier cells and extraordinary cells read from their cached Bezier nets
(:class:`~tsplcam.model.cells.LevelCells`). A point of either is one bicubic net at local
parameters (a polynomial cell's control points less its first one; the net of the point's
sub-cell at its level less the limit point), plus that offset, its derivatives times 2^level
(the level's scale) and divided by the cell's widths; where some cell has weights other than
1 (rational cells; extraordinary cells of a cage whose subdivided weights are 1 only to
rounding) the homogeneous values are then divided out (``diffgeom.rational_from_homogeneous``'s
formulas, which leave a point of weight 1 and weight derivatives 0 as it was, bit for bit).
Here every point takes one fixed sequence of
multiplications and additions for that: the Bernstein values of ``basis._bernstein3``, the
contraction along a (the net's four columns summed in order) and then along b, no BLAS
product (whose summation order depends on the library, the processor and the product's
shape). The compiled kernel (:mod:`tsplcam.compiled` ``cubic_points``) does it point after
point in about 0.07 us, its polynomial nets through a written-out copy of the loop (the
group-by-group numpy route, sorting the points by cell and one BLAS product per run of a
cell's points, took about 0.65 us a point on the path's calls);
without the kernels the same operations run element for element in numpy, so a point gets
the same bits with numba or without, on any processor, whatever else is in the call.

Points deeper than the nets' levels (within 2^-24 of a cell's width from an extraordinary
vertex) are evaluated by their group's configuration route, as before.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from .. import compiled
from ..npfast import clip as _clip
from .basis import _bernstein3
from .cells import _DS, _DT, BezierCells, LevelCells, divide_widths

# the numpy route's points per pass: its temporaries (the nets gathered, 48 values a point)
# stay a few MB
NUMPY_POINTS = 16384


@dataclass
class CubicTable:
    """What :func:`evaluate_points` reads of a patch.

    Per cell (iu, iv): ``kind`` 0 (Bezier) or 1 (extraordinary) and ``ref``, the Bezier
    cell's row of ``nets`` and ``origin``, or the extraordinary cell's number L (its
    ``limit``, ``corner`` (2, L) in (a, b), ``swap``, ``vertex`` values (L, 6, nc) and
    ``limit_normal``; its nets from row ``nb + (L * net_levels + level - 1) * 3 + key``).
    ``nets`` (rows, nc, 4 [j along b], 4 [i along a]) with nc 3 coordinates (x, y, z: every
    weight exactly 1) or 4 (w x, w y, w z, w); ``deep_cells``: per L its (LevelCells group,
    cell in the group) for the points below the nets' levels; ``levels``: the extraordinary
    cells' corners, swaps and levels as ``LevelCells._net_params`` reads them (the numpy
    route's)."""
    ubreaks: np.ndarray
    vbreaks: np.ndarray
    kind: np.ndarray
    ref: np.ndarray
    nets: np.ndarray
    origin: np.ndarray
    limit: np.ndarray
    corner: np.ndarray
    swap: np.ndarray
    vertex: np.ndarray
    limit_normal: np.ndarray
    nb: int
    net_levels: int
    max_level: int
    deep_cells: list
    levels: object = None


def cubic_table(patch) -> CubicTable | None:
    """The :class:`CubicTable` of ``patch``, or None when some group is neither a bicubic
    Bezier group nor an extraordinary group with bicubic nets (other degrees, other
    evaluators: the patch keeps its group-by-group route)."""
    from .patch import _exact_polynomial
    bez, lev = [], []
    for g, grp in enumerate(patch.groups):
        if type(grp) is BezierCells and grp.p == 3 and grp.q == 3:
            bez.append(g)
        elif type(grp) is LevelCells and grp.nets.shape[1:] == (4, 4, 4):
            lev.append(g)
        else:
            return None
    if len({(patch.groups[g].NET_LEVELS, patch.groups[g].MAX_LEVEL) for g in lev}) > 1:
        return None
    nc = 3 if all(_exact_polynomial(g) for g in patch.groups) else 4
    first, nets, origin = {}, [], []
    nb = 0
    for g in bez:
        grp = patch.groups[g]
        n = len(grp)
        # _cj[cell, j * grp.nc + c, i]: as the cell's products read them (a polynomial cell's
        # points less its first one; with 4 coordinates its weight rows 0 and its offset's 1,
        # which give the weight 1 and its derivatives 0 exactly, as the cell writes them)
        net = np.zeros((n, nc, 4, 4))
        net[:, :grp.nc] = grp._cj.reshape(n, 4, grp.nc, 4).transpose(0, 2, 1, 3)
        off = np.zeros((n, nc))
        off[:, :grp.nc] = grp._origin
        if grp.nc < nc:
            off[:, 3] = 1.0
        nets.append(net)
        origin.append(off)
        first[g], nb = nb, nb + n
    nl, deep_cells = 0, []
    for g in lev:
        grp = patch.groups[g]
        nets.append(grp.nets[:, :nc])
        deep_cells += [(grp, k) for k in range(len(grp))]
        first[g], nl = nl, nl + len(grp)
    groups = [patch.groups[g] for g in lev]
    kind = np.where(np.isin(patch.cell_group, lev), 1, 0).astype(np.int64)
    ref = (np.array([first[g] for g in range(len(patch.groups))], np.int64)[patch.cell_group]
           + patch.cell_local).astype(np.int64)

    def cat(arrays, shape, axis=0):
        return np.ascontiguousarray(np.concatenate(arrays, axis=axis)) if arrays else np.zeros(shape)
    t = CubicTable(
        ubreaks=np.ascontiguousarray(patch.ubreaks, float), vbreaks=np.ascontiguousarray(patch.vbreaks, float),
        kind=np.ascontiguousarray(kind), ref=np.ascontiguousarray(ref),
        nets=cat(nets, (0, nc, 4, 4)), origin=cat(origin, (0, nc)),
        limit=cat([g.limit[:, :nc] for g in groups], (0, nc)),
        corner=cat([g._corner for g in groups], (2, 0), axis=1),
        swap=np.ascontiguousarray(np.concatenate([g._swap for g in groups]) if groups else np.zeros(0, bool)),
        vertex=cat([g._vertex[:, :nc].transpose(2, 0, 1) for g in groups], (0, 6, nc)),
        limit_normal=cat([g.limit_normal for g in groups], (0, 3)),
        nb=nb, net_levels=int(groups[0].NET_LEVELS) if groups else 24,
        max_level=int(groups[0].MAX_LEVEL) if groups else 60, deep_cells=deep_cells)
    t.levels = SimpleNamespace(_corner=t.corner, _swap=t.swap, NET_LEVELS=t.net_levels, MAX_LEVEL=t.max_level)
    return t


def evaluate_points(t: CubicTable, u: np.ndarray, v: np.ndarray, nd: int = 6):
    """Derivatives (nd, 3, n) in (u, v) of the points u, v (clipped to [0, 1]; ``nd`` 6: the
    position, first and second derivatives, 3: the first three) and (rows, exact normals) of
    the points at extraordinary vertices (None when there are none)."""
    n = len(u)
    H = np.empty((nd, 3, n))
    flag = np.empty(n, np.int8)
    k = compiled.kernels()
    if k is not None:
        deep = k["cubic_points"](u, v, t.ubreaks, t.vbreaks, t.kind, t.ref, t.nets, t.origin, t.limit, t.corner,
                                 t.swap, t.vertex, t.nb, t.net_levels, t.max_level, H, flag)
    else:
        deep = 0
        for s in range(0, n, NUMPY_POINTS):
            e = min(n, s + NUMPY_POINTS)
            deep += _points_numpy(t, u[s:e], v[s:e], H[:, :, s:e], flag[s:e])
    if deep:
        _deep_points(t, u, v, H, np.nonzero(flag == 2)[0])
    at = np.nonzero(flag == 1)[0]
    if not len(at):
        return H, None
    return H, (at, t.limit_normal[t.ref[_cells(t, u[at], v[at])[:2]]])


def _cells(t: CubicTable, u, v):
    """(iu, iv, width along u, width along v, a, b): the points' cells and local parameters."""
    nu, nv = t.kind.shape
    iu = _clip(t.ubreaks.searchsorted(u, side="right") - 1, 0, nu - 1)
    iv = _clip(t.vbreaks.searchsorted(v, side="right") - 1, 0, nv - 1)
    wu = t.ubreaks[iu + 1] - t.ubreaks[iu]
    wv = t.vbreaks[iv + 1] - t.vbreaks[iv]
    return iu, iv, wu, wv, (u - t.ubreaks[iu]) / wu, (v - t.vbreaks[iv]) / wv


def _points_numpy(t: CubicTable, u, v, H, flag) -> int:
    """:func:`evaluate_points`' kernel in numpy, element for element its operations (the same
    bits); writes H (nd, 3, n) and flag (0, 1 at a vertex, 2 deeper than the nets); returns
    the number of deep points."""
    nd, n = H.shape[0], len(u)
    iu, iv, wu, wv, a, b = _cells(t, u, v)
    kind, ref = t.kind[iu, iv], t.ref[iu, iv]
    key = ref.copy()
    add = np.empty((t.nets.shape[1], n))
    scale = np.ones(n)
    flag[:] = 0
    bz = kind == 0
    add[:, bz] = t.origin[ref[bz]].T
    lv = np.nonzero(~bz)[0]
    if len(lv):
        L = ref[lv]
        E, lkey, sc, atv, deep = LevelCells._net_params(t.levels, L, a[lv], b[lv])
        key[lv] = t.nb + lkey
        a[lv], b[lv] = E[0], E[1]
        scale[lv] = sc
        add[:, lv] = t.limit[L].T
        flag[lv[deep]] = 2
        flag[lv[atv]] = 1
    no = 3 if nd == 6 else 2
    nc = t.nets.shape[1]
    Hh = H if nc == 3 else np.empty((nd, 4, n))
    bs, bt = _bernstein3(a), _bernstein3(b)
    X = t.nets[key].transpose(3, 2, 1, 0)              # [i, j, c, point]
    T = np.empty((no, 4, nc, n))                       # along a: [order, j, c, point]
    for d in range(no):
        np.multiply(X[0], bs[d, 0], out=T[d])
        for i in (1, 2, 3):
            T[d] += X[i] * bs[d, i]
    for k in range(nd):
        ds, dt = _DS[k], _DT[k]
        h = Hh[k]
        np.multiply(bt[dt, 0], T[ds, 0], out=h)
        for j in (1, 2, 3):
            h += bt[dt, j] * T[ds, j]
    Hh[0] += add
    Hh[1] *= scale
    Hh[2] *= scale
    if nd > 3:
        ss = scale * scale
        Hh[3] *= ss
        Hh[4] *= ss
        Hh[5] *= ss
    at = np.nonzero(flag == 1)[0]
    if len(at):
        Hh[:, :, at] = t.vertex[ref[at], :nd].transpose(1, 2, 0)
    divide_widths(Hh, wu, wv)
    if nc == 4:
        _euclidean(Hh, H)
    return int(np.count_nonzero(flag == 2))


def _deep_points(t: CubicTable, u, v, H, rows) -> None:
    """The points ``rows`` below the nets' deepest level, by their group's configuration
    route (``LevelCells._evaluate``), into H."""
    nd = H.shape[0]
    iu, iv, wu, wv, a, b = _cells(t, u[rows], v[rows])
    L = t.ref[iu, iv]
    for k in np.unique(L).tolist():
        sel = np.nonzero(L == k)[0]
        grp, local = t.deep_cells[k]
        Hd = divide_widths(grp._evaluate(np.full(len(sel), local), a[sel], b[sel])[0][:nd], wu[sel], wv[sel])
        if t.nets.shape[1] == 4:
            E = np.empty((nd, 3, len(sel)))
            _euclidean(Hd, E)
            Hd = E
        H[:, :, rows[sel]] = Hd[:, :3]


def _euclidean(Hh: np.ndarray, H: np.ndarray) -> None:
    """Euclidean derivatives H (nd, 3, n) of homogeneous ones Hh (nd, 4, n): the formulas of
    ``diffgeom.rational_from_homogeneous`` with its operations in its order (the kernel's too)."""
    B, W = Hh[:, :3], Hh[:, 3]
    w = W[0]
    np.divide(B[0], w, out=H[0])
    S = H[0]
    np.divide(B[1] - W[1] * S, w, out=H[1])
    np.divide(B[2] - W[2] * S, w, out=H[2])
    if len(H) > 3:
        Su, Sv = H[1], H[2]
        np.divide(B[3] - 2.0 * W[1] * Su - W[3] * S, w, out=H[3])
        np.divide(B[4] - W[4] * S - W[1] * Sv - W[2] * Su, w, out=H[4])
        np.divide(B[5] - 2.0 * W[2] * Sv - W[5] * S, w, out=H[5])
