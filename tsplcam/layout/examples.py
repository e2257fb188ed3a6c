"""Known patch layouts: the sample models' patch graphs and the paper's figures 4 and 5c.

Built by hand with :meth:`Layout.from_quads` (corners 0..3 counter-clockwise seen from the
tool side: lower-left, lower-right, upper-right, upper-left), with node positions in mm so
each can later become a real sample surface. tests/model/test_samples.py checks that the
real sample models (``tsplcam.model``) produce the same graphs.

``EXAMPLES`` maps the names the command line accepts to the functions.
"""
from __future__ import annotations

import numpy as np

from ..model.samples import bump, figure4_arrangement
from .layout import Layout


def keycap() -> Layout:
    """Open box: a top and four sides, 5 patches (the keycap sample's layout).

    The four top corners are extraordinary nodes of valence 3 (top + two sides); the
    bottom rim is an open boundary. Sides lean in by 1 mm over 10 mm (draft)::

        top (patch 0) seen from above        side i: b_i -> b_i+1 along u, up along v
          7 ------- 6
          |    0    |     nodes 0..3: bottom rim b0..b3 at z = 0
          4 ------- 5     nodes 4..7: top corners t0..t3 at z = 10
    """
    pts = [(-10, -10, 0), (10, -10, 0), (10, 10, 0), (-10, 10, 0),
           (-9, -9, 10), (9, -9, 10), (9, 9, 10), (-9, 9, 10)]
    quads = [(4, 5, 6, 7)] + [(i, (i + 1) % 4, 4 + (i + 1) % 4, 4 + i) for i in range(4)]
    names = ["top", "front", "right", "back", "left"]
    return Layout.from_quads(quads, pts, extraordinary=(4, 5, 6, 7), names=names)


def head() -> Layout:
    """Head-like closed model: the cube layout, 6 patches, 8 extraordinary nodes of valence 3.

    Node k has the signs of (x, y, z) = bits of (0: -,-,-), (1: +,-,-), (2: +,+,-),
    (3: -,+,-), then 4..7 the same at +z; half sizes 40 x 50 x 60 mm (a head's box).
    Every face is counter-clockwise seen from outside.
    """
    sx, sy, sz = 40.0, 50.0, 60.0
    pts = [(-sx, -sy, -sz), (sx, -sy, -sz), (sx, sy, -sz), (-sx, sy, -sz),
           (-sx, -sy, sz), (sx, -sy, sz), (sx, sy, sz), (-sx, sy, sz)]
    quads = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    names = ["neck", "crown", "face", "right", "back", "left"]
    return Layout.from_quads(quads, pts, extraordinary=range(8), names=names)


def figure4() -> Layout:
    """12 patches after the paper's figure 4 (:func:`tsplcam.model.samples.figure4_arrangement`:
    a 4 x 3 grid with one edge rotated; b, c, e, f extraordinary).

    Patch 0 (the rotated quad a-b-c-f) is boundary linked with 1, 3, 4 and 6 (blue in
    the paper), corner linked only with 2, 5, 7, 8 and 9 (green), and unlinked with 10
    and 11 (gray). z follows a smooth bump.
    """
    a = figure4_arrangement()
    return Layout.from_quads(a.corner_nodes, a.node_points, extraordinary=a.extraordinary, names=a.names)


def _grid_quads(cells, stride):
    return [(j * stride + i, j * stride + i + 1, (j + 1) * stride + i + 1, (j + 1) * stride + i)
            for i, j in cells]


def _grid_points(nx, ny, size=20.0):
    return np.array([(size * i, size * j, bump(size * i, size * j))
                     for j in range(ny + 1) for i in range(nx + 1)])


def figure5c() -> Layout:
    """A layout whose every order needs corner links (the paper's figure 5c): a cross.

    The centre patch 0 shares an edge with each arm; the arms touch each other only at
    the centre's corners. The boundary-link graph is a star (no Hamiltonian path), and
    any order crosses at least two corners, e.g. 1 -c- 2 -b- 0 -b- 4 -c- 3::

               +----+
               | 1  |
          +----+----+----+
          | 4  | 0  | 2  |
          +----+----+----+
               | 3  |
               +----+
    """
    cells = [(1, 1), (1, 2), (2, 1), (1, 0), (0, 1)]
    return Layout.from_quads(_grid_quads(cells, 4), _grid_points(3, 3),
                             names=["centre", "north", "east", "south", "west"])


