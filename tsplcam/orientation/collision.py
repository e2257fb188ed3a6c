"""Collision geometry with python-fcl: the workpiece as one BVH, the tool as fcl shapes.

Workpiece: every patch is tessellated on a (u, v) grid refined until the *measured* chordal
error (distance between the surface and the triangles, sampled at every grid edge midpoint
and cell centre) is below ``tolerance``; optional stock and fixture triangle meshes are
added as they are. One ``fcl.BVHModel`` (OBBRSS) holds all of it, built once where fcl is
asked about many poses; questions about a few poses are answered from a BVH of the triangles
near them (:mod:`~tsplcam.orientation.nearby`, the same answers). Every triangle remembers its
owner (a patch or a named mesh) so a collision names its obstacle.

Tool: the solids above the ball centre (flutes, shank, holder segments; see
:meth:`Tool.parts`) are turned into one closed triangle mesh of circumscribed polygons
(the polygon contains the true circle), each part grown by ``margin`` (the chordal
tolerance plus the requested clearance) in every direction: the smallest frustum of its
slope that holds every point within ``margin`` of it (:func:`grown_frustum`: the side moved
out by ``margin`` across the side, the ends by ``margin`` along the axis), except past an end
another solid of the tool covers (a shank's bottom on flutes as wide: the flutes cut, and
keep only the chordal tolerance). So a pose the checker passes keeps the true tool at least
``clearance`` away from the true surface, and a reported collision is at most ``margin`` +
the polygon excess (``polygon_tolerance``) from a real touch, ``sqrt(2)`` times that at a
rim. (Grown across the axis only, as before, a cone kept ``margin / sqrt(1 + slope^2)``
and nothing was kept below a bottom or above a top: keycap_mold's holder rim came 0.176 mm
from the stock at clearance 0.3.) The same parts also exist as fcl primitives
(``fcl.Cylinder``, and ``fcl.Convex`` frustums): :meth:`CollisionChecker.collides_primitives`
uses them as the independent reference the tests compare against; the mesh form answers
about four times faster (BVH-BVH queries, part by part until one touches, instead of one GJK
traversal per part).

Broad phase: :mod:`tsplcam.orientation.broadphase` decides most poses of a batch at once
in numpy (a proof that the pose is free, or that it collides, from distance bounds to the
mesh, empty balls per ball centre and samples of the mesh inside the tool); only the poses it
cannot decide go to fcl, one ``fcl.collide`` per pose (python-fcl's broad-phase managers
call back into Python for every overlapping pair, so they cannot beat that loop when the
workpiece is a single BVH). ``broad_phase=False`` asks fcl for every pose (the reference).

The ball: it touches the surface at the contact by construction, so it is left out of the
per-axis checks (it does not depend on the axis). :meth:`ball_gouges` checks it once per
point: a sphere shrunk by ``gouge_tolerance`` must not touch the workpiece. With the
chordal error below half of ``gouge_tolerance`` this never fires on the tangent contact
(the mesh lies within ``tolerance`` of the true surface, outside the true ball) and finds
every gouge deeper than ``gouge_tolerance + tolerance``.
"""
from __future__ import annotations

import multiprocessing
import weakref
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..errors import GeometryError, InputError
from ..toolpath.parallel import map_pieces, worker_count
from ..npfast import cross_rows, row_norms
from .broadphase import FREE, HIT, UNKNOWN, BroadPhase, Profile, longest_edges, mesh_components, row_bits
from .nearby import MAX_FRUSTUMS, NearWorkpiece, bvh_model as _bvh
from .tool import Tool

try:                                   # python-fcl is a dependency of this stage only
    import fcl
except ImportError:                    # pragma: no cover - reported when a checker is built
    fcl = None


# --- workpiece tessellation ------------------------------------------------------------------

@dataclass
class TriangleMesh:
    """Triangles with an owner per triangle (index into ``owners``, names for messages)."""
    vertices: np.ndarray            # (nv, 3)
    triangles: np.ndarray           # (nt, 3) int
    owner: np.ndarray               # (nt,) int
    owners: list                    # names, e.g. "patch 3 'top'", "stock"
    owner_patch: list               # patch index per owner, or None for a mesh
    chordal_error: float = 0.0      # measured, mm (0 for meshes taken as they are)

    @staticmethod
    def concat(meshes: list) -> "TriangleMesh":
        V, T, O, names, patches = [], [], [], [], []
        off = 0
        err = 0.0
        for m in meshes:
            V.append(m.vertices)
            T.append(m.triangles + off)
            O.append(m.owner + len(names))
            names += list(m.owners)
            patches += list(m.owner_patch)
            off += len(m.vertices)
            err = max(err, m.chordal_error)
        return TriangleMesh(np.concatenate(V), np.concatenate(T), np.concatenate(O), names, patches, err)


TESSELLATION_PASSES = 24       # grid refinements a graded tessellation may take
GRADED_LINES = 256             # grid lines per direction from which a patch's grid is graded


def _grid_triangles(nu: int, nv: int) -> np.ndarray:
    """Two triangles per cell of an (nu+1) x (nv+1) vertex grid (u-major index)."""
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = (i * (nv + 1) + j).ravel()
    b = a + (nv + 1)
    return np.concatenate([np.column_stack([a, b, b + 1]), np.column_stack([a, b + 1, a + 1])])


def _plane_distance(P, A, B, C):
    """Distance of points P from the planes of triangles ABC (all (n,3)). The normal's
    components and length are ``np.cross``'s and ``np.linalg.norm``'s operations written out
    (the same bits, in half the time)."""
    nrm = cross_rows(B - A, C - A)
    ln = row_norms(nrm)
    return np.abs(np.einsum("ij,ij->i", P - A, nrm)) / np.where(ln > 0, ln, 1.0)


def _patch_grid_error(patch, gu: np.ndarray, gv: np.ndarray,
                      coarse: float = np.inf) -> tuple[float, float, np.ndarray]:
    """Chordal error of the grid gu x gv measured on the patch: (along u, along v) maxima,
    and the grid's own points ((nu+1)(nv+1), 3), the tessellation's vertices once it is fine.
    Where both edge maxima reach ``coarse`` the cells' points are not measured and the edge
    maxima are returned (lower bounds: the caller refines by its largest factor either way).

    Sampled at edge midpoints (distance from the chord) and at the quarter points of each
    cell's diagonals (distance from the triangle planes): the error of a smooth surface
    between grid lines peaks near those places. Positions only (``Patch.grids_points``: each
    point as ``Patch.evaluate`` gives it, the five grids in one call, or with ``coarse`` the
    edges' three first): no derivative is needed.
    """
    nu, nv = len(gu) - 1, len(gv) - 1
    mu = 0.5 * (gu[:-1] + gu[1:])
    mv = 0.5 * (gv[:-1] + gv[1:])
    # the points of every cell at 1/3 along both triangles' barycentres form tensor grids
    thirds = [(gu[:-1] + fa * np.diff(gu), gv[:-1] + fb * np.diff(gv))
              for fa, fb in ((2 / 3, 1 / 3), (1 / 3, 2 / 3))]
    # (the grids' values do not depend on which are asked together: ``Patch.grids_points``)
    edges = [(mu, gv), (gu, gv), (gu, mv)]
    Pu, grid, Pv, *Pc = patch.grids_points(edges if np.isfinite(coarse) else edges + thirds)
    G = grid.reshape(nu + 1, nv + 1, 3)
    # u-edges: (mu, gv), v-edges: (gu, mv)
    eu = np.linalg.norm(Pu.reshape(nu, nv + 1, 3) - 0.5 * (G[:-1] + G[1:]), axis=2).max()
    ev = np.linalg.norm(Pv.reshape(nu + 1, nv, 3) - 0.5 * (G[:, :-1] + G[:, 1:]), axis=2).max()
    if eu >= coarse and ev >= coarse:
        return eu, ev, grid
    if not Pc:
        Pc = patch.grids_points(thirds)
    # inside the cells: distance from the planes of the cell's two triangles
    A, B, C, D = G[:-1, :-1], G[1:, :-1], G[1:, 1:], G[:-1, 1:]
    ec = 0.0
    for P, tri in zip(Pc, ((A, B, C), (A, C, D))):
        ec = max(ec, _plane_distance(P, *(t.reshape(-1, 3) for t in tri)).max())
    return max(eu, ec), max(ev, ec), grid


def _capped_error(tolerance: float) -> float:
    """The least error e with ``1.1 * sqrt(e / tolerance) >= 4`` (``tessellate_patch``'s factor
    at its cap), found in floats: any error from it up gets the factor 4 (the formula's
    operations are monotone)."""
    e = (4.0 / 1.1) ** 2 * tolerance
    while 1.1 * np.sqrt(e / tolerance) < 4.0:
        e = np.nextafter(e, np.inf)
    while 1.1 * np.sqrt(np.nextafter(e, 0.0) / tolerance) >= 4.0:
        e = np.nextafter(e, 0.0)
    return float(e)


