"""A four-sided patch of the model with its own (u, v) on the unit square.

The domain is cut by ``ubreaks`` x ``vbreaks`` into a grid of cells; every cell belongs to
one cell evaluator group (Bezier or extraordinary, see ``cells.py``). A patch whose cells are
all bicubic (every sample's; Bezier cells and extraordinary cells' nets) evaluates its points
in one pass, point by point (``cubic_points.py``: the compiled kernel, else the same operations
in numpy). Any other patch's evaluation of any number of points is a handful of array calls:
locate cells with ``searchsorted``, sort the
points by group call and cell, evaluate each group's points at once into their block (a
patch's extraordinary groups, one per corner configuration, together; their Bernstein values
and the Bezier cells' in one call), convert homogeneous to Euclidean derivatives (nothing to
convert on a polynomial patch). Every shortcut gives each point the
same arithmetic as the others would (the path's programs stay the same bytes when it gets
faster): the only value that depends on the other points of a call is a Bezier cell's BLAS
product, which is made run by run of the cell's points as before. Callers that read no
second derivatives (the cusps' edge pass, the chord placement) ask for the position and first
derivatives alone (``second=False``): on a polynomial patch the same products for those,
without the second-order ones.

Corners and edges of the unit square (shang2020 section 3.2), used by every later stage:
corner k sits at ``CORNER_UV[k]``: 0 = (0,0) lower left, 1 = (1,0) lower right, 2 = (1,1)
upper right, 3 = (0,1) upper left. Edge k runs from corner k to corner k+1: 0 = bottom
(v=0), 1 = right (u=1), 2 = top (v=1), 3 = left (u=0).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# numpy's C functions without their Python dispatch wrappers: the same calls, a few
# microseconds less each on the many small arrays here
from ..npfast import where as _where, c_einsum as _einsum, concatenate as _concatenate
from ..npfast import bincount as _bincount, clip as _clip, count_nonzero as _count_nonzero
from ..npfast import cross_rows as _cross

from ..errors import InputError
from .basis import bernstein, bernstein_rows
from .cells import SQUARE_MAPS, BezierCells, LevelCells, divide_widths
from .cubic_points import cubic_table, evaluate_points
from .diffgeom import SurfacePoints, rational_from_homogeneous

CORNER_UV = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
EDGE_CORNERS = ((0, 1), (1, 2), (2, 3), (3, 0))
CORNER_NAMES = ("lower-left", "lower-right", "upper-right", "upper-left")
EDGE_NAMES = ("bottom", "right", "top", "left")

CHUNK = 1 << 17
_min, _max = np.minimum.reduce, np.maximum.reduce    # ndarray.min / max without theirs


def rotation_map(rotation: int) -> int:
    """Index of the ``cells.SQUARE_MAPS`` entry that takes corner m of the unit square to
    corner (m + rotation) % 4."""
    for idx, (A, o) in enumerate(SQUARE_MAPS):
        if all(np.allclose(A @ CORNER_UV[m] + o, CORNER_UV[(m + rotation) % 4]) for m in range(4)):
            return idx
    raise AssertionError(rotation)


@dataclass(frozen=True)
class EdgeNeighbour:
    """Across an edge of a patch: patch ``patch``'s edge ``edge``; ``reversed`` as in EdgeLink."""
    patch: int
    edge: int
    reversed: bool = True


