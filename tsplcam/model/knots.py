"""Local knot vectors of a T-spline's blending functions, read off the T-mesh by ray casting.

Each blending function is B_i(s, t) = N[s_i](s) N[t_i](t) (Sederberg et al. 2003), cubic
B-spline basis functions whose local knot vectors s_i, t_i (five knots each, the vertex in
the middle) come from rays: from the vertex along +s, -s, +t, -t, the first two edges
crossed give the knots (``twalk.py`` walks the rays on the mesh itself). Conventions:

* Boundary: a ray that leaves the mesh repeats the last knot (zero knot intervals beyond the
  boundary). A grid T-mesh with zero outer intervals is therefore a clamped B-spline, and
  boundary curves interpolate their control points; boundaries must be clamped
  (``check_clamped``).
* A ray that passes through an extraordinary point continues with its mean spoke interval,
  and an extraordinary point's own knots are uniform: only pieces of functions on the two
  rings of faces around the point depend on these, and there ``stars.py`` takes over.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .tmesh import TMesh
from .twalk import Walker, inverse, map_knots


def check_clamped(mesh: TMesh) -> None:
    """Every boundary edge must lie on a face of zero width across it (a zero outer knot
    interval): under the boundary rule only then do the boundary's own control points
    carry the surface to the boundary; otherwise every blending function vanishes there
    and the surface degenerates (0/0 at the boundary)."""
    topo = mesh.topology
    for (a, b), (f, i) in topo.edge_at.items():
        if (b, a) in topo.edge_at:
            continue
        W, H = topo.size[f]
        across = H if topo.side[f][i] % 2 == 0 else W
        if across.real > topo.tol:
            raise mesh.error(f"{mesh.face_name(f)}: its boundary edge {a + 1}-{b + 1} is not clamped "
                             f"(the face is {across.real:g} knot units wide across it). T-spline "
                             f"boundaries need a row of control points at zero knot interval from the "
                             f"boundary (zero outer intervals, as in a clamped B-spline); without it "
                             f"every blending function vanishes on the boundary")


@dataclass
class LocalKnots:
    """Knot vectors (n, 5) along s and t of every vertex's blending function, in the vertex's
    own frame (angle 0 of its fan = +s), as knot positions value + i*order."""
    s: np.ndarray
    t: np.ndarray

    def in_frame(self, A: int, m) -> tuple[np.ndarray, np.ndarray]:
        """Real knot vectors (x, y) of vertex A's blending function in the frame of a face
        whose map to A's frame is m."""
        xk, yk = map_knots(self.s[A], self.t[A], inverse(m))
        return xk.real, yk.real


def local_knots(walker: Walker, ep_interval: dict) -> LocalKnots:
    """Local knot vectors of every vertex (``ep_interval``: the mean spoke interval of each
    extraordinary vertex; the functions that see it are replaced next to the star by
    ``stars.py``)."""
    n = walker.mesh.n_vertices
    sk = np.zeros((n, 5), dtype=complex)
    tk = np.zeros((n, 5), dtype=complex)
    rays = _Rays(walker, ep_interval)
    for v in range(n):
        if v in ep_interval:
            d = ep_interval[v]
            e = rays.ray(v, 0)
            n_ = rays.ray(v, 1)
            sk[v] = [-2 * d, -d, 0, e[0], e[1]]
            tk[v] = [-2 * d, -d, 0, n_[0], n_[1]]
            continue
        e, n_, w, s = (rays.ray(v, th) for th in range(4))
        sk[v] = [-w[1], -w[0], 0, e[0], e[1]]
        tk[v] = [-s[1], -s[0], 0, n_[0], n_[1]]
    return LocalKnots(sk, tk)


def knot_vectors(mesh: TMesh) -> tuple[np.ndarray, np.ndarray]:
    """Every vertex's local knot vectors (n, 5) along s and t, relative to the vertex and
    expressed in the frame of the first face of its fan (``mesh.topology.fan[v][0]``); for
    meshes laid out in one plane with aligned face frames (``tmesh.from_lines``) that is the
    plane's frame. Greville points: the vertex's knot position plus the mean of knots 1..3."""
    from .extraordinary import find_extraordinary
    mesh.validate()
    walker = Walker(mesh)
    knots = local_knots(walker, find_extraordinary(mesh, walker).interval)
    topo = mesh.topology
    S = np.empty((mesh.n_vertices, 5))
    T = np.empty((mesh.n_vertices, 5))
    for v in range(mesh.n_vertices):
        f, i = topo.fan[v][0]
        q = (topo.fan_angle[v][0] - topo.out_dir(f, i)) % 4          # face frame -> vertex frame
        xk, yk = map_knots(knots.s[v], knots.t[v], inverse((q, 0j, 0j)))
        S[v], T[v] = xk.real, yk.real
    return S, T


class _Rays:
    """Rays from vertices (``Walker`` steps; extraordinary points continue uniformly)."""

    def __init__(self, walker: Walker, ep_interval: dict):
        self.walker = walker
        self.topo = walker.topo
        self.ep_interval = ep_interval

    def perpendicular(self, w: int, back: int) -> bool:
        """Whether a ray arriving at w along the edge at angle ``back`` crosses a knot line
        there (an edge leaves w to either side, or w is extraordinary)."""
        topo = self.topo
        if w in self.ep_interval:
            return True
        edges = topo.edge_by_angle[w]
        if not topo.boundary[w]:
            return ((back + 1) % 4) in edges or ((back + 3) % 4) in edges
        T = int(topo.total[w])
        return (back + 1 <= T and (back + 1) in edges) or (back - 1 >= 0 and (back - 1) in edges)

    def straight_or_ep(self, w: int, back: int):
        if w in self.ep_interval:
            return 0          # continued virtually at the next step
        return self.walker.straight(w, back)

    def ray(self, v: int, th: int, count: int = 2) -> list[complex]:
        """Distances of the first ``count`` knots along the ray from v in direction th;
        repeats the last knot where the ray leaves the mesh."""
        topo, ep = self.topo, self.ep_interval
        knots: list[complex] = []
        dist = 0j

        def onward(w, back):
            return None if w in ep and len(knots) >= count else self.straight_or_ep(w, back)

        for step in self.walker.walk(v, th, onward):
            if step[0] == "vertex":
                _, w, thw = step
                if len(knots) >= count or thw is None:
                    break
                if w in ep:                    # beyond an extraordinary point: its interval
                    while len(knots) < count:
                        dist += ep[w]
                        knots.append(dist)
                    break
            elif step[0] == "edge":
                _, a, w, back = step
                dist = dist + topo.length(a, w)
                if self.perpendicular(w, back):
                    knots.append(dist)
            else:
                if len(knots) >= count:
                    break
                _, f, _, _, dirf = step
                W, H = topo.size[f]
                dist = dist + (W if dirf % 2 == 0 else H)
                knots.append(dist)
        last = knots[-1] if knots else 0j
        while len(knots) < count:
            knots.append(last)
        return knots
