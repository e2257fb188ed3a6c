"""Faces whose limit surface is neither a B-spline patch nor a single self-similar irregular
corner yet: resolved by local refinement.

Near a semi-sharp crease the subdivision rules change from one level to the next (the
sharpness drops by 1 per level, OpenSubdiv's uniform creasing), and a face may have two or
more irregular corners. Such a face is refined locally, level by level, until every piece of
it is either a regular patch (a bicubic B-spline, with phantom points beyond boundaries and
infinitely sharp creases: ``QuadMesh.regular_stencil``) or a face with one irregular corner
whose neighbourhood refines into itself (``eigen.scheme_for``, evaluated level by level by
``cells.LevelCells``). This is OpenSubdiv's feature-adaptive refinement, with exact patches
at every leaf instead of approximations.

Each level refines only the faces still unresolved and the two rings of faces around them
(the support every new point of their children needs); points computed from an incomplete
neighbourhood are flagged (``QuadMesh.refine``'s taint) and never used.

Each level's faces are classified together (``classify_many``: regularity, stationarity and
stencils as array operations on the level's mesh, the same numbers as ``classify`` face by
face). ``resolve(mesh, H, roots)`` returns the leaves; ``AdaptiveCells`` evaluates them: one cell
per root face, points located in its quadtree by one sorted search per level.
"""
from __future__ import annotations

import functools

import numpy as np

from ..errors import InputError
from .basis import BSPLINE_TO_BEZIER
from .cells import BezierCells, LevelCells
from .eigen import NotSelfSimilar, scheme_for
from .patch import rotation_map
from .quadmesh import QuadMesh, refined_points

#: ``patch.rotation_map``, remembered (it tests all eight square maps each call)
rotation_index = functools.lru_cache(maxsize=None)(rotation_map)
MAX_LEVEL = 20          # semi-sharp creases are resolved after ceil(s) < 10 levels
_OFFSET = ((0, 0), (1, 0), (1, 1), (0, 1))


def _corner_irregular(mesh: QuadMesh, f: int) -> list[int]:
    return [k for k in range(4) if not mesh.is_regular_in(int(mesh.faces[f][k]), f)]


def _stationary(mesh: QuadMesh, f: int) -> bool:
    """No semi-sharp edge or vertex among the faces around f's corners: the neighbourhood's
    rules no longer change under refinement."""
    for g in mesh.neighbourhood_faces(f):
        for v in mesh.faces[g]:
            if mesh.has_semi_sharp_at(int(v)):
                return False
    return True


def classify(mesh: QuadMesh, f: int, rot: int, tainted: np.ndarray | None = None):
    """A leaf for face f of ``mesh`` when it can be evaluated as it is: ("bezier", 16-point
    stencil) or ("stam", scheme, configuration, corner), else None. ``rot``: the face corner
    at the cell's corner 0."""
    irregular = _corner_irregular(mesh, f)
    if not irregular:
        stencil = mesh.regular_stencil(f, rot)
        if tainted is not None and tainted[stencil.indices].any():
            raise AssertionError("a regular stencil uses a point of an incomplete neighbourhood")
        return ("bezier", stencil)
    if len(irregular) == 1 and _stationary(mesh, f):
        try:
            scheme, cfg = scheme_for(mesh, f, irregular[0])
        except NotSelfSimilar:
            return None
        if tainted is not None and tainted[cfg].any():
            raise AssertionError("a configuration uses a point of an incomplete neighbourhood")
        return ("stam", scheme, cfg, irregular[0])
    return None


