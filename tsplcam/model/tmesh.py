"""T-meshes: control points with weights, faces with T-junctions, knot intervals on edges.

A ``TMesh`` is the control structure of a T-spline (Sederberg et al. 2003, "T-splines and
T-NURCCs"; shang2020 section 2.1; docs/method.md section 1.1):

* ``points`` (n, 3) in mm and ``weights`` (n,) > 0: one control point per vertex;
* ``faces``: vertex loops, counter-clockwise seen from the side the normal points to. Every
  face is a rectangle in knot space: four loop positions are its *corners*
  (``corners[f]``, increasing loop positions; corner 0 is the face's lower left, side k runs
  from corner k to corner k+1, so side 0 is the bottom, 1 the right, 2 the top, 3 the left);
  the other loop vertices are T-junctions on the face's sides;
* ``intervals[f][i]``: the knot interval of the edge from ``faces[f][i]`` to
  ``faces[f][i+1]`` (>= 0). Both faces along an edge must give it the same interval, and
  opposite sides of a face must have equal sums.

Holes are missing faces; open boundaries are edges with a face on one side only.
Extraordinary points are interior vertices whose faces do not add up to a full turn
(not four corners, or two corners and one T-junction), see ``tspline.py``.

Zero knot intervals are allowed (clamped boundaries, multiple knots). Where they meet,
faces have zero size in knot space and their topology can no longer be read off knot
values. Positions in knot space are therefore kept as pairs (value, order): the order
part gives every zero interval a positive infinitesimal length, chosen so that every face
stays a rectangle. That choice is a feasibility problem (opposite sides of every face equal,
every zero interval at least 1), solved exactly by a linear program (``Topology``); a mesh
where some zero interval can only be a point is refused naming that edge. The order part
only decides which of two points with the same knot value comes first, never a value.

``from_lines`` builds a T-mesh from horizontal and vertical segments on a grid of knot
lines (samples, tests, B-spline surfaces: ``bspline_tmesh``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property, cmp_to_key

import numpy as np

from ..errors import InputError
from ..inputfile import COORDINATE_LIMIT, WEIGHT_LIMIT, first_coordinate_error, weight_error


@dataclass
class TMesh:
    points: np.ndarray
    weights: np.ndarray
    faces: list
    corners: list
    intervals: list
    source: str | None = None
    face_lines: list | None = None       # 1-based file line of each face (errors)
    vertex_lines: list | None = None     # 1-based file line of each vertex (errors)
    name: str | None = None
    vertex_labels: list | None = None    # how errors name vertices (default "vertex k+1")
    face_labels: list | None = None      # how errors name faces (default "face k+1")
    #: how errors name edges: (a, b) with a < b -> (name, file line); default "edge a+1-b+1"
    edge_labels: dict | None = None
    _topology: "Topology" = field(default=None, init=False, repr=False)

    def __post_init__(self):
        self.points = np.asarray(self.points, dtype=float).reshape(-1, 3)
        self.weights = (np.ones(len(self.points)) if self.weights is None
                        else np.asarray(self.weights, dtype=float).reshape(-1))
        self.faces = [np.asarray(f, dtype=int).reshape(-1) for f in self.faces]
        self.corners = [tuple(int(c) for c in cs) for cs in self.corners]
        self.intervals = [np.asarray(d, dtype=float).reshape(-1) for d in self.intervals]

    # -- naming ---------------------------------------------------------------------------
    def face_name(self, f: int) -> str:
        if self.face_labels is not None:
            return self.face_labels[f]
        line = f" (line {self.face_lines[f]})" if self.face_lines is not None else ""
        return f"face {f + 1}{line}"

    def vertex_name(self, v: int) -> str:
        if self.vertex_labels is not None:
            return self.vertex_labels[v]
        line = f" (line {self.vertex_lines[v]})" if self.vertex_lines is not None else ""
        return f"vertex {v + 1}{line}"

    def edge_name(self, a: int, b: int) -> str:
        label = (self.edge_labels or {}).get((min(a, b), max(a, b)))
        return label[0] if label else f"edge {a + 1}-{b + 1}"

    def edge_line(self, a: int, b: int) -> int | None:
        label = (self.edge_labels or {}).get((min(a, b), max(a, b)))
        return label[1] if label else None

    def error(self, message: str, face: int | None = None, vertex: int | None = None,
              line: int | None = None) -> InputError:
        """An InputError on the mesh's file, at ``line`` or else the line of ``face`` or
        ``vertex`` when known."""
        if line is not None:
            return InputError(message, path=self.source, line=line)
        if face is not None and self.face_lines is not None:
            line = self.face_lines[face]
        elif vertex is not None and self.vertex_lines is not None:
            line = self.vertex_lines[vertex]
        return InputError(message, path=self.source, line=line)

    @property
    def n_vertices(self) -> int:
        return len(self.points)

    def homogeneous(self) -> np.ndarray:
        return np.column_stack([self.points * self.weights[:, None], self.weights])

    @property
    def topology(self) -> "Topology":
        if self._topology is None:
            self.validate()
            self._topology = Topology(self)
        return self._topology

    @property
    def topology_built(self) -> bool:
        """Whether :attr:`topology` was made (the mesh was validated then, as it was)."""
        return self._topology is not None

    # -- validation -----------------------------------------------------------------------
    def validate(self) -> None:
        """Raise InputError naming the face or vertex for anything the kernel cannot use."""
        n = len(self.points)
        if len(self.weights) != n:
            raise self.error(f"{len(self.weights)} weights for {n} vertices")
        if not self.faces:
            raise self.error("the T-mesh has no faces")
        if not (len(self.corners) == len(self.faces) == len(self.intervals)):
            raise self.error("faces, corners and knot intervals differ in number")
        bad = first_coordinate_error(self.points)
        if bad is not None:
            raise self.error(f"{self.vertex_name(bad[0])}: {bad[1]}", vertex=bad[0])
        badw = ~((self.weights >= 1.0 / WEIGHT_LIMIT) & (self.weights <= WEIGHT_LIMIT))
        if badw.any():
            v = int(np.nonzero(badw)[0][0])
            raise self.error(f"{self.vertex_name(v)}: {weight_error(self.weights[v])}", vertex=v)
        used = np.zeros(n, bool)
        for f, (loop, cs, d) in enumerate(zip(self.faces, self.corners, self.intervals)):
            name = self.face_name(f)
            if len(loop) < 4:
                raise self.error(f"{name} has {len(loop)} vertices: a face needs at least four", f)
            if loop.min() < 0 or loop.max() >= n:
                raise self.error(f"{name} refers to a vertex that does not exist", f)
            if len(set(loop.tolist())) != len(loop):
                raise self.error(f"{name} uses a vertex twice", f)
            if len(cs) != 4 or len(set(cs)) != 4 or list(cs) != sorted(cs) or cs[0] < 0 or cs[-1] >= len(loop):
                raise self.error(f"{name}: corners {list(cs)} must be four increasing positions in its "
                                 f"loop of {len(loop)} vertices", f)
            if len(d) != len(loop):
                raise self.error(f"{name} has {len(d)} knot intervals for {len(loop)} edges", f)
            bad_d = ~((d >= 0) & (d <= COORDINATE_LIMIT))          # NaN fails both
            if bad_d.any():
                i = int(np.nonzero(bad_d)[0][0])
                raise self.error(f"{name}: knot interval {d[i]:g} of edge "
                                 f"{loop[i] + 1}-{loop[(i + 1) % len(loop)] + 1} is not a number in "
                                 f"[0, {COORDINATE_LIMIT:g}]", f)
            used[loop] = True
        if not used.all():
            v = int(np.nonzero(~used)[0][0])
            raise self.error(f"{self.vertex_name(v)} is not used by any face "
                             f"({int((~used).sum())} unused vertices)", vertex=v)
        scale = max(float(max(d.max() for d in self.intervals)), 1e-300)
        tol = 1e-9 * scale
        for f, d in enumerate(self.intervals):
            # an interval is zero (a clamped or collapsed edge) or a length: one below the
            # tolerance the sides are compared with is neither, and would divide by ~0
            tiny = (d > 0) & (d < tol)
            if tiny.any():
                raise self.error(f"{self.face_name(f)}: knot interval {d[np.argmax(tiny)]:g} is neither 0 "
                                 f"nor a length (the largest is {scale:g}; below {tol:g} write 0)", f)
        edges = {}
        for f, loop in enumerate(self.faces):
            m = len(loop)
            for i in range(m):
                a, b = int(loop[i]), int(loop[(i + 1) % m])
                if (a, b) in edges:
                    g = edges[(a, b)][0]
                    raise self.error(f"edge {a + 1}-{b + 1} is used in the same direction by "
                                     f"{self.face_name(g)} and {self.face_name(f)}: the T-mesh is "
                                     f"non-manifold or not consistently oriented", f)
                edges[(a, b)] = (f, i)
        for (a, b), (f, i) in edges.items():
            twin = edges.get((b, a))
            if twin is not None and a < b:
                g, j = twin
                if abs(self.intervals[f][i] - self.intervals[g][j]) > tol:
                    raise self.error(f"edge {a + 1}-{b + 1} has knot interval {self.intervals[f][i]:g} in "
                                     f"{self.face_name(f)} but {self.intervals[g][j]:g} in "
                                     f"{self.face_name(g)}", max(f, g))
        for f in range(len(self.faces)):
            s = self.side_sums(f)
            if abs(s[0] - s[2]) > tol or abs(s[1] - s[3]) > tol:
                raise self.error(f"{self.face_name(f)}: knot intervals of opposite sides differ "
                                 f"(bottom {s[0]:g}, top {s[2]:g}, right {s[1]:g}, left {s[3]:g})", f)

    def side_of(self, f: int) -> np.ndarray:
        """Side index (0..3) of every loop edge of face f."""
        m = len(self.faces[f])
        cs = self.corners[f]
        side = np.empty(m, dtype=int)
        for k in range(4):
            i = cs[k]
            while True:
                side[i] = k
                i = (i + 1) % m
                if i == cs[(k + 1) % 4]:
                    break
        return side

    def side_sums(self, f: int) -> np.ndarray:
        side = self.side_of(f)
        return np.array([self.intervals[f][side == k].sum() for k in range(4)])

    def is_quad(self, f: int) -> bool:
        return len(self.faces[f]) == 4

    # -- editing helpers --------------------------------------------------------------------
    def copy(self) -> "TMesh":
        return TMesh(self.points.copy(), self.weights.copy(), [f.copy() for f in self.faces],
                     list(self.corners), [d.copy() for d in self.intervals], self.source,
                     self.face_lines, self.vertex_lines, self.name, self.vertex_labels, self.face_labels,
                     self.edge_labels)


#: order parts of knot positions (:class:`Lex`) within this of each other are one
ORDER_TOL = 1e-7


class Lex:
    """Comparisons of knot positions value + i*order: values with the tolerance ``tol``, ties
    broken by the order part (see the module docstring)."""

    def __init__(self, tol: float):
        self.tol = tol

    def cmp(self, a: complex, b: complex) -> int:
        if a.real < b.real - self.tol:
            return -1
        if a.real > b.real + self.tol:
            return 1
        if a.imag < b.imag - ORDER_TOL:
            return -1
        if a.imag > b.imag + ORDER_TOL:
            return 1
        return 0

    def lt(self, a, b) -> bool:
        """``cmp(a, b) < 0``, written out (the walks call it most)."""
        if a.real < b.real - self.tol:
            return True
        if a.real > b.real + self.tol:
            return False
        return a.imag < b.imag - ORDER_TOL

    def eq(self, a, b) -> bool:
        """``cmp(a, b) == 0``, written out."""
        return not (a.real < b.real - self.tol or a.real > b.real + self.tol
                    or a.imag < b.imag - ORDER_TOL or a.imag > b.imag + ORDER_TOL)

    def key(self):
        """A sort key: ``sorted(values, key=lex.key())``."""
        return cmp_to_key(self.cmp)

    def unique(self, values) -> list:
        """The values sorted, each run of equal ones kept once (its first)."""
        values = list(values)
        if len(values) == 2:                         # most faces: no chords, as sorted() would do
            a, b = values
            c = self.cmp(b, a)
            return [b, a] if c < 0 else [a] if c == 0 else [a, b]
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


class Topology:
    """Derived structure of a validated T-mesh: face frames (positions of loop vertices in
    knot units, as complex numbers value + i*order), directed edges, fans of faces around
    every vertex with their angles in quarter turns."""

    def __init__(self, mesh: TMesh):
        self.mesh = mesh
        faces = mesh.faces
        self.nf = len(faces)
        scale = max(float(max(d.max() for d in mesh.intervals)), 1e-300)
        self.tol = 1e-9 * scale
        self.side = [mesh.side_of(f) for f in range(self.nf)]
        self.edge_at = {}                      # (a, b) -> (face, loop index)
        for f, loop in enumerate(faces):
            m = len(loop)
            for i in range(m):
                self.edge_at[(int(loop[i]), int(loop[(i + 1) % m]))] = (f, i)
        self._orders()
        self._frames()
        self._fans()

    # knot intervals as (value, order) -------------------------------------------------------
    def _orders(self):
        """Order parts of the knot intervals, found by a linear program (a feasibility problem,
        solved exactly): every face stays a rectangle (opposite sides have equal order totals)
        while every zero interval gets an order part of at least 1; positive intervals take
        whatever order parts that needs, as small as possible in total. Refused, naming an edge
        that can only have length zero, when no such arrangement exists."""
        mesh = self.mesh
        und = {}
        for (a, b), (f, i) in self.edge_at.items():
            key = (min(a, b), max(a, b))
            und.setdefault(key, mesh.intervals[f][i])
        keys = list(und)
        eid = {k: n for n, k in enumerate(keys)}
        zero = np.array([und[k] <= 0.0 for k in keys])
        xi = np.zeros(len(keys))
        if zero.any():
            xi = self._solve_orders(keys, eid, zero)
        self.edge_len = {}
        for k, e in eid.items():
            self.edge_len[k] = complex(und[k], xi[e])

    def _order_matrix(self, eid: dict):
        """Rows 2 f (sides 0 - 2) and 2 f + 1 (sides 1 - 3) of every face over the edges."""
        import scipy.sparse as sp
        rows, cols, vals = [], [], []
        for f, loop in enumerate(self.mesh.faces):
            m = len(loop)
            for i in range(m):
                a, b = int(loop[i]), int(loop[(i + 1) % m])
                k = int(self.side[f][i])
                rows.append(2 * f + (k % 2))
                cols.append(eid[(min(a, b), max(a, b))])
                vals.append(1.0 if k < 2 else -1.0)
        A = sp.csr_matrix((vals, (rows, cols)), shape=(2 * self.nf, len(eid)))
        A.sum_duplicates()
        return A

    def _solve_orders(self, keys: list, eid: dict, zero: np.ndarray) -> np.ndarray:
        """The order parts by ``scipy.optimize.linprog`` (HiGHS): variables x (one per edge) and
        p, q >= 0 with x = p - q for positive intervals; A x = 0, x >= 1 on zero intervals;
        minimise the sum of the zero intervals' x and of |x| on the others."""
        import scipy.sparse as sp
        from scipy.optimize import linprog
        mesh = self.mesh
        A = self._order_matrix(eid)
        n = len(keys)
        pos = np.nonzero(~zero)[0]
        # columns: x (n), then q for every positive interval (x = x+ - q with x+ >= 0 the x column)
        S = sp.csr_matrix((-np.ones(len(pos)), (pos, np.arange(len(pos)))), shape=(n, len(pos)))
        A_eq = sp.hstack([A, A @ S]).tocsr()
        c = np.ones(n + len(pos))
        lower = np.concatenate([np.where(zero, 1.0, 0.0), np.zeros(len(pos))])
        res = linprog(c, A_eq=A_eq, b_eq=np.zeros(A.shape[0]),
                      bounds=np.column_stack([lower, np.full(n + len(pos), np.inf)]), method="highs")
        if res.status == 0:
            x = res.x[:n].copy()
            x[pos] -= res.x[n:]
            resid = np.abs(A @ x)
            if resid.max() <= 1e-9 * max(1.0, np.abs(x).max()):
                return x
        # infeasible: the zero intervals that cannot have a positive order part in any
        # arrangement (the largest set that can is unique: arrangements add), by a second
        # programme maximising sum min(x, 1) over the zero intervals
        zi = np.nonzero(zero)[0]
        nz = len(zi)
        T = sp.csr_matrix((np.ones(nz), (np.arange(nz), zi)), shape=(nz, n))
        # variables x (n, free for positive, >= 0 for zero intervals), t (nz) in [0, 1]; t <= x
        A_ub = sp.hstack([-T, sp.identity(nz)]).tocsr()
        A_eq = sp.hstack([A, sp.csr_matrix((A.shape[0], nz))]).tocsr()
        bounds = [(0.0, None) if z else (None, None) for z in zero] + [(0.0, 1.0)] * nz
        res = linprog(np.concatenate([np.zeros(n), -np.ones(nz)]), A_ub=A_ub, b_ub=np.zeros(nz),
                      A_eq=A_eq, b_eq=np.zeros(A.shape[0]), bounds=bounds, method="highs")
        stuck = zi if res.status != 0 else zi[res.x[n:] < 0.5]
        a, b = keys[int(stuck[0])] if len(stuck) else keys[int(zi[0])]
        f, _ = self.edge_at.get((a, b)) or self.edge_at[(b, a)]
        raise mesh.error(f"zero knot interval of {mesh.edge_name(a, b)}: the T-mesh's zero intervals "
                         f"are inconsistent (this edge would have to be a point: no arrangement of "
                         f"the faces of zero size keeps them all rectangles)", f,
                         line=mesh.edge_line(a, b))

    def length(self, a: int, b: int) -> complex:
        return self.edge_len[(min(a, b), max(a, b))]

    def _frames(self):
        """Positions of every loop vertex in its face's frame: corner 0 at 0, side 0 along +x."""
        mesh = self.mesh
        self.pos = []             # per face: (m, 2) complex
        self.size = []            # per face: (W, H) complex
        for f, loop in enumerate(mesh.faces):
            m = len(loop)
            side = self.side[f]
            lens = [self.length(int(loop[i]), int(loop[(i + 1) % m])) for i in range(m)]
            W = sum(lens[i] for i in range(m) if side[i] == 0)
            H = sum(lens[i] for i in range(m) if side[i] == 1)
            start = {0: (0j, 0j), 1: (W, 0j), 2: (W, H), 3: (0j, H)}
            step = {0: (1, 0), 1: (0, 1), 2: (-1, 0), 3: (0, -1)}
            pos = np.empty((m, 2), dtype=complex)
            cs = mesh.corners[f]
            for k in range(4):
                i = cs[k]
                x, y = start[k]
                while True:
                    pos[i] = (x, y)
                    sx, sy = step[k]
                    x, y = x + sx * lens[i], y + sy * lens[i]
                    i = (i + 1) % m
                    if i == cs[(k + 1) % 4]:
                        break
            self.pos.append(pos)
            self.size.append((W, H))

    # fans ---------------------------------------------------------------------------------
    def _fans(self):
        """For every vertex: faces around it counter-clockwise as (face, loop index), the
        angle (quarter turns) of each face's outgoing edge, the total angle, boundary flag,
        and the angle of every edge (v -> w)."""
        mesh = self.mesh
        incident = [[] for _ in range(mesh.n_vertices)]
        for f, loop in enumerate(mesh.faces):
            for i, v in enumerate(loop):
                incident[int(v)].append((f, i))
        self.fan = []
        self.fan_angle = []
        self.total = np.zeros(mesh.n_vertices, dtype=int)
        self.boundary = np.zeros(mesh.n_vertices, dtype=bool)
        self.edge_angle = {}
        for v in range(mesh.n_vertices):
            inc = incident[v]
            start = inc[0]
            cur, boundary = start, False
            for _ in range(len(inc) + 1):          # walk clockwise to a boundary, if any
                prv = self._cw(cur)
                if prv is None:
                    boundary = True
                    break
                cur = prv
                if cur == start:
                    break
            first = cur if boundary else start
            order = [first]
            while True:
                nxt = self._ccw(order[-1])
                if nxt is None or nxt == first:
                    break
                order.append(nxt)
                if len(order) > len(inc):
                    break
            if len(order) != len(inc):
                raise mesh.error(f"{mesh.vertex_name(v)} is non-manifold: its {len(inc)} faces do not "
                                 f"form one fan", vertex=v)
            angles, a = [], 0
            for f, i in order:
                angles.append(a)
                w_out = int(mesh.faces[f][(i + 1) % len(mesh.faces[f])])
                w_back = int(mesh.faces[f][i - 1])
                sp = self.span(f, i)
                self.edge_angle.setdefault((v, w_out), a)
                a += sp
                self.edge_angle.setdefault((v, w_back), a)
            self.fan.append(order)
            self.fan_angle.append(angles)
            self.total[v] = a
            self.boundary[v] = boundary

    def _ccw(self, fi):
        f, i = fi
        loop = self.mesh.faces[f]
        v, prv = int(loop[i]), int(loop[i - 1])
        hit = self.edge_at.get((v, prv))
        return hit

    def _cw(self, fi):
        f, i = fi
        loop = self.mesh.faces[f]
        v, nxt = int(loop[i]), int(loop[(i + 1) % len(loop)])
        hit = self.edge_at.get((nxt, v))
        if hit is None:
            return None
        g, j = hit
        return g, (j + 1) % len(self.mesh.faces[g])

    def span(self, f: int, i: int) -> int:
        """Quarter turns face f covers at its loop position i: 1 at a corner, 2 at a T-junction."""
        side = self.side[f]
        return 1 if side[i] != side[i - 1] else 2

    def out_dir(self, f: int, i: int) -> int:
        """Direction (0 +x, 1 +y, 2 -x, 3 -y) of the edge leaving loop position i, in f's frame."""
        return int(self.side[f][i])

    def is_extraordinary(self, v: int) -> bool:
        """Interior vertex whose faces do not make a full turn, or boundary vertex with a
        full turn or more."""
        return (self.total[v] != 4) if not self.boundary[v] else (self.total[v] >= 4)

    def is_layout_vertex(self, v: int) -> bool:
        """Start of patch boundaries: extraordinary points and boundary corners (convex or
        concave), i.e. every vertex where the surface's knot domain is not locally a
        half-plane or plane."""
        return (self.total[v] != 4) if not self.boundary[v] else (self.total[v] != 2)

    def is_boundary_edge(self, a: int, b: int) -> bool:
        return ((a, b) in self.edge_at) != ((b, a) in self.edge_at)

    @cached_property
    def edge_by_angle(self) -> list[dict]:
        """Per vertex: angle (quarter turns in the vertex's fan) -> the vertex at the other end."""
        out = [dict() for _ in range(self.mesh.n_vertices)]
        for (v, w), a in self.edge_angle.items():
            out[v][a] = w
        return out

    @cached_property
    def fan_position(self) -> dict:
        """(face, loop index) -> angle of that face's outgoing edge in the vertex's fan."""
        out = {}
        for v in range(self.mesh.n_vertices):
            for fi, a in zip(self.fan[v], self.fan_angle[v]):
                out[fi] = a
        return out


