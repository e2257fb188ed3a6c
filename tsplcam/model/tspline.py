"""T-spline surfaces: blending functions by ray casting, Bezier extraction, patches.

The surface of a T-mesh (``tmesh.py``) is S = sum w_i B_i P_i / sum w_i B_i
(docs/method.md section 1.1, Sederberg et al. 2003). Each blending function is
B_i(s, t) = N[s_i](s) N[t_i](t), cubic B-spline basis functions whose local knot vectors
s_i, t_i (five knots each, the vertex in the middle) are read off the T-mesh by ray casting:
from the vertex along +s, -s, +t, -t, the first two edges crossed give the knots.

Rays are walked on the mesh itself (along edges, straight through vertices, across face
interiors from a T-junction's stem), not in a global parameter plane, so they follow the
surface across patch boundaries and around holes. Conventions:

* Boundary: a ray that leaves the mesh repeats the last knot (zero knot intervals beyond
  the boundary). A grid T-mesh with zero outer intervals is therefore a clamped B-spline
  (``tmesh.bspline_tmesh``), and boundary curves interpolate their control points.
* Extraordinary points (interior vertices whose faces do not make a full turn) follow the
  T-NURCC rule, which with uniform knot intervals is Catmull-Clark. The faces around an
  extraordinary point are evaluated exactly by the cage machinery (``eigen.scheme_for``,
  ``EigenCells``/``LevelCells``, Stam 1998); every other face by its blending functions.
  This is exact when every blending function that reaches those faces is uniform (all
  its knot intervals equal to the extraordinary point's): that is checked, and anything
  else (non-uniform intervals or T-junctions near the point, a face with two extraordinary
  corners, extraordinary points on the boundary) is refused with an error that names the
  vertex or face rather than evaluated with a guess. A ray that passes through an
  extraordinary point continues with its uniform interval.

Each blending function is spread over the faces its support covers (a walk over faces
from its vertex, in the vertex's frame), then every face is cut into cells by the knot
lines inside it and each piece of each function becomes Bernstein coefficients (exact:
sampled at four interior points of the cell, a cubic per cell). Faces are grouped into
four-sided patches like ``decompose.py`` does for cages: lines run from every
extraordinary point and boundary corner (convex or concave) straight through the mesh
(through a face where they meet a T-junction's stem) to the next such point or the
boundary; each region between them is a rectangle in knot units, with T-junctions inside,
laid out on a grid of all its cells' knot lines and mapped to the unit square.

API: ``tspline_model(mesh)`` -> ``TSplineModel`` (a ``Model``; ``evaluate_faces`` in T-mesh
face coordinates), ``knot_vectors(mesh)`` (every vertex's local knot vectors),
``homogeneous_parts(patch)`` (sum w B P and sum w B without the division, for checks).
"""
from __future__ import annotations

from collections import defaultdict
from functools import cmp_to_key

import numpy as np

from ..errors import InputError
from ..layout.layout import CORNER_UV
from .basis import bernstein
from .cage import _map_index
from .cells import BezierCells, EigenCells, LevelCells, _chain
from .diffgeom import SurfacePoints
from .eigen import NotSelfSimilar, scheme_for
from .model import ExtraordinaryPoint, Model, link_patches
from .patch import Patch
from .quadmesh import QuadMesh
from .tmesh import TMesh

_STEP = ((1, 0), (0, 1), (-1, 0), (0, -1))       # unit vector of direction 0..3


def _rot(q: int, x, y):
    """(x, y) turned by q quarter turns counter-clockwise."""
    q %= 4
    if q == 0:
        return x, y
    if q == 1:
        return -y, x
    if q == 2:
        return -x, -y
    return y, -x


def _compose(outer, inner):
    """Maps p -> R_q p + t as (q, tx, ty): outer(inner(p))."""
    q1, x1, y1 = outer
    q2, x2, y2 = inner
    rx, ry = _rot(q1, x2, y2)
    return ((q1 + q2) % 4, rx + x1, ry + y1)


def _inverse(m):
    q, x, y = m
    rx, ry = _rot(-q, x, y)
    return ((-q) % 4, -rx, -ry)


def _apply(m, x, y):
    q, tx, ty = m
    rx, ry = _rot(q, x, y)
    return rx + tx, ry + ty


def _map_knots(xk, yk, m):
    """Knot vectors (ascending, along x and y) seen after the map p -> R_q p + t."""
    q, tx, ty = m
    if q == 0:
        return xk + tx, yk + ty
    if q == 1:
        return tx - yk[::-1], xk + ty
    if q == 2:
        return tx - xk[::-1], ty - yk[::-1]
    return yk + tx, ty - xk[::-1]


class _Lex:
    """Comparisons of knot positions value + i*order (see tmesh.py): values with a tolerance,
    ties broken by the order part."""

    def __init__(self, tol: float):
        self.tol = tol

    def cmp(self, a: complex, b: complex) -> int:
        if a.real < b.real - self.tol:
            return -1
        if a.real > b.real + self.tol:
            return 1
        if a.imag < b.imag - 1e-7:
            return -1
        if a.imag > b.imag + 1e-7:
            return 1
        return 0

    def lt(self, a, b) -> bool:
        return self.cmp(a, b) < 0

    def eq(self, a, b) -> bool:
        return self.cmp(a, b) == 0

    def unique(self, values) -> list:
        out = []
        for v in sorted(values, key=cmp_to_key(self.cmp)):
            if not out or not self.eq(out[-1], v):
                out.append(v)
        return out

    def index(self, sorted_values, v) -> int:
        lo, hi = 0, len(sorted_values)
        while lo < hi:
            mid = (lo + hi) // 2
            c = self.cmp(sorted_values[mid], v)
            if c == 0:
                return mid
            if c < 0:
                lo = mid + 1
            else:
                hi = mid
        raise KeyError(v)


# -- cubic B-spline basis functions with five local knots, and their Bezier pieces ----------
_NODES = np.array([1.0, 3.0, 5.0, 7.0]) / 8.0
_TO_BERNSTEIN = np.linalg.inv(bernstein(3, _NODES, 0)[:, 0, :])     # values at nodes -> coefficients


def _basis5(knots: np.ndarray, x: np.ndarray) -> np.ndarray:
    """N[k0..k4](x) for knot rows (..., 5) and points x (...), Cox-de Boor with 0/0 = 0."""
    k = knots
    N = [((k[..., i] <= x) & (x < k[..., i + 1])).astype(float) for i in range(4)]
    with np.errstate(divide="ignore", invalid="ignore"):
        for p in range(1, 4):
            nxt = []
            for i in range(4 - p):
                d1 = k[..., i + p] - k[..., i]
                d2 = k[..., i + p + 1] - k[..., i + 1]
                a = np.where(d1 > 0, (x - k[..., i]) / d1, 0.0)
                b = np.where(d2 > 0, (k[..., i + p + 1] - x) / d2, 0.0)
                nxt.append(a * N[i] + b * N[i + 1])
            N = nxt
    return N[0]


