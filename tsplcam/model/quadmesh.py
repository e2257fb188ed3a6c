"""Quad control meshes: topology, validation, Catmull-Clark refinement, regular stencils.

A ``QuadMesh`` is the topology of a cage (faces of four vertex indices, counter-clockwise
seen from the side the normal points to) plus its boundary rule. Positions are kept apart
(homogeneous (n, 4) arrays), so that refinement is a sparse matrix R with
``new_points = R @ old_points``: the same matrix gives the refined cage, OpenSubdiv-style
reference meshes, and the local subdivision matrices of extraordinary points.

Boundary rules follow OpenSubdiv (``Sdc::Options::VtxBoundaryInterpolation``):
``edge-only`` (default, tag value 2): boundary edges are infinitely sharp creases, every
boundary vertex uses the crease rule (a + 6 v + b)/8, so the boundary limit curve is the
uniform cubic B-spline of the boundary vertices; ``edge-and-corner`` (tag value 1): as
edge-only, but vertices with a single face are infinitely sharp corners (v' = v).

Creases follow OpenSubdiv's Catmull-Clark rules with the uniform creasing method
(``Sdc::Crease``, ``Sdc::Scheme``): an edge of sharpness s (``sharpness``, 0-based vertex
pairs) is refined with the crease rule (midpoint) while s >= 1 and blends the smooth and
crease rules with weight s when 0 < s < 1; its two child edges get s - 1 (s >= 10 is
infinitely sharp and stays so). A vertex's rule comes from its sharp edges (boundary edges
count as infinitely sharp) and its own sharpness (``corner_sharpness``, the ``corner`` tag):
none or one sharp edge smooth, two a crease ((a + 6 v + b) / 8 with a, b the crease
neighbours), more, or a sharp vertex, a corner (v' = v). Where the rule of the child vertex
differs from the parent's, the two masks are blended with the parent's fractional weight
(the mean sharpness of the edges that become smooth, and the vertex's own, capped at 1).
Sharpness values are single precision, as OpenSubdiv keeps them.

Speed: the topology is also kept as arrays (``arrays``: half-edge twins, fans in the order
of ``fan``), and refinement, corner regularity and regular stencils are array operations
over a whole mesh (``_refine_arrays``, ``regularity_arrays``, ``regular_stencils``). They
give the same numbers to the bit as the face-by-face code: the refinement matrix gets each
row's entries in the same order (scipy sums repeated entries in that order), and stencil
terms are summed in column order from 0, as the sparse product does. The face-by-face code
stays for meshes under ``ARRAY_MIN_FACES`` faces and for cages that are not clean manifolds,
whose errors it names.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..errors import InputError

BOUNDARY_RULES = ("edge-only", "edge-and-corner")
#: sharpness at or above which an edge or vertex is infinitely sharp (OpenSubdiv's
#: ``Sdc::Crease::SHARPNESS_INFINITE``)
INFINITE = 10.0
#: meshes with fewer faces are refined and classified face by face (``QuadMesh.fast_arrays``)
ARRAY_MIN_FACES = 64


def decrement(s: float) -> float:
    """The sharpness of a child edge or vertex under the uniform creasing method, in single
    precision as OpenSubdiv computes it: s - 1 while s > 1, infinite stays infinite."""
    if s >= INFINITE:
        return INFINITE
    if s > 1.0:
        return float(np.float32(s) - np.float32(1.0))
    return 0.0


def is_semi_sharp(s: float) -> bool:
    return 0.0 < s < INFINITE


def unit_weights(H: np.ndarray) -> bool:
    """Whether homogeneous points (n, 4) all have weight exactly 1 (a polynomial cage's):
    then so has every point a subdivision makes of them, exactly (its rows sum to 1)."""
    return H.shape[-1] == 4 and bool(np.all(H[..., 3] == 1.0))


def refined_points(R, H: np.ndarray) -> np.ndarray:
    """``R @ H``: homogeneous points (n, 4) through a refinement ``R`` (QuadMesh.refine), with
    the weights kept exactly 1 where all of H's are (:func:`unit_weights`). Computed, they
    are 1 only up to the rounding of the sums (the Fusion mold's cage, refined once for its
    faces with two irregular corners: 1 - 1e-16, which made 8 of its 32 patches rational:
    ``Patch._polynomial``)."""
    out = np.asarray(R @ H, dtype=float)
    if unit_weights(H):
        out[:, 3] = 1.0
    return out


@dataclass
class QuadMesh:
    faces: np.ndarray                      # (F, 4) vertex indices
    n_vertices: int
    boundary_rule: str = "edge-only"
    source: str | None = None              # file, for error messages
    face_lines: np.ndarray | None = None   # (F,) 1-based line of each face in the source file
    #: crease sharpness of interior edges, (a, b) with a < b -> s > 0 (single-precision values)
    sharpness: dict | None = None
    #: vertex sharpness (OpenSubdiv's ``corner`` tag), v -> s > 0
    corner_sharpness: dict | None = None
    _edges: dict = field(default=None, init=False, repr=False)
    _fans: list = field(default=None, init=False, repr=False)
    _arr: dict = field(default=None, init=False, repr=False)

    def __post_init__(self):
        self.faces = np.asarray(self.faces, dtype=int).reshape(-1, 4)
        if self.boundary_rule not in BOUNDARY_RULES:
            raise InputError(f"unknown boundary rule {self.boundary_rule!r}", path=self.source)

    # -- naming ---------------------------------------------------------------------------
    def face_name(self, f: int) -> str:
        line = f" (line {int(self.face_lines[f])})" if self.face_lines is not None else ""
        return f"face {f + 1}{line}"

    def face_line(self, f: int) -> int | None:
        """The file line of face f, when the cage came from a file."""
        return int(self.face_lines[f]) if self.face_lines is not None else None

    @staticmethod
    def vertex_name(v: int) -> str:
        return f"vertex {v + 1}"

    # -- topology -------------------------------------------------------------------------
    @property
    def edges(self) -> dict:
        """Directed edge (a, b) -> (face, local edge k) with face[k] = a, face[k+1] = b."""
        if self._edges is None:
            self._build_edges()
        return self._edges

    def _build_edges(self):
        t = self.fast_arrays()
        if t is not None:
            self._edges = dict(zip(zip(t["a"].tolist(), t["b"].tolist()),
                                   zip(t["hf"].tolist(), t["hk"].tolist())))
            return
        self._build_edges_checked()

    def _build_edges_checked(self):
        """The directed-edge map built edge by edge, raising the error of the first bad edge."""
        edges = {}
        for f, quad in enumerate(self.faces):
            for k in range(4):
                a, b = int(quad[k]), int(quad[(k + 1) % 4])
                if a == b:
                    raise InputError(f"{self.face_name(f)} uses {self.vertex_name(a)} twice in a row",
                                     path=self.source, line=self.face_line(f))
                if (a, b) in edges:
                    g = edges[(a, b)][0]
                    if g == f:
                        raise InputError(f"{self.face_name(f)} repeats the edge {a + 1}-{b + 1}",
                                         path=self.source, line=self.face_line(f))
                    raise InputError(
                        f"edge {a + 1}-{b + 1} is used in the same direction by {self.face_name(g)} and "
                        f"{self.face_name(f)}: the cage is non-manifold or not consistently oriented",
                        path=self.source, line=self.face_line(f))
                edges[(a, b)] = (f, k)
        self._edges = edges

    def fast_arrays(self) -> dict | None:
        """``arrays()`` for meshes big enough to gain from them; None for small ones (Stam
        configurations, templates), where the face-by-face code is quicker."""
        if self._arr is None and len(self.faces) < ARRAY_MIN_FACES:
            return None
        return self.arrays()

    def arrays(self) -> dict | None:
        """The topology as arrays (cached), or None where the cage is not a clean manifold (a
        face repeating a vertex, a repeated directed edge, a non-manifold vertex: the Python
        walks of ``_build_edges_checked``/``_build_fans_walked`` then raise the errors).

        Half-edge (and corner) c = 4 f + k runs from a[c] = faces[f][k] to b[c] =
        faces[f][k+1]; twin[c] is the opposite half-edge or -1 on the boundary. fan_c lists the
        corners of each vertex in the order of ``fan`` (fan_ptr: CSR offsets), boundary[v]
        whether v is a boundary vertex."""
        if self._arr is not None:
            return self._arr or None
        self._arr = {}
        F, n = len(self.faces), self.n_vertices
        if F == 0 or self.faces.min() < 0 or self.faces.max() >= n:
            return None
        a = self.faces.reshape(-1)
        b = self.faces[:, (1, 2, 3, 0)].reshape(-1)
        srt = np.sort(self.faces, axis=1)
        if (srt[:, 1:] == srt[:, :-1]).any():
            return None                      # a face uses a vertex twice
        key = a.astype(np.int64) * n + b
        order = np.argsort(key, kind="stable")
        ks = key[order]
        if len(ks) > 1 and (ks[1:] == ks[:-1]).any():
            return None                      # a directed edge used twice
        rkey = b.astype(np.int64) * n + a
        pos = np.minimum(np.searchsorted(ks, rkey), len(ks) - 1)
        twin = np.where(ks[pos] == rkey, order[pos], -1)
        c = np.arange(4 * F)
        f4 = c - c % 4
        # around vertex a[c]: next turns across edge (v, prev), prev across (v, next)
        inc = f4 + (c + 3) % 4
        nxt = twin[inc]                                          # corner of the twin's face at v
        prv = np.where(twin >= 0, (twin - twin % 4) + (twin + 1) % 4, -1)
        cnt = np.bincount(a, minlength=n)
        heads = np.bincount(a[prv < 0], minlength=n)
        if (heads > 1).any():
            return None
        boundary = heads == 1
        # closed fans start at the vertex's first corner (lowest c): cut the cycle there
        fan_ptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(cnt, out=fan_ptr[1:])
        by_vertex = np.argsort(a, kind="stable")
        closed = np.nonzero(~boundary & (cnt > 0))[0]
        prv_cut = prv.copy()
        prv_cut[by_vertex[fan_ptr[closed]]] = -1
        # list ranking by pointer doubling: rank = steps back to the fan's first corner
        rank = (prv_cut >= 0).astype(np.int64)
        ptr = prv_cut.copy()
        for _ in range(64):
            live = ptr >= 0
            if not live.any():
                break
            rank[live] += rank[ptr[live]]
            ptr[live] = ptr[ptr[live]]
        else:
            return None
        fan_c = np.lexsort((rank, a))
        expect = np.arange(4 * F) - np.repeat(fan_ptr[:-1], cnt)
        if not np.array_equal(rank[fan_c], expect):
            return None                      # several fans (or cycles) around one vertex
        # the fan order must follow ``nxt`` from corner to corner, as the walk does
        fa = fan_c
        last = np.zeros(4 * F, dtype=bool)
        last[fan_ptr[1:][cnt > 0] - 1] = True
        if not np.array_equal(nxt[fa[:-1]][~last[:-1]], fa[1:][~last[:-1]]):
            return None
        pos_in_fan = np.empty(4 * F, dtype=np.int64)
        pos_in_fan[fan_c] = expect
        self._arr = dict(a=a, b=b, twin=twin, hf=c // 4, hk=c % 4, fan_c=fan_c, fan_ptr=fan_ptr,
                         boundary=boundary, valence=cnt, pos=pos_in_fan)
        return self._arr

    def is_boundary_edge(self, a: int, b: int) -> bool:
        return ((a, b) in self.edges) != ((b, a) in self.edges)

    def undirected_edges(self) -> list[tuple[int, int]]:
        """Each edge once, as (a, b) with a < b, in a fixed order."""
        seen = set()
        out = []
        for f, quad in enumerate(self.faces):
            for k in range(4):
                a, b = int(quad[k]), int(quad[(k + 1) % 4])
                key = (a, b) if a < b else (b, a)
                if key not in seen:
                    seen.add(key)
                    out.append(key)
        return out

    def fan(self, v: int) -> tuple[list[tuple[int, int]], bool]:
        """Faces around vertex v in rotational order, as (face, local corner), and whether v
        is a boundary vertex (then the fan runs from one boundary edge to the other)."""
        if self._fans is None:
            self._build_fans()
        return self._fans[v]

    def _next_around(self, f: int, k: int):
        """The face after (f, corner k) around the vertex, turning across edge (v, prev)."""
        quad = self.faces[f]
        return self.edges.get((int(quad[k]), int(quad[(k + 3) % 4])))

    def _prev_around(self, f: int, k: int):
        """The face before (f, corner k) around the vertex, turning across edge (v, next)."""
        quad = self.faces[f]
        hit = self.edges.get((int(quad[(k + 1) % 4]), int(quad[k])))
        return None if hit is None else (hit[0], (hit[1] + 1) % 4)

    def _build_fans(self):
        t = self.fast_arrays()
        if t is not None:
            fc, ptr, bnd = t["fan_c"].tolist(), t["fan_ptr"].tolist(), t["boundary"].tolist()
            pairs = [(c >> 2, c & 3) for c in fc]
            self._fans = [(pairs[ptr[v]:ptr[v + 1]], bnd[v]) for v in range(self.n_vertices)]
            return
        self._build_fans_walked()

    def _build_fans_walked(self):
        """Fans by walking around each vertex, raising the error of the first non-manifold one."""
        incident = [[] for _ in range(self.n_vertices)]
        for f, quad in enumerate(self.faces):
            for k in range(4):
                incident[int(quad[k])].append((f, k))
        fans = []
        for v in range(self.n_vertices):
            if not incident[v]:
                fans.append(([], False))
                continue
            start = incident[v][0]
            # walk backwards to a boundary (if any)
            cur, boundary, steps = start, False, 0
            while True:
                prv = self._prev_around(*cur)
                if prv is None:
                    boundary = True
                    break
                cur = prv
                steps += 1
                if cur == start or steps > len(incident[v]):
                    break
            first = cur if boundary else start
            order = [first]
            cur = first
            while True:
                nxt = self._next_around(*cur)
                if nxt is None or nxt == first:
                    break
                order.append(nxt)
                cur = nxt
                if len(order) > len(incident[v]):
                    break
            if len(order) != len(incident[v]):
                f = incident[v][0][0]
                raise InputError(
                    f"{self.vertex_name(v)} is non-manifold: its {len(incident[v])} faces do not form "
                    f"one fan (e.g. two surfaces touch at this vertex; one of them is "
                    f"{self.face_name(f)})", path=self.source, line=self.face_line(f))
            fans.append((order, boundary))
        self._fans = fans

    # -- creases --------------------------------------------------------------------------
    @property
    def creased(self) -> bool:
        return bool(self.sharpness) or bool(self.corner_sharpness)

    def edge_sharpness(self, a: int, b: int) -> float:
        """Sharpness of edge a-b: boundary edges are infinitely sharp."""
        if self.is_boundary_edge(a, b):
            return INFINITE
        return (self.sharpness or {}).get((a, b) if a < b else (b, a), 0.0)

    def vertex_sharpness(self, v: int) -> float:
        """The vertex's own sharpness; a vertex with one face under the edge-and-corner
        rule is an infinitely sharp corner."""
        fan, boundary = self.fan(v)
        if boundary and len(fan) == 1 and self.boundary_rule == "edge-and-corner":
            return INFINITE
        return (self.corner_sharpness or {}).get(v, 0.0)

    def neighbours(self, v: int) -> list[int]:
        """Vertices at the other end of v's edges, in fan order (n + 1 of them on the
        boundary, from the leading to the trailing boundary edge)."""
        fan, boundary = self.fan(v)
        out = [int(self.faces[f][(k + 1) % 4]) for f, k in fan]
        if boundary and fan:
            f, k = fan[-1]
            out.append(int(self.faces[f][(k + 3) % 4]))
        return out

    def vertex_rule(self, v: int, child: bool = False) -> tuple[str, tuple]:
        """OpenSubdiv's rule of vertex v ("smooth", "crease" with the two crease neighbours,
        or "corner"), from the sharpness now or, with ``child``, after one refinement."""
        step = decrement if child else (lambda x: x)
        if step(self.vertex_sharpness(v)) > 0.0:
            return "corner", ()
        sharp = [w for w in self.neighbours(v) if step(self.edge_sharpness(v, w)) > 0.0]
        if len(sharp) > 2:
            return "corner", ()
        if len(sharp) == 2:
            return "crease", tuple(sharp)
        return "smooth", ()

    def _fractional_weight(self, v: int) -> float:
        """Weight of the parent rule where a vertex's rule changes (uniform creasing)."""
        return _fractional_weight(self.vertex_sharpness(v),
                                  [self.edge_sharpness(v, w) for w in self.neighbours(v)])

    def sectors(self, v: int) -> list[list[tuple[int, int]]]:
        """v's faces split into runs between infinitely sharp edges (and the boundary)."""
        fan, boundary = self.fan(v)
        if not fan:
            return []
        cuts = [j for j in range(len(fan))
                if self.edge_sharpness(v, int(self.faces[fan[j][0]][(fan[j][1] + 3) % 4])) >= INFINITE
                and (boundary is False or j < len(fan) - 1)]
        if not boundary:
            if not cuts:
                return [list(fan)]
            start = cuts[-1] + 1                  # a closed fan: start after the last cut
            fan = fan[start:] + fan[:start]
            cuts = [(j - start) % len(fan) for j in cuts]
        out, run = [], []
        for j, fk in enumerate(fan):
            run.append(fk)
            if j in cuts:
                out.append(run)
                run = []
        out.append(run)
        return [r for r in out if r]

    def sector_of(self, v: int, f: int) -> list[tuple[int, int]]:
        for run in self.sectors(v):
            if any(g == f for g, _ in run):
                return run
        raise KeyError((v, f))

    def has_semi_sharp_at(self, v: int) -> bool:
        """Whether v or one of its edges is semi-sharp (its rules still change)."""
        if is_semi_sharp(self.vertex_sharpness(v)):
            return True
        return any(is_semi_sharp(self.edge_sharpness(v, w)) for w in self.neighbours(v))

    def sharpness_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """``edge_sharpness`` of every half-edge (4F,) and ``vertex_sharpness`` of every vertex
        (n,), as arrays (cached; needs ``arrays()``)."""
        t = self._arr
        if "he_sharp" not in t:
            a, b, n = t["a"], t["b"], self.n_vertices
            hs = np.zeros(len(a))
            if self.sharpness:
                kv = np.array(list(self.sharpness), dtype=np.int64).reshape(-1, 2)
                keys = kv[:, 0] * n + kv[:, 1]
                vals = np.array(list(self.sharpness.values()), dtype=float)
                srt = np.argsort(keys)
                keys, vals = keys[srt], vals[srt]
                q = np.minimum(a, b).astype(np.int64) * n + np.maximum(a, b)
                pos = np.minimum(np.searchsorted(keys, q), len(keys) - 1)
                hit = keys[pos] == q
                hs[hit] = vals[pos[hit]]
            hs[t["twin"] < 0] = INFINITE
            vs = np.zeros(n)
            if self.corner_sharpness:
                vs[list(self.corner_sharpness)] = list(self.corner_sharpness.values())
            if self.boundary_rule == "edge-and-corner":
                vs[t["boundary"] & (t["valence"] == 1)] = INFINITE
            t["he_sharp"], t["v_sharp"] = hs, vs
        return t["he_sharp"], t["v_sharp"]

    def regularity_arrays(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(regular, semi): ``is_regular_in`` of every corner c = 4 f + k (4F,) and
        ``has_semi_sharp_at`` of every vertex (n,), as arrays; None where ``fast_arrays()`` is."""
        t = self.fast_arrays()
        if t is None:
            return None
        if "regular" in t:
            return t["regular"], t["semi"]
        hs, vs = self.sharpness_arrays()
        a, n = t["a"], self.n_vertices
        semi_e = (hs > 0.0) & (hs < INFINITE)
        semi = ((vs > 0.0) & (vs < INFINITE)) | (np.bincount(a, weights=semi_e, minlength=n) > 0)
        bnd, val = t["boundary"], t["valence"]
        # sharp edges at v: its outgoing half-edges, and the incoming boundary edge
        nsharp = np.bincount(a, weights=hs > 0.0, minlength=n).astype(np.int64) + bnd
        kind = np.where(vs > 0.0, 2, np.where(nsharp > 2, 2, np.where(nsharp == 2, 1, 0)))
        # sectors: fans cut after corners whose edge to the previous vertex is infinitely sharp
        fc, ptr = t["fan_c"], t["fan_ptr"]
        inc = fc - fc % 4 + (fc + 3) % 4
        cut = (hs[inc] >= INFINITE).astype(np.int64)
        av = a[fc]
        ends = ptr[1:][val > 0] - 1
        cut[ends[bnd[val > 0]]] = 0                # a boundary fan's last corner ends it anyway
        cs = np.cumsum(cut) - cut                  # cuts before each corner
        base = np.zeros(n, dtype=np.int64)
        base[val > 0] = cs[ptr[:-1][val > 0]]
        sid = cs - base[av]
        ncut = np.bincount(av, weights=cut, minlength=n).astype(np.int64)
        wrap = ~bnd[av] & (ncut[av] > 0)
        sid[wrap] %= ncut[av][wrap]
        gid = ptr[:-1][av] + sid
        size = np.bincount(gid, minlength=len(fc))[gid]
        regular = np.zeros(len(a), dtype=bool)
        k = kind[av]
        reg_fan = np.where(k == 0, ~bnd[av] & (val[av] == 4) & (nsharp[av] == 0),
                           size == np.where(k == 1, 2, 1))
        regular[fc] = reg_fan & ~semi[av]
        t["regular"], t["semi"] = regular, semi
        return regular, semi

    def is_regular_in(self, v: int, f: int) -> bool:
        """Whether the limit surface of face f near its corner v is a plain B-spline (with
        phantom points beyond infinitely sharp creases and boundaries): interior valence 4
        without sharp edges, a straight crease or boundary (two faces on f's side) or a
        corner with f alone in its sector."""
        if self.has_semi_sharp_at(v):
            return False
        rule, _ = self.vertex_rule(v)
        fan, boundary = self.fan(v)
        if rule == "smooth":
            return not boundary and len(fan) == 4 and all(
                self.edge_sharpness(v, w) <= 0.0 for w in self.neighbours(v))
        n = len(self.sector_of(v, f))
        return n == (2 if rule == "crease" else 1)

    def valence(self, v: int) -> int:
        """Number of faces around v."""
        return len(self.fan(v)[0])

    def is_regular_vertex(self, v: int) -> bool:
        """Whether the limit surface near v is a plain (boundary) B-spline in every face
        around it: interior valence 4, boundary with 2 faces, a 1-face corner under the
        edge-and-corner rule, a straight infinitely sharp crease (``is_regular_in``)."""
        fan, _ = self.fan(v)
        if not self.creased:
            boundary = self.fan(v)[1]
            if not boundary:
                return len(fan) == 4
            if len(fan) == 2:
                return True
            return len(fan) == 1 and self.boundary_rule == "edge-and-corner"
        return all(self.is_regular_in(v, f) for f, _ in fan)

    def is_layout_vertex(self, v: int) -> bool:
        """Whether v starts patch boundaries: extraordinary points, boundary corners, and
        where infinitely sharp creases end, meet or turn."""
        fan, boundary = self.fan(v)
        if (len(fan) != 2) if boundary else (len(fan) != 4):
            return True
        if not self.sharpness and not self.corner_sharpness:
            return False
        if self.vertex_sharpness(v) >= INFINITE and not (boundary and len(fan) == 1):
            return True
        nb = self.neighbours(v)
        sharp = [j for j, w in enumerate(nb) if not self.is_boundary_edge(v, w)
                 and self.edge_sharpness(v, w) >= INFINITE]
        if not sharp:
            return False
        if boundary:
            return True                      # a crease reaching the boundary
        return not (len(sharp) == 2 and (sharp[1] - sharp[0]) == 2)

    def crease_edges(self) -> set:
        """Interior edges (a < b) that are infinitely sharp: patch boundaries."""
        return {e for e, s in (self.sharpness or {}).items() if s >= INFINITE
                and not self.is_boundary_edge(*e)}

    def validate(self, points: np.ndarray | None = None):
        """Raise InputError for what the kernel cannot evaluate, naming the face or vertex."""
        if len(self.faces) == 0:
            raise InputError("the cage has no faces", path=self.source)
        if self.faces.min() < 0 or self.faces.max() >= self.n_vertices:
            f = int(np.nonzero((self.faces < 0).any(1) | (self.faces >= self.n_vertices).any(1))[0][0])
            raise InputError(f"{self.face_name(f)} refers to a vertex that does not exist", path=self.source,
                             line=self.face_line(f))
        if points is not None:
            bad = ~np.isfinite(points).all(axis=1)
            if bad.any():
                v = int(np.nonzero(bad)[0][0])
                raise InputError(f"{self.vertex_name(v)} has a coordinate that is not a number",
                                 path=self.source)
            if points.shape[1] == 4 and np.any(points[:, 3] <= 0):
                v = int(np.nonzero(points[:, 3] <= 0)[0][0])
                raise InputError(f"{self.vertex_name(v)} has weight {points[v, 3]:g}: weights must "
                                 f"be positive", path=self.source)
        self.edges  # noqa: B018  (orientation and manifold edges)
        used = np.zeros(self.n_vertices, bool)
        used[self.faces.reshape(-1)] = True
        if not used.all():
            v = int(np.nonzero(~used)[0][0])
            raise InputError(f"{self.vertex_name(v)} is not used by any face "
                             f"({int((~used).sum())} unused vertices)", path=self.source)
        for v in range(self.n_vertices):
            self.fan(v)

    # -- refinement -----------------------------------------------------------------------
    def refine(self, cut_edges: set | None = None, tainted_in: np.ndarray | None = None
               ) -> tuple["QuadMesh", sp.csr_matrix, np.ndarray]:
        """One Catmull-Clark step (with OpenSubdiv's crease rules): (child mesh, R, tainted).

        New vertex numbering: vertex points keep the old indices, then one edge point per
        edge of ``undirected_edges()``, then one face point per face. Child face 4 f + k is
        (V(v_k), E(v_k, v_k+1), F(f), E(v_k-1, v_k)) for face f = (v_0..v_3), so children keep
        the parent's orientation and child 4 f + k has its corner 0 at the parent's corner k.
        ``cut_edges``: edges (a, b) with a < b where this mesh was cut out of a bigger one;
        new points whose rule would need the missing faces are flagged in ``tainted``, and so
        are points made from vertices flagged in ``tainted_in``.
        """
        if self.fast_arrays() is not None:
            return self._refine_arrays(cut_edges, tainted_in)
        cut_edges = cut_edges or set()
        nv = self.n_vertices
        und = self.undirected_edges()
        eid = {e: i for i, e in enumerate(und)}
        ne, nf = len(und), len(self.faces)
        rows, cols, vals = [], [], []

        def put(r, c, w):
            rows.append(r)
            cols.append(c)
            vals.append(w)

        # face points
        for f, quad in enumerate(self.faces):
            for v in quad:
                put(nv + ne + f, int(v), 0.25)
        tainted = np.zeros(nv + ne + nf, dtype=bool)
        # edge points: smooth (a + b + F1 + F2) / 4, crease (a + b) / 2, blended for 0 < s < 1
        for i, (a, b) in enumerate(und):
            r = nv + i
            fa = self.edges.get((a, b))
            fb = self.edges.get((b, a))
            if (a, b) in cut_edges:
                tainted[r] = True
            sharp = INFINITE if (fa is None or fb is None) else (self.sharpness or {}).get((a, b), 0.0)
            if sharp >= 1.0:
                put(r, a, 0.5)
                put(r, b, 0.5)
                continue
            put(r, a, 0.25 + 0.25 * sharp)
            put(r, b, 0.25 + 0.25 * sharp)
            for f, _ in (fa, fb):
                for v in self.faces[f]:
                    put(r, int(v), 0.0625 * (1.0 - sharp))
        # vertex points
        for v in range(nv):
            fan, boundary = self.fan(v)
            if not fan:
                continue
            nbrs = self.neighbours(v)
            if any(((v, w) if v < w else (w, v)) in cut_edges for w in nbrs):
                tainted[v] = True
            if not self.creased:                     # the common case: boundary rules only
                if boundary:
                    rule = (("corner", ()) if len(fan) == 1 and self.boundary_rule == "edge-and-corner"
                            else ("crease", (nbrs[0], nbrs[-1])))
                else:
                    rule = ("smooth", ())
                self._put_vertex_mask(put, v, fan, nbrs, rule, 1.0)
                continue
            rule = self.vertex_rule(v)
            child = self.vertex_rule(v, child=True)
            if rule[0] == "smooth" or child[0] == rule[0]:
                self._put_vertex_mask(put, v, fan, nbrs, rule, 1.0)
                continue
            w = self._fractional_weight(v)
            self._put_vertex_mask(put, v, fan, nbrs, rule, w)
            self._put_vertex_mask(put, v, fan, nbrs, child, 1.0 - w)
        R = sp.csr_matrix((vals, (rows, cols)), shape=(nv + ne + nf, nv))
        R.sum_duplicates()
        if tainted_in is not None and tainted_in.any():
            tainted |= (abs(R) @ tainted_in.astype(float)) > 0
        child = np.empty((4 * nf, 4), dtype=int)
        for f, quad in enumerate(self.faces):
            for k in range(4):
                a, b, c = int(quad[k]), int(quad[(k + 1) % 4]), int(quad[(k + 3) % 4])
                child[4 * f + k] = (a, nv + eid[(a, b) if a < b else (b, a)], nv + ne + f,
                                    nv + eid[(c, a) if c < a else (a, c)])
        lines = None if self.face_lines is None else np.repeat(self.face_lines, 4)
        sharpness, corners = None, None
        if self.sharpness:
            sharpness = {}
            for (a, b), s_ in self.sharpness.items():
                c_ = decrement(s_)
                if c_ > 0.0 and (a, b) in eid:
                    e = nv + eid[(a, b)]
                    sharpness[(a, e)] = c_
                    sharpness[(b, e)] = c_
        if self.corner_sharpness:
            corners = {v: decrement(s_) for v, s_ in self.corner_sharpness.items() if decrement(s_) > 0.0}
        mesh = QuadMesh(child, nv + ne + nf, self.boundary_rule, self.source, lines, sharpness or None,
                        corners or None)
        return mesh, R, tainted

    def _refine_arrays(self, cut_edges: set | None, tainted_in: np.ndarray | None
                       ) -> tuple["QuadMesh", sp.csr_matrix, np.ndarray]:
        """``refine`` with the topology as arrays: the same matrix entry for entry, each row's
        entries in the same order (so scipy sums repeated entries alike), smooth vertices'
        masks written as arrays and the few crease and corner vertices one by one."""
        t = self.arrays()
        nv, nf = self.n_vertices, len(self.faces)
        a, b, twin, Q = t["a"], t["b"], t["twin"], self.faces
        hc = np.arange(4 * nf)
        inc = hc - hc % 4 + (hc + 3) % 4                  # the half-edge into each corner
        lo = np.minimum(a, b).astype(np.int64)
        hi = np.maximum(a, b).astype(np.int64)
        key = lo * nv + hi
        uk, first, he_eid = np.unique(key, return_index=True, return_inverse=True)
        rank = np.empty(len(uk), dtype=np.int64)
        rank[np.argsort(first, kind="stable")] = np.arange(len(uk))
        he_eid = rank[he_eid]                     # each half-edge's edge, in undirected_edges() order
        ec = np.sort(first)                               # each edge's first half-edge
        ne = len(ec)
        ea, eb = lo[ec], hi[ec]
        rows, cols, vals = [], [], []
        # face points
        rows.append(np.repeat(nv + ne + np.arange(nf), 4))
        cols.append(Q.reshape(-1))
        vals.append(np.full(4 * nf, 0.25))
        tainted = np.zeros(nv + ne + nf, dtype=bool)
        cut_he = np.zeros(4 * nf, dtype=bool)
        if cut_edges:
            ck = np.array([x * nv + y for x, y in cut_edges], dtype=np.int64)
            cut_he = np.isin(key, ck)
            tainted[nv:nv + ne] = cut_he[ec]
        # edge points: smooth (a + b + F1 + F2) / 4, crease (a + b) / 2, blended for 0 < s < 1
        hs, _ = self.sharpness_arrays()
        sharp = hs[ec]
        hard = sharp >= 1.0
        r_e = nv + np.arange(ne)
        h1 = np.where(a[ec] == ea, ec, twin[ec])          # half-edge ea -> eb, and eb -> ea
        h2 = np.where(a[ec] == ea, twin[ec], ec)
        soft = np.nonzero(~hard)[0]
        wab = np.where(hard, 0.5, 0.25 + 0.25 * sharp)
        wf = 0.0625 * (1.0 - sharp[soft])
        Fs = np.concatenate([Q[h1[soft] // 4], Q[h2[soft] // 4]], axis=1)        # (m, 8)
        nrow = np.where(hard, 2, 10)
        start = np.zeros(ne, dtype=np.int64)
        np.cumsum(nrow[:-1], out=start[1:])
        er = np.empty(int(nrow.sum()), dtype=np.int64)
        ecol = np.empty_like(er)
        ev = np.empty(len(er))
        er[start], ecol[start], ev[start] = r_e, ea, wab
        er[start + 1], ecol[start + 1], ev[start + 1] = r_e, eb, wab
        pos = start[soft][:, None] + 2 + np.arange(8)
        er[pos], ecol[pos], ev[pos] = r_e[soft][:, None], Fs, wf[:, None]
        rows.append(er)
        cols.append(ecol)
        vals.append(ev)
        # vertex points: smooth vertices by arrays, the rest as ``refine`` does them
        fc, ptr, val, bnd = t["fan_c"], t["fan_ptr"], t["valence"], t["boundary"]
        if cut_edges:
            tv = np.zeros(nv, dtype=bool)
            tv[a[cut_he]] = True
            tv[b[cut_he]] = True
            tainted[:nv] |= tv
        if self.creased:
            _, vs = self.sharpness_arrays()
            nsharp = np.bincount(a, weights=hs > 0.0, minlength=nv).astype(np.int64) + bnd
            smooth = (vs <= 0.0) & (nsharp < 2) & (val > 0)
        else:
            smooth = ~bnd & (val > 0)
        sv = np.nonzero(smooth)[0]
        n = val[sv].astype(float)
        nn = n * n
        cnt = val[sv]
        corners = fc[np.repeat(ptr[sv] - np.cumsum(cnt) + cnt, cnt) + np.arange(int(cnt.sum()))]
        # per row: v, then its n neighbours, then the 4 n vertices of its faces
        rl = 1 + 5 * cnt
        vstart = np.zeros(len(sv), dtype=np.int64)
        np.cumsum(rl[:-1], out=vstart[1:])
        m = int(rl.sum())
        vr = np.repeat(sv, rl)
        vcol = np.empty(m, dtype=np.int64)
        vval = np.empty(m)
        vcol[vstart], vval[vstart] = sv, (n - 2.0) / n
        grp = np.repeat(np.arange(len(sv)), cnt)                       # vertex of each fan corner
        j = np.arange(len(corners)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        pn = vstart[grp] + 1 + j
        vcol[pn], vval[pn] = b[corners], (1.0 / nn)[grp]
        pf = (vstart[grp] + 1 + cnt[grp] + 4 * j)[:, None] + np.arange(4)
        vcol[pf], vval[pf] = Q[corners // 4], (0.25 / nn)[grp][:, None]
        rows.append(vr)
        cols.append(vcol)
        vals.append(vval)
        prow, pcol, pval = [], [], []

        def put(r, c, w):
            prow.append(r)
            pcol.append(c)
            pval.append(w)

        # crease and corner vertices whose rule stays: one mask each, as arrays
        rest = np.nonzero(~smooth & (val > 0))[0]
        L = val + bnd
        nb_ptr = np.zeros(nv + 1, dtype=np.int64)
        np.cumsum(L, out=nb_ptr[1:])
        nb = np.empty(int(nb_ptr[-1]), dtype=np.int64)         # ``neighbours`` of every vertex
        nb_s = np.full(len(nb), INFINITE)                       # and the sharpness of each edge
        fv = a[fc]
        fj = np.arange(len(fc)) - ptr[fv]
        nb[nb_ptr[fv] + fj] = b[fc]
        ends_at = np.nonzero(bnd & (val > 0))[0]
        nb[nb_ptr[ends_at] + val[ends_at]] = a[inc[fc[ptr[ends_at + 1] - 1]]]
        if self.creased:
            nb_s[nb_ptr[fv] + fj] = hs[fc]
            dec = _decrement_array
            owner = np.repeat(np.arange(nv), L)

            def rule_kind(vsx, nsx):
                sharp = nsx > 0.0
                count = np.bincount(owner, weights=sharp, minlength=nv)
                kind = np.where(vsx > 0.0, 2, np.where(count > 2, 2, np.where(count == 2, 1, 0)))
                cum = np.cumsum(sharp) - np.repeat(np.concatenate([[0], np.cumsum(sharp)])[nb_ptr[:-1]], L)
                e0 = np.zeros(nv, dtype=np.int64)
                e1 = np.zeros(nv, dtype=np.int64)
                e0[owner[sharp & (cum == 1)]] = nb[sharp & (cum == 1)]
                e1[owner[sharp & (cum == 2)]] = nb[sharp & (cum == 2)]
                return kind, e0, e1

            kind, e0, e1 = rule_kind(vs, nb_s)
            ckind, c0, c1 = rule_kind(dec(vs), dec(nb_s))
            stays = rest[ckind[rest] == kind[rest]]
            blend = rest[ckind[rest] != kind[rest]]
        else:
            kind = np.where(val == 1, 2 if self.boundary_rule == "edge-and-corner" else 1, 1)
            e0, e1 = nb[nb_ptr[:-1].clip(max=len(nb) - 1)], nb[(nb_ptr[1:] - 1).clip(min=0)]
            stays, blend = rest, rest[:0]
        cv = stays[kind[stays] == 2]
        rows.append(cv)
        cols.append(cv)
        vals.append(np.ones(len(cv)))
        kv = stays[kind[stays] == 1]
        rows.append(np.repeat(kv, 3))
        cols.append(np.stack([kv, e0[kv], e1[kv]], axis=1).reshape(-1))
        vals.append(np.tile([0.75, 0.125, 0.125], len(kv)))
        names = ("smooth", "crease", "corner")
        for v in blend.tolist():                          # rules blended by the fractional weight
            fan = [(c >> 2, c & 3) for c in fc[ptr[v]:ptr[v + 1]].tolist()]
            nbrs = nb[nb_ptr[v]:nb_ptr[v + 1]].tolist()
            rule = (names[kind[v]], (int(e0[v]), int(e1[v])) if kind[v] == 1 else ())
            child = (names[ckind[v]], (int(c0[v]), int(c1[v])) if ckind[v] == 1 else ())
            w = _fractional_weight(float(vs[v]), nb_s[nb_ptr[v]:nb_ptr[v + 1]].tolist())
            self._put_vertex_mask(put, v, fan, nbrs, rule, w)
            self._put_vertex_mask(put, v, fan, nbrs, child, 1.0 - w)
        rows.append(np.array(prow, dtype=np.int64))
        cols.append(np.array(pcol, dtype=np.int64))
        vals.append(np.array(pval, dtype=float))
        R = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(nv + ne + nf, nv))
        R.sum_duplicates()
        if tainted_in is not None and tainted_in.any():
            tainted |= (abs(R) @ tainted_in.astype(float)) > 0
        child = np.stack([a, nv + he_eid, nv + ne + hc // 4, nv + he_eid[inc]], axis=1)
        lines = None if self.face_lines is None else np.repeat(self.face_lines, 4)
        sharpness, corners_ = None, None
        if self.sharpness:
            eid = dict(zip(zip(ea.tolist(), eb.tolist()), range(ne)))
            sharpness = {}
            for (x, y), s_ in self.sharpness.items():
                c_ = decrement(s_)
                if c_ > 0.0 and (x, y) in eid:
                    e = nv + eid[(x, y)]
                    sharpness[(x, e)] = c_
                    sharpness[(y, e)] = c_
        if self.corner_sharpness:
            corners_ = {v: decrement(s_) for v, s_ in self.corner_sharpness.items() if decrement(s_) > 0.0}
        mesh = QuadMesh(child, nv + ne + nf, self.boundary_rule, self.source, lines, sharpness or None,
                        corners_ or None)
        return mesh, R, tainted

    def _put_vertex_mask(self, put, v, fan, nbrs, rule, weight):
        """Add ``weight`` times the mask of ``rule`` for vertex v (OpenSubdiv's Catmark
        masks: smooth (n-2)/n v + sum of neighbours and face points over n^2, crease
        3/4 v + 1/8 of each crease neighbour, corner v)."""
        if weight == 0.0:
            return
        kind, ends = rule
        if kind == "corner":
            put(v, v, weight)
        elif kind == "crease":
            put(v, v, 0.75 * weight)
            put(v, ends[0], 0.125 * weight)
            put(v, ends[1], 0.125 * weight)
        else:
            n = len(fan)
            put(v, v, weight * (n - 2.0) / n)
            for w in nbrs[:n]:
                put(v, w, weight / (n * n))
            for f, _ in fan:
                for w in self.faces[f]:
                    put(v, int(w), weight * 0.25 / (n * n))

    # -- stencils -------------------------------------------------------------------------
    def regular_stencil(self, f: int, k0: int, cut_edges: set | None = None) -> sp.csr_matrix:
        """The 16 B-spline control points of face f (all corners regular) as rows of a sparse
        matrix on the mesh vertices, grid index j*4+i with i along corner k0 -> k0+1 and j
        along k0 -> k0-1. Missing points beyond the boundary are the phantom points
        2 P_edge - P_inner (OpenSubdiv's regular boundary and corner patches), and so are
        points beyond infinitely sharp creases, which bound the patch like a boundary. ``cut_edges``
        (a < b) mark where this mesh was cut out of a bigger one: no phantom may stand there."""
        grid = {}

        def place(face, rot, ci, cj):
            # face corner (rot + m) sits at cell corner m of cell (ci, cj)
            for m, (di, dj) in enumerate(((0, 0), (1, 0), (1, 1), (0, 1))):
                key = (ci + di, cj + dj)
                v = int(self.faces[face][(rot + m) % 4])
                if grid.setdefault(key, v) != v:
                    raise InputError(f"{self.face_name(f)}: its neighbourhood folds onto itself "
                                     f"(cannot form a regular 4x4 stencil)", path=self.source)

        cells = {(1, 1): (f, k0)}
        place(f, k0, 1, 1)
        queue = [(1, 1)]
        steps = ((0, -1), (1, 0), (0, 1), (-1, 0))       # across cell edge m
        while queue:
            ci, cj = queue.pop(0)
            face, rot = cells[(ci, cj)]
            for m, (di, dj) in enumerate(steps):
                ni, nj = ci + di, cj + dj
                if not (0 <= ni <= 2 and 0 <= nj <= 2) or (ni, nj) in cells:
                    continue
                k = (rot + m) % 4
                a, b = int(self.faces[face][k]), int(self.faces[face][(k + 1) % 4])
                hit = self.edges.get((b, a))
                if hit is not None and self.sharpness and self.edge_sharpness(a, b) >= INFINITE:
                    hit = None                   # an infinitely sharp crease: a boundary here
                if hit is None:
                    if cut_edges and (min(a, b), max(a, b)) in cut_edges:
                        raise AssertionError("stencil reaches the cut of a local neighbourhood")
                    continue
                g, kk = hit
                rot_g = (kk - (m + 2)) % 4
                cells[(ni, nj)] = (g, rot_g)
                place(g, rot_g, ni, nj)
                queue.append((ni, nj))
        rows = {}
        for key, v in grid.items():
            rows[key] = {v: 1.0}
        # The boundary lines of a regular configuration are sides of F whose neighbouring
        # cell is missing; phantoms are extrapolated across those lines only.
        _extrapolate_phantoms(rows, {0: (1, 0) not in cells, 3: (1, 2) not in cells},
                              {0: (0, 1) not in cells, 3: (2, 1) not in cells})
        if len(rows) != 16:
            raise InputError(f"{self.face_name(f)}: cannot form its 4x4 stencil (irregular "
                             f"neighbourhood)", path=self.source)
        data, ri, ci_ = [], [], []
        for (i, j), combo in rows.items():
            for w, x in combo.items():
                ri.append(j * 4 + i)
                ci_.append(w)
                data.append(x)
        M = sp.csr_matrix((data, (ri, ci_)), shape=(16, self.n_vertices))
        M.sum_duplicates()
        return M

    def regular_stencils(self, f: np.ndarray, k0: np.ndarray):
        """``regular_stencil`` of many faces at once, as (cols, weights, ok): (n, 16, 4) arrays
        whose row r lists the terms of stencil row r in increasing column order (padding:
        weight 0 after them), so that summing weight * point in that order from 0 repeats the
        sparse product bit for bit (``stencil_points``). ``ok`` is False for faces whose
        neighbourhood is not a plain 3 x 3 grid of cells (folds, cells reached round a
        corner, one vertex twice in a row's terms): ``regular_stencil`` handles those,
        errors included. Needs ``arrays()``."""
        t = self.arrays()
        hs, _ = self.sharpness_arrays()
        twin, Q = t["twin"], self.faces
        f = np.asarray(f, dtype=np.int64).reshape(-1)
        N = len(f)
        face = np.full((3, 3, N), -1, dtype=np.int64)
        rot = np.zeros((3, 3, N), dtype=np.int64)
        face[1, 1], rot[1, 1] = f, np.asarray(k0, dtype=np.int64).reshape(-1)

        def across(ci, cj, m):
            fc = face[ci, cj]
            h = 4 * np.maximum(fc, 0) + (rot[ci, cj] + m) % 4
            tw = twin[h]
            ok = (fc >= 0) & (tw >= 0) & (hs[h] < INFINITE)
            return ok, tw // 4, (tw % 4 - (m + 2)) % 4

        edge_cells = ((1, 0), (2, 1), (1, 2), (0, 1))
        bad = np.zeros(N, dtype=bool)
        for m, (ni, nj) in enumerate(edge_cells):
            ok, g, rg = across(1, 1, m)
            face[ni, nj] = np.where(ok, g, -1)
            rot[ni, nj] = np.where(ok, rg, 0)
        corner_cells = []
        for ci, cj in edge_cells:                      # the breadth-first order of regular_stencil
            for m, (di, dj) in enumerate(_STEPS):
                ni, nj = ci + di, cj + dj
                if not (0 <= ni <= 2 and 0 <= nj <= 2) or (ni, nj) == (1, 1) or (ni, nj) in edge_cells:
                    continue
                ok, g, rg = across(ci, cj, m)
                new = ok & (face[ni, nj] < 0)
                face[ni, nj] = np.where(new, g, face[ni, nj])
                rot[ni, nj] = np.where(new, rg, rot[ni, nj])
                if (ni, nj) not in corner_cells:
                    corner_cells.append((ni, nj))
        for ci, cj in corner_cells:                    # a second wave would reach missing edge cells
            for m, (di, dj) in enumerate(_STEPS):
                ni, nj = ci + di, cj + dj
                if (ni, nj) in edge_cells:
                    ok, _, _ = across(ci, cj, m)
                    bad |= ok & (face[ni, nj] < 0)
        V = np.full((4, 4, N), -1, dtype=np.int64)      # grid point (i, j)
        for ci in range(3):
            for cj in range(3):
                fc = face[ci, cj]
                there = fc >= 0
                for m, (di, dj) in enumerate(_OFFSETS):
                    v = np.where(there, Q[np.maximum(fc, 0), (rot[ci, cj] + m) % 4], -1)
                    cur = V[ci + di, cj + dj]
                    bad |= there & (cur >= 0) & (cur != v)
                    V[ci + di, cj + dj] = np.where(cur >= 0, cur, v)
        sides = np.stack([face[1, 0] < 0, face[1, 2] < 0, face[0, 1] < 0, face[2, 1] < 0])
        present = (V >= 0).transpose(1, 0, 2).reshape(16, N)          # grid index j*4+i
        code = ((present * (1 << np.arange(16))[:, None]).sum(0)
                + (sides * (1 << np.arange(16, 20))[:, None]).sum(0))
        Vf = V.transpose(1, 0, 2).reshape(16, N)
        cols = np.zeros((N, 16, 4), dtype=np.int64)
        wts = np.zeros((N, 16, 4))
        for c in np.unique(code):
            sel = np.nonzero(code == c)[0]
            pat = _phantom_pattern(int(c))
            if pat is None:
                bad[sel] = True
                continue
            gp, w = pat                                  # (16, 4) grid indices (-1: none), weights
            vid = np.where(gp[None] >= 0, Vf[:, sel][np.maximum(gp, 0)].transpose(2, 0, 1), -1)   # (n, 16, 4)
            real = vid >= 0
            srt = np.sort(np.where(real, vid, -1), axis=2)
            bad[sel] |= ((srt[:, :, 1:] == srt[:, :, :-1]) & (srt[:, :, 1:] >= 0)).any(axis=(1, 2))
            big = np.iinfo(np.int64).max
            order = np.argsort(np.where(real, vid, big), axis=2, kind="stable")
            cols[sel] = np.take_along_axis(np.where(real, vid, 0), order, axis=2)
            wts[sel] = np.take_along_axis(np.broadcast_to(w, vid.shape), order, axis=2)
        return cols, wts, ~bad

    @staticmethod
    def stencil_points(cols: np.ndarray, wts: np.ndarray, H: np.ndarray) -> np.ndarray:
        """Stencils (``regular_stencils``) applied to points H: (n, 16, d), summed term by term
        in column order from 0 as scipy's sparse product does."""
        out = np.zeros(cols.shape[:2] + H.shape[1:])
        for t in range(cols.shape[2]):
            out = out + wts[:, :, t, None] * H[cols[:, :, t]]
        return out

    def config(self, f: int, k: int) -> list[int]:
        """Vertices of the faces around the corners of face f, in a canonical order starting
        at corner k: the configuration whose subdivision is closed (Stam 1998's 2N+8 points
        for an interior extraordinary vertex)."""
        order, seen = [], set()
        for c in range(4):
            v = int(self.faces[f][(k + c) % 4])
            fan, _ = self.fan(v)
            start = fan.index(next(x for x in fan if x[0] == f))
            for g, kk in fan[start:] + fan[:start]:
                for m in range(4):
                    w = int(self.faces[g][(kk + m) % 4])
                    if w not in seen:
                        seen.add(w)
                        order.append(w)
        return order

    def neighbourhood_faces(self, f: int) -> list[int]:
        """Faces sharing a vertex with face f (f included), in a fixed order."""
        out, seen = [], set()
        for v in self.faces[f]:
            for g, _ in self.fan(int(v))[0]:
                if g not in seen:
                    seen.add(g)
                    out.append(g)
        return out


def _fractional_weight(sv: float, edges: list) -> float:
    """The parent rule's weight for a vertex of sharpness sv with edges of these sharpnesses
    (in ``neighbours`` order): the mean of the sharpness values that drop to 0, capped at 1."""
    count, total = 0, 0.0
    if sv > 0.0 and decrement(sv) <= 0.0:
        count, total = 1, sv
    for s in edges:
        if 0.0 < s <= 1.0:
            count += 1
            total += s
    return 0.0 if count == 0 else min(1.0, total / count)


def _decrement_array(s: np.ndarray) -> np.ndarray:
    """``decrement`` of an array of sharpness values (the same single-precision steps)."""
    step = (s.astype(np.float32) - np.float32(1.0)).astype(float)
    return np.where(s >= INFINITE, INFINITE, np.where(s > 1.0, step, 0.0))


_STEPS = ((0, -1), (1, 0), (0, 1), (-1, 0))          # across cell edge m
_OFFSETS = ((0, 0), (1, 0), (1, 1), (0, 1))          # cell corner m


def _extrapolate_phantoms(rows: dict, jside: dict, iside: dict) -> None:
    """The missing rows of a 4 x 4 stencil (``rows``: grid point (i, j) -> {point: weight})
    as phantoms 2 p - q, extrapolated across the configuration's boundary lines only:
    ``jside``/``iside`` {0 or 3: True} for the rows (columns) j (i) beyond a boundary; rows
    first, then columns (the columns' phantoms may use the rows')."""
    def lin(p, q):   # 2 p - q
        out = {}
        for w, x in rows[p].items():
            out[w] = out.get(w, 0.0) + 2.0 * x
        for w, x in rows[q].items():
            out[w] = out.get(w, 0.0) - x
        return out

    for (i, j) in [(i, j) for j in range(4) for i in range(4)]:
        if (i, j) in rows or iside.get(i, False):
            continue
        if jside.get(j, False):
            dj = 1 if j == 0 else -1
            if (i, j + dj) in rows and (i, j + 2 * dj) in rows:
                rows[(i, j)] = lin((i, j + dj), (i, j + 2 * dj))
    for (i, j) in [(i, j) for j in range(4) for i in range(4)]:
        if (i, j) in rows or not iside.get(i, False):
            continue
        di = 1 if i == 0 else -1
        if (i + di, j) in rows and (i + 2 * di, j) in rows:
            rows[(i, j)] = lin((i + di, j), (i + 2 * di, j))


@functools.lru_cache(maxsize=None)
def _phantom_pattern(code: int):
    """The rows of ``regular_stencil`` for one pattern of present grid points (bits 0-15, grid
    index j*4+i) and missing side cells (bits 16-19: (1,0), (1,2), (0,1), (2,1)), in grid
    points: ((16, 4) grid indices, -1 for none; (16, 4) weights), or None if incomplete."""
    rows = {(i, j): {j * 4 + i: 1.0} for j in range(4) for i in range(4) if code >> (j * 4 + i) & 1}
    _extrapolate_phantoms(rows, {0: bool(code >> 16 & 1), 3: bool(code >> 17 & 1)},
                          {0: bool(code >> 18 & 1), 3: bool(code >> 19 & 1)})
    if len(rows) != 16 or max(len(r) for r in rows.values()) > 4:
        return None
    gp = np.full((16, 4), -1, dtype=np.int64)
    w = np.zeros((16, 4))
    for (i, j), combo in rows.items():
        for n, (g, x) in enumerate(combo.items()):
            gp[j * 4 + i, n], w[j * 4 + i, n] = g, x
    return gp, w