# -- building T-meshes ----------------------------------------------------------------------
_DIRS = ((1, 0), (0, 1), (-1, 0), (0, -1))


def from_lines(X, Y, hsegs, vsegs, points, weights=None, holes=None, name=None) -> TMesh:
    """A T-mesh from axis-parallel segments on a grid of knot lines.

    ``X`` (nx,) and ``Y`` (ny,) are the knot values of grid columns and rows (non-decreasing;
    repeated values give zero intervals, i.e. multiple knots). ``hsegs`` are horizontal
    segments (row j, column i0, column i1), ``vsegs`` vertical ones (column i, row j0, row
    j1). Vertices are the grid nodes where a horizontal and a vertical segment meet;
    ``points(i, j)`` gives their (x, y, z) (a callable, or an array indexed [i, j]),
    ``weights`` likewise (default 1). ``holes(i, j)`` (the face's centre in grid units)
    drops faces. Faces are the bounded regions of the arrangement, counter-clockwise.
    """
    X = np.asarray(X, float)
    Y = np.asarray(Y, float)
    # lines[0]: rows j -> [(i0, i1)], lines[1]: columns i -> [(j0, j1)]; position t on line k
    # is the grid node (t, k) of a row, (k, t) of a column
    lines = ({}, {})
    for axis, segs in ((0, hsegs), (1, vsegs)):
        for k, t0, t1 in segs:
            t0, t1 = sorted((int(t0), int(t1)))
            lines[axis].setdefault(int(k), []).append((t0, t1))

    def node(axis, k, t):
        return (t, k) if axis == 0 else (k, t)

    def on(axis, k, t):
        return any(a <= t <= b for a, b in lines[axis].get(k, ()))

    nodes = set()
    for axis in (0, 1):
        for k, segs in lines[axis].items():
            for a, b in segs:
                nodes.update(node(axis, k, t) for t in range(a, b + 1) if on(1 - axis, t, k))
    names = (("horizontal", "row", "column", "vertical"), ("vertical", "column", "row", "horizontal"))
    for axis in (0, 1):
        kind, line, across, other = names[axis]
        for k, segs in lines[axis].items():
            for a, b in segs:
                for t in (a, b):
                    if node(axis, k, t) not in nodes:
                        raise InputError(f"{kind} segment on {line} {k} ends at {across} {t}, where no "
                                         f"{other} segment passes (a T-mesh's lines end on other lines)")
    nodes = sorted(nodes, key=lambda ij: (ij[1], ij[0]))
    vid = {ij: k for k, ij in enumerate(nodes)}
    nbr = {ij: [None] * 4 for ij in nodes}
    for axis in (0, 1):                       # neighbours along +x / +y (axis) and back (axis + 2)
        for k, segs in lines[axis].items():
            for a, b in segs:
                run = [node(axis, k, t) for t in range(a, b + 1) if node(axis, k, t) in vid]
                for p, q in zip(run[:-1], run[1:]):
                    nbr[p][axis] = q
                    nbr[q][axis + 2] = p
    used, faces, corners, intervals = set(), [], [], []
    for u in nodes:
        for d0 in range(4):
            if nbr[u][d0] is None or (u, d0) in used:
                continue
            loop, dirs = [], []
            cur, d = u, d0
            while (cur, d) not in used:
                used.add((cur, d))
                loop.append(cur)
                dirs.append(d)
                nxt = nbr[cur][d]
                for turn in (1, 0, 3, 2):          # left, straight, right, back
                    nd = (d + turn) % 4
                    if nbr[nxt][nd] is not None:
                        break
                cur, d = nxt, nd
            area = 0.0
            for k in range(len(loop)):
                (x0, y0), (x1, y1) = loop[k], loop[(k + 1) % len(loop)]
                area += x0 * y1 - x1 * y0
            if area <= 0:
                continue
            cx = np.mean([p[0] for p in loop])
            cy = np.mean([p[1] for p in loop])
            if holes is not None and holes(cx, cy):
                continue
            m = len(loop)
            cs = [k for k in range(m) if dirs[k] != dirs[k - 1]]
            # corner 0: the lower-left corner (first edge along +x)
            k0 = next(k for k in cs if dirs[k] == 0)
            loop = loop[k0:] + loop[:k0]
            dirs = dirs[k0:] + dirs[:k0]
            cs = [k for k in range(m) if dirs[k] != dirs[k - 1]]
            d = []
            for k in range(m):
                (i0, j0), (i1, j1) = loop[k], loop[(k + 1) % m]
                d.append(abs(X[i1] - X[i0]) if j0 == j1 else abs(Y[j1] - Y[j0]))
            faces.append([vid[p] for p in loop])
            corners.append(cs)
            intervals.append(d)
    if callable(points):
        P = np.array([points(i, j) for i, j in nodes], float)
    else:
        P = np.array([np.asarray(points)[i, j] for i, j in nodes], float)
    if weights is None:
        w = np.ones(len(nodes))
    elif callable(weights):
        w = np.array([weights(i, j) for i, j in nodes], float)
    else:
        w = np.array([np.asarray(weights)[i, j] for i, j in nodes], float)
    used = sorted({v for f in faces for v in f})          # holes may leave vertices unused
    new = {v: k for k, v in enumerate(used)}
    faces = [[new[v] for v in f] for f in faces]
    mesh = TMesh(P[used], w[used], faces, corners, intervals, name=name)
    mesh.grid_index = np.array(nodes, dtype=int)[used]
    return mesh