def tee() -> Layout:
    """A T: a bar of three patches and a stem under its middle; one corner link needed."""
    cells = [(1, 1), (0, 1), (2, 1), (1, 0)]
    return Layout.from_quads(_grid_quads(cells, 4), _grid_points(3, 2),
                             names=["centre", "west", "east", "stem"])


def propeller() -> Layout:
    """Three patches touching only at one node (three sectors of a six-fold fan).

    Whatever the order, the middle patch would start and finish at the shared node,
    which a zigzag cannot: every order needs one retraction.
    """
    pts = [(0.0, 0.0, 0.0)]
    for k in range(6):
        t = np.radians(60 * k)
        pts.append((20 * np.cos(t), 20 * np.sin(t), 0.0))
    for k in range(6):
        t = np.radians(60 * k + 30)
        pts.append((28 * np.cos(t), 28 * np.sin(t), 0.0))
    quads = [(0, 1 + k, 7 + k, 1 + (k + 1) % 6) for k in (0, 2, 4)]
    return Layout.from_quads(quads, pts, names=["blade 0", "blade 1", "blade 2"])


def twin() -> Layout:
    """Two separate strips of two patches (two cavities): one retraction between them."""
    cells = [(0, 0), (1, 0), (3, 0), (4, 0)]
    return Layout.from_quads(_grid_quads(cells, 6), _grid_points(5, 1))


def grid(nx: int = 10, ny: int = 10, size: float = 10.0) -> Layout:
    """A regular nx x ny grid of patches (all interior nodes regular)."""
    cells = [(i, j) for j in range(ny) for i in range(nx)]
    return Layout.from_quads(_grid_quads(cells, nx + 1), _grid_points(nx, ny, size))


def random_layout(seed: int, n: int, style: str = "grid") -> Layout:
    """Small random layouts for brute-force tests.

    ``grid``: n random cells of a square grid (holes, corner-only contacts, pieces);
    ``fan``: sectors around nodes of random valence 3..6 glued to grid cells (corner
    links around extraordinary nodes); ``pool``: quads on random nodes of a small pool
    (arbitrary, even non-manifold topology: a stress test of the rules, not a surface).
    """
    rng = np.random.default_rng(seed)
    if style == "grid":
        side = int(np.ceil(np.sqrt(n))) + 1
        cells = [(int(c) % side, int(c) // side)
                 for c in rng.choice(side * side, size=n, replace=False)]
        return Layout.from_quads(_grid_quads(cells, side + 1), _grid_points(side, side))
    if style == "fan":
        quads: list = []
        anchors: list = []
        next_node = 0
        while len(quads) < n:
            val = int(rng.integers(3, 7))
            if anchors and rng.random() < 0.8:
                centre = int(rng.choice(anchors))
            else:
                centre, next_node = next_node, next_node + 1
            spokes = list(range(next_node, next_node + val))
            outer = list(range(next_node + val, next_node + 2 * val))
            next_node += 2 * val
            keep = rng.random(val) < 0.6
            keep[int(rng.integers(val))] = True
            for k in range(val):
                if keep[k] and len(quads) < n:
                    quads.append((centre, spokes[k], outer[k], spokes[(k + 1) % val]))
            anchors += [centre] + spokes + outer
        return Layout.from_quads(quads)
    if style == "pool":
        pool = max(5, int(1.6 * n))
        quads = [tuple(int(x) for x in rng.choice(pool, size=4, replace=False))
                 for _ in range(n)]
        return Layout.from_quads(quads)
    raise ValueError(f"unknown random layout style {style!r}")


EXAMPLES = {
    "keycap": keycap,
    "head": head,
    "figure4": figure4,
    "figure5c": figure5c,
    "tee": tee,
    "propeller": propeller,
    "twin": twin,
    "grid10": grid,
}