def tessellate_patch(patch, tolerance: float, max_cells: int = 4000) -> tuple:
    """Grid (u, v) tessellation of one patch with measured chordal error <= tolerance.

    The grid starts from the patch's cell breaks (2 per cell) and is refined per direction
    by the factor sqrt(error / tolerance) (the chordal error of a smooth surface falls with
    the square of the spacing) until the measured error is below the tolerance. One spacing
    for the whole patch is set by its worst place; where it would pass ``GRADED_LINES`` lines
    in a direction (next to an extraordinary point, whose second derivatives grow without
    bound: the figure4 sample's patches asked 616 x 615 and 697 x 620 lines, 5.8 M triangles
    in all, 23 s), the grid is refined interval by interval instead (:func:`_graded`), as
    it is from the start on uneven cell breaks (a T-spline's knot intervals), whose lines it
    keeps. Returns (vertices, triangles, uv, error).
    """
    if not (_even(patch.ubreaks) and _even(patch.vbreaks)):
        # uneven cell breaks (T-spline knot intervals): evenly spaced lines would cross the
        # cells' joins, where a crease (a triple knot line) runs; graded lines start on them
        return _graded(patch, tolerance, _break_lines(patch.ubreaks), _break_lines(patch.vbreaks), max_cells)
    nu = max(4, 2 * (len(patch.ubreaks) - 1))
    nv = max(4, 2 * (len(patch.vbreaks) - 1))
    coarse, capped = _capped_error(tolerance), True
    first = None
    for _ in range(12):
        gu = np.linspace(0.0, 1.0, nu + 1)
        gv = np.linspace(0.0, 1.0, nv + 1)
        first = first or (gu, gv)
        # a first grid far too coarse (the keycap's: edge errors 20 times the tolerance) is
        # refined by the factor 4 along both directions whatever its cells' errors add (the
        # error only grows with them, and the factor's formula with the error): those points
        # are measured only on grids that may be kept or refined by less (or where the grid
        # would outgrow max_cells, whose message gives the whole error); tried while the grid
        # is the first or was refined so (else the five grids in one call: their extraordinary
        # cells' points in one evaluation)
        grow = capped and 4 * max(nu, nv) <= max_cells
        eu, ev, P = _patch_grid_error(patch, gu, gv, coarse if grow else np.inf)
        capped = eu >= coarse and ev >= coarse
        if eu <= tolerance and ev <= tolerance:
            break
        if eu > tolerance:
            nu = int(np.ceil(nu * min(4.0, 1.1 * np.sqrt(eu / tolerance))))
        if ev > tolerance:
            nv = int(np.ceil(nv * min(4.0, 1.1 * np.sqrt(ev / tolerance))))
        if max(nu, nv) > GRADED_LINES:                 # from the first grid again
            return _graded(patch, tolerance, first[0], first[1], max_cells)
        if nu > max_cells or nv > max_cells:
            raise GeometryError(f"{patch.name}: tessellation to {tolerance:g} mm needs more than "
                                f"{max_cells} grid lines (error {max(eu, ev):.3g} mm at {nu} x {nv})")
    else:                                                      # pragma: no cover
        raise GeometryError(f"{patch.name}: tessellation did not reach {tolerance:g} mm")
    uv = np.column_stack([np.repeat(gu, len(gv)), np.tile(gv, len(gu))])
    return np.ascontiguousarray(P), _grid_triangles(nu, nv), uv, max(eu, ev)


EDGE_FRACTIONS = (0.5,)                       # along each grid interval's edges
# points inside each cell of a graded grid, (a, b) from its first corner: two in each of its
# two triangles (a >= b: corners (0, 0), (1, 0), (1, 1); b >= a: (0, 0), (1, 1), (0, 1)).
# Against the distance to the mesh at 900 random points a patch (crowded toward corners and
# edges): the triangles' centroids alone let figure4's graded grids through at 0.0063 for
# 0.005 mm; these four held (worst 0.0044, head 0.0035), as three a triangle with edge
# quarter points did at more cost
CELL_POINTS = ((0.5, 0.25), (0.75, 0.5), (0.25, 0.5), (0.5, 0.75))


def _interval_errors(patch, gu: np.ndarray, gv: np.ndarray, coarse: float = np.inf, prev=None):
    """Chordal error of the grid gu x gv measured on the patch, per grid interval: (along u,
    (nu,), along v, (nv,)) maxima, the grid's own points ((nu+1)(nv+1), 3), the tessellation's
    vertices once it is fine, and what the next call may take over (``prev``).

    Each sampled surface point is compared with the point of the mesh at the same (u, v): the
    linear interpolation of its edge's ends (``EDGE_FRACTIONS`` of every interval, along both
    directions), or of its triangle's corners (``CELL_POINTS``), so every measured distance
    bounds that point's distance to the mesh from above. A cell's error counts for both its
    intervals. Where every interval's edge error reaches ``coarse`` the cells' points are not
    measured and the edge maxima are returned (lower bounds: the caller refines every interval
    by its largest factor either way). ``prev``: the state of the call on a grid these lines
    refine (lines only added): its vertices and the errors of its edges and cells that no new
    line crosses are taken over, only the rest measured (a last pass often adds a few
    lines). Positions only (``Patch.grids_points``: each point as ``Patch.evaluate`` gives it,
    the grids of a pass in one call): no derivative is needed."""
    nu, nv = len(gu) - 1, len(gv) - 1
    du, dv = np.diff(gu), np.diff(gv)
    ne, nc = len(EDGE_FRACTIONS), len(CELL_POINTS)
    lu = _kept_lines(gu, prev[0] if prev else None)      # index among the previous lines, or -1
    lv = _kept_lines(gv, prev[1] if prev else None)
    ou, ov = lu >= 0, lv >= 0
    # intervals of the previous grid (both ends kept and neighbours there): their old index
    iu = np.where(ou[:-1] & ou[1:] & (lu[1:] - lu[:-1] == 1), lu[:-1], -1)
    iv = np.where(ov[:-1] & ov[1:] & (lv[1:] - lv[:-1] == 1), lv[:-1], -1)
    G = np.empty((nu + 1, nv + 1, 3))
    Eu, Ev = np.empty((ne, nu, nv + 1)), np.empty((ne, nu + 1, nv))
    Ec = np.empty((nc, nu, nv))
    cells_kept = prev is not None and prev[5] is not None
    if prev is not None:
        _, _, pG, pEu, pEv, pEc = prev
        G[np.ix_(ou, ov)] = pG[np.ix_(lu[ou], lv[ov])]
        Eu[np.ix_(range(ne), np.nonzero(iu >= 0)[0], np.nonzero(ov)[0])] = pEu[np.ix_(range(ne), iu[iu >= 0], lv[ov])]
        Ev[np.ix_(range(ne), np.nonzero(ou)[0], np.nonzero(iv >= 0)[0])] = pEv[np.ix_(range(ne), lu[ou], iv[iv >= 0])]
        if cells_kept:
            Ec[np.ix_(range(nc), np.nonzero(iu >= 0)[0], np.nonzero(iv >= 0)[0])] = pEc[np.ix_(range(nc), iu[iu >= 0], iv[iv >= 0])]

    def missing(new_rows, new_cols):
        """What a tensor array lacks: new rows by every column, kept rows by new columns."""
        r, c = np.nonzero(new_rows)[0], np.nonzero(new_cols)[0]
        return [(r, np.arange(len(new_cols))), (np.nonzero(~new_rows)[0], c)]

    asks = []                                            # (what, rows, columns, u values, v values)
    for r, c in missing(~ou, ~ov):
        asks.append(("G", r, c, gu[r], gv[c]))
    for k, f in enumerate(EDGE_FRACTIONS):
        for r, c in missing(iu < 0, ~ov):
            asks.append((("u", k), r, c, gu[r] + f * du[r], gv[c]))
        for r, c in missing(~ou, iv < 0):
            asks.append((("v", k), r, c, gu[r], gv[c] + f * dv[c]))

    def cell_asks():
        new_r, new_c = (iu < 0, iv < 0) if cells_kept else (np.ones(nu, bool), np.ones(nv, bool))
        return [(("c", k), r, c, gu[r] + a * du[r], gv[c] + b * dv[c])
                for k, (a, b) in enumerate(CELL_POINTS) for r, c in missing(new_r, new_c)]

    edges_first = np.isfinite(coarse)
    got = _ask(patch, asks if edges_first else asks + cell_asks())
    for (what, r, c), P in got:
        if what == "G":
            G[np.ix_(r, c)] = P
    for (what, r, c), P in got:                          # errors against the mesh's points
        if what[0] == "u":
            f = EDGE_FRACTIONS[what[1]]
            Eu[what[1]][np.ix_(r, c)] = np.linalg.norm(P - (1 - f) * G[np.ix_(r, c)] - f * G[np.ix_(r + 1, c)], axis=2)
        elif what[0] == "v":
            f = EDGE_FRACTIONS[what[1]]
            Ev[what[1]][np.ix_(r, c)] = np.linalg.norm(P - (1 - f) * G[np.ix_(r, c)] - f * G[np.ix_(r, c + 1)], axis=2)
    eu, ev = Eu.max(axis=(0, 2)), Ev.max(axis=(0, 1))
    if edges_first and (eu >= coarse).all() and (ev >= coarse).all():
        return eu, ev, G.reshape(-1, 3), (gu, gv, G, Eu, Ev, None)
    if edges_first:
        got = _ask(patch, cell_asks())
    for (what, r, c), P in got:
        if what[0] == "c":
            a, b = CELL_POINTS[what[1]]
            A, B, C, D = (G[np.ix_(r + x, c + y)] for x, y in ((0, 0), (1, 0), (1, 1), (0, 1)))
            L = (1 - a) * A + (a - b) * B + b * C if a >= b else (1 - b) * A + a * C + (b - a) * D
            Ec[what[1]][np.ix_(r, c)] = np.linalg.norm(P - L, axis=2)
    ec = Ec.max(axis=0)
    return np.maximum(eu, ec.max(axis=1)), np.maximum(ev, ec.max(axis=0)), G.reshape(-1, 3), (gu, gv, G, Eu, Ev, Ec)