def bspline_tmesh(poles, weights, uknots, vknots, name=None) -> TMesh:
    """The T-mesh of a bicubic (rational) B-spline surface: poles (nu, nv, 3), weights
    (nu, nv) or None, flat knot vectors of length nu+4 and nv+4. Pole (i, j) sits at knot
    (u_{i+2}, v_{j+2}); clamped ends give zero outer intervals, multiple interior knots
    zero interior intervals, and the boundary rule (a ray leaving the mesh repeats the last
    knot) reproduces the B-spline exactly when the end knots are clamped."""
    poles = np.asarray(poles, float)
    nu, nv = poles.shape[:2]
    uknots = np.asarray(uknots, float)
    vknots = np.asarray(vknots, float)
    if len(uknots) != nu + 4 or len(vknots) != nv + 4:
        raise InputError(f"knot vectors of length {len(uknots)}, {len(vknots)} do not fit {nu} x {nv} "
                         f"bicubic poles")
    X = uknots[2:nu + 2]
    Y = vknots[2:nv + 2]
    hsegs = [(j, 0, nu - 1) for j in range(nv)]
    vsegs = [(i, 0, nv - 1) for i in range(nu)]
    return from_lines(X, Y, hsegs, vsegs, poles, weights, name=name)


def quad_tmesh(points, faces, weights=None, interval: float = 1.0, name=None) -> TMesh:
    """A T-mesh without T-junctions from quad faces (a cage), every knot interval equal."""
    faces = np.asarray(faces, dtype=int).reshape(-1, 4)
    return TMesh(points, weights, list(faces), [(0, 1, 2, 3)] * len(faces),
                 [np.full(4, float(interval))] * len(faces), name=name)