class Patch:
    """One patch: cells on a grid of the unit square, neighbours, corner nodes.

    ``knot_size`` (ku, kv) is the patch's extent in knot units (for a cage: faces along u
    and v); it fixes the scale of the parameter transform to neighbours.
    """

    def __init__(self, index: int, ubreaks, vbreaks, cell_group, cell_local, groups,
                 name: str | None = None, knot_size=(1.0, 1.0)):
        self.index = index
        self.name = name or f"patch {index}"
        self.ubreaks = np.asarray(ubreaks, float)
        self.vbreaks = np.asarray(vbreaks, float)
        self.cell_group = np.asarray(cell_group, int)      # (nu, nv)
        self.cell_local = np.asarray(cell_local, int)      # (nu, nv)
        self.groups = list(groups)
        self.knot_size = tuple(float(x) for x in knot_size)
        self.neighbours: list[EdgeNeighbour | None] = [None, None, None, None]
        self.corner_nodes = np.full(4, -1, dtype=int)
        nu, nv = len(self.ubreaks) - 1, len(self.vbreaks) - 1
        if self.cell_group.shape != (nu, nv) or self.cell_local.shape != (nu, nv):
            raise ValueError(f"{self.name}: cell table shape {self.cell_group.shape} != ({nu}, {nv})")

    def __repr__(self) -> str:
        return (f"<Patch {self.index} '{self.name}' {len(self.ubreaks) - 1}x{len(self.vbreaks) - 1} cells>")

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.ubreaks) - 1, len(self.vbreaks) - 1

    def evaluate(self, u, v, second: bool = True) -> SurfacePoints:
        """Position, first and second partial derivatives and everything derived from them,
        at parameters u, v (arrays of equal length, or scalars) in [0, 1].

        ``second`` False: the caller reads no second derivatives; a polynomial patch then
        leaves them out (Puu, Puv, Pvv None; the position and first derivatives are the
        same values, made by the same products), any other gives them all."""
        u = np.asarray(u, dtype=float).reshape(-1)       # (a scalar: one point)
        v = np.asarray(v, dtype=float).reshape(-1)
        if u.shape != v.shape:
            u, v = np.broadcast_arrays(u, v)
            u, v = u.copy(), v.copy()
        # four reductions decide the common case (NaN fails both comparisons)
        if not (_min(u, initial=0.0) >= -1e-9 and _min(v, initial=0.0) >= -1e-9
                and _max(u, initial=1.0) <= 1 + 1e-9 and _max(v, initial=1.0) <= 1 + 1e-9):
            bad = ~(np.isfinite(u) & np.isfinite(v)) | (u < -1e-9) | (u > 1 + 1e-9) | (v < -1e-9) | (v > 1 + 1e-9)
            i = int(np.nonzero(bad)[0][0])
            raise InputError(f"parameter (u, v) = ({u[i]:g}, {v[i]:g}) is outside the unit square "
                             f"({int(bad.sum())} such points)", item=self.name)
        u = _clip(u, 0.0, 1.0)
        v = _clip(v, 0.0, 1.0)
        n = len(u)
        ep_rows, ep_normals = [], []
        cubic = self._cubic_table()
        if cubic is not None:
            # bicubic cells: every point in one pass (cubic_points)
            nd = 6 if second else 3
            H, ep = evaluate_points(cubic, u, v, nd)
            out = tuple(H[k] for k in range(nd)) + (None,) * (6 - nd)
            if ep is not None:
                ep_rows.append(ep[0])
                ep_normals.append(ep[1])
        elif n <= CHUNK:
            # a polynomial patch: the weight rows are 1 and 0 (rational_from_homogeneous's test
            # would pass), not gathered back
            tables = self._tables()
            poly = tables[4]
            nd = 6 if second or not poly else 3
            order, H, ep = self._evaluate_h(u, v, tables, nd)
            if order is not None:                            # back from cell order: one gather
                inverse = np.empty_like(order)
                inverse[order] = np.arange(n)
                H = (H[:, :3] if poly else H).take(inverse, axis=2)
            if poly:
                out = tuple(H[k, :3] for k in range(nd)) + (None,) * (6 - nd)
            else:
                out = rational_from_homogeneous(H)           # six (3, n), point by point
            if ep is not None:
                ep_rows.append(ep[0] if order is None else order[ep[0]])
                ep_normals.append(ep[1])
        else:
            out = np.empty((6, 3, n))                        # coordinate-major
            for start in range(0, n, CHUNK):
                stop = min(n, start + CHUNK)
                order, H, ep = self._evaluate_h(u[start:stop], v[start:stop])
                E = rational_from_homogeneous(H)             # six (3, m), in cell order
                rows = start + (np.arange(stop - start) if order is None else order)
                for k in range(6):
                    out[k][:, rows] = E[k]
                if ep is not None:
                    ep_rows.append(rows[ep[0]])
                    ep_normals.append(ep[1])
        # (n, 3) views of the coordinate-major rows: no copy
        P, Pu, Pv, Puu, Puv, Pvv = (None if x is None else x.T for x in out)
        normal_override = None
        if ep_rows:
            rows = _concatenate(ep_rows)
            nrm = _concatenate(ep_normals)
            normal_override = _unit(_cross(Pu, Pv))
            sign = np.sign(_einsum("ij,ij->i", nrm, normal_override[rows]))
            normal_override[rows] = nrm * _where(sign == 0, 1.0, sign)[:, None]
        return SurfacePoints(P, Pu, Pv, Puu, Puv, Pvv, u, v, self.index, normal_override)

    def evaluate_grid(self, us, vs, second: bool = True) -> SurfacePoints:
        """Everything :meth:`evaluate` gives, on the tensor grid us x vs: rows in the order of
        ``np.meshgrid(us, vs, indexing='ij')`` (u slowest). Bezier cells are evaluated with
        two BLAS products per cell (tessellation, verification grids, iso-lines); other cells
        through :meth:`evaluate`. ``second`` False: the points, first derivatives and normals
        alone, the same values (Puu, Puv, Pvv None; half the memory: the verification's grid
        of tjunction_mold, 2,448,180 samples, holds 176 MB less)."""
        us, vs, iu, iv = self._grid_cells(us, vs)
        kinds = 6 if second else 3
        out = np.empty((kinds, 3, len(us), len(vs)))      # coordinate-major, filled by blocks
        normal = None
        for ci in np.unique(iu):
            I = _index_or_slice(np.nonzero(iu == ci)[0])
            wu = self.ubreaks[ci + 1] - self.ubreaks[ci]
            a = (us[I] - self.ubreaks[ci]) / wu
            for cj in np.unique(iv):
                J = _index_or_slice(np.nonzero(iv == cj)[0])
                ni, nj = len(a), len(vs[J])
                group = self.groups[self.cell_group[ci, cj]]
                contiguous = isinstance(I, slice) and isinstance(J, slice)
                rows = (I, J) if contiguous else np.ix_(np.arange(len(us))[I], np.arange(len(vs))[J])
                block = (slice(None), slice(None)) + tuple(rows)
                nrm = None
                if isinstance(group, BezierCells):
                    wv = self.vbreaks[cj + 1] - self.vbreaks[cj]
                    b = (vs[J] - self.vbreaks[cj]) / wv
                    if not group.rational and contiguous:
                        # polynomial cell: the BLAS product writes into the grid itself
                        group.evaluate_tensor(self.cell_local[ci, cj], a, b, wu, wv, out=out[block])
                        continue
                    H = group.evaluate_tensor(self.cell_local[ci, cj], a, b, wu, wv)
                    E = (rational_from_homogeneous(H.reshape(6, 4, -1)) if group.rational
                         else H.reshape(6, 3, -1))
                else:
                    U, V = np.meshgrid(us[I], vs[J], indexing="ij")
                    sp = self.evaluate(U.ravel(), V.ravel(), second=second)
                    E = [x.T for x in (sp.P, sp.Pu, sp.Pv, sp.Puu, sp.Puv, sp.Pvv)[:kinds]]
                    nrm = sp.normal_override
                for k in range(kinds):
                    out[k][block[1:]] = E[k].reshape(3, ni, nj)
                if nrm is not None:
                    if normal is None:
                        normal = np.full((len(us), len(vs), 3), np.nan)
                    normal[rows] = nrm.reshape(ni, nj, 3)
        # (n, 3) views of the coordinate-major blocks: no copy
        P, Pu, Pv, Puu, Puv, Pvv = [x.reshape(3, -1).T for x in out] + [None] * (6 - kinds)
        if normal is not None:
            normal = normal.reshape(-1, 3)
            fill = np.isnan(normal[:, 0])
            normal[fill] = _unit(np.cross(Pu[fill], Pv[fill]))
        return SurfacePoints(P, Pu, Pv, Puu, Puv, Pvv, np.repeat(us, len(vs)), np.tile(vs, len(us)),
                             self.index, normal)

    def _grid_cells(self, us, vs):
        """The grid's parameters checked and clipped to [0, 1], and the cell row and column of
        each (a value on a cell break goes to the cell above it, the last break to the last
        cell)."""
        us = np.asarray(us, float).reshape(-1)
        vs = np.asarray(vs, float).reshape(-1)
        for name, x in (("u", us), ("v", vs)):
            if not np.isfinite(x).all() or x.min(initial=0.0) < -1e-9 or x.max(initial=0.0) > 1 + 1e-9:
                raise InputError(f"grid {name} values must lie in [0, 1]", item=self.name)
        us, vs = _clip(us, 0.0, 1.0), _clip(vs, 0.0, 1.0)
        nu, nv = self.shape
        iu = _clip(np.searchsorted(self.ubreaks, us, side="right") - 1, 0, nu - 1)
        iv = _clip(np.searchsorted(self.vbreaks, vs, side="right") - 1, 0, nv - 1)
        return us, vs, iu, iv

    def grid_points(self, us, vs) -> np.ndarray:
        """The positions alone on the tensor grid us x vs, (len(us) * len(vs), 3) in
        :meth:`evaluate_grid`'s row order, for callers that need no derivatives (the collision
        checker's tessellation). A patch of bicubic cells (every sample's) evaluates them point
        by point (:func:`~tsplcam.model.cubic_points.evaluate_points`): each point's position
        as :meth:`evaluate` gives it, bit for bit, in 0.05 us (the keycap's tessellation, 185k
        points: 31 -> 18 ms; the blocks' BLAS products cost more in Python per cell than in
        arithmetic). Other patches: polynomial Bezier blocks take only the position's product
        from bases made once per row and column of cells (``BezierCells.tensor_positions``,
        :meth:`evaluate_grid`'s ``P`` bit for bit), the extraordinary cells' blocks in one
        :meth:`evaluate` call, other blocks as there."""
        return self.grids_points([(us, vs)])[0]

    def grids_points(self, grids) -> list:
        """:meth:`grid_points` of several grids [(us, vs), ...]: the points of all of them in
        one point-by-point pass (or one :meth:`evaluate` call for the other patches'
        extraordinary blocks: a tessellation measures five grids at a time) when none lies
        within 2^-20 of a cell's corner but on it (no point there goes below the cached nets'
        levels, the one route whose products span points), else one per grid."""
        cubic = self._cubic_table()
        if cubic is not None:
            return self._grids_by_points(cubic, grids)
        outs, pending = [], []
        for us, vs in grids:
            out, blocks = self._grid_blocks(us, vs)
            outs.append(out)
            pending.append(blocks)
        if any(pending):
            together = len(pending) == 1 or not self._near_corners(
                _concatenate([b[3] for bs in pending for b in bs]),
                _concatenate([b[4] for bs in pending for b in bs]))
            for ks in ([range(len(pending))] if together else [[k] for k in range(len(pending))]):
                blocks = [(k, b) for k in ks for b in pending[k]]
                if not blocks:
                    continue
                # their points are evaluated point by point (LevelCells' nets, _LevelSet), the
                # few below the nets' deepest level per cell and level: the same values together
                # (positions alone: no second derivatives, the same positions by the same products)
                P = self.evaluate(_concatenate([b[3] for _, b in blocks]),
                                  _concatenate([b[4] for _, b in blocks]), second=False).P.T
                start = 0
                for k, (rows, ni, nj, _, _) in blocks:
                    outs[k][(slice(None),) + tuple(rows)] = P[:, start:start + ni * nj].reshape(3, ni, nj)
                    start += ni * nj
        return [out.reshape(3, -1).T for out in outs]

    def _grids_by_points(self, cubic, grids) -> list:
        """:meth:`grids_points` of a patch of bicubic cells: every grid point through
        :func:`evaluate_points` (its position, the first derivatives left unread)."""
        lines = [self._grid_cells(us, vs)[:2] for us, vs in grids]
        near = len(lines) > 1 and any(self._near_corner_lines(us, vs) for us, vs in lines)
        out = [None] * len(lines)
        for ks in ([[k] for k in range(len(lines))] if near else [range(len(lines))]):
            u = _concatenate([np.repeat(lines[k][0], len(lines[k][1])) for k in ks])
            v = _concatenate([np.tile(lines[k][1], len(lines[k][0])) for k in ks])
            H, _ = evaluate_points(cubic, u, v, 3)
            P, start = H[0].T, 0
            for k in ks:
                n = len(lines[k][0]) * len(lines[k][1])
                out[k] = P[start:start + n]
                start += n
        return out

    def _near_corner_lines(self, us, vs) -> bool:
        """:meth:`_near_corners` of the tensor grid us x vs from its lines: a point lies within
        2^-20 of its cell's corner but not on it where both its lines lie within 2^-20 of a
        cell's side and one of them not on it."""
        du, dv = self._side_distances(us, self.ubreaks), self._side_distances(vs, self.vbreaks)
        u_in, v_in = bool(np.any(du < 2.0 ** -20)), bool(np.any(dv < 2.0 ** -20))
        u_near = bool(np.any((du > 0.0) & (du < 2.0 ** -20)))
        v_near = bool(np.any((dv > 0.0) & (dv < 2.0 ** -20)))
        return (u_near and v_in) or (u_in and v_near)

    @staticmethod
    def _side_distances(x, breaks) -> np.ndarray:
        """Each parameter's distance from the nearer side of its cell, in the cell's widths (a
        value on a break goes to the cell above it, the last break to the last cell)."""
        i = _clip(np.searchsorted(breaks, x, side="right") - 1, 0, len(breaks) - 2)
        a = (x - breaks[i]) / (breaks[i + 1] - breaks[i])
        return np.minimum(a, 1.0 - a)

    def _near_corners(self, u, v) -> bool:
        """Whether a point lies within 2^-20 of its cell's width from one of the cell's corners
        without being on it."""
        d = np.maximum(self._side_distances(u, self.ubreaks), self._side_distances(v, self.vbreaks))
        return bool(np.any((d > 0.0) & (d < 2.0 ** -20)))

    def _grid_blocks(self, us, vs):
        """One grid of :meth:`grids_points`: its positions (3, len(us), len(vs)) with every
        block but the LevelCells ones filled, and those as (rows, ni, nj, u, v)."""
        us, vs, iu, iv = self._grid_cells(us, vs)
        out = np.empty((3, len(us), len(vs)))             # coordinate-major, as evaluate_grid's P
        ucells = [(ci, _index_or_slice(np.nonzero(iu == ci)[0])) for ci in np.unique(iu).tolist()]
        vcells = [(cj, _index_or_slice(np.nonzero(iv == cj)[0])) for cj in np.unique(iv).tolist()]
        # every grid value's local parameter in its cell (as per block: the same operations)
        wu_all = self.ubreaks[iu + 1] - self.ubreaks[iu]
        wv_all = self.vbreaks[iv + 1] - self.vbreaks[iv]
        a_all = (us - self.ubreaks[iu]) / wu_all
        b_all = (vs - self.vbreaks[iv]) / wv_all
        values, bases = {}, {}
        level_blocks = []                                 # extraordinary cells: one call for all
        for ci, I in ucells:
            wu = self.ubreaks[ci + 1] - self.ubreaks[ci]
            a = (us[I] - self.ubreaks[ci]) / wu
            for cj, J in vcells:
                group = self.groups[self.cell_group[ci, cj]]
                contiguous = isinstance(I, slice) and isinstance(J, slice)
                if isinstance(group, BezierCells) and not group.rational and contiguous:
                    ka, kb = ("u", ci, group.p), ("v", cj, group.q)
                    if ka not in bases:
                        if ("u", group.p) not in values:
                            values["u", group.p] = bernstein(group.p, a_all)
                        bases[ka] = BezierCells.tensor_bases(values["u", group.p][I], wu)
                    if kb not in bases:
                        if ("v", group.q) not in values:
                            values["v", group.q] = bernstein(group.q, b_all)
                        bases[kb] = BezierCells.tensor_bases(values["v", group.q][J], wv_all[J.start])
                    group.tensor_positions(self.cell_local[ci, cj], bases[ka][0], bases[kb][1], out[:, I, J])
                    continue
                # every other block as evaluate_grid does it, its positions kept
                rows = (I, J) if contiguous else np.ix_(np.arange(len(us))[I], np.arange(len(vs))[J])
                ni, nj = len(a), len(vs[J])
                if isinstance(group, BezierCells):
                    wv = self.vbreaks[cj + 1] - self.vbreaks[cj]
                    b = (vs[J] - self.vbreaks[cj]) / wv
                    H = group.evaluate_tensor(self.cell_local[ci, cj], a, b, wu, wv)
                    P = (rational_from_homogeneous(H.reshape(6, 4, -1))[0] if group.rational
                         else H.reshape(6, 3, -1)[0])
                else:
                    U, V = np.meshgrid(us[I], vs[J], indexing="ij")
                    if type(group) is LevelCells:
                        level_blocks.append((rows, ni, nj, U.ravel(), V.ravel()))
                        continue
                    P = self.evaluate(U.ravel(), V.ravel(), second=False).P.T
                out[(slice(None),) + tuple(rows)] = P.reshape(3, ni, nj)
        return out, level_blocks

    def _evaluate_h(self, u, v, tables=None, nd: int = 6):
        """Homogeneous derivatives (nd, 4, m) of the points sorted by cell, the sorting order
        (None when they come sorted), and (rows in sorted order, exact normals) of points at
        irregular vertices. ``tables``: :meth:`_tables`, when the caller has them. ``nd`` 3:
        the position and first derivatives alone (polynomial patches only: their groups are
        Bezier and extraordinary cells, which make them so).

        With several groups the points are sorted by group call first (``_tables``), then
        by cell: each call's points are one block, which it writes in place, and every group
        sees its points in the same order as sorted by cell alone (the same runs, the same
        values). A Bezier group of cubic cells and the extraordinary cells' nets (the common
        patch) share one Bernstein evaluation (``_bezier_and_nets``)."""
        nu, nv = self.shape
        # a polynomial patch reads no weight rows: its extraordinary cells make x, y, z alone
        nc = 3 if (tables or self._tables())[4] else 4
        # a point on a cell break (or rounded off it) goes to either cell: the surface is
        # continuous there, both give the same point up to rounding
        iu = _clip(self.ubreaks.searchsorted(u, side="right") - 1, 0, nu - 1)
        iv = _clip(self.vbreaks.searchsorted(v, side="right") - 1, 0, nv - 1)
        single = len(self.groups) == 1
        if not single:
            tables = tables or self._tables()
        key = iu * nv + iv if single else tables[3][iu, iv]
        if len(key) < 2 or bool((key[1:] >= key[:-1]).all()):
            order = None                                   # sorted already: the stable order
        else:
            order = key.argsort(kind="stable")
            iu, iv, u, v = iu[order], iv[order], u[order], v[order]
        wu = self._widths(0).take(iu)                      # ubreaks[iu + 1] - ubreaks[iu]
        wv = self._widths(1).take(iv)
        a = (u - self.ubreaks.take(iu)) / wu
        b = (v - self.vbreaks.take(iv)) / wv
        local = self.cell_local[iu, iv]
        H = np.empty((nd, 4, len(u)))
        ep = None
        if single:
            g0 = self.groups[0]
            if type(g0) is LevelCells:
                H[:], at_vertex, ep_normal = g0.evaluate(local, a, b, nd=nd, nc=nc)
            elif nd == 6:
                H[:], at_vertex, ep_normal = g0.evaluate(local, a, b)
            else:
                H[:], at_vertex, ep_normal = g0.evaluate(local, a, b, nd=nd)
            if at_vertex is not None and at_vertex.any():
                ep = (np.nonzero(at_vertex)[0], ep_normal[at_vertex])
        else:
            group = self.cell_group[iu, iv]
            counts = _bincount(group, minlength=len(self.groups))
            present = counts.nonzero()[0]
            levels = tables[1]
            calls = present.tolist()
            if levels is not None and _count_nonzero(levels.member[present]) >= 2:
                # the extraordinary cells' groups in one call (the same values point by point)
                calls = [g for g in calls if not levels.member[g]] + [levels]
            # the calls in the order their points are sorted in, each with its block
            rank = tables[2]
            calls.sort(key=lambda g: rank[-1] if g is levels else rank[g])
            counts = counts.tolist()
            blocks, start = [], 0
            for g in calls:
                m = sum(counts[k] for k in levels.members) if g is levels else counts[g]
                blocks.append(slice(start, start + m))
                start += m
            results = None
            if len(calls) == 2:
                results = self._bezier_and_nets(calls, blocks, levels, group, local, a, b, H, nd, nc)
            if results is None:
                results = []
                for g, sel in zip(calls, blocks):
                    if g is levels:
                        Hg, at_vertex, ep_normal = levels.evaluate(group[sel], local[sel], a[sel], b[sel], nd, nc)
                    elif type(self.groups[g]) is LevelCells:
                        Hg, at_vertex, ep_normal = self.groups[g].evaluate(local[sel], a[sel], b[sel], nd=nd, nc=nc)
                    elif nd == 6:
                        Hg, at_vertex, ep_normal = self.groups[g].evaluate(local[sel], a[sel], b[sel])
                    else:
                        Hg, at_vertex, ep_normal = self.groups[g].evaluate(local[sel], a[sel], b[sel], nd=nd)
                    H[:, :, sel] = Hg
                    results.append((sel, at_vertex, ep_normal))
            for sel, at_vertex, ep_normal in results:
                if at_vertex is not None and at_vertex.any():
                    rows = np.arange(sel.start, sel.stop)[at_vertex]
                    ep = (rows, ep_normal[at_vertex]) if ep is None else (
                        _concatenate([ep[0], rows]), _concatenate([ep[1], ep_normal[at_vertex]]))
        # from cell (a, b) to patch (u, v) (a polynomial patch's weight rows, 0, stay 0)
        divide_widths(H[:, :nc], wu, wv)
        return order, H, ep

    def _bezier_and_nets(self, calls, blocks, levels, group, local, a, b, H, nd: int = 6, nc: int = 4):
        """Two calls, cubic Bezier cells and extraordinary cells' nets (LevelCells alone or
        a _LevelSet), written into their blocks of H with the Bernstein values of both made
        in one call (they are made point by point: the same values); None for other pairs.
        Returns [(block, at_vertex, exact normals)] per call."""
        g0, g1 = calls
        bez = self.groups[g0] if not (g0 is levels) else None
        if g1 is levels:
            lv, lidx = levels, levels.offset[group[blocks[1]]] + local[blocks[1]]
        else:
            lv, lidx = self.groups[g1], local[blocks[1]]
            if type(lv) is not LevelCells:
                return None
        if type(bez) is not BezierCells or bez.p != 3 or bez.q != 3:
            return None
        sb, sl = blocks
        nb = sb.stop - sb.start
        prepared = LevelCells.prepare(lv, lidx, a[sl], b[sl])
        E = prepared[3][0]
        B = bernstein_rows(3, _concatenate([a[sb], b[sb], E[0], E[1]]))
        bez.evaluate(local[sb], a[sb], b[sb], out=H[:, :, sb], bases=(B[:, :, :nb], B[:, :, nb:2 * nb]), nd=nd)
        if lv is levels:
            _, at_vertex, ep_normal = levels.finish(group[sl], prepared, H[:, :, sl], B[:, :, 2 * nb:], nd, nc)
        else:
            _, at_vertex, ep_normal = lv.finish(prepared, H[:, :, sl], B[:, :, 2 * nb:], nd, nc)
        return [(sb, None, None), (sl, at_vertex, ep_normal)]

    def _widths(self, axis: int) -> np.ndarray:
        """The cells' widths along u (axis 0) or v: the differences of consecutive breaks,
        per cell once (the same differences as per point), made again if the breaks change."""
        cached = getattr(self, "_cell_widths", None)
        if cached is None or cached[0] is not self.ubreaks or cached[1] is not self.vbreaks:
            cached = (self.ubreaks, self.vbreaks, (self.ubreaks[1:] - self.ubreaks[:-1],
                                                   self.vbreaks[1:] - self.vbreaks[:-1]))
            self._cell_widths = cached
        return cached[2][axis]

    def _tables(self):
        """What the evaluation reads of the patch's groups, made again when the groups or
        the level set change (one check per evaluation): (groups' ids, the level set
        (``_level_set``), per group the rank of its call in the order points are sorted in
        (the groups in their order, the extraordinary cells' groups last when they are called
        together; the last entry that call's rank), per cell (nu, nv) the key points are
        sorted by (the rank of the cell's call, then the cell), and whether the patch is
        polynomial (``_polynomial``))."""
        gkey = tuple(map(id, self.groups))
        levels = self._level_set(gkey)
        cached = getattr(self, "_calls", None)
        if cached is None or cached[0] != gkey or cached[1] is not levels:
            ng = len(self.groups)
            rank = np.arange(ng + 1)
            if levels is not None:
                rank[:ng][levels.member] = ng
            nu, nv = self.shape
            table = rank[self.cell_group] * (nu * nv) + np.arange(nu * nv).reshape(nu, nv)
            poly = all(_exact_polynomial(g) for g in self.groups)
            cached = (gkey, levels, rank.tolist(), table, poly)
            self._calls = cached
        return cached

    def _cubic_table(self):
        """The patch's :class:`~tsplcam.model.cubic_points.CubicTable` (None when its cells are
        not all bicubic Bezier or extraordinary ones), made again when its groups or cells
        change."""
        now = (self.groups, self.ubreaks, self.vbreaks, self.cell_group, self.cell_local)
        cached = getattr(self, "_cubic", None)
        if (cached is None or len(cached[0]) != len(self.groups)
                or any(x is not y for x, y in zip(cached[0], self.groups))
                or any(x is not y for x, y in zip(cached[1:5], now[1:]))):
            cached = (list(self.groups),) + now[1:] + (cubic_table(self),)
            self._cubic = cached
        return cached[5]

    def _polynomial(self) -> bool:
        """Whether every group gives the weight exactly 1 and its derivatives exactly 0 (each
        a sum of zero terms), so that ``rational_from_homogeneous``'s exact test passes for
        any points: polynomial Bezier cells (which write them so) and extraordinary cells
        whose nets, levels, limits and vertex values all have weight 1 and weight
        differences 0 (a polynomial cage's)."""
        return self._tables()[4]

    def _level_set(self, key: tuple | None = None):
        """The patch's LevelCells groups as one :class:`_LevelSet` (None when it has fewer than
        two), made again when the groups change (readers may add groups after construction;
        ``key``: the groups' ids, when the caller has them)."""
        key = tuple(map(id, self.groups)) if key is None else key
        cached = getattr(self, "_levels", None)
        if cached is None or cached[0] != key:
            members = [g for g, grp in enumerate(self.groups) if type(grp) is LevelCells]
            ok = len(members) >= 2 and len({(self.groups[g].NET_LEVELS, self.groups[g].MAX_LEVEL,
                                             self.groups[g].nets.shape[1:]) for g in members}) == 1
            cached = (key, _LevelSet(self.groups, members) if ok else None)
            self._levels = cached
        return cached[1]

    def corner_point(self, k: int) -> np.ndarray:
        return self.evaluate(*CORNER_UV[k]).P[0]

    def edge_params(self, edge: int, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(u, v) along edge ``edge`` at fraction tau from its first corner to its second."""
        c0, c1 = EDGE_CORNERS[edge]
        tau = np.asarray(tau, float)
        uv = CORNER_UV[c0][None, :] * (1 - tau)[:, None] + CORNER_UV[c1][None, :] * tau[:, None]
        return uv[:, 0], uv[:, 1]


class _LevelSet:
    """Several LevelCells groups of one patch (one per subdivision scheme, i.e. per kind of
    extraordinary corner: figure4's first patch has two) evaluated from their cached Bezier
    nets in one call: their per-cell tables one after the other, the same per-point
    arithmetic (``LevelCells._evaluate_nets``; no product spans points). Points below the
    nets' deepest level go to their own group's configuration route, the same points in the
    same order as the group's own call would give it."""

    def __init__(self, groups: list, members: list[int]):
        gs = [groups[g] for g in members]
        self.groups = groups
        self.member = np.zeros(len(groups), bool)
        self.member[members] = True
        self.members = list(members)
        self.offset = np.zeros(len(groups), int)          # first cell of each member
        self.offset[members] = np.cumsum([0] + [len(g) for g in gs])[:-1]
        self.NET_LEVELS, self.MAX_LEVEL = gs[0].NET_LEVELS, gs[0].MAX_LEVEL
        self.nets = _concatenate([g.nets for g in gs])
        self._corner = _concatenate([g._corner for g in gs], axis=1)
        self._swap = _concatenate([g._swap for g in gs])
        self.limit = _concatenate([g.limit for g in gs])
        self.limit_normal = _concatenate([g.limit_normal for g in gs])
        self._vertex = _concatenate([g._vertex for g in gs], axis=2)

    def evaluate(self, gid: np.ndarray, local: np.ndarray, a: np.ndarray, b: np.ndarray, nd: int = 6,
                 nc: int = 4):
        """As the members' ``evaluate`` for points of groups ``gid`` and their cells ``local``."""
        idx = self.offset[gid] + local
        return self.finish(gid, LevelCells.prepare(self, idx, a, b), nd=nd, nc=nc)

    def finish(self, gid: np.ndarray, prepared, out=None, B=None, nd: int = 6, nc: int = 4):
        """:meth:`evaluate` from ``LevelCells.prepare`` of the set's cell indices (``out``,
        ``B``, ``nd``, ``nc``: as for ``LevelCells._net_values``)."""
        idx, a, b, params = prepared
        H, at_vertex, deep = LevelCells._net_values(self, idx, params, out, B, nd, nc)
        if deep.any():
            local = idx - self.offset[gid]
            for g in np.unique(gid[deep]).tolist():
                rows = np.nonzero(deep & (gid == g))[0]
                H[:, :, rows] = self.groups[g]._evaluate(local[rows], a[rows], b[rows])[0][:nd]
        ep_normal = None
        if at_vertex.any():
            ep_normal = np.zeros((len(idx), 3))
            ep_normal[at_vertex] = self.limit_normal[idx[at_vertex]]
        return H, at_vertex, ep_normal


def _exact_polynomial(group) -> bool:
    """See :meth:`Patch._polynomial`."""
    if type(group) is BezierCells:
        return not group.rational and group.nc == 3
    if type(group) is LevelCells:
        return bool(group.nets.shape[1] == 4 and np.all(group.nets[:, 3] == 0.0)
                    and np.all(group.d[..., 3] == 0.0) and np.all(group.limit[:, 3] == 1.0)
                    and np.all(group._vertex[0, 3] == 1.0) and np.all(group._vertex[1:, 3] == 0.0)
                    and np.all(np.isfinite(group.nets)) and np.all(np.isfinite(group.d)))
    return False


def _index_or_slice(idx: np.ndarray):
    """A slice when the indices are one contiguous run (sorted grids), else the indices."""
    if len(idx) and idx[-1] - idx[0] + 1 == len(idx):
        return slice(int(idx[0]), int(idx[-1]) + 1)
    return idx


def _unit(x: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(x, axis=1, keepdims=True)
    return x / _where(n > 0, n, 1.0)
