"""The patch graph the planner works on (shang2020 section 3.2) and per-patch preferences.

Pure queries over a :class:`~tsplcam.layout.layout.Layout`: the kind of link between every
pair of patches (boundary, corner, none) as one numpy matrix, and for every patch corner
the corners of other patches at the same node (where a step may hand over to the next).
"""
from __future__ import annotations

import hashlib

import numpy as np

from ..layout.layout import EDGE_CORNERS

NONE, CORNER, BOUNDARY = 0, 1, 2
KIND_NAMES = {NONE: None, CORNER: "corner", BOUNDARY: "boundary"}


class PatchGraph:
    """Link kinds and hand-over corners of a layout, computed once.

    ``kind[a, b]`` is BOUNDARY when a and b share a whole edge, CORNER when they share
    only corner nodes, NONE otherwise. ``entries(p, f, q)`` lists q's corners at the node
    of p's corner f: the start corners q may take when p finishes at f.
    """

    def __init__(self, layout):
        self.layout = layout
        cn = np.asarray(layout.corner_nodes, dtype=np.int64)
        n = len(cn)
        self.n = n
        n_nodes = int(cn.max()) + 1 if cn.size else 0
        inc = np.zeros((n, max(n_nodes, 1)), dtype=np.int32)
        for k in range(4):
            inc[np.arange(n), cn[:, k]] = 1
        share = (inc @ inc.T) > 0
        kind = np.where(share, CORNER, NONE).astype(np.int8)
        for link in layout.edge_links:
            kind[link.a, link.b] = kind[link.b, link.a] = BOUNDARY
        np.fill_diagonal(kind, NONE)
        self.kind = kind
        at_node: dict[int, list[tuple[int, int]]] = {}
        for p in range(n):
            for k in range(4):
                at_node.setdefault(int(cn[p, k]), []).append((p, k))
        self.at_node = at_node
        # _enter[p][f] = {q: (s', ...)}
        self._enter = [[{} for _ in range(4)] for _ in range(n)]
        for members in at_node.values():
            for p, f in members:
                d = self._enter[p][f]
                for q, s in members:
                    if q != p:
                        d.setdefault(q, [])
                        if s not in d[q]:
                            d[q].append(s)
        self.corner_nodes = cn

    def entries(self, p: int, f: int, q: int) -> list[int]:
        """Corners of q at the same node as corner f of p (possible starts of q)."""
        return self._enter[p][f].get(q, [])

    def link(self, a: int, b: int) -> str | None:
        return KIND_NAMES[int(self.kind[a, b])]

    def boundary_adjacency(self) -> list[list[int]]:
        return [list(np.flatnonzero(self.kind[p] == BOUNDARY)) for p in range(self.n)]

    def shared_edge_corners(self, p: int, q: int) -> list[tuple[int, int]]:
        """(corner, corner) of p's edges shared with q: figure 6's shared edge."""
        return [EDGE_CORNERS[l.ea] for l in self.layout.edge_links_between(p, q)]


def layout_hash(layout) -> str:
    """A short fingerprint of the layout's topology (patch corners as nodes).

    Written into the processing list so that loading it against another model's layout
    is refused rather than silently misread.
    """
    cn = np.ascontiguousarray(np.asarray(layout.corner_nodes, dtype=np.int64))
    h = hashlib.sha256()
    h.update(str(cn.shape).encode())
    h.update(cn.tobytes())
    return "sha256:" + h.hexdigest()[:16]


def chord_edge_lengths(layout, p: int) -> np.ndarray:
    """Edge lengths of patch p estimated by the chords between its corner points (mm)."""
    pts = layout.node_points[layout.corner_nodes[p]]
    return np.array([np.linalg.norm(pts[b] - pts[a]) for a, b in EDGE_CORNERS])


def model_edge_lengths(model, samples: int = 17):
    """A callable patch -> its 4 edge lengths (mm), measured on ``model``'s surface.

    Polyline length through ``samples`` points of each edge (``model.evaluate(p, u, v).P``).
    """
    from ..layout.layout import CORNER_UV
    t = np.linspace(0.0, 1.0, samples)

    def lengths(p: int) -> np.ndarray:
        out = np.empty(4)
        for k, (a, b) in enumerate(EDGE_CORNERS):
            uv = CORNER_UV[a][None, :] + t[:, None] * (CORNER_UV[b] - CORNER_UV[a])[None, :]
            pts = np.asarray(model.evaluate(p, uv[:, 0], uv[:, 1]).P).reshape(-1, 3)
            out[k] = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
        return out

    return lengths


def preferred_crossfeeds(layout, edge_lengths=None, hints=None) -> list[str]:
    """Default crossfeed per patch: across the patch's shorter extent (section 3.3).

    The paper's default is the direction giving the shorter path. On a patch of extents
    Lu (along u: edges 0 and 2) and Lv (edges 1 and 3) with side step g, crossfeed u makes
    about Lu/g + 1 lines of length Lv and crossfeed v about Lv/g + 1 lines of length Lu:
    both cut Lu*Lv/g + Lu + Lv, so on a near-flat patch the length hardly decides; what
    differs is the number of lines, i.e. of reversals where the machine slows down. Fewer,
    longer lines come from stepping across the *shorter* extent: 'u' when Lu < Lv, 'v'
    when Lv < Lu, and the paper's default 'u' on a tie or when lengths are unknown (zero).

    ``edge_lengths(p)`` returns the four edge lengths of patch p (the kernel's true
    lengths); without it the chords between corner points are used. ``hints`` maps
    patch -> 'u'/'v' and overrides both.
    """
    out = []
    for p in range(layout.n_patches):
        if hints and p in hints:
            out.append(hints[p])
            continue
        lengths = np.asarray(edge_lengths(p) if edge_lengths else chord_edge_lengths(layout, p),
                             dtype=float)
        lu = 0.5 * (lengths[0] + lengths[2])
        lv = 0.5 * (lengths[1] + lengths[3])
        scale = max(lu, lv)
        if not np.isfinite(scale) or scale <= 0 or abs(lu - lv) <= 1e-9 * scale:
            out.append("u")
        else:
            out.append("u" if lu < lv else "v")
    return out