def _ask(patch, asks: list) -> list:
    """The points of the non-empty tensor grids of ``asks`` ((what, rows, columns, u values,
    v values)) in one ``grids_points`` call: [((what, rows, columns), (rows, columns, 3))]."""
    asks = [a for a in asks if len(a[3]) and len(a[4])]
    if not asks:
        return []
    pts = patch.grids_points([(a[3], a[4]) for a in asks])
    return [((a[0], a[1], a[2]), P.reshape(len(a[3]), len(a[4]), 3)) for a, P in zip(asks, pts)]


def _kept_lines(g: np.ndarray, old) -> np.ndarray:
    """Per line of ``g``, its index among the previous grid's lines ``old``, or -1 (new)."""
    out = np.full(len(g), -1)
    if old is not None:
        at = np.searchsorted(g, old)
        ok = (at < len(g)) & (g[np.minimum(at, len(g) - 1)] == old)
        out[at[ok]] = np.nonzero(ok)[0]
    return out


def _refined(g: np.ndarray, err: np.ndarray, tolerance: float) -> np.ndarray:
    """Grid lines ``g`` with every interval whose error exceeds the tolerance split evenly by
    the factor sqrt(error / tolerance) (the chordal error of a smooth surface falls with the
    square of the spacing), 1.1 times that and at most 4 (``tessellate_patch``'s rule, per
    interval)."""
    k = np.where(err > tolerance, np.ceil(np.minimum(4.0, 1.1 * np.sqrt(err / tolerance))), 1.0).astype(int)
    return _split(g, k)