def classify_many(mesh: QuadMesh, faces, rots, H: np.ndarray, tainted: np.ndarray | None = None) -> list:
    """``classify`` of the faces ``faces`` (cell corner 0 at face corner ``rots``), all at once:
    per face None, ("bezier", its 16 B-spline points (16, d) from H) or ("stam", scheme,
    configuration, corner). Regularity, stationarity and stencils are array operations over
    the whole mesh (``QuadMesh.regularity_arrays``, ``regular_stencils``); the points are
    summed in the order of the sparse stencil's product, so they are the same to the bit."""
    faces = np.asarray(faces, dtype=np.int64).reshape(-1)
    rots = np.asarray(rots, dtype=np.int64).reshape(-1)
    arrays = mesh.regularity_arrays()
    if arrays is None:                               # not a clean manifold: the face-by-face path
        out = []
        for f, rot in zip(faces.tolist(), rots.tolist()):
            leaf = classify(mesh, f, rot, tainted)
            out.append(leaf if leaf is None or leaf[0] != "bezier" else ("bezier", leaf[1] @ H))
        return out
    regular, semi = arrays
    reg4 = regular.reshape(-1, 4)[faces]
    nirr = 4 - reg4.sum(axis=1)
    semi_f = semi[mesh.faces].any(axis=1)
    touch = np.bincount(mesh.faces.reshape(-1), weights=np.repeat(semi_f, 4),
                        minlength=mesh.n_vertices) > 0
    stationary = ~touch[mesh.faces[faces]].any(axis=1)
    out: list = [None] * len(faces)
    bez = np.nonzero(nirr == 0)[0]
    if len(bez):
        cols, wts, ok = mesh.regular_stencils(faces[bez], rots[bez])
        G = mesh.stencil_points(cols, wts, H)
        if tainted is not None and (tainted[cols] & (wts != 0.0))[ok].any():
            raise AssertionError("a regular stencil uses a point of an incomplete neighbourhood")
        for n, i in enumerate(bez.tolist()):
            if ok[n]:
                out[i] = ("bezier", G[n])
            else:
                stencil = mesh.regular_stencil(int(faces[i]), int(rots[i]))
                if tainted is not None and tainted[stencil.indices].any():
                    raise AssertionError("a regular stencil uses a point of an incomplete neighbourhood")
                out[i] = ("bezier", stencil @ H)
    for i in np.nonzero((nirr == 1) & stationary)[0].tolist():
        f = int(faces[i])
        k = int(np.nonzero(~reg4[i])[0][0])
        try:
            scheme, cfg = scheme_for(mesh, f, k)
        except NotSelfSimilar:
            continue
        if tainted is not None and tainted[cfg].any():
            raise AssertionError("a configuration uses a point of an incomplete neighbourhood")
        out[i] = ("stam", scheme, cfg, k)
    return out


def _ring(mesh: QuadMesh, faces, rings: int) -> list[int]:
    """The faces, then ``rings`` times the faces sharing a vertex with those so far, each
    face once, in the order of first meeting (``neighbourhood_faces`` face by face)."""
    t = mesh.fast_arrays()
    if t is None:
        return _ring_walked(mesh, faces, rings)
    out = np.array(list(dict.fromkeys(int(f) for f in faces)), dtype=np.int64)
    seen = np.zeros(len(mesh.faces), dtype=bool)
    seen[out] = True
    fc, ptr = t["fan_c"], t["fan_ptr"]
    for _ in range(rings):
        v = mesh.faces[out].reshape(-1)
        cnt = ptr[v + 1] - ptr[v]
        idx = np.repeat(ptr[v] - np.cumsum(cnt) + cnt, cnt) + np.arange(int(cnt.sum()))
        seq = fc[idx] // 4
        uniq, first = np.unique(seq, return_index=True)
        new = uniq[np.argsort(first, kind="stable")]
        new = new[~seen[new]]
        seen[new] = True
        out = np.concatenate([out, new])
    return out.tolist()


def _ring_walked(mesh: QuadMesh, faces, rings: int) -> list[int]:
    """``_ring`` face by face, for cages ``QuadMesh.arrays`` does not take."""
    out = list(dict.fromkeys(int(f) for f in faces))
    seen = set(out)
    for _ in range(rings):
        for f in list(out):
            for g in mesh.neighbourhood_faces(f):
                if g not in seen:
                    seen.add(g)
                    out.append(g)
    return out


