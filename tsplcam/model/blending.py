"""T-spline blending functions: cubic B-spline pieces on five local knots, and where on the
T-mesh each function is non-zero.

The surface of a T-mesh is S = sum w_i B_i P_i / sum w_i B_i with B_i(s, t) = N[s_i](s)
N[t_i](t) (Sederberg et al. 2003); the knot vectors s_i, t_i come from ``knots.py``. Each
function is spread over the faces its support covers by a walk over faces from its vertex,
in the vertex's frame; a cubic piece of it on a cell is turned into Bernstein coefficients
exactly (sampled at four interior points of the cell).
"""
from __future__ import annotations

import numpy as np

from .basis import bernstein
from .knots import LocalKnots
from .tmesh import ORDER_TOL
from .twalk import Walker, compose, rot

_NODES = np.array([1.0, 3.0, 5.0, 7.0]) / 8.0
_TO_BERNSTEIN = np.linalg.inv(bernstein(3, _NODES, 0)[:, 0, :])     # values at nodes -> coefficients


def basis5(knots: np.ndarray, x: np.ndarray) -> np.ndarray:
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


def bezier_1d(knots: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Bernstein coefficients (k, c, 4) of functions with knot rows (k, 5) on intervals
    [lo, hi] (c,)."""
    x = lo[:, None] + (hi - lo)[:, None] * _NODES[None, :]                 # (c, 4)
    vals = basis5(knots[:, None, None, :], x[None, :, :])                # (k, c, 4)
    return vals @ _TO_BERNSTEIN.T


def bezier_1d_many(jobs: list) -> list:
    """``bezier_1d`` of many (knots (k, 5), lo (c,), hi (c,)) at once: one ``basis5`` over
    every (function, interval) pair (Cox-de Boor is elementwise, so each value is the one
    ``bezier_1d`` computes), then each job's change of basis as ``bezier_1d`` does it. Saves
    the per-call cost of the many small jobs of a Bezier extraction."""
    if not jobs:
        return []
    knots, x, shapes = [], [], []
    for k, lo, hi in jobs:
        xs = lo[:, None] + (hi - lo)[:, None] * _NODES[None, :]             # (c, 4)
        knots.append(np.repeat(k, len(xs), axis=0))
        x.append(np.tile(xs, (len(k), 1)))
        shapes.append((len(k), len(xs)))
    vals = basis5(np.concatenate(knots)[:, None, :], np.concatenate(x))      # (sum k c, 4)
    out, at = [], 0
    for k, c in shapes:
        out.append(vals[at:at + k * c].reshape(k, c, 4) @ _TO_BERNSTEIN.T)
        at += k * c
    return out


def supports(walker: Walker, knots: LocalKnots, stars: set, zone: dict | None = None) -> list[list]:
    """For every face, the vertices whose blending functions are non-zero on it, with the
    map from the face's frame to the vertex's frame: ``out[f]`` = [(vertex, map), ...].

    ``stars``: the extraordinary vertices (their own functions live on the two rings of faces
    around them only, where ``stars.py`` evaluates them: left out here). ``zone``: per face
    of those rings, (star, sector, allowed): a function may reach such a face by two ways
    around the star (ignored there), and the functions of a star's neighbours spread only
    through the rings' faces of the sectors next to them (``allowed``: vertex -> sectors)."""
    mesh, topo, lex = walker.mesh, walker.topo, walker.lex
    zone = zone or {}
    contrib = [[] for _ in range(topo.nf)]
    # the walks below run on Python complex numbers (numpy's scalars cost several times more
    # per operation): the same values, and only sums, negations and comparisons of them
    crossing = {}
    face_rect, tol, otol = walker.face_rect, lex.tol, ORDER_TOL
    loops = [[int(x) for x in loop] for loop in mesh.faces]

    def cross_map(f, j):
        key = (f, j)
        if key not in crossing:
            hit = walker.cross_map(f, j)
            crossing[key] = None if hit is None else (hit[0], (hit[1][0], complex(hit[1][1]),
                                                                complex(hit[1][2])))
        return crossing[key]

    for A in range(mesh.n_vertices):
        if A in stars:
            continue
        s5, t5 = [complex(k) for k in knots.s[A]], [complex(k) for k in knots.t[A]]
        if s5[4].real - s5[0].real <= walker.tol or t5[4].real - t5[0].real <= walker.tol:
            continue                      # identically zero
        starts = []
        for (f, i), a in zip(topo.fan[A], topo.fan_angle[A]):
            q = (a - topo.out_dir(f, i)) % 4
            px, py = rot(q, *topo.pos[f][i])
            starts.append((f, (q, -complex(px), -complex(py))))

        # lex.lt(a, b) written out (tolerance on the value, then the order part), the sums
        # with the function's own knots taken once
        s0r, s0i, t0r, t0i = s5[0].real, s5[0].imag, t5[0].real, t5[0].imag
        s4m, s4p, s4i = s5[4].real - tol, s5[4].real + tol, s5[4].imag - otol
        t4m, t4p, t4i = t5[4].real - tol, t5[4].real + tol, t5[4].imag - otol

        def inside(f, m):
            x0, x1, y0, y1 = face_rect(f, m)
            a = x0.real
            if not (a < s4m or (not a > s4p and x0.imag < s4i)):
                return False
            b = x1.real
            if not (s0r < b - tol or (not s0r > b + tol and s0i < x1.imag - otol)):
                return False
            a = y0.real
            if not (a < t4m or (not a > t4p and y0.imag < t4i)):
                return False
            b = y1.real
            return t0r < b - tol or (not t0r > b + tol and t0i < y1.imag - otol)

        def allowed(g):
            z = zone.get(g)
            return z is None or A not in z[2] or z[1] in z[2][A]

        visited = {}
        queue = []
        for f, m in starts:
            if f not in visited and inside(f, m):
                visited[f] = m
                queue.append(f)
        while queue:
            f = queue.pop()
            m = visited[f]
            contrib[f].append((A, m))
            loop = loops[f]
            nl = len(loop)
            for j in range(nl):
                a, b = loop[j], loop[(j + 1) % nl]
                if a in stars or b in stars:
                    continue
                hit = cross_map(f, j)
                if hit is None:
                    continue
                g, mg = hit
                mm = compose(m, mg)
                if not inside(g, mm) or not allowed(g):
                    continue
                old = visited.get(g)
                if old is None:
                    visited[g] = mm
                    queue.append(g)
                elif not walker.same_map(old, mm):
                    if g in zone:
                        continue
                    raise mesh.error(f"the blending function of {mesh.vertex_name(A)} wraps onto itself "
                                     f"at {mesh.face_name(g)} (its support goes around an extraordinary "
                                     f"point or a closed loop of faces)")
    return contrib
