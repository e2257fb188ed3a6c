"""Walking straight lines on a T-mesh in knot space.

Two things walk the mesh the same way: the rays that read a vertex's local knot vectors off
the T-mesh (``knots.py``) and the lines that cut the surface into patches
(``decompose.py``). A line runs along edges, straight through vertices, and across a face's
interior where it leaves a T-junction by its stem (a *chord*), so it follows the surface
across faces of any orientation and around holes, never through a global parameter plane.

Every face has its own frame (corner 0 at the origin, side 0 along +x, positions in knot
units as value + i*order, see ``tmesh.py``). Maps between frames are rotations by q quarter
turns followed by a translation, kept as triples (q, tx, ty): p -> R_q p + t.
"""
from __future__ import annotations

from .tmesh import Lex, TMesh, Topology

STEP = ((1, 0), (0, 1), (-1, 0), (0, -1))       # unit vector of direction 0..3


def rot(q: int, x, y):
    """(x, y) turned by q quarter turns counter-clockwise."""
    q %= 4
    if q == 0:
        return x, y
    if q == 1:
        return -y, x
    if q == 2:
        return -x, -y
    return y, -x


def compose(outer, inner):
    """Maps p -> R_q p + t as (q, tx, ty): outer(inner(p))."""
    q1, x1, y1 = outer
    q2, x2, y2 = inner
    rx, ry = rot(q1, x2, y2)
    return ((q1 + q2) % 4, rx + x1, ry + y1)


def inverse(m):
    q, x, y = m
    rx, ry = rot(-q, x, y)
    return ((-q) % 4, -rx, -ry)


def apply(m, x, y):
    q, tx, ty = m
    rx, ry = rot(q, x, y)
    return rx + tx, ry + ty


def map_knots(xk, yk, m):
    """Knot vectors (ascending, along x and y) seen after the map p -> R_q p + t."""
    q, tx, ty = m
    if q == 0:
        return xk + tx, yk + ty
    if q == 1:
        return tx - yk[::-1], xk + ty
    if q == 2:
        return tx - xk[::-1], ty - yk[::-1]
    return yk + tx, ty - xk[::-1]


