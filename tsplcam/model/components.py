"""Connected components: of a graph given by its edges, and of points closer than a tolerance.

What the model builders group with it: faces or face pieces into patches (joined across
edges that are not patch boundaries), patch corners into nodes, element corners into
vertices. scipy does the work (``csgraph.connected_components``, ``cKDTree``); the labels are
numbered in the order of each component's smallest member, so results do not depend on how
the graph was traversed.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree


def components(n: int, pairs) -> np.ndarray:
    """Component label (n,) of each of n nodes joined by the edges ``pairs`` (k, 2): labels
    0, 1, ... in the order of each component's smallest node."""
    if n == 0:
        return np.zeros(0, dtype=int)
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    count, labels = connected_components(graph, directed=False)
    first = np.full(count, n)
    np.minimum.at(first, labels, np.arange(n))
    rank = np.empty(count, dtype=int)
    rank[np.argsort(first, kind="stable")] = np.arange(count)
    return rank[labels]


def groups(labels: np.ndarray) -> list[list[int]]:
    """The members of each component (ascending), components in label order."""
    labels = np.asarray(labels, dtype=int)
    order = np.argsort(labels, kind="stable")
    cuts = np.nonzero(np.diff(labels[order]))[0] + 1
    return [part.tolist() for part in np.split(order, cuts)] if len(labels) else []


def merge_points(points: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Points closer than ``tol`` (in chains) are one: (cluster id of each point, cluster
    means), clusters numbered by their first point."""
    points = np.asarray(points, float)
    pairs = cKDTree(points).query_pairs(tol, output_type="ndarray")
    ids = components(len(points), pairs)
    centres = np.zeros((ids.max() + 1, points.shape[1]))
    np.add.at(centres, ids, points)
    centres /= np.bincount(ids)[:, None]
    return ids, centres