def _split(g: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Grid lines ``g`` with interval i split evenly into ``k[i]`` parts (the old lines kept
    exactly)."""
    i = np.repeat(np.arange(len(k)), k)                     # the interval of each new line
    f = np.arange(len(i)) - np.repeat(np.cumsum(k) - k, k)  # its place in the interval
    return np.append(g[i] + (g[i + 1] - g[i]) * (f / k[i]), g[-1])


def _even(breaks: np.ndarray) -> bool:
    """Whether cell breaks are evenly spaced over [0, 1] (to rounding)."""
    b = np.asarray(breaks, float)
    return bool(np.allclose(b, np.linspace(0.0, 1.0, len(b)), rtol=0.0, atol=1e-12))


def _break_lines(breaks: np.ndarray) -> np.ndarray:
    """First grid lines on uneven cell breaks: every break, each cell split evenly in two (or
    more, to four intervals at least), as the even grids start."""
    b = np.asarray(breaks, float)
    cells = len(b) - 1
    return _split(b, np.full(cells, max(2, -(-4 // cells))))


def _graded(patch, tolerance: float, gu: np.ndarray, gv: np.ndarray, max_cells: int) -> tuple:
    """:func:`tessellate_patch` from the grid lines gu x gv, each interval whose measured error
    exceeds the tolerance split by its own factor (``_refined``) until none does: the lines
    crowd where the surface bends in the parameters and stay sparse elsewhere (figure4: 76k
    triangles in all against 5.8 M, head 229k against 1.34 M). The error is measured at more points of each cell
    (``_interval_errors``: long thin cells next to graded lines hid errors from the
    triangles' centroids), each pass taking over what the last one measured where no line
    was added."""
    coarse, capped, state = _capped_error(tolerance), True, None
    for _ in range(TESSELLATION_PASSES):
        grow = capped and 4 * max(len(gu), len(gv)) <= max_cells
        eu, ev, P, state = _interval_errors(patch, gu, gv, coarse if grow else np.inf, state)
        capped = bool((eu >= coarse).all() and (ev >= coarse).all())
        if eu.max() <= tolerance and ev.max() <= tolerance:
            break
        gu, gv = _refined(gu, eu, tolerance), _refined(gv, ev, tolerance)
        if len(gu) - 1 > max_cells or len(gv) - 1 > max_cells:
            raise GeometryError(f"{patch.name}: tessellation to {tolerance:g} mm needs more than "
                                f"{max_cells} grid lines (error {max(eu.max(), ev.max()):.3g} mm at "
                                f"{len(gu) - 1} x {len(gv) - 1})")
    else:                                                      # pragma: no cover
        raise GeometryError(f"{patch.name}: tessellation did not reach {tolerance:g} mm")
    uv = np.column_stack([np.repeat(gu, len(gv)), np.tile(gv, len(gu))])
    return (np.ascontiguousarray(P), _grid_triangles(len(gu) - 1, len(gv) - 1), uv,
            float(max(eu.max(), ev.max())))


def _tessellate_piece(model, tolerance, patches, i):
    V, T, _, err = tessellate_patch(model.patches[patches[i]], tolerance)
    return V, T, err


def tessellate_model(model, tolerance: float = 0.005, patches=None) -> TriangleMesh:
    """Every patch of the model (or those listed) as triangles within ``tolerance`` (mm); the
    patches in forked processes on the cores there are (the same triangles as in one)."""
    if not tolerance > 0:
        raise InputError(f"tessellation tolerance must be positive, not {tolerance!r}")
    ks = list(range(len(model.patches)) if patches is None else patches)
    size = [int(np.prod(model.patches[k].shape)) for k in ks]
    pieces = map_pieces(_tessellate_piece, (model, tolerance, ks), len(ks), worker_count(None, len(ks)),
                        order=np.argsort(size, kind="stable")[::-1])
    meshes = []
    for k, (V, T, err) in zip(ks, pieces):
        p = model.patches[k]
        meshes.append(TriangleMesh(V, T, np.zeros(len(T), int), [f"patch {k} ({p.name})"], [k], err))
    return TriangleMesh.concat(meshes)


def named_mesh(vertices, triangles, name: str) -> TriangleMesh:
    """A triangle mesh taken as it is (stock, fixture, neighbouring part)."""
    V = np.asarray(vertices, float).reshape(-1, 3)
    T = np.asarray(triangles, int).reshape(-1, 3)
    if len(T) and (T.min() < 0 or T.max() >= len(V)):
        raise InputError(f"triangle index out of range 0..{len(V) - 1}", item=name)
    if not np.all(np.isfinite(V)):
        raise InputError("a vertex is not finite", item=name)
    return TriangleMesh(V, T, np.zeros(len(T), int), [name], [None], 0.0)


def split_long_triangles(mesh: TriangleMesh, e_max: float) -> TriangleMesh:
    """The same surface with every triangle longer than ``e_max`` cut into k^2 triangles by a
    uniform barycentric subdivision (k = ceil(edge / e_max)), owners kept: fcl's bounding
    volumes then stay small near the tool (the two triangles of an 18 mm block face overlap
    every tool pose above it and are tested against every tool triangle)."""
    V, T = mesh.vertices, mesh.triangles
    if len(T) == 0:
        return mesh
    edge = longest_edges(V, T)
    k = np.maximum(1, np.ceil(edge / e_max - 1e-9)).astype(int)
    if k.max() == 1:
        return mesh
    Vs, Ts, Os = [V], [T[k == 1]], [mesh.owner[k == 1]]
    nv = len(V)
    for kk in np.unique(k[k > 1]):
        sel = np.nonzero(k == kk)[0]
        i, j = np.meshgrid(np.arange(kk + 1), np.arange(kk + 1), indexing="ij")
        keep = i + j <= kk
        i, j = i[keep], j[keep]
        local = -np.ones((kk + 1, kk + 1), int)
        local[i, j] = np.arange(len(i))
        a, b = np.meshgrid(np.arange(kk), np.arange(kk), indexing="ij")
        up = a + b <= kk - 1
        down = a + b <= kk - 2
        tri = np.concatenate([
            np.column_stack([local[a[up], b[up]], local[a[up] + 1, b[up]], local[a[up], b[up] + 1]]),
            np.column_stack([local[a[down] + 1, b[down]], local[a[down] + 1, b[down] + 1],
                             local[a[down], b[down] + 1]])])
        A, B, C = V[T[sel, 0]], V[T[sel, 1]], V[T[sel, 2]]
        u, w = (i / kk)[None, :, None], (j / kk)[None, :, None]
        P = A[:, None] + u * (B - A)[:, None] + w * (C - A)[:, None]
        Vs.append(P.reshape(-1, 3))
        Ts.append((tri[None] + (nv + len(i) * np.arange(len(sel)))[:, None, None]).reshape(-1, 3))
        Os.append(np.repeat(mesh.owner[sel], len(tri)))
        nv += len(sel) * len(i)
    # the points along shared edges come out once per triangle: weld them (connectivity)
    Vn, inv = np.unique(np.round(np.concatenate(Vs), 9), axis=0, return_inverse=True)
    Vn = np.concatenate(Vs)[np.unique(inv, return_index=True)[1]]
    return TriangleMesh(Vn, inv.reshape(-1)[np.concatenate(Ts)], np.concatenate(Os), mesh.owners,
                        mesh.owner_patch, mesh.chordal_error)


# --- tool shapes -----------------------------------------------------------------------------

def polygon_segments(radius: float, excess: float) -> int:
    """Sides of a circumscribed polygon whose corners stay within ``excess`` of the circle."""
    if radius <= 0:
        return 8
    c = radius / (radius + excess)
    return int(max(12, np.ceil(np.pi / np.arccos(min(c, 1.0 - 1e-12)))))


def corner_factor(radius: float, excess: float) -> float:
    """How far a corner of the circumscribed polygon of :func:`polygon_segments` lies out, as a
    multiple of the radius: 1 / cos(pi / sides)."""
    return 1.0 / np.cos(np.pi / polygon_segments(radius, excess))


def _circumscribed_ring(radius: float, excess: float):
    """(sides, corners (sides, 2)) of the circumscribed polygon of :func:`polygon_segments`
    about the unit circle: its edge midpoints on the circle."""
    n = polygon_segments(radius, excess)
    a = np.arange(n) * 2 * np.pi / n
    return n, np.column_stack([np.cos(a), np.sin(a)]) * (1.0 / np.cos(np.pi / n))


def _part_margin(name: str, margin: float, cutting_margin: float | None) -> float:
    """The flutes cut: they only must not touch other surfaces (``cutting_margin``), while the
    shank and holder keep the full ``margin`` (chordal error plus clearance)."""
    return margin if (cutting_margin is None or name != "flutes") else cutting_margin


def grown_frustum(z0: float, z1: float, r0: float, r1: float, grow: float,
                  bottom: bool = True, top: bool = True) -> tuple:
    """(z0, z1, r0, r1) of the smallest frustum of the same slope that holds every point
    within ``grow`` of the frustum (z0, z1, r0, r1), i.e. its Minkowski sum with a ball: its
    side moved out by ``grow`` across the side (``grow * sqrt(1 + slope^2)`` across the
    axis) and both ends moved out by ``grow`` along the axis (the bottom only when
    ``bottom``). The side's offset line is tangent to the rounded rims' arcs (circles of
    radius ``grow`` about the rims), so the arcs lie inside it; a frustum only grown across the
    axis keeps ``grow / sqrt(1 + slope^2)`` from a cone's side and nothing below its bottom or
    above its top (a holder's rim 0.176 mm from keycap_mold's stock at clearance 0.3)."""
    s = (r1 - r0) / (z1 - z0)
    c = grow * float(np.sqrt(1.0 + s * s))
    lo = grow if bottom else 0.0
    hi = grow if top else 0.0
    return z0 - lo, z1 + hi, r0 - s * lo + c, r1 + s * hi + c


def tool_frustums(tool: Tool, margin: float = 0.0, cutting_margin: float | None = None) -> list:
    """Per tool part (name, z0, z1, r0, r1): the part grown by ``margin`` (the flutes by
    ``cutting_margin`` when given) in every direction (:func:`grown_frustum`) but past an end
    another solid covers (:meth:`Tool.exposed_ends`): the tool the checker keeps off the
    workpiece. Below a covered bottom (a shank's on flutes as wide) the solid below rules:
    the flutes cut, and keep only the cutting margin (growing the keycap tool's shank 0.3 mm
    down into its flutes' top made the keycap job 0.40 -> 0.64 s and the long tool's 0.59 ->
    1.50 s). Above a covered top lies the part above (grown itself)."""
    return [(p.name, *grown_frustum(p.z0, p.z1, p.r0, p.r1, _part_margin(p.name, margin, cutting_margin),
                                    bottom=lo, top=hi))
            for p, (lo, hi) in zip(tool.parts(), tool.exposed_ends())]


def frustum_mesh(frustums: list, polygon_tolerance: float = 0.01):
    """Closed triangle mesh of frustums (name, z0, z1, r0, r1) about +z, each of circumscribed
    polygons within ``polygon_tolerance`` of its circles. Returns (V, T, frustum_of_triangle,
    names)."""
    V, T, owner = [], [], []
    names = [f[0] for f in frustums]
    for k, (_, z0, z1, r0, r1) in enumerate(frustums):
        n, ring = _circumscribed_ring(max(r0, r1), polygon_tolerance)
        base = sum(len(v) for v in V)
        bottom = np.column_stack([ring * r0, np.full(n, z0)])
        top = np.column_stack([ring * r1, np.full(n, z1)])
        V.append(np.vstack([bottom, top, [[0, 0, z0], [0, 0, z1]]]))
        i = np.arange(n)
        j = (i + 1) % n
        tri = np.concatenate([np.column_stack([i, j, n + j]), np.column_stack([i, n + j, n + i]),
                              np.column_stack([np.full(n, 2 * n), j, i]),
                              np.column_stack([np.full(n, 2 * n + 1), n + i, n + j])]) + base
        T.append(tri)
        owner.append(np.full(len(tri), k))
    return np.vstack(V), np.vstack(T), np.concatenate(owner), names


def tool_primitives(tool: Tool, margin: float = 0.0, polygon_tolerance: float = 0.01,
                    cutting_margin: float | None = None) -> list:
    """fcl shapes of the tool parts with their offsets along the axis: [(name, geometry,
    z_offset)]. Cylinders are exact ``fcl.Cylinder``; cone frustums are ``fcl.Convex``
    hulls of two circumscribed polygons. Margins as in :func:`tool_frustums`."""
    return [(name, frustum_shape(r0, r1, z1 - z0, polygon_tolerance), 0.5 * (z0 + z1))
            for name, z0, z1, r0, r1 in tool_frustums(tool, margin, cutting_margin)]


def frustum_shape(r0: float, r1: float, h: float, polygon_tolerance: float = 0.01):
    """An fcl shape centred on the origin along +z: ``fcl.Cylinder`` when r0 = r1, else the
    ``fcl.Convex`` hull of two circumscribed polygons (radius r0 at -h/2, r1 at +h/2)."""
    if abs(r0 - r1) < 1e-12:
        return fcl.Cylinder(r0, h)
    n, ring = _circumscribed_ring(max(r0, r1), polygon_tolerance)
    verts = np.vstack([np.column_stack([ring * r0, np.full(n, -0.5 * h)]),
                       np.column_stack([ring * r1, np.full(n, 0.5 * h)])])
    faces = [n] + list(range(n - 1, -1, -1)) + [n] + list(range(n, 2 * n))
    for i in range(n):
        j = (i + 1) % n
        faces += [4, i, j, n + j, n + i]
    return fcl.Convex(verts, n + 2, np.array(faces, np.int32))


def axis_quaternions(axes: np.ndarray) -> np.ndarray:
    """(w, x, y, z) quaternions of the shortest rotations taking +z to each unit axis (n,3)."""
    a = np.asarray(axes, float).reshape(-1, 3)
    w = 1.0 + a[:, 2]
    q = np.column_stack([w, -a[:, 1], a[:, 0], np.zeros(len(a))])
    flip = w < 1e-9                                          # axis ~ -z: half turn about x
    q[flip] = [0.0, 1.0, 0.0, 0.0]
    return q / np.linalg.norm(q, axis=1, keepdims=True)


POOL_MIN = 400                 # fcl batches at least twice this long go to worker processes,
POOL_START = 8000              # once a batch this long has started them (see CollisionChecker._fcl)
_POOL_CHECKER = None           # the checker forked workers inherit
NEAR_EPS = 1e-6                # mm: the frustums of a question to fcl widened past rounding
BESIDE_MIN = 1000              # poses: a batch this large is shared with the process beside
BESIDE_CELL = 1.0              # mm: ball centres in a checkerboard of cells go to one process or the other


def _pool_fcl(job):
    return _POOL_CHECKER._fcl_here(*job)


def decided_there(checker, C, A, grow) -> np.ndarray:
    """The process beside's answer to :meth:`CollisionChecker.collides`' request (its own
    copy of the checker, its own BVH)."""
    return checker._decided(C, A, float(grow))


# --- the checker ---------------------------------------------------------------------------

@dataclass
class Hit:
    """Which part of the tool touches which obstacle, and where (mm)."""
    part: str
    obstacle: str
    patch: int | None
    point: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    clearance: float = 0.0          # mm the part keeps (the holder clearance; 0 for the flutes)

    def __str__(self) -> str:
        p = self.point
        near = f"near ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})"
        if self.clearance > 0.0:
            return (f"the {self.part} comes within the {self.clearance:g} mm clearance it keeps of "
                    f"{self.obstacle} {near}")
        return f"the {self.part} touches {self.obstacle} {near}"


class CollisionChecker:
    """Tool poses against the workpiece, with the BVH built once.

    ``model``: a Model (its patches are tessellated within ``tolerance``) or None;
    ``meshes``: extra (name, vertices, triangles) obstacles (stock, fixture, neighbouring
    blades); ``clearance``: distance the shank and holder must keep (mm);
    ``gouge_tolerance``: depth below which the ball is not reported as gouging
    (must be at least twice ``tolerance``); ``broad_phase``: decide what the numpy broad
    phase can prove before asking fcl (same answers, see the module doc). Poses are given by
    ball centres and unit axes.
    """

    def __init__(self, model, tool: Tool, meshes=(), tolerance: float = 0.005,
                 clearance: float = 0.0, gouge_tolerance: float | None = None,
                 polygon_tolerance: float = 0.01, patches=None, broad_phase: bool = True):
        if fcl is None:
            raise GeometryError("python-fcl is not installed: tool orientation needs it "
                                "(pip install python-fcl)")
        self.tool = tool
        self.tolerance = float(tolerance)
        self.clearance = float(clearance)
        self.gouge_tolerance = 2.0 * self.tolerance if gouge_tolerance is None else float(gouge_tolerance)
        if self.gouge_tolerance < 2.0 * self.tolerance - 1e-12:
            raise InputError(f"gouge tolerance {self.gouge_tolerance:g} mm must be at least twice the "
                             f"tessellation tolerance {self.tolerance:g} mm")
        if self.gouge_tolerance >= tool.ball_radius:
            raise InputError(f"gouge tolerance {self.gouge_tolerance:g} mm is not below the ball radius")
        parts = []
        if model is not None:
            parts.append(tessellate_model(model, self.tolerance, patches))
        e_max, e_cap = 2.0, None
        if parts:                    # the tessellation's own spacing sets the samples' and the splits'
            V0, T0 = parts[0].vertices, parts[0].triangles
            edge = longest_edges(V0, T0)
            e_cap = max(0.1, float(np.quantile(edge, 0.99)))
            e_max = max(e_max, 4.0 * float(np.median(edge)))
        for item in meshes:
            if isinstance(item, TriangleMesh):
                parts.append(split_long_triangles(item, e_max))
            else:
                name, V, T = item
                parts.append(split_long_triangles(named_mesh(V, T, name), e_max))
        if not parts:
            raise InputError("nothing to check collisions against (no model and no meshes)")
        self.mesh = TriangleMesh.concat(parts)
        self.margin = self.mesh.chordal_error + self.clearance
        self.polygon_tolerance = float(polygon_tolerance)
        self._wp_object = None             # the workpiece's fcl BVH, built when first asked
        # an Aside whose forked process answers half of each large batch (decided_there): the
        # job's, while the axes are searched
        self.beside = None
        self.cutting_margin = self.mesh.chordal_error
        self._frustums = tool_frustums(tool, self.margin, self.cutting_margin)
        TV, TT, self._tool_owner, self.part_names = frustum_mesh(self._frustums, polygon_tolerance)
        self.tool_vertices, self.tool_triangles = TV, TT
        self._tool = fcl.CollisionObject(_bvh(TV, TT), fcl.Transform())
        self._prims = [(name, fcl.CollisionObject(g, fcl.Transform()), z)
                       for name, g, z in tool_primitives(tool, self.margin, polygon_tolerance,
                                                         self.cutting_margin)]
        self._ball = fcl.CollisionObject(fcl.Sphere(tool.ball_radius - self.gouge_tolerance), fcl.Transform())
        self._req = fcl.CollisionRequest()
        self.checks = 0                    # poses checked so far (for reports and benchmarks)
        self.fcl_checks = 0                # of those, asked of fcl
        self.broad = BroadPhase(self.mesh.vertices, self.mesh.triangles, self.profile,
                                tool.ball_radius - self.gouge_tolerance, e_cap) if broad_phase else None

    @property
    def _wp(self):
        """The workpiece as an fcl object (a BVH over the mesh's triangles), built when fcl is
        first asked about many poses (questions about a few: :meth:`_near`): the broad phase
        answers most questions without it (the keycap job's search, none of whose poses go to
        fcl), and its build (about 0.08 CPU-s on the keycap's 38k triangles, in C++ holding the
        GIL) is then done by the process that needs it (the job's forked one, beside the
        search, for the clearance) rather than while the path's workers need the cores."""
        if self._wp_object is None:
            self._wp_object = fcl.CollisionObject(_bvh(self.mesh.vertices, self.mesh.triangles), fcl.Transform())
        return self._wp_object

    def build_bvh(self) -> None:
        """Build the workpiece's BVH now (otherwise at fcl's first question): for timing the
        questions alone, or before forking processes that will ask fcl."""
        self._wp

    def _near(self, P0: np.ndarray, P1: np.ndarray, R0: np.ndarray, R1: np.ndarray):
        """The workpiece as fcl sees it for questions about solids inside the frustums about the
        segments P0-P1 (radii R0 at P0, R1 at P1): the whole BVH where it is built already (or
        there is no broad phase, or the frustums reach much of the workpiece), else a BVH of the
        triangles near them (:mod:`~tsplcam.orientation.nearby`: the same answers)."""
        if self._wp_object is not None or self.broad is None:
            return self._wp
        near = self.__dict__.get("_nearby")
        if near is None:
            near = self._nearby = NearWorkpiece(self.mesh.vertices, self.mesh.triangles, self.broad)
        obj = near.obj(P0, P1, R0, R1)
        return self._wp if obj is None else obj

    def _near_parts(self, C, A, frustums, masks):
        """:meth:`_near` for the parts in the bit masks ``masks`` (per pose, -1: all) of
        ``frustums`` (name, z0, z1, r0, r1, as the tool's meshes are made: circumscribed
        polygons) at the poses (C, A)."""
        if self._wp_object is not None or self.broad is None:
            return self._wp
        m = np.asarray(masks, np.int64).reshape(-1, 1)
        on = (m == -1) | ((m >> np.arange(len(frustums))) & 1).astype(bool)
        if int(on.sum()) > MAX_FRUSTUMS:
            return self._wp
        return self._near_at(C, A, *np.nonzero(on), frustums)

    def _near_at(self, C, A, k, j, frustums):
        """:meth:`_near` for part ``j[i]`` of ``frustums`` (name, z0, z1, r0, r1: held by
        circumscribed polygons) at pose ``k[i]`` of (C, A), for every i."""
        z0, z1, r0, r1 = (np.array(c, float) for c in list(zip(*frustums))[1:])
        f = np.array([corner_factor(r, self.polygon_tolerance) for r in np.maximum(r0, r1)])
        return self._near(C[k] + z0[j, None] * A[k], C[k] + z1[j, None] * A[k], (r0 * f + NEAR_EPS)[j],
                          (r1 * f + NEAR_EPS)[j])

    def profile(self, grow: float = 0.0) -> Profile:
        """The tool above the ball centre as the fcl checks see it, grown by ``grow`` mm more
        (as :meth:`_tool_object`): per part its heights and its inscribed (grown) and
        circumscribed (polygon corner) radii."""
        rows = []
        for _, z0, z1, r0, r1 in self._grown(grow):
            f = corner_factor(max(r0, r1), self.polygon_tolerance)
            rows.append((z0, z1, r0, r1, r0 * f, r1 * f))
        z0, z1, ri0, ri1, ro0, ro1 = (np.array(c, float) for c in zip(*rows))
        return Profile(z0, z1, ri0, ri1, ro0, ro1)

    def _grown(self, grow: float) -> list:
        """The tool's frustums grown by the margins and ``grow`` mm more (:func:`tool_frustums`):
        every point above a covered bottom within ``grow`` of what :meth:`clearance_of`
        measures to lies inside, so a pose that far touches at every larger growth (the
        smallest clearance's search); below a covered bottom only the solid below counts."""
        if not grow:
            return self._frustums
        return tool_frustums(self.tool, self.margin + grow, self.cutting_margin + grow)

    @property
    def triangles(self) -> int:
        return len(self.mesh.triangles)

    # --- batches -----------------------------------------------------------------------
    def _tool_object(self, grow: float = 0.0, parts: int = -1):
        """The fcl object of the tool mesh grown by ``grow`` mm more; only the parts in the
        bit mask ``parts`` (-1: all). A pose collides when some part does, and a part's
        triangles are the same in every subset, so asking only the parts the broad phase
        could not clear, one by one, gives the same answer."""
        key = (float(grow), int(parts))
        cache = self.__dict__.setdefault("_tool_objects", {})
        if key not in cache:
            V, T, own, _ = frustum_mesh(self._grown(grow), self.polygon_tolerance)
            keep = ((int(parts) >> own) & 1).astype(bool) if parts != -1 else np.ones(len(T), bool)
            cache[key] = fcl.CollisionObject(_bvh(V, T[keep]), fcl.Transform())
        return cache[key]

    def _decided(self, C, A, grow, ask=None):
        """Broad-phase decisions, with fcl for the poses it leaves open: ``ask(C, A, parts)``
        (``parts``: per pose the bit mask of the parts the broad phase could not clear), or by
        default the tool mesh reduced to the parts the broad phase could not clear. ``ask`` is
        asked only about the poses the tool mesh does not clear either: the mesh's
        circumscribed polygons contain the primitives (the same polygons for a ``Convex``, a
        polygon around a ``Cylinder``), so what the mesh clears they clear, and a mesh query
        costs a tenth of a primitive one against a large workpiece (the holder's cylinder).

        (A check of the open poses with the tool grown for a 1 deg swing, whose passes left
        cones of free axes for later poses at the same centre, was tried before the mesh while
        it paid; once the broad phase's side and exact passes decided most poses it never did:
        on the keycap_mold, deep_mold and Fusion mold searches it cost 12-24 % of their time,
        so it is gone.)"""
        if self.broad is None:
            return ask(C, A) if ask is not None else self._fcl(C, A, grow)
        st = self.broad.decide(C, A, grow)
        out = st == HIT
        open_ = np.nonzero(st == UNKNOWN)[0]
        mask = row_bits(self.broad.open_parts)
        if len(open_):
            out[open_] = self._fcl(C[open_], A[open_], grow, mask[open_])
        if ask is not None:
            sub = open_[out[open_]]
            out[sub] = ask(C[sub], A[sub], mask[sub])
        return out

    def _fcl(self, C, A, grow: float = 0.0, parts=None) -> np.ndarray:
        """fcl BVH-BVH queries per pose with the tool mesh grown by ``grow``, part by part, each
        pose with its own part mask ``parts`` (default all); large batches are shared among forked
        worker processes (each asks fcl the same question of the same objects). The workers
        are started by a batch of ``POOL_START`` poses or more (about 0.15-0.4 s of fcl): the
        forks cost about 10 ms each, and while the job's forked process checks the ball and
        builds its BVH beside the search they make four processes on two cores. Started by
        every batch of 800 or more (before), they made the Fusion mold's job take 3.71-4.06 s
        against 3.30-3.92 s without (its batches: 800-2,700 poses; three alternate pairs) and
        the bench's every-candidate check (1,320 poses to fcl) 0.135-0.18 s against
        0.135-0.14 s."""
        self.fcl_checks += len(C)
        parts = np.full(len(C), -1) if parts is None else np.asarray(parts)
        start = 2 * POOL_MIN if getattr(self, "_workers", None) is not None else POOL_START
        workers = worker_count(None, len(C) // POOL_MIN) if len(C) >= start else 1
        if workers > 1:
            pool = self._pool(workers)
            chunks = np.array_split(np.arange(len(C)), 2 * workers)
            got = pool.map(_pool_fcl, [(C[i], A[i], grow, parts[i]) for i in chunks])
            return np.concatenate(got)
        return self._fcl_here(C, A, grow, parts)

    def leave_pool(self) -> None:
        """In a process forked from the one that started this checker's pool: forget that
        pool (its workers serve the parent), so that a batch here starts one of its own."""
        self._workers = None

    def close_pool(self) -> None:
        """Stop the worker processes this checker started for its large fcl batches, and the
        pool's three threads in this process (a later large batch starts a new pool); for a
        checker kept after its work, as a test class keeps one, so that later forks happen
        beside no thread of it."""
        pool, self._workers = getattr(self, "_workers", None), None
        if pool is not None:
            pool.terminate()

    def _pool(self, workers: int):
        """Forked workers that inherit this checker."""
        pool = getattr(self, "_workers", None)
        if pool is None:
            global _POOL_CHECKER
            _POOL_CHECKER = self
            self.build_bvh()                         # (built once, inherited by the workers)
            pool = self._workers = multiprocessing.get_context("fork").Pool(workers)
            weakref.finalize(self, pool.terminate)
        return pool

    def _fcl_here(self, C, A, grow, parts) -> np.ndarray:
        Q = axis_quaternions(A).tolist()
        out = np.zeros(len(Q), bool)
        if len(Q) == 0:
            return out
        # the triangles near the parts asked (a few poses: a BVH of their own, not the whole one)
        wp = self._near_parts(C, A, self._grown(float(grow)), parts)
        req, collide, Res = self._req, fcl.collide, fcl.CollisionResult

        def ask(obj, rows):
            for k in rows:
                obj.setQuatRotation(Q[k])
                obj.setTranslation(C[k])
                if collide(obj, wp, req, Res()):
                    out[k] = True

        # the poses asked of every part (no broad phase): the whole tool at once, which
        # rejects a pose far from everything at its root (fcl alone on every candidate of the
        # bench: 249,000 poses/s against 186,000 part by part)
        whole = np.nonzero(parts == -1)[0]
        if len(whole):
            ask(self._tool_object(float(grow), -1), whole)
        # the poses the broad phase left open, near the workpiece: part by part, bottom up,
        # each pose until one part touches. The grown parts overlap where they meet (a holder
        # grown below its bottom around the shank's top), and there one BVH of several answers
        # slower than its parts one by one (the keycap's smallest clearance, 3,149 poses asked
        # of shank and holder: 0.076 s against 0.024 + 0.024 s; the keycap job 0.407 -> 0.391
        # s, keycap_mold 1.161 -> 1.100 s; the same answers: the same triangles)
        for j in range(len(self._frustums)):
            rows = np.nonzero((parts != -1) & ((parts >> j) & 1).astype(bool) & ~out)[0]
            if len(rows):
                ask(self._tool_object(float(grow), 1 << j), rows)
        return out

    def collides(self, centers, axes, grow: float = 0.0) -> np.ndarray:
        """True where the pose (ball centre, axis) makes flutes, shank or holder touch the
        workpiece (within the margin, plus ``grow`` mm): the broad phase's proofs, else one
        BVH-BVH fcl query per pose and part until one touches."""
        C = np.asarray(centers, float).reshape(-1, 3)
        A = np.asarray(axes, float).reshape(-1, 3)
        C, A = (np.ascontiguousarray(x) for x in np.broadcast_arrays(C, A)) if len(C) != len(A) else (C, A)
        out = self._shared(C, A, float(grow))
        if grow == 0.0:
            self.checks += len(C)
        return out

    def _shared(self, C, A, grow: float) -> np.ndarray:
        """:meth:`_decided`, a large batch (``BESIDE_MIN``) shared with the process beside
        (:attr:`beside`) once it serves: the poses whose ball centres lie in every other cell of
        a checkerboard (``BESIDE_CELL``) go there, the others are decided here meanwhile; so
        each process keeps seeing the same centres (the broad phase keeps free cones and hit
        witnesses by centre). The same answers: each is exact. On the molds the search's
        questions are most of the job, and that core idled through them (deep_mold's 1.1 s):
        deep_mold's job 1.81 -> 1.62 s, the Fusion mold's 1.86 -> 1.63, keycap_mold's 1.14 ->
        1.10 (its first large batch comes before the BVH there is built)."""
        helper = self.beside
        if helper is None or len(C) < BESIDE_MIN or not helper.serving():
            return self._decided(C, A, grow)
        cell = np.floor(C / BESIDE_CELL).astype(np.int64)
        there = ((cell[:, 0] + cell[:, 1] + cell[:, 2]) & 1).astype(bool)
        t, m = np.nonzero(there)[0], np.nonzero(~there)[0]
        if not len(t) or not len(m) or not helper.request(C[t], A[t], grow):
            return self._decided(C, A, grow)
        out = np.empty(len(C), bool)
        try:
            out[m] = self._decided(C[m], A[m], grow)
        finally:
            got = helper.answer()                 # (read even where this half failed)
        if got is None or len(got) != len(t):     # it failed there: here
            got = self._decided(C[t], A[t], grow)
        out[t] = got
        return out

    def collides_parts(self, centers, axes, grow: float, parts=None, only: int = -1):
        """Whether the tool parts in the bit mask ``only`` (-1: every part), grown by ``grow``
        mm, touch the workpiece: (hits, per pose the bit mask of the parts among them not
        proven clear). ``parts``: (a larger growth, the masks a call at it gave); then only
        those parts are asked, of fcl directly (poses that touch at a larger growth lie a
        hair from the workpiece, where the broad phase seldom decides), with every part added
        whose circumscribed frustum is not inside the larger growth's (:meth:`parts_within`).
        With every part, the same answers as :meth:`collides`."""
        C = np.asarray(centers, float).reshape(-1, 3)
        A = np.asarray(axes, float).reshape(-1, 3)
        C, A = (np.ascontiguousarray(x) for x in np.broadcast_arrays(C, A)) if len(C) != len(A) else (C, A)
        grow = float(grow)
        every = (1 << len(self.tool.parts())) - 1
        only = every if only == -1 else int(only) & every
        known = np.zeros(len(C), bool)                   # hits proven by the broad phase
        if parts is not None:
            larger, masks = parts
            masks = (np.asarray(masks, np.int64) | (every & ~self.parts_within(grow, float(larger)))) & only
        elif self.broad is None:
            masks = np.full(len(C), only, np.int64)
        else:
            st = self.broad.decide(C, A, grow, only)
            bits = row_bits(self.broad.open_parts)
            # (a pose proved hit may have parts the broad phase never looked at)
            masks = np.where(st == FREE, 0, np.where(st == UNKNOWN, bits, every)) & only
            # its hit proofs hold for the parts asked: a sample inside one of them whose piece
            # of the mesh reaches outside the whole tool, so outside that part too
            known = st == HIT
        out = known.copy()
        ask = np.nonzero((masks != 0) & ~known)[0]
        if len(ask):
            out[ask] = self._fcl(C[ask], A[ask], grow, masks[ask])
        return out, masks

    def clearance_parts(self) -> tuple[int, float]:
        """(bit mask, margin) of the tool parts that keep the clearance: every part but the
        flutes, grown by ``margin``; a tool of flutes alone: the flutes, grown by the cutting
        margin. The flutes cut, so next to the contact they come as close as the tilt puts them
        and keep only the cutting margin from other surfaces."""
        names = [p.name for p in self.tool.parts()]
        keep = [k for k, n in enumerate(names) if n != "flutes"]
        if not keep:
            return (1 << len(names)) - 1, self.cutting_margin
        return int(sum(1 << k for k in keep)), self.margin

    def touching_bound(self, grow: float) -> float:
        """A distance (mm, as :meth:`clearance_of` measures it) that a pose touching at
        ``grow`` (:meth:`collides_parts`) lies within: the farthest a point inside a part's
        circumscribed polygons grown by ``grow`` can be from its primitive (which holds the
        frustum of its inscribed radii): of a convex body the corners are the farthest, so
        the largest distance, in a plane through the axis, from a corner of the grown
        frustum (its polygons' corner radius) to the part's profile. On a side that is
        ``grow`` plus the polygons' excess; at a rim up to the hypotenuse of the side's and
        the end's growth (1.42-1.56 ``grow`` on the keycap's tool), and past the wide end of a
        cone, grown along its slope, more (1.8 ``grow`` on the keycap holder's cone, were its
        top not covered by the holder's cylinder)."""
        a, b = self.profile(grow), self.profile(0.0)
        far = 0.0
        for k in range(len(a.z0)):
            pts = np.array([[a.rout0[k], a.z0[k]], [a.rout1[k], a.z1[k]]])
            quad = np.array([[0.0, b.z0[k]], [b.rin0[k], b.z0[k]], [b.rin1[k], b.z1[k]], [0.0, b.z1[k]]])
            d = np.full(len(pts), np.inf)
            for p, q in zip(quad[:-1], quad[1:]):
                t = np.clip((pts - p) @ (q - p) / max(float((q - p) @ (q - p)), 1e-300), 0.0, 1.0)
                d = np.minimum(d, np.hypot(*(pts - (p + t[:, None] * (q - p))).T))
            far = max(far, float(d.max()))
        return far + 1e-9

    def parts_within(self, grow: float, larger: float) -> int:
        """Bit mask of the tool parts whose circumscribed frustum grown by ``grow`` lies inside
        the one grown by ``larger`` (so a part the broad phase cleared at ``larger`` is clear
        at ``grow``): the polygons' corners move with the growth's side count, and the
        grown frustums' ends move along the axis."""
        a, b = self.profile(grow), self.profile(larger)
        K = len(a.z0)
        ok = (a.z0 >= b.z0) & (a.z1 <= b.z1)
        for k in range(K):
            ok[k] &= bool(b.rout(k, a.z0[k]) >= a.rout0[k] and b.rout(k, a.z1[k]) >= a.rout1[k])
        return int(np.sum(ok.astype(np.int64) << np.arange(K)))

    def collides_fcl(self, centers, axes, grow: float = 0.0) -> np.ndarray:
        """:meth:`collides` asked of fcl alone: one BVH-BVH query per pose (the whole tool)."""
        C = np.asarray(centers, float).reshape(-1, 3)
        A = np.asarray(axes, float).reshape(-1, 3)
        C, A = np.broadcast_arrays(C, A) if len(C) != len(A) else (C, A)
        return self._fcl(C, A, float(grow))

    def collides_exact(self, centers, axes) -> np.ndarray:
        """The same question asked of fcl primitives (``Cylinder``/``Convex``) part by part,
        the reference the mesh form is tested against; the broad phase's proofs hold for both
        forms (its spheres cover the polygons, its hits lie inside the circles), and so does a
        pose the mesh clears (its polygons contain the primitives): only the poses the mesh
        hits are asked of the primitives, about the parts the broad phase left open."""
        C = np.asarray(centers, float).reshape(-1, 3)
        A = np.asarray(axes, float).reshape(-1, 3)
        C, A = (np.ascontiguousarray(x) for x in np.broadcast_arrays(C, A)) if len(C) != len(A) else (C, A)
        return self._decided(C, A, 0.0, self.collides_primitives)

    def collides_primitives(self, centers, axes, parts=None) -> np.ndarray:
        """:meth:`collides_exact` asked of fcl alone; ``parts``: per pose the bit mask of the
        parts to ask (default all; the broad phase proves the others clear)."""
        C = np.asarray(centers, float).reshape(-1, 3)
        A = np.asarray(axes, float).reshape(-1, 3)
        C, A = np.broadcast_arrays(C, A) if len(C) != len(A) else (C, A)
        Q = axis_quaternions(A)
        out = np.zeros(len(Q), bool)
        masks = np.full(len(Q), -1) if parts is None else np.broadcast_to(np.asarray(parts, np.int64), (len(Q),))
        if len(Q) == 0:
            return out
        wp = self._near_parts(C, A, self._frustums, masks)      # (the primitives lie inside the meshes)
        for k in range(len(Q)):
            m = int(masks[k])
            for j, (_, obj, z) in enumerate(self._prims):
                if not (m >> j) & 1:
                    continue
                obj.setQuatRotation(Q[k])
                obj.setTranslation(C[k] + z * A[k])
                if fcl.collide(obj, wp, self._req, fcl.CollisionResult()):
                    out[k] = True
                    break
        return out

    def ball_gouges(self, centers) -> np.ndarray:
        """True where the ball (shrunk by ``gouge_tolerance``) at the centre touches the
        workpiece anywhere: the ball would cut into the part deeper than the tolerance.
        The broad phase proves most balls clear; fcl answers for the rest."""
        C = np.asarray(centers, float).reshape(-1, 3)
        out = np.zeros(len(C), bool)
        ask = np.ones(len(C), bool) if self.broad is None else ~self.broad.ball_free(C)
        todo = np.nonzero(ask)[0]
        if len(todo) == 0:
            return out
        r = np.full(len(todo), self.tool.ball_radius - self.gouge_tolerance + NEAR_EPS)
        obj, wp, req = self._ball, self._near(C[todo], C[todo], r, r), self._req
        for k in todo:
            obj.setTranslation(C[k])
            out[k] = fcl.collide(obj, wp, req, fcl.CollisionResult()) > 0
        return out

    def clearance_of(self, centers, axes, parts: int = -1, smallest: bool = False,
                     below: float = np.inf) -> np.ndarray:
        """Distance (mm) between the tool parts above the ball (those in the bit mask
        ``parts``, -1 all) and the workpiece per pose (fcl.distance on the exact primitives; 0
        where they touch). The tool is grown by the margin, so the true distance is at least this
        plus ``margin`` (the flutes: ``cutting_margin``): as much on a side, more next to a
        rim (the grown part's corner stands 0.41 ``margin`` beyond the rounded offset). ``smallest``: only the smallest distance
        over the poses is wanted; a pose shown farther than the smallest one measured before it
        is not measured (inf), so the smallest value and its first pose are the same;
        ``below``: a bound known to lie above that smallest distance (see
        :meth:`touching_bound`), which the first poses are measured against as well (a part
        farther is not measured: the keycap's first pose spent 29 ms on its holder's distance).

        Parts are measured bottom up (the lowest are the nearest on most poses and the
        cheapest: the keycap's shank 0.4-0.8 ms a query, its holder's cone 6-29 ms; in the
        order of the broad phase's lower bounds, whose spheres on the fat holder's axis bound
        little, the cone went first); a part is skipped when that bound, or a collision query
        of the part grown by the nearest distance measured so far (it contains every point
        within that distance), shows it lies farther: it cannot be the smallest, and a
        distance query against the whole workpiece costs a hundred collision queries.
        """
        C = np.asarray(centers, float).reshape(-1, 3)
        A = np.asarray(axes, float).reshape(-1, 3)
        Q = axis_quaternions(A)
        out = np.full(len(Q), np.inf)
        req = fcl.DistanceRequest()
        bound = (np.zeros((len(C), len(self._prims))) if self.broad is None
                 else self.broad.part_lower_bounds(C, A))
        mask = int(parts)
        parts = self.tool.parts()
        floor = float(below) if smallest else np.inf  # the smallest distance measured so far
        wp, far = self._wp_object, np.zeros((len(C), len(parts)), bool)
        if wp is None and np.isfinite(floor) and self.broad is not None:
            # every distance measured here that can be the smallest lies below ``floor`` (a
            # part is measured where it is nearer: see above): the triangles within ``floor``
            # of the parts that may be measured are all fcl needs (a BVH of their own), and
            # the parts the broad phase shows farther than ``floor`` need none (the holders)
            far = self._proven_far(C, A, mask, floor)
            bits = ((mask >> np.arange(len(parts))) & 1).astype(bool)
            k, j = np.nonzero(bits[None, :] & ~far & (bound < floor))
            wp = self._near_at(C, A, k, j, [("", *self._grown_part(p, floor)[1:]) for p in range(len(parts))])
        wp = self._wp if wp is None else wp
        for k in range(len(Q)):
            best = floor if smallest else np.inf
            own = np.inf
            for j in range(len(parts)):
                if bound[k, j] >= best or not (mask >> j) & 1 or far[k, j]:
                    continue
                _, obj, z = self._prims[j]
                if np.isfinite(best) and not self._touches_grown(j, Q[k], C[k], A[k], best, wp):
                    continue
                obj.setQuatRotation(Q[k])
                obj.setTranslation(C[k] + z * A[k])
                d = max(fcl.distance(obj, wp, req, fcl.DistanceResult()), 0.0)
                best, own = min(best, d), min(own, d)
                if best <= 0:
                    break
            out[k] = own
            floor = min(floor, own)
        return out

    def _touches_grown(self, part: int, q, c, a, by: float, wp=None) -> bool:
        """Whether some point within ``by`` mm of part ``part``'s primitive lies in the workpiece
        (a part it clears lies farther than ``by``): those points lie in the primitive's
        frustum grown by ``by`` (:func:`grown_frustum`, both ends) and by the polygons'
        excess across the axis (a ``Convex`` primitive's corners), whose circumscribed polygons
        hold it. Asked as a mesh against the workpiece's mesh (a ``Convex`` against it tests
        each near triangle by GJK: the keycap's 64 asks 23 ms, as meshes 1 ms); a piece of the
        workpiece wholly inside meets none of its triangles, so one vertex of each piece is
        tested against the polygons' corner radii too. A larger region than the grown
        primitive only measures a part more often: the same smallest distance."""
        # (``by`` rounded up to a micrometre: a pose's part is measured at worst a micrometre
        # more often, and the grown meshes are made for a few values, not for every smallest
        # distance a batch goes through: the keycap's 13 closest poses, 13 meshes before)
        by, z0, z1, r0, r1 = self._grown_part(part, by)
        cache = self.__dict__.setdefault("_grown_objects", {})
        key = (int(part), float(by))             # (the smallest distance so far: few values)
        grown = cache.get(key)
        if grown is None:
            if len(cache) >= 64:
                cache.clear()
            V, T, _, _ = frustum_mesh([("", z0, z1, r0, r1)], self.polygon_tolerance)
            grown = cache[key] = fcl.CollisionObject(_bvh(V, T), fcl.Transform())
        grown.setQuatRotation(q)
        grown.setTranslation(c)
        if fcl.collide(grown, self._wp if wp is None else wp, self._req, fcl.CollisionResult()):
            return True
        P = self._piece_vertices - c
        t = P @ a
        rho = row_norms(P - t[:, None] * a)
        f = corner_factor(max(r0, r1), self.polygon_tolerance)
        rout = (r0 + (r1 - r0) * (t - z0) / (z1 - z0)) * f
        return bool(np.any((t >= z0) & (t <= z1) & (rho <= rout)))

    def _grown_part(self, part: int, by: float) -> tuple:
        """(``by`` rounded up to a micrometre, z0, z1, r0, r1): the region of
        :meth:`_touches_grown` for ``part``, its frustum grown by ``by`` at both ends
        (:func:`grown_frustum`) and, on a cone, by the polygons' excess across the axis (the
        corners of its ``Convex`` primitive), to be held by circumscribed polygons."""
        by = float(np.ceil(by * 1e3) * 1e-3)
        _, z0, z1, r0, r1 = self._frustums[part]
        z0, z1, r0, r1 = grown_frustum(z0, z1, r0, r1, by)
        pad = self.polygon_tolerance if abs(r1 - r0) > 1e-12 else 0.0
        return by, z0, z1, r0 + pad, r1 + pad

    def _proven_far(self, C, A, mask: int, by: float) -> np.ndarray:
        """(poses, parts): True where the broad phase proves that no point of the workpiece lies
        within ``by`` of the part's primitive, for the parts of the bit mask ``mask`` whose
        covered ends (:meth:`Tool.exposed_ends`) lie on parts of that set too: the set's
        frustums grown by ``by`` and the polygons' excess, at their exposed ends only, hold every
        such point (above a covered top lies the part above, grown itself; a shank's covered
        bottom lies on the flutes, which are not asked), so a pose the broad phase finds free
        at that growth has them all farther (asked together: one batch)."""
        parts = self.tool.parts()
        ends = self.tool.exposed_ends()
        group = {j for j in range(len(parts)) if (mask >> j) & 1}
        while True:
            drop = {j for j in group if (not ends[j][0] and j - 1 not in group)
                    or (not ends[j][1] and j + 1 not in group)}
            if not drop:
                break
            group -= drop
        out = np.zeros((len(C), len(parts)), bool)
        if not group or self.broad is None or len(C) == 0:
            return out
        grow = float(np.ceil(by * 1e3) * 1e-3) + self.polygon_tolerance + NEAR_EPS
        free = self.broad.decide(C, A, grow, int(sum(1 << j for j in group))) == FREE
        out[:, sorted(group)] = free[:, None]
        return out

    @cached_property
    def _piece_vertices(self) -> np.ndarray:
        """One vertex of each connected piece of the workpiece mesh (triangles sharing
        vertices)."""
        V, T = self.mesh.vertices, self.mesh.triangles
        if len(T) == 0:
            return np.zeros((0, 3))
        mark = np.zeros(len(V), bool)
        mark[T.ravel()] = True
        used = np.flatnonzero(mark)                  # (np.unique(T): the same, sorting 3 n)
        # the broad phase's components of the same mesh (its samples start with the vertices)
        comp = mesh_components(len(V), T) if self.broad is None else self.broad.sample_comp[:len(V)]
        _, first = np.unique(comp[used], return_index=True)
        return np.ascontiguousarray(V[used[first]])

    # --- one pose, for messages ------------------------------------------------------------
    def _contact(self, obj):
        """fcl's first contact of ``obj`` (placed) with the workpiece, or None."""
        res = fcl.CollisionResult()
        if not fcl.collide(obj, self._wp, fcl.CollisionRequest(num_max_contacts=1, enable_contact=True), res):
            return None
        return res.contacts[0]

    def _obstacle(self, triangle: int, part: str, pos) -> Hit:
        """A hit of tool part ``part`` on workpiece triangle ``triangle`` at ``pos``."""
        own = int(self.mesh.owner[triangle]) if 0 <= triangle < len(self.mesh.owner) else -1
        return Hit(part, self.mesh.owners[own] if own >= 0 else "the workpiece",
                   self.mesh.owner_patch[own] if own >= 0 else None, np.asarray(pos, float))

    def hit(self, center, axis) -> Hit | None:
        """What the pose touches (tool part, obstacle), or None when it is free."""
        self._tool.setQuatRotation(axis_quaternions(np.asarray(axis, float))[0])
        self._tool.setTranslation(np.asarray(center, float))
        c = self._contact(self._tool)
        if c is None:
            return None
        b1 = c.b1                            # triangles of o1 (the tool) and o2 (the workpiece)
        part = self.part_names[int(self._tool_owner[b1])] if 0 <= b1 < len(self._tool_owner) else "tool"
        hit = self._obstacle(c.b2, part, c.pos)
        hit.clearance = self.clearance if part not in ("flutes", "tool") else 0.0
        return hit

    def ball_hit(self, center) -> Hit | None:
        """What the shrunk ball touches at this centre, or None."""
        self._ball.setTranslation(np.asarray(center, float))
        c = self._contact(self._ball)
        return None if c is None else self._obstacle(c.b2 if c.b2 >= 0 else c.b1, "ball", c.pos)
