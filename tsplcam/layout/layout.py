"""Patch adjacency of a model: which patches share a whole edge, which only a corner.

Conventions (shang2020 section 3.2): every patch has (u, v) on the unit square, with the
corner and edge numbering of :mod:`tsplcam.model.patch` (re-exported here): corner 0 =
(0,0) lower left, counter-clockwise; edge k runs from corner k to corner k+1.

Every patch corner is a *node* (a point of the model shared by the patches meeting there);
two patch corners are the same point in space exactly when they are the same node.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..model.patch import CORNER_NAMES, CORNER_UV, EDGE_CORNERS, EDGE_NAMES  # noqa: F401


@dataclass(frozen=True)
class EdgeLink:
    """Patch ``a``'s edge ``ea`` is the whole of patch ``b``'s edge ``eb`` (a boundary link).

    ``reversed`` is True when a's edge, run from its corner ``ea`` to ``ea+1``, runs
    from b's corner ``eb+1`` to ``eb`` (the usual case for consistently oriented patches).
    """
    a: int
    ea: int
    b: int
    eb: int
    reversed: bool = True

    def corner_pairs(self) -> list[tuple[int, int]]:
        """(corner of a, corner of b) pairs that are the same point."""
        a0, a1 = EDGE_CORNERS[self.ea]
        b0, b1 = EDGE_CORNERS[self.eb]
        return [(a0, b1), (a1, b0)] if self.reversed else [(a0, b0), (a1, b1)]


@dataclass
class Layout:
    """The patch graph the processing list is planned on.

    ``corner_nodes[p, k]`` is the node at corner k of patch p; ``node_points[n]`` its
    position (mm); ``edge_links`` lists each shared edge once; ``extraordinary`` the nodes
    that are extraordinary points (valence != 4 inside the surface).
    """
    corner_nodes: np.ndarray
    node_points: np.ndarray
    edge_links: list[EdgeLink] = field(default_factory=list)
    extraordinary: frozenset = frozenset()
    patch_names: list[str] | None = None

    def __post_init__(self):
        self.corner_nodes = np.asarray(self.corner_nodes, dtype=int).reshape(-1, 4)
        self.node_points = np.asarray(self.node_points, dtype=float).reshape(-1, 3)
        self.extraordinary = frozenset(int(n) for n in self.extraordinary)
        self._edge_of = {}
        for link in self.edge_links:
            self._edge_of.setdefault((link.a, link.b), []).append(link)
            flipped = EdgeLink(link.b, link.eb, link.a, link.ea, link.reversed)
            self._edge_of.setdefault((link.b, link.a), []).append(flipped)

    @property
    def n_patches(self) -> int:
        return len(self.corner_nodes)

    def name(self, p: int) -> str:
        return self.patch_names[p] if self.patch_names else f"patch {p}"

    @classmethod
    def from_quads(cls, quads, points=None, extraordinary=(), names=None) -> "Layout":
        """A layout from patches given as 4 node ids each (corners 0..3 in the order above).

        Two patches are boundary-linked where they share two consecutive corner nodes.
        ``points`` defaults to nothing useful (zeros), which suits pure topology tests.
        """
        quads = np.asarray(quads, dtype=int).reshape(-1, 4)
        n_nodes = int(quads.max()) + 1 if quads.size else 0
        pts = np.zeros((n_nodes, 3)) if points is None else np.asarray(points, float)
        by_pair: dict[tuple[int, int], list[tuple[int, int, bool]]] = {}
        for p, q in enumerate(quads):
            for e, (c0, c1) in enumerate(EDGE_CORNERS):
                n0, n1 = int(q[c0]), int(q[c1])
                key = (min(n0, n1), max(n0, n1))
                by_pair.setdefault(key, []).append((p, e, n0 < n1))
        links = []
        for (n0, n1), uses in by_pair.items():
            for i in range(len(uses)):
                for j in range(i + 1, len(uses)):
                    (pa, ea, fa), (pb, eb, fb) = uses[i], uses[j]
                    links.append(EdgeLink(pa, ea, pb, eb, reversed=(fa != fb)))
        return cls(quads, pts, links, frozenset(extraordinary), names)

    @classmethod
    def from_model(cls, model) -> "Layout":
        """The patch graph of a surface model (:class:`tsplcam.model.model.Model`): a boundary
        link for every pair of patch edges the model made neighbours, the patches' corner
        nodes, and as extraordinary nodes the model's extraordinary points inside the surface."""
        links = []
        for p in model.patches:
            for e, nb in enumerate(p.neighbours):
                if nb is not None and (p.index, e) < (nb.patch, nb.edge):
                    links.append(EdgeLink(p.index, e, nb.patch, nb.edge, nb.reversed))
        corner_nodes = np.array([p.corner_nodes for p in model.patches])
        return cls(corner_nodes, model.node_points, links,
                   frozenset(x.node for x in model.extraordinary if not x.boundary),
                   [p.name for p in model.patches])

    # -- queries -------------------------------------------------------------------------
    def edge_links_between(self, a: int, b: int) -> list[EdgeLink]:
        """Boundary links from a to b, each oriented with a first."""
        return list(self._edge_of.get((a, b), []))

    def shared_corners(self, a: int, b: int) -> list[tuple[int, int]]:
        """(corner of a, corner of b) pairs that are the same node."""
        out = []
        for ca in range(4):
            for cb in range(4):
                if self.corner_nodes[a, ca] == self.corner_nodes[b, cb]:
                    out.append((ca, cb))
        return out

    def link_kind(self, a: int, b: int) -> str | None:
        """'boundary', 'corner' or None for two different patches."""
        if self.edge_links_between(a, b):
            return "boundary"
        if self.shared_corners(a, b):
            return "corner"
        return None

    def neighbours(self, p: int) -> dict[int, str]:
        out = {}
        for q in range(self.n_patches):
            if q != p:
                kind = self.link_kind(p, q)
                if kind:
                    out[q] = kind
        return out

    def corner_point(self, p: int, k: int) -> np.ndarray:
        return self.node_points[self.corner_nodes[p, k]]