class Walker:
    """The steps of a walk on ``mesh``: what lies in a direction at a vertex, where a chord
    leaves a face, what is across an edge, and the frame maps between neighbouring faces.

    ``topology`` may be given when the mesh is known to be valid (it is built otherwise)."""

    def __init__(self, mesh: TMesh, topology: Topology | None = None):
        self.mesh = mesh
        self.topo = topology if topology is not None else mesh.topology
        self.tol = self.topo.tol
        self.lex = Lex(self.tol)
        self._cross_cache: dict = {}

    def at_vertex(self, v: int, th: int):
        """What lies in direction th (quarter turns in v's fan) at vertex v: ("edge", w),
        ("face", f, loop index, angle of the face's first edge), or None off the mesh."""
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

    def straight(self, w: int, back: int):
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

    def chord_exit(self, f: int, x0: complex, y0: complex, dirf: int):
        """Where a line entering face f at (x0, y0) in direction dirf leaves it: ('vertex', j)
        or ('edge', j, coord) (loop position j)."""
        topo, lex = self.topo, self.lex
        exit_side = (dirf + 1) % 4
        along_y = dirf % 2 == 0
        coord = y0 if along_y else x0
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
                return ("vertex", j)
        for j in idx[:-1]:
            c0 = pos[j][1] if along_y else pos[j][0]
            c1 = pos[(j + 1) % m][1] if along_y else pos[(j + 1) % m][0]
            lo, hi = (c0, c1) if lex.lt(c0, c1) else (c1, c0)
            if lex.lt(lo, coord) and lex.lt(coord, hi):
                return ("edge", j, coord)
        raise AssertionError(f"ray lost in face {f}")

    def after_exit(self, f: int, dirf: int, hit):
        """The walk's next state after leaving face f in direction ``dirf`` through ``hit``
        (from :meth:`chord_exit`): at a vertex ("v", vertex, direction around it), across
        an edge ("c", face, x, y, direction), or None off the mesh."""
        topo = self.topo
        if hit[0] == "vertex":
            j = hit[1]
            w = int(self.mesh.faces[f][j])
            thw = topo.fan_position[(f, j)] + (dirf - topo.out_dir(f, j)) % 4
            if not topo.boundary[w]:
                thw %= int(topo.total[w])
            return ("v", w, thw)
        nxt = self.cross(f, hit[1], hit[2])
        if nxt is None:
            return None
        g, (x, y), dg = nxt
        return ("c", g, x, y, dg)

    def walk(self, v: int, th: int, onward):
        """The steps of a line from vertex v in direction th (quarter turns in v's fan), as
        events: ("edge", v, w, back) along the edge from v to w (arriving at angle ``back`` in
        w's fan), ("chord", f, x, y, direction) into face f at (x, y) of its frame, and
        ("vertex", w, th) at every vertex reached, th the direction it goes on in. At a vertex
        reached along an edge that direction is ``onward(w, back)``. The line ends off the
        mesh or where the direction is None; the caller ends it by leaving the loop."""
        state = ("v", v, th)
        first = True
        for _ in range(100000):
            if state[0] == "v":
                _, v, th = state
                if not first:
                    yield ("vertex", v, th)
                first = False
                if th is None:
                    return
                target = self.at_vertex(v, th)
                if target is None:
                    return
                if target[0] == "edge":
                    w = target[1]
                    back = self.topo.edge_angle[(w, v)]
                    yield ("edge", v, w, back)
                    state = ("v", w, onward(w, back))
                else:
                    state = self._into_face(target, th)
            else:
                _, f, x0, y0, dirf = state
                yield ("chord", f, x0, y0, dirf)
                state = self.after_exit(f, dirf, self.chord_exit(f, x0, y0, dirf))
                if state is None:
                    return
        raise AssertionError("a line on the T-mesh did not end")

    def _into_face(self, target, th: int):
        """The state ("c", face, x, y, direction) of a line leaving a vertex in direction th
        into the face ``target`` (an ``at_vertex`` answer of kind "face")."""
        _, f, i, a = target
        dirf = (th - a + self.topo.out_dir(f, i)) % 4
        x0, y0 = self.topo.pos[f][i]
        return ("c", f, x0, y0, dirf)

    def face_across(self, f: int, j: int):
        """(face, its loop edge) across loop edge j of face f, or None at the boundary."""
        loop = self.mesh.faces[f]
        a, b = int(loop[j]), int(loop[(j + 1) % len(loop)])
        return self.topo.edge_at.get((b, a))

    def cross(self, f: int, j: int, coord: complex):
        """The point ``coord`` on face f's loop edge j, seen from the face across: (g,
        (x, y), direction into g), or None at the boundary."""
        hit = self.face_across(f, j)
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
        ux, uy = STEP[(sg + 2) % 4]
        return g, (ax + ux * t, ay + uy * t), (sg + 1) % 4

    # -- frames -------------------------------------------------------------------------------
    def face_rect(self, f: int, m):
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

    def cross_map(self, f: int, j: int):
        """(g, map g -> f) across f's loop edge j, or None."""
        key = (f, j)
        if key not in self._cross_cache:
            self._cross_cache[key] = self._cross_map(f, j)
        return self._cross_cache[key]

    def _cross_map(self, f: int, j: int):
        hit = self.face_across(f, j)
        if hit is None:
            return None
        g, k = hit
        topo, m = self.topo, len(self.mesh.faces[f])
        q = (int(topo.side[f][j]) + 2 - int(topo.side[g][k])) % 4
        bx, by = topo.pos[f][(j + 1) % m]
        gx, gy = rot(q, *topo.pos[g][k])
        return g, (q, bx - gx, by - gy)

    def same_map(self, m1, m2) -> bool:
        return m1[0] == m2[0] and self.lex.eq(m1[1], m2[1]) and self.lex.eq(m1[2], m2[2])

    def side_range(self, f, j):
        """Loop edge j of face f: (side, coordinate at its start, sign, length)."""
        topo = self.topo
        side = int(topo.side[f][j])
        m = len(self.mesh.faces[f])
        p0, p1 = topo.pos[f][j], topo.pos[f][(j + 1) % m]
        ax = 0 if side % 2 == 0 else 1
        return side, p0[ax], (1 if side < 2 else -1), (p1[ax] - p0[ax]) * (1 if side < 2 else -1)