def _bezier_1d(knots: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Bernstein coefficients (k, c, 4) of functions with knot rows (k, 5) on intervals
    [lo, hi] (c,)."""
    x = lo[:, None] + (hi - lo)[:, None] * _NODES[None, :]                 # (c, 4)
    vals = _basis5(knots[:, None, None, :], x[None, :, :])                # (k, c, 4)
    return vals @ _TO_BERNSTEIN.T


class SubCells:
    """A cell group evaluated on sub-rectangles of another group's cells (faces evaluated
    whole, like extraordinary faces, that a patch's grid of knot lines cuts into pieces):
    cell i is the part [a0, a1] x [b0, b1] of the base group's cell ``parent[i]``."""

    def __init__(self, base, parent, box):
        self.base = base
        self.kind = base.kind
        self.parent = np.asarray(parent, dtype=int)
        self.box = np.asarray(box, dtype=float).reshape(-1, 4)

    def __len__(self) -> int:
        return len(self.parent)

    def evaluate(self, idx, a, b):
        a0, a1, b0, b1 = self.box[idx].T
        wa, wb = a1 - a0, b1 - b0
        A = np.where(a <= 0.0, a0, np.where(a >= 1.0, a1, a0 + wa * a))
        B = np.where(b <= 0.0, b0, np.where(b >= 1.0, b1, b0 + wb * b))
        H, at_vertex, normal = self.base.evaluate(self.parent[idx], A, B)
        H = H.copy()
        H[1] *= wa
        H[2] *= wb
        H[3] *= wa * wa
        H[4] *= wa * wb
        H[5] *= wb * wb
        return H, at_vertex, normal


class _ZoneMesh(QuadMesh):
    """The quad faces around one extraordinary point as a cage for ``eigen.scheme_for``;
    boundary and vertex names are those of the whole T-mesh."""

    def setup(self, tmesh: TMesh, glob: list[int]):
        self._tmesh = tmesh
        self._glob = glob
        return self

    def is_boundary_edge(self, a: int, b: int) -> bool:
        return self._tmesh.topology.is_boundary_edge(self._glob[a], self._glob[b])

    def vertex_name(self, v: int) -> str:
        return self._tmesh.vertex_name(self._glob[v])


class TSplineModel(Model):
    """A T-spline model: patches plus where every T-mesh face lies in them."""

    def evaluate_faces(self, face, s, t) -> SurfacePoints:
        """Evaluate in T-mesh faces' own coordinates: (0,0) at the face's corner 0, s toward
        corner 1, t toward corner 3, both scaled to [0, 1]. Returns P, Ps, Pt, ... in the
        fields P, Pu, Pv, ..."""
        face, s, t = np.broadcast_arrays(np.asarray(face, int).reshape(-1),
                                         np.asarray(s, float).reshape(-1), np.asarray(t, float).reshape(-1))
        n = len(face)
        H = np.empty((6, 3, n))
        normal = np.empty((n, 3))
        J = np.empty((n, 2, 2))
        patch = np.full(n, -1)
        u = np.empty(n)
        v = np.empty(n)
        for f in np.unique(face):
            rows = np.nonzero(face == f)[0]
            if f < 0 or f >= len(self.face_pieces):
                raise InputError(f"face index {f} out of range", path=self.source)
            W, Hh = self.face_size[f]
            if W <= 0 or Hh <= 0:
                raise InputError(f"{self.control.face_name(int(f))} has zero size in knot space: "
                                 f"it is not part of the surface", path=self.source)
            x, y = s[rows] * W, t[rows] * Hh
            for p, (x0, x1, y0, y1), (q, tx, ty), (PW, PH) in self.face_pieces[f]:
                tolx, toly = 1e-12 * W, 1e-12 * Hh
                inside = (x >= x0 - tolx) & (x <= x1 + tolx) & (y >= y0 - toly) & (y <= y1 + toly) & (patch[rows] < 0)
                sel = rows[inside]
                if not len(sel):
                    continue
                px, py = _rot(q, x[inside], y[inside])
                u[sel] = np.clip((px + tx) / PW, 0.0, 1.0)
                v[sel] = np.clip((py + ty) / PH, 0.0, 1.0)
                patch[sel] = p
                R = np.array([_rot(q, 1.0, 0.0), _rot(q, 0.0, 1.0)]).T         # columns: images of ex, ey
                J[sel] = (np.diag([1.0 / PW, 1.0 / PH]) @ R @ np.diag([W, Hh]))[None]
        if np.any(patch < 0):
            raise InputError("a face point lies outside every patch", path=self.source)
        for p in np.unique(patch):
            sel = np.nonzero(patch == p)[0]
            sp_ = self.patches[p].evaluate(u[sel], v[sel])
            for k, arr in enumerate((sp_.P, sp_.Pu, sp_.Pv, sp_.Puu, sp_.Puv, sp_.Pvv)):
                H[k][:, sel] = arr.T
            normal[sel] = sp_.normal
        H = _chain(H, J).transpose(0, 2, 1)
        return SurfacePoints(H[0], H[1], H[2], H[3], H[4], H[5], s, t, None, normal)


def knot_vectors(mesh: TMesh) -> tuple[np.ndarray, np.ndarray]:
    """Every vertex's local knot vectors (n, 5) along s and t, relative to the vertex and
    expressed in the frame of the first face of its fan (``mesh.topology.fan[v][0]``); for
    meshes laid out in one plane with aligned face frames (``tmesh.from_lines``) that is the
    plane's frame. Greville points: the vertex's knot position plus the mean of knots 1..3."""
    b = _Builder(mesh)
    b._extraordinary()
    b._anchor_knots()
    topo = mesh.topology
    S = np.empty((mesh.n_vertices, 5))
    T = np.empty((mesh.n_vertices, 5))
    for v in range(mesh.n_vertices):
        f, i = topo.fan[v][0]
        q = (topo.fan_angle[v][0] - topo.out_dir(f, i)) % 4          # face frame -> vertex frame
        xk, yk = _map_knots(b.sk[v], b.tk[v], _inverse((q, 0j, 0j)))
        S[v], T[v] = xk.real, yk.real
    return S, T


def homogeneous_parts(patch: Patch) -> tuple[Patch, Patch]:
    """Two polynomial patches over a T-spline patch's Bezier cells, without the rational
    division: the first evaluates to sum w_i B_i P_i, the second to (sum w_i B_i, 0, 0).
    With unit weights the second is the sum of the blending functions (partition of unity
    checks) and the first their combination of the points (linear precision checks)."""
    out = []
    for part in ("numerator", "weight"):
        groups = []
        for g in patch.groups:
            if not isinstance(g, BezierCells):
                raise InputError("homogeneous parts exist for Bezier cells only (this patch has "
                                 "extraordinary cells)", item=patch.name)
            c = g.ctrl.copy()
            if part == "weight":
                c[..., 0] = c[..., 3]
                c[..., 1:3] = 0.0
            c[..., 3] = 1.0
            groups.append(BezierCells(c))
        out.append(Patch(patch.index, patch.ubreaks, patch.vbreaks, patch.cell_group, patch.cell_local,
                         groups, name=f"{patch.name} ({part})", knot_size=patch.knot_size))
    return out[0], out[1]


def tspline_model(mesh: TMesh, name: str | None = None) -> TSplineModel:
    """The surface of a T-mesh as patches over Bezier (and extraordinary) cells."""
    return _Builder(mesh).build(name)


class _Builder:
    def __init__(self, mesh: TMesh):
        self.mesh = mesh
        mesh.validate()                   # points and weights may have changed since the topology
        self.topo = mesh.topology
        self.tol = self.topo.tol
        self.lex = _Lex(self.tol)
        self.Pw = mesh.homogeneous()

    def build(self, name):
        self._clamped()
        self._extraordinary()
        self._anchor_knots()
        self._paint()
        self._zones()
        self._decompose()
        patches = self._patches()
        return self._model(patches, name)

    def _clamped(self):
        """Every boundary edge must lie on a face of zero width across it (a zero outer knot
        interval): under the boundary rule only then do the boundary's own control points
        carry the surface to the boundary; otherwise every blending function vanishes there
        and the surface degenerates (0/0 at the boundary)."""
        mesh, topo = self.mesh, self.topo
        for (a, b), (f, i) in topo.edge_at.items():
            if (b, a) in topo.edge_at:
                continue
            W, H = topo.size[f]
            across = H if topo.side[f][i] % 2 == 0 else W
            if across.real > self.tol:
                raise mesh.error(f"{mesh.face_name(f)}: its boundary edge {a + 1}-{b + 1} is not clamped "
                                 f"(the face is {across.real:g} knot units wide across it). T-spline "
                                 f"boundaries need a row of control points at zero knot interval from the "
                                 f"boundary (zero outer intervals, as in a clamped B-spline); without it "
                                 f"every blending function vanishes on the boundary")

    # -- extraordinary points -----------------------------------------------------------------
    def _extraordinary(self):
        mesh, topo = self.mesh, self.topo
        self.ep_interval = {}
        self.cc_face = {}                 # face -> extraordinary vertex
        for v in range(mesh.n_vertices):
            if not topo.is_extraordinary(v):
                continue
            if topo.boundary[v]:
                raise mesh.error(f"{mesh.vertex_name(v)} is an extraordinary point on the boundary "
                                 f"({topo.total[v]} quarter turns of faces): not supported in T-spline "
                                 f"models (save it as a Catmull-Clark cage, or split the faces)")
            if any(topo.span(f, i) != 1 for f, i in topo.fan[v]):
                raise mesh.error(f"{mesh.vertex_name(v)} is a T-junction whose faces do not make a full "
                                 f"turn: extraordinary points must be corners of all their faces")
            if topo.total[v] < 3:
                raise mesh.error(f"{mesh.vertex_name(v)} is an interior vertex with only "
                                 f"{topo.total[v]} faces")
            d = [mesh.intervals[f][i] for f, i in topo.fan[v]]
            if max(d) - min(d) > self.tol or min(d) <= 0:
                raise mesh.error(f"knot intervals at extraordinary {mesh.vertex_name(v)} are not uniform "
                                 f"({', '.join(f'{x:g}' for x in d)}): T-NURCC refinement of non-uniform "
                                 f"intervals is not supported; make the intervals of its two rings of "
                                 f"faces equal")
            self.ep_interval[v] = float(np.mean(d))
            for f, _ in topo.fan[v]:
                if not mesh.is_quad(f):
                    raise mesh.error(f"{mesh.face_name(f)} touches extraordinary {mesh.vertex_name(v)} "
                                     f"and has T-junctions: not supported next to extraordinary points")
                if f in self.cc_face:
                    raise mesh.error(f"{mesh.face_name(f)} has two extraordinary corners "
                                     f"({mesh.vertex_name(self.cc_face[f])} and {mesh.vertex_name(v)}): "
                                     f"refine the T-mesh so that they are further apart")
                self.cc_face[f] = v

    # -- ray casting --------------------------------------------------------------------------
    def _at_vertex(self, v: int, th: int):
        """What lies in direction th (quarter turns in v's fan) at vertex v."""
        topo = self.topo
        T = int(topo.total[v])
        if topo.boundary[v]:
            if th < 0 or th > T:
                return None
        else:
            th %= T
        w = topo.edge_by_angle[v].get(th)
        if w is not None:
            return ("edge", w)
        for (f, i), a in zip(topo.fan[v], topo.fan_angle[v]):
            if a < th < a + topo.span(f, i):
                return ("face", f, i, a)
        return None

    def _straight(self, w: int, back: int):
        """Travel direction at w after arriving along the edge at angle ``back``."""
        topo = self.topo
        if not topo.boundary[w]:
            return (back + 2) % int(topo.total[w])
        T = int(topo.total[w])
        if back + 2 <= T:
            return back + 2
        if back - 2 >= 0:
            return back - 2
        return None

    def _perpendicular(self, w: int, back: int) -> bool:
        topo = self.topo
        if w in self.ep_interval:
            return True
        edges = topo.edge_by_angle[w]
        if not topo.boundary[w]:
            return ((back + 1) % 4) in edges or ((back + 3) % 4) in edges
        T = int(topo.total[w])
        return (back + 1 <= T and (back + 1) in edges) or (back - 1 >= 0 and (back - 1) in edges)

    def _chord_exit(self, f: int, x0: complex, y0: complex, dirf: int):
        """Where a ray entering face f at (x0, y0) in direction dirf leaves it: (extent,
        ('vertex', j) | ('edge', j, coord))."""
        topo, lex = self.topo, self.lex
        W, H = topo.size[f]
        exit_side = (dirf + 1) % 4
        along_y = dirf % 2 == 0
        coord = y0 if along_y else x0
        extent = W if along_y else H
        loop = self.mesh.faces[f]
        m = len(loop)
        side = topo.side[f]
        pos = topo.pos[f]
        j = self.mesh.corners[f][exit_side]
        idx = []
        while True:
            idx.append(j)
            if side[j] != exit_side:
                break
            j = (j + 1) % m
        # idx: loop positions along the exit side, from its first corner to the next corner
        for j in idx:
            c = pos[j][1] if along_y else pos[j][0]
            if lex.eq(c, coord):
                return extent, ("vertex", j)
        for j in idx[:-1]:
            c0 = pos[j][1] if along_y else pos[j][0]
            c1 = pos[(j + 1) % m][1] if along_y else pos[(j + 1) % m][0]
            lo, hi = (c0, c1) if lex.lt(c0, c1) else (c1, c0)
            if lex.lt(lo, coord) and lex.lt(coord, hi):
                return extent, ("edge", j, coord)
        raise AssertionError(f"ray lost in face {f}")

    def _after_exit(self, f: int, dirf: int, hit):
        """The walk's next state after leaving face f in direction ``dirf`` through ``hit``
        (from :meth:`_chord_exit`): at a vertex ("v", vertex, direction around it), across
        an edge ("c", face, x, y, direction), or None off the mesh."""
        topo = self.topo
        if hit[0] == "vertex":
            j = hit[1]
            w = int(self.mesh.faces[f][j])
            thw = topo.fan_position[(f, j)] + (dirf - topo.out_dir(f, j)) % 4
            if not topo.boundary[w]:
                thw %= int(topo.total[w])
            return ("v", w, thw)
        nxt = self._cross(f, hit[1], hit[2])
        if nxt is None:
            return None
        g, (x, y), dg = nxt
        return ("c", g, x, y, dg)

    def _face_across(self, f: int, j: int):
        """(face, its loop edge) across loop edge j of face f, or None at the boundary."""
        loop = self.mesh.faces[f]
        a, b = int(loop[j]), int(loop[(j + 1) % len(loop)])
        return self.topo.edge_at.get((b, a))

    def _cross(self, f: int, j: int, coord: complex):
        """The point ``coord`` on face f's loop edge j, seen from the face across: (g,
        (x, y), direction into g), or None at the boundary."""
        hit = self._face_across(f, j)
        if hit is None:
            return None
        g, k = hit
        topo = self.topo
        side = int(topo.side[f][j])
        ca = topo.pos[f][j][1] if side % 2 else topo.pos[f][j][0]
        t = (coord - ca) if side < 2 else (ca - coord)          # distance from a along the edge
        mg = len(self.mesh.faces[g])
        sg = int(topo.side[g][k])
        ax, ay = topo.pos[g][(k + 1) % mg]
        ux, uy = _STEP[(sg + 2) % 4]
        return g, (ax + ux * t, ay + uy * t), (sg + 1) % 4

    def _ray(self, v: int, th: int, count: int = 2) -> list[complex]:
        """Distances of the first ``count`` knots along the ray from v in direction th;
        repeats the last knot where the ray leaves the mesh."""
        topo = self.topo
        knots: list[complex] = []
        dist = 0j
        state = ("v", v, th)
        start = True
        for _ in range(100000):
            if len(knots) >= count:
                break
            if state[0] == "v":
                _, v, th = state
                if th is None:
                    break
                if not start and v in self.ep_interval:
                    d = self.ep_interval[v]
                    while len(knots) < count:
                        dist += d
                        knots.append(dist)
                    break
                start = False
                target = self._at_vertex(v, th)
                if target is None:
                    break
                if target[0] == "edge":
                    w = target[1]
                    dist = dist + topo.length(v, w)
                    back = topo.edge_angle[(w, v)]
                    if self._perpendicular(w, back):
                        knots.append(dist)
                    state = ("v", w, None if w in self.ep_interval and len(knots) >= count
                             else self._straight_or_ep(w, back))
                else:
                    _, f, i, a = target
                    dirf = (th - a + topo.out_dir(f, i)) % 4
                    x0, y0 = topo.pos[f][i]
                    state = ("c", f, x0, y0, dirf)
            else:
                _, f, x0, y0, dirf = state
                extent, hit = self._chord_exit(f, x0, y0, dirf)
                dist = dist + extent
                knots.append(dist)
                state = self._after_exit(f, dirf, hit)
                if state is None:
                    break
        else:
            raise AssertionError("ray did not end")
        last = knots[-1] if knots else 0j
        while len(knots) < count:
            knots.append(last)
        return knots

    def _straight_or_ep(self, w: int, back: int):
        if w in self.ep_interval:
            return 0          # continued virtually at the next step
        return self._straight(w, back)

    def _anchor_knots(self):
        """Local knot vectors of every vertex in its own frame (angle 0 of its fan = +s)."""
        n = self.mesh.n_vertices
        self.sk = np.zeros((n, 5), dtype=complex)
        self.tk = np.zeros((n, 5), dtype=complex)
        for v in range(n):
            if v in self.ep_interval:
                d = self.ep_interval[v]
                e = self._ray(v, 0)
                n_ = self._ray(v, 1)
                self.sk[v] = [-2 * d, -d, 0, e[0], e[1]]
                self.tk[v] = [-2 * d, -d, 0, n_[0], n_[1]]
                continue
            e, n_, w, s = (self._ray(v, th) for th in range(4))
            self.sk[v] = [-w[1], -w[0], 0, e[0], e[1]]
            self.tk[v] = [-s[1], -s[0], 0, n_[0], n_[1]]

    # -- spreading blending functions over faces ------------------------------------------------
    def _face_rect(self, f: int, m):
        """Face f's rectangle in the frame of map m (face -> frame), as (x0, x1, y0, y1)."""
        W, H = self.topo.size[f]
        q, tx, ty = m
        if q == 0:
            return tx, tx + W, ty, ty + H
        if q == 1:
            return tx - H, tx, ty, ty + W
        if q == 2:
            return tx - W, tx, ty - H, ty
        return tx, tx + H, ty - W, ty

    def _cross_map(self, f: int, j: int):
        """(g, map g -> f) across f's loop edge j, or None."""
        key = (f, j)
        cache = self.__dict__.setdefault("_cross_cache", {})
        if key not in cache:
            cache[key] = self._cross_map_uncached(f, j)
        return cache[key]

    def _cross_map_uncached(self, f: int, j: int):
        hit = self._face_across(f, j)
        if hit is None:
            return None
        g, k = hit
        topo, m = self.topo, len(self.mesh.faces[f])
        q = (int(topo.side[f][j]) + 2 - int(topo.side[g][k])) % 4
        bx, by = topo.pos[f][(j + 1) % m]
        gx, gy = _rot(q, *topo.pos[g][k])
        return g, (q, bx - gx, by - gy)

    def _same_map(self, m1, m2) -> bool:
        return m1[0] == m2[0] and self.lex.eq(m1[1], m2[1]) and self.lex.eq(m1[2], m2[2])

    def _paint(self):
        """For every face, the vertices whose blending functions are non-zero on it, with the
        map from the face's frame to the vertex's frame."""
        mesh, topo, lex = self.mesh, self.topo, self.lex
        self.contrib = [[] for _ in range(topo.nf)]
        eps = set(self.ep_interval)
        for A in range(mesh.n_vertices):
            s5, t5 = self.sk[A], self.tk[A]
            if s5[4].real - s5[0].real <= self.tol or t5[4].real - t5[0].real <= self.tol:
                continue                      # identically zero
            starts = []
            for (f, i), a in zip(topo.fan[A], topo.fan_angle[A]):
                q = (a - topo.out_dir(f, i)) % 4
                px, py = _rot(q, *topo.pos[f][i])
                starts.append((f, (q, -px, -py)))
                if A in eps:
                    break

            def inside(f, m):
                x0, x1, y0, y1 = self._face_rect(f, m)
                return lex.lt(x0, s5[4]) and lex.lt(s5[0], x1) and lex.lt(y0, t5[4]) and lex.lt(t5[0], y1)

            visited = {}
            queue = []
            for f, m in starts:
                if f not in visited and inside(f, m):
                    visited[f] = m
                    queue.append(f)
            while queue:
                f = queue.pop()
                m = visited[f]
                self.contrib[f].append((A, m))
                loop = mesh.faces[f]
                nl = len(loop)
                for j in range(nl):
                    a, b = int(loop[j]), int(loop[(j + 1) % nl])
                    if a in eps or b in eps:
                        continue
                    hit = self._cross_map(f, j)
                    if hit is None:
                        continue
                    g, mg = hit
                    mm = _compose(m, mg)
                    if not inside(g, mm):
                        continue
                    old = visited.get(g)
                    if old is None:
                        visited[g] = mm
                        queue.append(g)
                    elif not self._same_map(old, mm):
                        if A in eps or g in self.cc_face:
                            continue
                        raise mesh.error(f"the blending function of {mesh.vertex_name(A)} wraps onto itself "
                                         f"at {mesh.face_name(g)} (its support goes around an extraordinary "
                                         f"point or a closed loop of faces)")

    def _knots_in(self, A: int, m):
        """Real knot vectors (x, y) of vertex A's blending function in the frame of a face
        whose map to A's frame is m."""
        xk, yk = _map_knots(self.sk[A], self.tk[A], _inverse(m))
        return xk.real, yk.real

    # -- extraordinary faces --------------------------------------------------------------------
    def _zones(self):
        """Catmull-Clark schemes for the faces around extraordinary points, with the check that
        every blending function reaching them is uniform."""
        mesh, topo = self.mesh, self.topo
        self.cc_cells = {}                 # face -> (scheme, C0, corner k)
        for v, d in self.ep_interval.items():
            ring1 = [f for f, _ in topo.fan[v]]
            verts1 = {int(x) for f in ring1 for x in mesh.faces[f]}
            ring2 = sorted({g for w in verts1 for g, _ in topo.fan[w]})
            for g in ring2:
                if not mesh.is_quad(g):
                    raise mesh.error(f"{mesh.face_name(g)} has T-junctions within two rings of faces of "
                                     f"extraordinary {mesh.vertex_name(v)}: not supported (T-NURCC "
                                     f"refinement); move the T-junctions further away")
            glob = sorted({int(x) for g in ring2 for x in mesh.faces[g]})
            loc = {x: k for k, x in enumerate(glob)}
            qm = _ZoneMesh(np.array([[loc[int(x)] for x in mesh.faces[g]] for g in ring2]), len(glob),
                           "edge-only", mesh.source).setup(mesh, glob)
            for f in ring1:
                k = [int(x) for x in mesh.faces[f]].index(v)
                try:
                    scheme, cfg = scheme_for(qm, ring2.index(f), k)
                except NotSelfSimilar as exc:
                    raise mesh.error(f"around extraordinary {mesh.vertex_name(v)}: {exc.message}")
                cfg_glob = [glob[c] for c in cfg]
                got = {A for A, _ in self.contrib[f]}
                if got != set(cfg_glob):
                    raise mesh.error(f"the blending functions on {mesh.face_name(f)} next to extraordinary "
                                     f"{mesh.vertex_name(v)} are not those of its Catmull-Clark "
                                     f"neighbourhood: the knot intervals around it are not uniform")
                want = np.array([-2 * d, -d, 0.0, d, 2 * d])
                for A, _ in self.contrib[f]:
                    if (np.abs(self.sk[A].real - want).max() > self.tol
                            or np.abs(self.tk[A].real - want).max() > self.tol):
                        raise mesh.error(
                            f"knot intervals near extraordinary {mesh.vertex_name(v)} are not uniform: "
                            f"{mesh.vertex_name(A)} has knots s {np.round(self.sk[A].real, 9).tolist()}, "
                            f"t {np.round(self.tk[A].real, 9).tolist()} (T-NURCC refinement of non-uniform "
                            f"intervals is not supported)")
                self.cc_cells[f] = (scheme, self.Pw[cfg_glob], k)

    # -- patches ----------------------------------------------------------------------------------
    def _trace_all(self, starts: set):
        """Separatrices from the start vertices: traced edges and chords through faces."""
        topo = self.topo
        traced = set()
        chords = defaultdict(lambda: ([], []))         # face -> (x values of vertical, y of horizontal)
        for v in sorted(starts):
            T = int(topo.total[v])
            dirs = range(1, T) if topo.boundary[v] else range(T)
            for th in dirs:
                self._trace(v, th, starts, traced, chords)
        return traced, chords

    def _trace(self, v, th, starts, traced, chords):
        topo, lex = self.topo, self.lex
        state = ("v", v, th)
        first = True
        for _ in range(100000):
            if state[0] == "v":
                _, v, th = state
                if not first and (v in starts or th is None):
                    return
                first = False
                target = self._at_vertex(v, th)
                if target is None:
                    return
                if target[0] == "edge":
                    w = target[1]
                    key = (min(v, w), max(v, w))
                    if key in traced or topo.is_boundary_edge(v, w):
                        return
                    traced.add(key)
                    back = topo.edge_angle[(w, v)]
                    state = ("v", w, self._straight(w, back) if w not in self.ep_interval else None)
                    if w in self.ep_interval:
                        return
                else:
                    _, f, i, a = target
                    dirf = (th - a + topo.out_dir(f, i)) % 4
                    x0, y0 = topo.pos[f][i]
                    state = ("c", f, x0, y0, dirf)
            else:
                _, f, x0, y0, dirf = state
                xs, ys = chords[f]
                if dirf % 2 == 0:
                    if any(lex.eq(y0, y) for y in ys):
                        return
                    ys.append(y0)
                else:
                    if any(lex.eq(x0, x) for x in xs):
                        return
                    xs.append(x0)
                _, hit = self._chord_exit(f, x0, y0, dirf)
                state = self._after_exit(f, dirf, hit)
                if state is None:
                    return
        raise AssertionError("separatrix did not end")

    def _side_range(self, f, j):
        """Loop edge j of face f: (side, coordinate at its start, sign, length)."""
        topo = self.topo
        side = int(topo.side[f][j])
        m = len(self.mesh.faces[f])
        p0, p1 = topo.pos[f][j], topo.pos[f][(j + 1) % m]
        ax = 0 if side % 2 == 0 else 1
        return side, p0[ax], (1 if side < 2 else -1), (p1[ax] - p0[ax]) * (1 if side < 2 else -1)

    def _decompose(self):
        """Regions of face pieces between separatrices, each a rectangle in knot units."""
        mesh, topo = self.mesh, self.topo
        starts = {v for v in range(mesh.n_vertices) if topo.is_layout_vertex(v)}
        for _attempt in range(mesh.n_vertices + 1):
            traced, chords = self._trace_all(starts)
            bad = self._regions(traced, chords)
            if bad is None:
                return
            candidates = [int(x) for f in bad for x in mesh.faces[f] if int(x) not in starts]
            if not candidates:
                raise mesh.error(f"cannot split the faces around {mesh.face_name(bad[0])} into four-sided "
                                 f"patches")
            starts.add(min(candidates))
        raise mesh.error("cannot split the surface into four-sided patches")

    def _regions(self, traced, chords):
        """Pieces, their connections and regions; returns None when every region is a
        rectangle, else the faces of a region that is not."""
        mesh, topo, lex = self.mesh, self.topo, self.lex
        pieces = []                 # (face, xa, xb, ya, yb) in face frame
        piece_at = {}               # (face, ia, ib) -> piece id
        breaks = []
        for f in range(topo.nf):
            W, H = topo.size[f]
            xs, ys = chords.get(f, ([], [])) if f in chords else ([], [])
            xb = lex.unique([0j, W] + list(xs))
            yb = lex.unique([0j, H] + list(ys))
            breaks.append((xb, yb))
            for ia in range(len(xb) - 1):
                for ib in range(len(yb) - 1):
                    piece_at[(f, ia, ib)] = len(pieces)
                    pieces.append((f, xb[ia], xb[ia + 1], yb[ib], yb[ib + 1]))
        parent = list(range(len(pieces)))

        def find(x):
            while parent[x] != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x

        links = []            # (piece P, piece Q, f, j) connected across f's loop edge j
        cuts = []             # (piece P, piece Q) on either side of a separatrix
        for f in range(topo.nf):
            xb, yb = breaks[f]
            for ia in range(len(xb) - 1):          # chords inside the face
                for ib in range(len(yb) - 1):
                    if ia + 1 < len(xb) - 1:
                        cuts.append((piece_at[(f, ia, ib)], piece_at[(f, ia + 1, ib)]))
                    if ib + 1 < len(yb) - 1:
                        cuts.append((piece_at[(f, ia, ib)], piece_at[(f, ia, ib + 1)]))
            loop = mesh.faces[f]
            m = len(loop)
            for j in range(m):
                a, b = int(loop[j]), int(loop[(j + 1) % m])
                hit = topo.edge_at.get((b, a))
                if hit is None or (a > b):
                    continue
                g, k = hit
                for P, Q in self._across(f, j, g, k, breaks, piece_at):
                    if (min(a, b), max(a, b)) in traced:
                        cuts.append((P, Q))
                    else:
                        links.append((P, Q, f, j))
                        parent[find(P)] = find(Q)
        comps = defaultdict(list)
        for p in range(len(pieces)):
            comps[find(p)].append(p)
        regions = sorted(comps.values(), key=lambda c: c[0])
        region_of = np.empty(len(pieces), dtype=int)
        for r, comp in enumerate(regions):
            region_of[comp] = r
        # place faces in each region
        adj = defaultdict(list)
        for P, Q, f, j in links:
            adj[P].append((Q, f, j))
            adj[Q].append((P, f, j))
        face_map = [dict() for _ in regions]
        for r, comp in enumerate(regions):
            fm = face_map[r]
            f0 = pieces[comp[0]][0]
            fm[f0] = (0, 0j, 0j)
            queue = [comp[0]]
            seen = {comp[0]}
            ok = True
            while queue and ok:
                P = queue.pop()
                fP = pieces[P][0]
                for Q, f, j in adj[P]:
                    fQ = pieces[Q][0]
                    # crossing from fP to fQ over f's loop edge j (f is one of the two)
                    if f == fP:
                        _, mg = self._cross_map(fP, j)              # map fQ -> fP
                        mq = _compose(fm[fP], mg)
                    else:
                        _, mg = self._cross_map(fQ, j)              # map fP -> fQ
                        mq = _compose(fm[fP], _inverse(mg))
                    old = fm.get(fQ)
                    if old is None:
                        fm[fQ] = mq
                    elif not self._same_map(old, mq):
                        ok = False
                        break
                    if Q not in seen:
                        seen.add(Q)
                        queue.append(Q)
            if not ok:
                return sorted({pieces[p][0] for p in comp})
        # slits: a separatrix with the same region on both sides
        for P, Q in cuts:
            if region_of[P] == region_of[Q]:
                return sorted({pieces[P][0], pieces[Q][0]})
        # each region must tile its bounding box exactly
        self.pieces = pieces
        self.regions = regions
        self.region_of = region_of
        self.face_map = face_map
        self.links_across = links
        self.breaks = breaks
        self.piece_at = piece_at
        self.region_rects = []
        for r, comp in enumerate(regions):
            rects = [self._piece_rect(p, face_map[r]) for p in comp]
            xs = lex.unique([c for x0, x1, _, _ in rects for c in (x0, x1)])
            ys = lex.unique([c for _, _, y0, y1 in rects for c in (y0, y1)])
            cover = np.zeros((len(xs) - 1, len(ys) - 1), dtype=int)
            for x0, x1, y0, y1 in rects:
                cover[lex.index(xs, x0):lex.index(xs, x1), lex.index(ys, y0):lex.index(ys, y1)] += 1
            if not np.all(cover == 1):
                return sorted({pieces[p][0] for p in comp})
            self.region_rects.append((xs[0], xs[-1], ys[0], ys[-1]))
        return None

    def _across(self, f, j, g, k, breaks, piece_at):
        """Pairs of pieces (of f, of g) that share a stretch of the edge f:j = g:k."""
        lex = self.lex
        out = []
        sf, cf, sgnf, L = self._side_range(f, j)
        sg, cg, sgng, _ = self._side_range(g, k)

        def side_pieces(face, side):
            xb, yb = breaks[face]
            na, nb = len(xb) - 1, len(yb) - 1
            if side == 0:
                return [(piece_at[(face, a, 0)], xb[a], xb[a + 1]) for a in range(na)]
            if side == 1:
                return [(piece_at[(face, na - 1, b)], yb[b], yb[b + 1]) for b in range(nb)]
            if side == 2:
                return [(piece_at[(face, a, nb - 1)], xb[a], xb[a + 1]) for a in range(na)]
            return [(piece_at[(face, 0, b)], yb[b], yb[b + 1]) for b in range(nb)]

        # parameter along the edge from f's loop vertex j (distance)
        def clip(lo, hi):
            lo = lo if lex.lt(0j, lo) else 0j
            hi = hi if lex.lt(hi, L) else L
            return lo, hi

        fr = []
        for P, c0, c1 in side_pieces(f, sf):
            t0, t1 = (c0 - cf) * sgnf, (c1 - cf) * sgnf
            lo, hi = (t0, t1) if lex.lt(t0, t1) else (t1, t0)
            lo, hi = clip(lo, hi)
            if lex.lt(lo, hi):
                fr.append((P, lo, hi))
        # on g the edge runs from f's j+1 vertex (g's k) to f's j vertex: distance from f's j
        # vertex is L - (distance from g's k vertex)
        for Q, c0, c1 in side_pieces(g, sg):
            u0, u1 = L - (c0 - cg) * sgng, L - (c1 - cg) * sgng
            lo, hi = (u0, u1) if lex.lt(u0, u1) else (u1, u0)
            lo, hi = clip(lo, hi)
            if not lex.lt(lo, hi):
                continue
            for P, a0, a1 in fr:
                if lex.lt(max(lo, a0, key=cmp_to_key(lex.cmp)), min(hi, a1, key=cmp_to_key(lex.cmp))):
                    out.append((P, Q))
        return out

    def _piece_rect(self, p, fm):
        f, x0, x1, y0, y1 = self.pieces[p]
        m = fm[f]
        cx = [_apply(m, x, y) for x in (x0, x1) for y in (y0, y1)]
        key = cmp_to_key(self.lex.cmp)
        xs = sorted([c[0] for c in cx], key=key)
        ys = sorted([c[1] for c in cx], key=key)
        return xs[0], xs[-1], ys[0], ys[-1]

    def _node_key(self, f: int, x: complex, y: complex):
        """A name for the point (x, y) of face f that is the same from every face: a vertex,
        a point on an edge (by its distance from the edge's lower-numbered end) or a face point."""
        topo, lex = self.topo, self.lex
        loop = self.mesh.faces[f]
        m = len(loop)
        for j in range(m):
            px, py = topo.pos[f][j]
            if lex.eq(px, x) and lex.eq(py, y):
                return ("v", int(loop[j]))
        for j in range(m):
            side, c0, sgn, L = self._side_range(f, j)
            px, py = topo.pos[f][j]
            on = lex.eq(py, y) if side % 2 == 0 else lex.eq(px, x)
            if not on:
                continue
            t = ((x if side % 2 == 0 else y) - c0) * sgn
            if lex.lt(0j, t) and lex.lt(t, L):
                a, b = int(loop[j]), int(loop[(j + 1) % m])
                if a > b:
                    a, b, t = b, a, L - t
                return ("e", a, b, round(t.real / self.tol), round(t.imag * 1e6))
        return ("f", f, round(x.real / self.tol), round(x.imag * 1e6), round(y.real / self.tol),
                round(y.imag * 1e6))

    def _patches(self) -> list[Patch]:
        mesh, topo = self.mesh, self.topo
        patches = []
        self.region_patch = {}
        self.face_pieces = [[] for _ in range(topo.nf)]
        self.patch_corner_keys = []
        self.patch_corner_points = []
        for r, comp in enumerate(self.regions):
            fm = self.face_map[r]
            X0, X1, Y0, Y1 = self.region_rects[r]
            PW, PH = (X1 - X0).real, (Y1 - Y0).real
            if PW <= self.tol or PH <= self.tol:
                raise mesh.error(f"the patch around {mesh.face_name(self.pieces[comp[0]][0])} has zero size "
                                 f"in knot space (zero knot intervals along a whole patch side)")
            shift = (0, -X0, -Y0)
            items = []
            ub, vb = [0.0, PW], [0.0, PH]
            for p in comp:
                f, x0, x1, y0, y1 = self.pieces[p]
                if (x1 - x0).real <= self.tol or (y1 - y0).real <= self.tol:
                    continue                   # no area: no cells
                m = _compose(shift, fm[f])     # face -> patch frame
                px0, px1, py0, py1 = (c.real for c in self._piece_rect(p, fm))
                px0, px1, py0, py1 = px0 - X0.real, px1 - X0.real, py0 - Y0.real, py1 - Y0.real
                knots = []
                if f not in self.cc_cells:
                    for A, ma in self.contrib[f]:
                        xk, yk = self._knots_in(A, ma)
                        mr = (m[0], m[1].real, m[2].real)
                        uk, vk = _map_knots(xk, yk, mr)
                        knots.append((A, uk, vk))
                        ub.extend(k for k in uk if px0 < k < px1)
                        vb.extend(k for k in vk if py0 < k < py1)
                ub.extend((px0, px1))
                vb.extend((py0, py1))
                items.append((p, f, m, (px0, px1, py0, py1), knots))
                self.face_pieces[f].append((r, (x0.real, x1.real, y0.real, y1.real),
                                            (m[0], m[1].real, m[2].real), (PW, PH)))
            ub = _cluster(ub, self.tol)
            vb = _cluster(vb, self.tol)
            nu, nv = len(ub) - 1, len(vb) - 1
            owner = np.full((nu, nv), -1)
            group = np.zeros((nu, nv), dtype=int)
            local = np.zeros((nu, nv), dtype=int)
            bez = []                                    # bicubic Bezier cells
            cc = {}                # id(scheme) -> (scheme, C0s, maps, parent face, box in it, patch cell)
            for n_item, (p, f, m, (px0, px1, py0, py1), knots) in enumerate(items):
                iu0, iu1 = _locate(ub, px0, self.tol), _locate(ub, px1, self.tol)
                iv0, iv1 = _locate(vb, py0, self.tol), _locate(vb, py1, self.tol)
                if np.any(owner[iu0:iu1, iv0:iv1] >= 0):
                    raise AssertionError("patch cells covered twice")
                owner[iu0:iu1, iv0:iv1] = n_item
                lo_u, hi_u = np.array(ub[iu0:iu1]), np.array(ub[iu0 + 1:iu1 + 1])
                lo_v, hi_v = np.array(vb[iv0:iv1]), np.array(vb[iv0 + 1:iv1 + 1])
                if f in self.cc_cells:
                    scheme, C0, k = self.cc_cells[f]
                    W, H = topo.size[f]                          # the whole face in patch units
                    fx = [_apply((m[0], m[1].real, m[2].real), x, y)
                          for x, y in ((0.0, 0.0), (W.real, H.real))]
                    FX0, FX1 = sorted((fx[0][0], fx[1][0]))
                    FY0, FY1 = sorted((fx[0][1], fx[1][1]))
                    entry = cc.setdefault(id(scheme), (scheme, [], [], [], [], []))
                    parent = len(entry[1])
                    entry[1].append(C0)
                    entry[2].append(_map_index((-m[0] - k) % 4))
                    for iu in range(iu0, iu1):
                        for iv in range(iv0, iv1):
                            entry[3].append(parent)
                            entry[4].append(((ub[iu] - FX0) / (FX1 - FX0), (ub[iu + 1] - FX0) / (FX1 - FX0),
                                             (vb[iv] - FY0) / (FY1 - FY0), (vb[iv + 1] - FY0) / (FY1 - FY0)))
                            entry[5].append((iu, iv))
                    continue
                As = np.array([A for A, _, _ in knots], dtype=int)
                UK = np.array([uk for _, uk, _ in knots])
                VK = np.array([vk for _, _, vk in knots])
                Cu = _bezier_1d(UK, lo_u, hi_u)                 # (k, cu, 4)
                Cv = _bezier_1d(VK, lo_v, hi_v)                 # (k, cv, 4)
                ctrl = np.einsum("kbj,kai,kc->abjic", Cv, Cu, self.Pw[As])   # (cu, cv, 4, 4, 4)
                for a in range(iu1 - iu0):
                    for b in range(iv1 - iv0):
                        cell = ctrl[a, b]
                        if min(cell[0, 0, 3], cell[0, -1, 3], cell[-1, 0, 3], cell[-1, -1, 3]) <= 0.0:
                            raise mesh.error(f"the surface has no point at a corner of a cell of "
                                             f"{mesh.face_name(f)} (no blending function reaches it)")
                        local[iu0 + a, iv0 + b] = len(bez)
                        bez.append(cell)
            if np.any(owner < 0):
                raise mesh.error(f"the patch around {mesh.face_name(self.pieces[comp[0]][0])} is not covered "
                                 f"by its faces")
            groups = [BezierCells(np.array(bez))] if bez else []
            for scheme, C0s, maps, parents, boxes, cells in cc.values():
                cls = LevelCells if scheme.defective else EigenCells
                base = cls(scheme, np.array(C0s), np.array(maps))
                g = len(groups)
                groups.append(SubCells(base, parents, boxes))
                for n_cell, (iu, iv) in enumerate(cells):
                    group[iu, iv] = g
                    local[iu, iv] = n_cell
            patch = Patch(len(patches), np.array(ub) / PW, np.array(vb) / PH, group, local, groups,
                          knot_size=(PW, PH))
            self.region_patch[r] = len(patches)
            patches.append(patch)
        return patches

    def _corner_keys(self, r):
        """Node keys of region r's four corners (lower left counter-clockwise)."""
        fm = self.face_map[r]
        X0, X1, Y0, Y1 = self.region_rects[r]
        out = []
        for cx, cy in ((X0, Y0), (X1, Y0), (X1, Y1), (X0, Y1)):
            key = None
            for p in self.regions[r]:
                f = self.pieces[p][0]
                x0, x1, y0, y1 = self._piece_rect(p, fm)
                if self.lex.eq(x0, cx) or self.lex.eq(x1, cx):
                    if self.lex.eq(y0, cy) or self.lex.eq(y1, cy):
                        fx, fy = _apply(_inverse(fm[f]), cx, cy)
                        key = self._node_key(f, fx, fy)
                        break
            out.append(key)
        return out

    def _links(self):
        """Whole-edge neighbours between patches: ((patch, edge), (patch', edge'), reversed)."""
        mesh = self.mesh
        corner_keys = [self._corner_keys(r) for r in range(len(self.regions))]
        across = defaultdict(set)          # (region, side) -> {(region', side')}
        for P, Q, kP, kQ in self._cut_pairs():
            rp, rq = int(self.region_of[P]), int(self.region_of[Q])
            eP = (kP + self.face_map[rp][self.pieces[P][0]][0]) % 4
            eQ = (kQ + self.face_map[rq][self.pieces[Q][0]][0]) % 4
            across[(rp, eP)].add((rq, eQ))
            across[(rq, eQ)].add((rp, eP))
        out = []
        done = set()
        for (r, e), others in sorted(across.items()):
            if (r, e) in done:
                continue
            name = f"patch {self.region_patch[r]} (around {mesh.face_name(self.pieces[self.regions[r][0]][0])})"
            if len(others) != 1:
                raise mesh.error(f"{name}: its side {e} is not one whole edge of a neighbouring patch")
            rb, eb = next(iter(others))
            ka = (corner_keys[r][e], corner_keys[r][(e + 1) % 4])
            kb = (corner_keys[rb][eb], corner_keys[rb][(eb + 1) % 4])
            if ka == kb[::-1]:
                rev = True
            elif ka == kb:
                rev = False
            else:
                raise mesh.error(f"{name} and patch {self.region_patch[rb]} share only part of an edge")
            out.append(((self.region_patch[r], e), (self.region_patch[rb], eb), rev))
            done.add((r, e))
            done.add((rb, eb))
        return out, corner_keys

    def _cut_pairs(self):
        """Pieces of different regions on either side of a separatrix, with the side (in
        their faces' frames) each one shows the other: (P, Q, side of P, side of Q)."""
        mesh, topo = self.mesh, self.topo
        out = []
        for f in range(topo.nf):
            xb, yb = self.breaks[f]
            for ia in range(len(xb) - 1):
                for ib in range(len(yb) - 1):
                    if ia + 1 < len(xb) - 1:
                        out.append((self.piece_at[(f, ia, ib)], self.piece_at[(f, ia + 1, ib)], 1, 3))
                    if ib + 1 < len(yb) - 1:
                        out.append((self.piece_at[(f, ia, ib)], self.piece_at[(f, ia, ib + 1)], 2, 0))
            loop = mesh.faces[f]
            m = len(loop)
            for j in range(m):
                a, b = int(loop[j]), int(loop[(j + 1) % m])
                hit = topo.edge_at.get((b, a))
                if hit is None or a > b:
                    continue
                g, k = hit
                for P, Q in self._across(f, j, g, k, self.breaks, self.piece_at):
                    out.append((P, Q, int(topo.side[f][j]), int(topo.side[g][k])))
        return [x for x in out if self.region_of[x[0]] != self.region_of[x[1]]]

    def _model(self, patches, name):
        mesh = self.mesh
        links, corner_keys = self._links()
        link_patches(patches, links)
        node_of = {}
        for r in range(len(self.regions)):
            for key in corner_keys[r]:
                node_of.setdefault(key, len(node_of))
        node_points = np.zeros((len(node_of), 3))
        for r, keys in enumerate(corner_keys):
            patch = patches[self.region_patch[r]]
            patch.corner_nodes = np.array([node_of[k] for k in keys])
            node_points[patch.corner_nodes] = patch.evaluate(CORNER_UV[:, 0], CORNER_UV[:, 1]).P
        eps = []
        for v in sorted(self.ep_interval):
            key = ("v", v)
            if key in node_of:
                eps.append(ExtraordinaryPoint(node_of[key], int(self.topo.total[v]), node_points[node_of[key]],
                                              False))
        model = TSplineModel(patches, node_points, eps, "t-spline", mesh.source, None, control=mesh,
                             name=name or mesh.name)
        model.face_pieces = [[(self.region_patch[r], box, m, size) for r, box, m, size in pcs]
                             for pcs in self.face_pieces]
        model.face_size = [(W.real, H.real) for W, H in self.topo.size]
        model.node_keys = list(node_of)
        return model


def _cluster(values, tol) -> list:
    """Sorted values with neighbours closer than tol merged."""
    out = []
    for v in sorted(values):
        if not out or v - out[-1] > tol:
            out.append(float(v))
    return out


def _locate(breaks, x, tol) -> int:
    i = int(np.searchsorted(breaks, x - tol))
    if i >= len(breaks) or abs(breaks[i] - x) > tol:
        raise AssertionError(f"{x} is not a break")
    return i