def _submesh(mesh: QuadMesh, faces: list[int]):
    """The faces as a mesh of their own: (mesh, global vertex ids, cut edges). Edges where it
    was cut out look like boundaries in it; only points flagged by the refinement's taint
    depend on that, and only faces whose neighbourhood lies inside are classified."""
    t = mesh.fast_arrays()
    if t is None:
        return _submesh_walked(mesh, faces)
    faces = np.asarray(faces, dtype=np.int64)
    Qs = mesh.faces[faces]
    verts = np.unique(Qs)
    quads = np.searchsorted(verts, Qs)
    inside = np.zeros(len(mesh.faces), dtype=bool)
    inside[faces] = True
    h = (4 * faces[:, None] + np.arange(4)).reshape(-1)
    tw = t["twin"][h]
    hit = (tw >= 0) & ~inside[np.maximum(tw, 0) // 4]
    la = np.searchsorted(verts, t["a"][h[hit]])
    lb = np.searchsorted(verts, t["b"][h[hit]])
    cut = set(zip(np.minimum(la, lb).tolist(), np.maximum(la, lb).tolist()))
    used = np.zeros(mesh.n_vertices, dtype=bool)
    used[verts] = True
    sharp = None
    if mesh.sharpness:
        kv = np.array(list(mesh.sharpness), dtype=np.int64).reshape(-1, 2)
        keep = used[kv[:, 0]] & used[kv[:, 1]]
        lk = np.searchsorted(verts, kv[keep]).tolist()
        vals = [s for s, k in zip(mesh.sharpness.values(), keep.tolist()) if k]
        sharp = {(x, y): s for (x, y), s in zip(lk, vals)}
    corners = None
    if mesh.corner_sharpness:
        corners = {int(np.searchsorted(verts, v)): s for v, s in mesh.corner_sharpness.items() if used[v]}
    lines = None if mesh.face_lines is None else mesh.face_lines[faces]
    sub = QuadMesh(quads, len(verts), mesh.boundary_rule, mesh.source, lines, sharp or None, corners or None)
    return sub, verts, cut


def _submesh_walked(mesh: QuadMesh, faces: list[int]):
    """``_submesh`` face by face, for cages ``QuadMesh.arrays`` does not take."""
    verts = sorted({int(v) for f in faces for v in mesh.faces[f]})
    loc = {v: i for i, v in enumerate(verts)}
    quads = np.array([[loc[int(v)] for v in mesh.faces[f]] for f in faces])
    inside = set(faces)
    cut = set()
    for f in faces:
        q = mesh.faces[f]
        for k in range(4):
            a, b = int(q[k]), int(q[(k + 1) % 4])
            hit = mesh.edges.get((b, a))
            if hit is not None and hit[0] not in inside:
                la, lb = loc[a], loc[b]
                cut.add((min(la, lb), max(la, lb)))
    sharp = None
    if mesh.sharpness:
        sharp = {}
        for (a, b), s in mesh.sharpness.items():
            if a in loc and b in loc:
                la, lb = loc[a], loc[b]
                sharp[(min(la, lb), max(la, lb))] = s
    corners = None
    if mesh.corner_sharpness:
        corners = {loc[v]: s for v, s in mesh.corner_sharpness.items() if v in loc}
    lines = None if mesh.face_lines is None else mesh.face_lines[faces]
    sub = QuadMesh(quads, len(verts), mesh.boundary_rule, mesh.source, lines, sharp or None, corners or None)
    return sub, np.array(verts), cut


def resolve(mesh: QuadMesh, H: np.ndarray, roots: list[tuple[int, int]]) -> list[list]:
    """Leaves of the faces ``roots`` = [(face, rot)] of ``mesh`` (points ``H``, homogeneous):
    per root, a list of (level, i, j, leaf data) with data ("bezier", ctrl (4, 4, 4)) or
    ("stam", scheme, C0, map index); (i, j) is the leaf's square at that level in the root
    cell's frame."""
    leaves = [[] for _ in roots]
    # active items: (face in current mesh, root, level, i, j, rot)
    items = [(int(f), r, 0, 0, 0, int(rot)) for r, (f, rot) in enumerate(roots)]
    cur, Hc, tainted = mesh, H, np.zeros(mesh.n_vertices, dtype=bool)
    for level in range(MAX_LEVEL + 1):
        todo = []
        found = classify_many(cur, [t[0] for t in items], [t[5] for t in items], Hc, tainted)
        for (f, r, L, i, j, rot), leaf in zip(items, found):
            if leaf is None:
                todo.append((f, r, L, i, j, rot))
            elif leaf[0] == "bezier":
                G = leaf[1].reshape(4, 4, 4)
                leaves[r].append((L, i, j, ("bezier", np.einsum("aj,bi,jic->abc", BSPLINE_TO_BEZIER,
                                                                 BSPLINE_TO_BEZIER, G))))
            else:
                _, scheme, cfg, k = leaf
                leaves[r].append((L, i, j, ("stam", scheme, Hc[cfg], rotation_index((rot - k) % 4))))
        if not todo:
            return leaves
        if level == MAX_LEVEL:
            f = todo[0][0]
            raise InputError(f"the limit surface near {cur.face_name(f)} cannot be resolved in "
                             f"{MAX_LEVEL} refinements", path=mesh.source)
        region = _ring(cur, [t[0] for t in todo], 2)
        pos = {f: n for n, f in enumerate(region)}
        sub, verts, cut = _submesh(cur, region)
        child, R, child_tainted = sub.refine(cut, tainted[verts])
        Hc = refined_points(R, Hc[verts])
        tainted = child_tainted
        items = []
        for f, r, L, i, j, rot in todo:
            g = pos[f]
            for kk in range(4):
                m = (kk - rot) % 4
                di, dj = _OFFSET[m]
                items.append((4 * g + kk, r, L + 1, 2 * i + di, 2 * j + dj, (-m) % 4))
        cur = child
    raise AssertionError("unreachable")


class AdaptiveCells:
    """Cells resolved into quadtrees of leaves (``resolve``): cell c's leaves are squares
    [i, i+1] x [j, j+1] / 2^L of the cell, each a Bezier patch or a self-similar irregular
    corner evaluated level by level."""

    kind = "adaptive"

    def __init__(self, leaves: list[list]):
        keys, bez, stam, where = [], [], {}, []
        for c, cell in enumerate(leaves):
            for L, i, j, data in cell:
                keys.append(self._key(c, L, i, j))
                if data[0] == "bezier":
                    where.append((0, len(bez)))
                    bez.append(data[1])
                else:
                    _, scheme, C0, m = data
                    entry = stam.setdefault(id(scheme), (scheme, [], []))
                    where.append((1 + list(stam).index(id(scheme)), len(entry[1])))
                    entry[1].append(C0)
                    entry[2].append(m)
        order = np.argsort(keys)
        self.keys = np.asarray(keys, dtype=np.int64)[order]
        where = np.asarray(where, dtype=int).reshape(-1, 2)[order]
        self.group = where[:, 0]
        self.local = where[:, 1]
        self.groups = [BezierCells(np.array(bez)) if bez else None]
        for scheme, C0s, maps in stam.values():
            self.groups.append(LevelCells(scheme, np.array(C0s), np.array(maps)))
        self.ncell = len(leaves)
        self.max_level = max((L for cell in leaves for L, _, _, _ in cell), default=0)

    @staticmethod
    def _key(c, L, i, j):
        return (((int(c) * 64 + int(L)) << 48) | (int(i) << 24) | int(j))

    def __len__(self) -> int:
        return self.ncell

    def evaluate(self, idx: np.ndarray, a: np.ndarray, b: np.ndarray):
        n = len(a)
        leaf = np.full(n, -1)
        level = np.zeros(n, dtype=int)
        ii = np.zeros(n, dtype=np.int64)
        jj = np.zeros(n, dtype=np.int64)
        open_ = np.arange(n)
        for L in range(self.max_level + 1):
            if not len(open_):
                break
            scale = float(1 << L)
            i = np.clip(np.floor(a[open_] * scale), 0, scale - 1).astype(np.int64)
            j = np.clip(np.floor(b[open_] * scale), 0, scale - 1).astype(np.int64)
            key = ((idx[open_].astype(np.int64) * 64 + L) << 48) | (i << 24) | j
            pos = np.clip(np.searchsorted(self.keys, key), 0, len(self.keys) - 1)
            hit = self.keys[pos] == key
            rows = open_[hit]
            leaf[rows] = pos[hit]
            level[rows] = L
            ii[rows], jj[rows] = i[hit], j[hit]
            open_ = open_[~hit]
        if len(open_):
            raise AssertionError("a point outside every leaf of its cell")
        scale = np.ldexp(1.0, level)
        la = np.clip(a * scale - ii, 0.0, 1.0)
        lb = np.clip(b * scale - jj, 0.0, 1.0)
        H = np.empty((6, 4, n))
        at_vertex = np.zeros(n, dtype=bool)
        normal = None
        g_of = self.group[leaf]
        for g in np.unique(g_of):
            sel = np.nonzero(g_of == g)[0]
            loc = self.local[leaf[sel]]
            order = np.argsort(loc, kind="stable")
            sel = sel[order]
            Hg, atv, nrm = self.groups[g].evaluate(self.local[leaf[sel]], la[sel], lb[sel])
            H[:, :, sel] = Hg
            if atv is not None and atv.any():
                at_vertex[sel[atv]] = True
                if normal is None:
                    normal = np.zeros((n, 3))
                normal[sel[atv]] = nrm[atv]
        s = scale
        H[1] *= s
        H[2] *= s
        H[3] *= s * s
        H[4] *= s * s
        H[5] *= s * s
        return H, (at_vertex if at_vertex.any() else None), normal
