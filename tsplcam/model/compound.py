"""Compound models: separate four-sided patches (CAD faces) joined where their edges meet.

The compound-NURBS baseline of shang2020: every face is a patch of its own, and two faces
are neighbours where a whole edge of one is a whole edge of the other. Edges are matched
by geometry (both end points and three inner points within a tolerance, in the same or
the opposite direction), so sewn solids and loose faces from STEP/IGES files behave alike;
a face edge that meets only part of another's is left without a neighbour. Corners closer
than the tolerance are one node; nodes inside the surface where other than four patches
meet (a box corner: three) are extraordinary points, as in the kernel's patch layouts.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError
from .components import merge_points
from .model import ExtraordinaryPoint, Model
from .patch import EdgeNeighbour, Patch

TOL_REL = 1e-6                    # default tolerance: this times the model's size
_TAU = np.array([0.0, 0.25, 0.5, 0.75, 1.0])


def edge_samples(patches: list[Patch]) -> np.ndarray:
    """Points at _TAU along every patch edge, (npatch, 4, len(_TAU), 3)."""
    out = np.empty((len(patches), 4, len(_TAU), 3))
    for i, p in enumerate(patches):
        for e in range(4):
            out[i, e] = p.evaluate(*p.edge_params(e, _TAU)).P
    return out


def compound_model(patches: list[Patch], source: str | None = None, name: str | None = None,
                   tol: float | None = None, kind: str = "compound nurbs") -> Model:
    """Join ``patches`` (indices 0..n-1 in order) into a Model: neighbours, corner nodes,
    extraordinary points. ``tol`` defaults to TOL_REL times the size of the model."""
    if not patches:
        raise InputError("no faces to make patches of", path=source)
    S = edge_samples(patches)
    if not np.all(np.isfinite(S)):
        i = int(np.nonzero(~np.isfinite(S).all(axis=(1, 2, 3)))[0][0])
        raise InputError("its edges do not evaluate to finite points", path=source, item=patches[i].name)
    pts = S.reshape(-1, 3)
    size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    tol = float(tol) if tol is not None else TOL_REL * max(size, 1e-12)
    _check_collapsed(patches, S, tol, source)
    links = _match_edges(patches, S, tol, source)
    for (a, ea), (b, eb), rev in links:
        patches[a].neighbours[ea] = EdgeNeighbour(b, eb, rev)
        patches[b].neighbours[eb] = EdgeNeighbour(a, ea, rev)
    # nodes: corners merged within tol
    corners = S[:, :, 0, :].reshape(-1, 3)             # corner k = start of edge k
    node, node_points = merge_points(corners, tol)
    node = node.reshape(len(patches), 4)
    for p, nn in zip(patches, node):
        p.corner_nodes = nn.copy()
    eps = []
    for n in range(len(node_points)):
        uses = np.argwhere(node == n)
        boundary = False
        for p, k in uses:
            # the two edges of patch p at corner k: k (starting there) and k-1 (ending there)
            if patches[p].neighbours[k] is None or patches[p].neighbours[(k - 1) % 4] is None:
                boundary = True
        valence = len(uses)
        if (not boundary and valence != 4) or (boundary and valence > 2):
            eps.append(ExtraordinaryPoint(n, valence, node_points[n].copy(), boundary))
    return Model(patches, node_points, eps, kind, source, name=name)


def _check_collapsed(patches, S, tol, source) -> None:
    for i, p in enumerate(patches):
        for e in range(4):
            if np.linalg.norm(S[i, e] - S[i, e, :1], axis=1).max() <= tol:
                raise InputError(f"its edge {e} is collapsed to a point (a pole): such faces have "
                                 f"no normal there and are not supported", path=source, item=p.name)


def _match_edges(patches, S, tol, source) -> list:
    mids = S[:, :, 2, :].reshape(-1, 3)
    tree = cKDTree(mids)
    links, partner = [], {}
    for i, j in sorted(tree.query_pairs(tol)):
        a, ea = divmod(int(i), 4)
        b, eb = divmod(int(j), 4)
        A, B = S[a, ea], S[b, eb]
        fwd = np.linalg.norm(A - B, axis=1).max()
        rev = np.linalg.norm(A - B[::-1], axis=1).max()
        if min(fwd, rev) > tol:
            continue
        for x, y in (((a, ea), (b, eb)), ((b, eb), (a, ea))):
            if x in partner and partner[x] != y:
                names = {patches[x[0]].name, patches[y[0]].name, patches[partner[x][0]].name}
                raise InputError(f"more than two faces meet along one edge ({', '.join(sorted(names))}): "
                                 f"non-manifold shapes are not supported", path=source,
                                 item=patches[x[0]].name)
            partner[x] = y
        if (a, ea) == (b, eb):
            continue
        links.append(((a, ea), (b, eb), bool(rev <= fwd)))
    seen, out = set(), []
    for l in links:
        key = frozenset(l[:2])
        if key not in seen:
            seen.add(key)
            out.append(l)
    return out
